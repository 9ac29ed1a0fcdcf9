"""Stopping policies on recorded traces of three interruptible modules of two domains, against
the clairvoyant stopping point of each trace (not a test: nothing here is asserted).

Modules: the navigation plugin's anytime abstract planner (`find-path`), and the routing
plugin's 2-opt/Or-opt tours (`plan-tours`) and its k-means clustering (`cluster-stops`), each
run at one input quality on its own registered problem set. The traces are recorded by the
profile builder (`traces=True`) on a grid finer than the shipped profile's: training traces with
one seed, test traces with another (disjoint instances). Each policy is built from the training
traces' dynamic profile and replayed on every test trace.

Utility: U(q, t) = q^p - c t / T with T the grid's last time (the value of the answer's
quality, less the cost of the time used), for several (p, c); a monitoring cost m is charged
per look. Each cell is the mean utility of a policy as a fraction of the mean clairvoyant
utility, max over t of U(q_t, t) of each test trace, which knows the whole trace.

1. Without a monitoring cost: fixed (the best expected contract time, never looks), myopic,
   projected (online fit of the run's own curve), optimal (backward induction on the dynamic
   profile); target: optimal >= 0.98 on every module, and never below fixed or myopic by more
   than the standard error of the paired difference.
2. With a monitoring cost: look never (fixed), look every step (the optimal policy of free
   looks, paying for each), and the optimal policy that chooses when to look; target: the last
   beats the other two in every setting.
3. A stopping rule with a guarantee (`ConformalStopping`, calibrated on the training traces):
   how often a test run could still have gained more than epsilon after its stop (the risk it
   promises to keep below alpha; target: at most alpha + 0.01) and the time it used.

Run: .venv/bin/python benchmarks/bench_stopping.py [--quick] [--trials N]
"""

from __future__ import annotations

import argparse
import math
import time
from functools import partial
from pathlib import Path
from typing import Any

import attrs
import numpy as np
from attrs import frozen
from tables import machine, table

from anytime.library import AnytimeLibrary
from anytime.measure.builder import build_profile
from anytime.profiles import DynamicProfile, QualityTraces, load_traces, save_traces
from anytime.profiles.profile import Array
from anytime.runtime.conformal import ConformalStopping
from anytime.runtime.offline import clairvoyant, replay
from anytime.runtime.policies import (
    FixedStopping,
    MyopicStopping,
    OptimalStopping,
    ProjectedStopping,
    StoppingPolicy,
    Utility,
)


@frozen
class Case:
    """A module, the input quality it runs at and the grid its traces are recorded on."""

    module: str
    domain: str
    input_quality: float
    time: tuple[float, ...]


CASES = (
    Case("find-path", "navigation", 1.0, tuple(np.arange(0.0, 2001.0, 50.0))),
    Case("plan-tours", "routing", 0.9, tuple(np.arange(0.0, 49.0, 1.0))),
    Case("cluster-stops", "routing", 0.8, tuple(np.arange(0.0, 25.0, 1.0))),
)

#: (p, c): value q^p, cost c per whole grid of time.
SETTINGS = ((1, 0.02), (1, 0.1), (1, 0.3), (8, 0.1))
MONITORING_COSTS = (0.001, 0.005, 0.02)
#: What the monitor sees: the module's own report of its quality, or its true quality.
VIEWS = ("reported", "true quality")
#: States of the dynamic profiles (quantile bins of what the monitor sees).
STATES = 10


@frozen
class PowerValue:
    """The value of an answer of quality q: q^power."""

    power: float

    def value(self, state: Any, contract: Array, quality: Array) -> Array:
        answer: Array = np.asarray(quality, dtype=np.float64) ** self.power
        return answer


@frozen
class TimeCost:
    """The cost of stopping at time t: rate * t / horizon."""

    rate: float
    horizon: float

    def cost(self, state: Any, contract: Array, quality: Array) -> Array:
        answer: Array = self.rate * np.asarray(contract, dtype=np.float64) / self.horizon
        return answer


def record(case: Case, trials: int, seed: int) -> QualityTraces:
    """`trials` traces of the case's module on its registered problem set."""
    library = AnytimeLibrary.default()
    entry = library[case.module]
    problems = library.measurement(case.module).problems
    build = build_profile(
        entry.module,
        problems,
        time=case.time,
        input_grids=[[case.input_quality]] * len(entry.module.inputs),
        trials=trials,
        seed=seed,
        progress=False,
        traces=True,
    )
    assert build.traces is not None
    return build.traces


def recorded(case: Case, trials: int, seed: int, directory: Path | None) -> QualityTraces:
    """The case's traces: from `directory` when they were kept there, else recorded (and
    kept there)."""
    path = None if directory is None else directory / f"{case.module}-{trials}-{seed}.yaml"
    if path is not None and path.exists():
        return load_traces(path)
    traces = record(case, trials, seed)
    if path is not None:
        directory.mkdir(parents=True, exist_ok=True)
        save_traces(traces, path)
    return traces


def flat(traces: QualityTraces) -> tuple[Array, Array, Array]:
    """Observed quality, true quality and whether there was a result, one row per trace."""
    m = len(traces.time)
    return (
        traces.observed.reshape(-1, m),
        traces.quality.reshape(-1, m),
        traces.scored.reshape(-1, m),
    )


def realised(
    policy: StoppingPolicy, test: QualityTraces, utility: Utility, monitoring: float
) -> tuple[Array, Array]:
    """The utility each test trace gets under the policy (started afresh on each), looks paid,
    and the looks it took."""
    observed, true, scored = flat(test)
    ended = test.end_index().reshape(-1)
    t = test.time
    stops, looks = np.empty(len(true), dtype=np.intp), np.empty(len(true))
    for i in range(len(true)):  # a policy reads the trace as it goes: one replay per trace
        result = replay(policy, t, observed[i], scored=scored[i], ended=int(ended[i]))
        stops[i], looks[i] = result.stop_index, result.looks
    value: Array = utility(t[stops], true[np.arange(len(true)), stops][:, None])[:, 0]
    return value - monitoring * looks, looks


def make(
    profile: DynamicProfile,
    value: PowerValue,
    cost: TimeCost,
    input_quality: float,
    kind: type,
    **options: Any,
) -> StoppingPolicy:
    """A policy of `kind` on the profile at the input quality its traces were recorded at."""
    inputs = [input_quality] * len(profile.input_grids)
    policy: StoppingPolicy = kind(profile, value, cost, input_quality=inputs, **options)
    return policy


def ratio(utilities: Array, best: Array) -> str:
    return f"{utilities.mean() / best.mean():.3f}"


def paired_se(a: Array, b: Array, best: Array) -> float:
    """The standard error of mean(a - b), as a fraction of the mean clairvoyant utility."""
    difference = a - b
    return float(difference.std(ddof=1) / math.sqrt(len(a)) / best.mean())


def view_of(traces: QualityTraces, view: str) -> QualityTraces:
    """The traces as a monitor sees them: what the module reports, or its true quality (as a
    module that could score itself would report it)."""
    if view == "reported":
        return traces
    return attrs.evolve(traces, reports="true", estimate=None)


def free_looks(
    case: Case, profile: DynamicProfile, test: QualityTraces, label: str
) -> list[list[str]]:
    """Rows of section 1: each policy's utility ratio, per utility setting."""
    rows = []
    for power, rate in SETTINGS:
        value, cost = PowerValue(power), TimeCost(rate, case.time[-1])
        utility = Utility(value, cost)
        best = clairvoyant(test.time, flat(test)[1], utility)
        policy = partial(make, profile, value, cost, case.input_quality)
        got = {
            name: realised(policy(kind), test, utility, 0.0)[0]
            for name, kind in (
                ("fixed", FixedStopping),
                ("myopic", MyopicStopping),
                ("projected", ProjectedStopping),
                ("optimal", OptimalStopping),
            )
        }
        others = ("fixed", "myopic")
        lead = min((got["optimal"] - got[o]).mean() / best.mean() for o in others)
        se = max(paired_se(got["optimal"], got[o], best) for o in others)
        rows.append(
            [
                f"{label}, q^{power} - {rate:g} t/T",
                *(ratio(got[name], best) for name in got),
                f"{lead:+.4f} ({se:.4f})",
            ]
        )
    return rows


def costly_looks(
    case: Case, profile: DynamicProfile, test: QualityTraces, label: str
) -> list[list[str]]:
    """Rows of section 2: looking never, every step, or when the policy chooses, per
    monitoring cost, with utility q - 0.1 t/T."""
    value, cost = PowerValue(1), TimeCost(0.1, case.time[-1])
    utility = Utility(value, cost)
    best = clairvoyant(test.time, flat(test)[1], utility)
    policy = partial(make, profile, value, cost, case.input_quality)
    rows = []
    for monitoring in MONITORING_COSTS:
        runs = {
            name: realised(policy(kind, **options), test, utility, monitoring)
            for name, kind, options in (
                ("never", FixedStopping, {}),
                ("every step", OptimalStopping, {}),
                ("when to look", OptimalStopping, {"monitoring_cost": monitoring}),
            )
        }
        mean = {name: run[0].mean() for name, run in runs.items()}
        rows.append(
            [
                f"{label}, {monitoring:g} a look",
                *(f"{mean[name] / best.mean():.3f}" for name in runs),
                f"{runs['when to look'][1].mean():.1f}",
                verdict(mean, runs["when to look"][1]),
            ]
        )
    return rows


#: (alpha, epsilon) of the rule with a guarantee: the risk, and the gain in true quality.
GUARANTEES = ((0.1, 0.02), (0.05, 0.02), (0.1, 0.05))


def guaranteed(
    case: Case, train: QualityTraces, test: QualityTraces, label: str
) -> list[list[str]]:
    """Rows of section 3: the conformal rule calibrated on the training traces, replayed on the
    test traces: how often going on would still have gained more than epsilon (the risk it
    promises to keep below alpha), and the time it used."""
    observed, true, scored = flat(test)
    ended = test.end_index().reshape(-1)
    t = test.time
    rows = []
    for alpha, epsilon in GUARANTEES:
        policy = ConformalStopping(
            train, epsilon, alpha, input_quality=[case.input_quality] * len(train.input_grids)
        )
        stops = np.array(
            [
                replay(policy, t, observed[i], scored=scored[i], ended=int(ended[i])).stop_index
                for i in range(len(true))
            ]
        )
        at_stop = true[np.arange(len(true)), stops]
        later = np.where(np.arange(len(t)) >= stops[:, None], true, -np.inf).max(axis=1)
        missed = (later - at_stop) > epsilon
        rate = float(missed.mean())
        se = math.sqrt(max(rate * (1 - rate), 1e-12) / len(missed))
        rows.append(
            [
                label,
                f"{alpha:g}",
                f"{epsilon:g}",
                f"{rate:.3f} ({se:.3f})",
                "yes" if rate <= alpha + 0.01 else "NO",
                f"{float(t[stops].mean() / t[-1]):.2f}",
                f"{float(at_stop.mean()):.3f}",
                f"{float(later.mean()):.3f}",
            ]
        )
    return rows


def verdict(mean: dict[str, float], looks: Array) -> str:
    """Whether choosing when to look beat looking never and looking every step; a policy that
    finds looking not worth its cost never looks, and ties with never looking."""
    ahead = mean["when to look"] - max(mean["never"], mean["every step"])
    if not looks.any() and mean["when to look"] == mean["never"]:
        return "ties never (no look is worth it)"
    return "yes" if ahead > 0 else "no"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer traces (about a minute)")
    parser.add_argument("--trials", type=int, help="training and test traces (default 400)")
    parser.add_argument(
        "--traces",
        type=Path,
        help="a directory to keep the recorded traces in (anytime-traces/1 files), read back"
        " when they are there with as many trials",
    )
    args = parser.parse_args()
    trials = args.trials or (150 if args.quick else 400)
    print(machine())
    started = time.perf_counter()
    data = {}
    for case in CASES:
        data[case.module] = (
            recorded(case, trials, 1, args.traces),
            recorded(case, trials, 2, args.traces),
        )
    print(f"\n(traces recorded in {time.perf_counter() - started:.0f} s)")

    free_rows, costly_rows, guarantee_rows = [], [], []
    for case in CASES:
        for view in VIEWS:
            train, test = (view_of(traces, view) for traces in data[case.module])
            profile = DynamicProfile.from_traces(train, states=STATES)
            label = f"{case.module} ({case.domain}), {view}"
            free_rows.extend(free_looks(case, profile, test, label))
            costly_rows.extend(costly_looks(case, profile, test, label))
            guarantee_rows.extend(guaranteed(case, train, test, label))
    print()
    print(
        table(
            [
                "module, what the monitor sees, utility",
                "fixed",
                "myopic",
                "projected",
                "optimal",
                "optimal - best of fixed, myopic (se)",
            ],
            free_rows,
        )
    )
    print(
        f"\n(mean utility over {trials} test traces as a fraction of the clairvoyant's; the"
        f" policies come from {trials} training traces of other instances; target: optimal >="
        " 0.98, and its lead over fixed and myopic never below minus its standard error)"
    )
    print()
    print(
        table(
            [
                "module, utility, monitoring cost",
                "look never",
                "look every step",
                "when to look",
                "looks",
                "beats both",
            ],
            costly_rows,
        )
    )
    print(
        "\n(utility less the monitoring cost of each look, as a fraction of the clairvoyant's"
        " (who pays none); looks: the mean number the when-to-look policy takes)"
    )
    print()
    print(
        table(
            [
                "module, what the monitor sees",
                "alpha",
                "epsilon",
                "missed (se)",
                "<= alpha + 0.01",
                "time used",
                "quality at stop",
                "best later",
            ],
            guarantee_rows,
        )
    )
    print(
        "\n(ConformalStopping calibrated on the training traces, replayed on the test traces:"
        " missed, the share of test runs whose true quality would still have risen by more than"
        " epsilon after the stop, which the rule promises to keep below alpha; time used, as a"
        " fraction of the grid's last time; quality at stop and the best the run reached later,"
        " means)"
    )
    print(f"(all: {time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
