"""Stopping policies on recorded traces of four interruptible modules, against the clairvoyant
stopping point of each trace, and on synthetic families against their exact Bayes optimum (not
a test: nothing here is asserted).

Modules: the navigation plugin's anytime abstract planner (`find-path`), the routing plugin's
2-opt/Or-opt tours (`plan-tours`) and its k-means clustering (`cluster-stops`), each run at one
input quality on its own registered problem set, and a module that stalls, the toy test
plugin's random-restart local search (`toy-search`, tests/plugins/toy_plugin: it registers a
result only when it improves, often at first and rarely after ~40 ticks). The traces are
recorded by the profile builder (`traces=True`) on a grid finer than the shipped profile's:
training traces with one seed, test traces with another (disjoint instances). Each policy is
built from the training traces' dynamic profile and replayed on every test trace.

Utility: U(q, t) = q^p - c t / T with T the grid's last time (the value of the answer's
quality, less the cost of the time used), for several (p, c); a monitoring cost m is charged
per look. Each cell is the mean utility of a policy as a fraction of the mean clairvoyant
utility, max over t of U(q_t, t) of each test trace, which knows the whole trace.

1. Without a monitoring cost: fixed (the best expected contract time, never looks), myopic,
   projected (online fit of the run's own curve), optimal (backward induction on the dynamic
   profile); target: optimal >= 0.98 on every module, and never below fixed or myopic by more
   than the standard error of the paired difference.
2. With a monitoring cost: look never (fixed), look every step (the optimal policy of free
   looks, paying for each), and the optimal policy that chooses when to look (on the state
   `fit_optimal` chose, and on 10 bins for comparison); target: the fitted one beats the other
   two in every setting (or ties looking never, where no look is worth its cost).
3. A stopping rule with a guarantee (`ConformalStopping`, calibrated on the training traces):
   how often a test run could still have gained more than epsilon after its stop (the risk it
   promises to keep below alpha; target: at most alpha + 0.01) and the time it used and saved
   against running each run to its end.
4. Synthetic families with their exact Bayes optimum, computed here: q(t) = 1 - exp(-lambda t)
   on 32 grid times, lambda drawn per run from a prior on 600 rates (log-uniform, or gamma).
   The monitor sees the true quality, a quantised estimate (q floored to 10 levels) or a
   biased one (the quantised q times 1 + beta, beta drawn per run from five values): each a
   deterministic function of the hidden state, so the posterior given the looks is the prior
   restricted to the states that would have shown the same, and backward induction over the
   cells of states the looks cannot tell apart is exact Bayes (with a monitoring cost, a
   memoised recursion over (time of the last look, cell) choosing the next look or a stop
   without looking; a cell is a range of rates per bias). Policies are built on 2,000
   training runs and replayed on 2,000 test runs; the Bayes policy is replayed too, and its
   realised mean checked against its exact value. The optimal policy is `fit_optimal`'s: the
   Markov policy on the state (quality bins x classes of the time the run entered its bin),
   or the history policy where it beats every such state by more than a standard error, that
   5-fold cross-validation on the training runs chose, its claim the cross-validated utility;
   "optimal, bin only" is the Markov policy on 10 bins alone, its claim its model's
   value, for comparison. Targets for the optimal (and history) policy: >= 0.98 of the Bayes
   optimum, never below fixed by more than the se of the paired difference, its claimed
   expected utility within 2 se of what it realises (the se of both: the claim's own and the
   test runs').

   Section 1 has the fitted optimal policy too (and "optimal, 10 bins", the Markov policy on
   the benchmark's own profile), with its chosen state and its claim against what it realised.

Run: .venv/bin/python benchmarks/bench_stopping.py [--quick] [--quick-synthetic] [--trials N]
[--part all|modules|synthetic]
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

import attrs
import numpy as np
from attrs import frozen
from numpy.typing import NDArray
from tables import machine, table

from anytime.library import AnytimeLibrary
from anytime.measure.builder import build_profile
from anytime.modules import AnytimeModule
from anytime.problems import ProblemSet
from anytime.profiles import DynamicProfile, QualityTraces, load_traces, save_traces
from anytime.profiles.profile import Array
from anytime.runtime.conformal import ConformalStopping
from anytime.runtime.learned import HistoryStopping
from anytime.runtime.observe import Decision
from anytime.runtime.offline import clairvoyant, replay
from anytime.runtime.policies import (
    LOOK_AT,
    STOP,
    STOP_AT,
    FixedStopping,
    MyopicStopping,
    OptimalStopping,
    ProjectedStopping,
    StoppingPolicy,
    Utility,
)
from anytime.runtime.selection import FittedStopping, fit_optimal


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
    # A module that stalls: it registers only when it improves, and rarely does after ~40 ticks.
    Case("toy-search", "test plugin", 1.0, tuple(np.arange(0.0, 101.0, 2.0))),
)

#: The test plugin that holds the stalling module (tests/plugins/toy_plugin, not installed).
TOY_PLUGIN = Path(__file__).resolve().parent.parent / "tests" / "plugins" / "toy_plugin"

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
    module, problems = module_and_problems(case)
    build = build_profile(
        module,
        problems,
        time=case.time,
        input_grids=[[case.input_quality]] * len(module.inputs),
        trials=trials,
        seed=seed,
        progress=False,
        traces=True,
    )
    assert build.traces is not None
    return build.traces


def module_and_problems(case: Case) -> tuple[AnytimeModule, ProblemSet]:
    """The case's module and its problem set: from the installed plugins, or from the test
    plugin's source."""
    if case.domain == "test plugin":
        sys.path.insert(0, str(TOY_PLUGIN))
        from toy_anytime_plugin.search import PLUGIN

        (module,) = PLUGIN.modules
        return module, PLUGIN.problem_sets[case.module].problems
    library = AnytimeLibrary.default()
    entry = library[case.module]
    assert entry.module is not None
    return entry.module, library.measurement(case.module).problems


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


def lead(got: dict[str, Array], name: str, best: Array) -> str:
    """A policy's least lead over fixed and myopic, with the largest paired standard error, as
    fractions of the mean clairvoyant utility ('-': not measured)."""
    if name not in got:
        return "-"
    others = ("fixed", "myopic")
    ahead = min((got[name] - got[o]).mean() / best.mean() for o in others)
    se = max(paired_se(got[name], got[o], best) for o in others)
    return f"{ahead:+.4f} ({se:.4f})"


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
    case: Case,
    profile: DynamicProfile,
    train: QualityTraces,
    test: QualityTraces,
    label: str,
    history: bool,
) -> list[list[str]]:
    """Rows of section 1: each policy's utility ratio, per utility setting (the history
    policy's, learned on the training traces, when asked: "-" otherwise), and the fitted
    optimal policy's state and claim against what it realised."""
    rows = []
    for power, rate in SETTINGS:
        value, cost = PowerValue(power), TimeCost(rate, case.time[-1])
        utility = Utility(value, cost)
        best = clairvoyant(test.time, flat(test)[1], utility)
        policy = partial(make, profile, value, cost, case.input_quality)
        inputs = [case.input_quality] * len(train.input_grids)
        fit = fit_optimal(train, utility, input_quality=inputs)
        got = {
            name: realised(policy(kind), test, utility, 0.0)[0]
            for name, kind in (
                ("fixed", FixedStopping),
                ("myopic", MyopicStopping),
                ("projected", ProjectedStopping),
                ("optimal, 10 bins", OptimalStopping),
            )
        }
        got["optimal"] = realised(fit.policy, test, utility, 0.0)[0]
        learned = history_policy(train, utility, 0.0, case.input_quality) if history else None
        if learned is not None:
            got["history"] = realised(learned, test, utility, 0.0)[0]
        claim = Outcome(got["optimal"], fit.utility, fit.standard_error)
        rows.append(
            [
                f"{label}, q^{power} - {rate:g} t/T",
                *(ratio(got[name], best) for name in got),
                *(["-"] if "history" not in got else []),
                lead(got, "optimal", best),
                lead(got, "history", best),
                state_of(fit),
                _claim(claim),
            ]
        )
    return rows


def costly_looks(
    case: Case, profile: DynamicProfile, train: QualityTraces, test: QualityTraces, label: str
) -> list[list[str]]:
    """Rows of section 2: looking never, every step, or when the policy chooses (on the
    benchmark's profile, and on the state `fit_optimal` chose), per monitoring cost, with
    utility q - 0.1 t/T."""
    value, cost = PowerValue(1), TimeCost(0.1, case.time[-1])
    utility = Utility(value, cost)
    best = clairvoyant(test.time, flat(test)[1], utility)
    policy = partial(make, profile, value, cost, case.input_quality)
    inputs = [case.input_quality] * len(train.input_grids)
    rows = []
    for monitoring in MONITORING_COSTS:
        runs = {
            name: realised(policy(kind, **options), test, utility, monitoring)
            for name, kind, options in (
                ("never", FixedStopping, {}),
                ("every step", OptimalStopping, {}),
                ("when to look, 10 bins", OptimalStopping, {"monitoring_cost": monitoring}),
            )
        }
        fit = fit_optimal(train, utility, monitoring_cost=monitoring, input_quality=inputs)
        runs["when to look"] = realised(fit.policy, test, utility, monitoring)
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
#: delta of the rule: None, the marginal promise (on average over calibration sets); 0.1, the
#: promise held by the one calibration set at hand with probability 0.9.
DELTAS = (None, 0.1)


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
    for (alpha, epsilon), delta in itertools.product(GUARANTEES, DELTAS):
        policy = ConformalStopping(
            train,
            epsilon,
            alpha,
            input_quality=[case.input_quality] * len(train.input_grids),
            delta=delta,
        )
        stops = np.array(
            [
                replay(policy, t, observed[i], scored=scored[i], ended=int(ended[i])).stop_index
                for i in range(len(true))
            ]
        )
        at_stop = true[np.arange(len(true)), stops]
        # Time saved against running each run to its end (the allocation, or where it ended).
        used = float(t[stops].sum() / t[ended].sum())
        later = np.where(np.arange(len(t)) >= stops[:, None], true, -np.inf).max(axis=1)
        missed = (later - at_stop) > epsilon
        rate = float(missed.mean())
        se = math.sqrt(max(rate * (1 - rate), 1e-12) / len(missed))
        rows.append(
            [
                label,
                f"{alpha:g}",
                f"{epsilon:g}",
                "marginal" if delta is None else f"{delta:g}",
                f"{rate:.3f} ({se:.3f})",
                "yes" if rate <= alpha + 0.01 else "NO",
                f"{used:.2f}",
                f"{1 - used:.2f}",
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


# --- section 4: synthetic families with their exact Bayes optimum ---------------------------

#: The synthetic grid: 32 times, one tick apart (T = 31).
SYNTHETIC_TIME = np.arange(0.0, 32.0)
#: The rates lambda (per tick) a run's curve q(t) = 1 - exp(-lambda t) is drawn from: a
#: geometric grid, lambda T from 0.6 to 31 (runs that never get far, and runs done at once).
RATES = np.geomspace(0.02, 1.0, 600)
#: Levels of the quantised estimate, and the biases of the biased one (equally likely).
LEVELS = 10
BIASES = (-0.2, -0.1, 0.0, 0.1, 0.2)
#: Synthetic training and test traces, and their seeds.
SYNTHETIC_TRIALS, TRAIN_SEED, TEST_SEED = 2000, 11, 12
#: (p, c) of the synthetic utilities q^p - c t/T, and the monitoring costs (0: looks free).
SYNTHETIC_SETTINGS = ((1, 0.05), (1, 0.2), (8, 0.05), (8, 0.2))
SYNTHETIC_MONITORING = (0.0, 0.005)


def _gamma_weights(shape: float, mean: float) -> Array:
    """Prior weights on the geometric grid `RATES` of a gamma density (times the grid's
    spacing, lambda d(log lambda))."""
    scale = mean / shape
    log_density = (shape - 1) * np.log(RATES) - RATES / scale
    weights = np.exp(log_density - log_density.max()) * RATES
    normalised: Array = weights / weights.sum()
    return normalised


#: The families: prior weights on `RATES`.
FAMILIES = {
    "log-uniform": np.full(len(RATES), 1.0 / len(RATES)),
    "gamma(2)": _gamma_weights(2.0, 0.15),
}
SYNTHETIC_VIEWS = ("true", "quantised", "biased")


@frozen
class Hypotheses:
    """The hidden states of a synthetic family under a view: (bias, rate) pairs, `blocks` of
    `len(RATES)` rates each (one block per bias), the rates increasing within a block, so that
    what the monitor sees at a time never decreases along a block.

    Attributes:
        weight: `(H,)` the prior.
        quality: `(H, m)` the true quality at each grid time.
        observed: `(H, m)` what the monitor sees there (a deterministic function of the
            hidden state, so the posterior given the looks is the prior restricted to the
            states that would have shown the same).
        blocks: how many blocks.
    """

    weight: Array
    quality: Array
    observed: Array
    blocks: int


def hypotheses(family: str, view: str) -> Hypotheses:
    """The family's hidden states and what the monitor sees of each: the true quality, the
    quantised one, or the quantised one times 1 + beta (one block per bias beta)."""
    quality = 1.0 - np.exp(-np.outer(RATES, SYNTHETIC_TIME))  # (R, m)
    prior = FAMILIES[family]
    if view == "true":
        return Hypotheses(prior, quality, quality, 1)
    levels = np.floor(quality * LEVELS) / LEVELS  # the same float for the same level
    if view == "quantised":
        return Hypotheses(prior, quality, levels, 1)
    biases = np.asarray(BIASES)
    seen = np.round(np.clip(levels[None] * (1 + biases[:, None, None]), 0.0, 1.0), 12)
    weight = np.tile(prior, len(biases)) / len(biases)
    return Hypotheses(
        weight,
        np.tile(quality, (len(biases), 1)),
        seen.reshape(-1, len(SYNTHETIC_TIME)),
        len(biases),
    )


def synthetic_traces(
    hyp: Hypotheses, view: str, family: str, seed: int
) -> tuple[QualityTraces, Array]:
    """`SYNTHETIC_TRIALS` runs drawn from the prior: their traces, and which state each is."""
    rng = np.random.default_rng(seed)
    drawn = rng.choice(len(hyp.weight), size=SYNTHETIC_TRIALS, p=hyp.weight)
    estimate = view != "true"
    traces = QualityTraces(
        module=f"synthetic {family}",
        time=SYNTHETIC_TIME,
        quality=hyp.quality[drawn],
        scored=np.ones((SYNTHETIC_TRIALS, len(SYNTHETIC_TIME)), bool),
        estimate=hyp.observed[drawn] if estimate else None,
        reports="estimate" if estimate else "true",
    )
    return traces, drawn


def bayes_every_step(hyp: Hypotheses, utility: Array) -> tuple[float, Array]:
    """The exact Bayes optimum with free looks (the monitor looks at every grid time): backward
    induction over the cells of hypotheses that the histories so far cannot tell apart.

    Returns its value and `(m, H)` whether it stops at each time in the cell of each state."""
    w, m = hyp.weight, utility.shape[1]
    _, codes = np.unique(hyp.observed, return_inverse=True)
    codes = codes.reshape(hyp.observed.shape)
    cells = np.empty((m, len(w)), dtype=np.intp)
    current = np.zeros(len(w), dtype=np.intp)
    for j in range(m):  # a cell at j: the cell at j - 1 and what is seen at j
        _, current = np.unique(np.stack([current, codes[:, j]]), axis=1, return_inverse=True)
        cells[j] = current.reshape(-1)

    def mean(j: int, x: Array) -> Array:  # E[x | cell at j], for each state
        mass = np.bincount(cells[j], w)
        answer: Array = (np.bincount(cells[j], w * x) / mass)[cells[j]]
        return answer

    stops = np.ones((m, len(w)), dtype=bool)
    value = mean(m - 1, utility[:, m - 1])
    for j in range(m - 2, -1, -1):
        now, later = mean(j, utility[:, j]), mean(j, value)
        stops[j] = now >= later - 1e-12  # ties: stop
        value = np.where(stops[j], now, later)
    return float(w @ value), stops


def stop_index(stops: Array) -> NDArray[np.intp]:
    """The first grid time each state's run stops at."""
    index: NDArray[np.intp] = np.argmax(stops, axis=0)
    return index


class BayesEveryStep:
    """The exact Bayes policy with free looks, as a stopping policy for `replay`: it keeps the
    states that would have shown what the run showed, and stops where the solution says."""

    name = "bayes"
    observed = None

    def __init__(self, hyp: Hypotheses, stops: Array) -> None:
        self.hyp, self.stops = hyp, stops
        self.alive = np.ones(len(hyp.weight), dtype=bool)

    def start(self, allocation: float) -> Decision:
        self.alive = np.ones(len(self.hyp.weight), dtype=bool)
        return Decision.later(SYNTHETIC_TIME[0], SYNTHETIC_TIME[-1], "looks every step")

    def observe(self, time: float, quality: float | None) -> Decision:
        j = int(np.searchsorted(SYNTHETIC_TIME, time))
        self.alive &= self.hyp.observed[:, j] == quality
        if self.stops[j, int(np.argmax(self.alive))]:
            return Decision.now("the posterior says stop")
        return Decision.later(SYNTHETIC_TIME[j + 1], SYNTHETIC_TIME[-1], "the posterior says go on")


Cell = tuple[tuple[int, int], ...]  # per block, the range of rates [lo, hi) still possible


class CostlyBayes:
    """The exact Bayes optimum with a monitoring cost per look: memoised backward induction
    over (grid time of the last look, cell), the choices those of `OptimalStopping` (stop now,
    stop later without looking, look at a later time). A cell is a range of rates per block:
    what is seen at a time never decreases along a block, so the states that show one value
    there are a range, and ranges intersect into ranges."""

    def __init__(self, hyp: Hypotheses, utility: Array, cost: float) -> None:
        self.hyp, self.cost = hyp, cost
        b, m = hyp.blocks, utility.shape[1]
        r = len(hyp.weight) // b
        w = hyp.weight.reshape(b, r)
        self.observed = hyp.observed.reshape(b, r, m)
        # Prefix sums along each block: a cell's mass and expectations in O(blocks).
        self.mass = np.concatenate([np.zeros((b, 1)), np.cumsum(w, axis=1)], axis=1)
        wu = w[..., None] * utility.reshape(b, r, m)
        self.sums = np.concatenate([np.zeros((b, 1, m)), np.cumsum(wu, axis=1)], axis=1)
        # What perfect information from time i on would be worth: a bound that prunes looks.
        best_later = np.maximum.accumulate(utility[:, ::-1], axis=1)[:, ::-1].reshape(b, r, m)
        self.bound = np.concatenate(
            [np.zeros((b, 1, m)), np.cumsum(w[..., None] * best_later, axis=1)], axis=1
        )
        self.memo: dict[tuple[int, Cell], tuple[float, int, int]] = {}
        self.m = m
        self.root: Cell = tuple((0, r) for _ in range(b))
        self.value = self.solve(-1, self.root)[0]

    def expect(self, table: Array, cell: Cell) -> Array:
        lo, hi = np.array(cell).T
        rows = np.arange(len(cell))
        mass = (self.mass[rows, hi] - self.mass[rows, lo]).sum()
        answer: Array = (table[rows, hi] - table[rows, lo]).sum(axis=0) / mass
        return answer

    def children(self, cell: Cell, i: int) -> list[tuple[float, Cell]]:
        """What a look at grid time i can show from `cell`: each value's probability and
        cell."""
        parts: dict[float, list[tuple[int, int]]] = {}
        for block, (lo, hi) in enumerate(cell):
            if lo == hi:
                continue
            seen = self.observed[block, lo:hi, i]
            starts = np.r_[0, np.flatnonzero(seen[1:] != seen[:-1]) + 1]
            ends = np.r_[starts[1:], hi - lo]
            for s, e in zip(starts, ends, strict=True):
                parts.setdefault(float(seen[s]), [(0, 0)] * len(cell))[block] = (lo + s, lo + e)
        total = sum(self.mass[b, hi] - self.mass[b, lo] for b, (lo, hi) in enumerate(cell))
        answer = []
        for ranges in parts.values():
            child = tuple(ranges)
            weight = sum(self.mass[b, hi] - self.mass[b, lo] for b, (lo, hi) in enumerate(child))
            answer.append((float(weight / total), child))
        return answer

    def solve(self, j: int, cell: Cell) -> tuple[float, int, int]:
        """(value, action, target) at a look at grid index j (-1: the start) in `cell`."""
        key = (j, cell)
        if key in self.memo:
            return self.memo[key]
        utility = self.expect(self.sums, cell)
        first = max(j, 0)
        later = np.arange(first, self.m)
        # Stop now (at a look), or at a later time without looking (at the start: any time).
        blind = utility[first:]
        chosen = int(np.argmax(blind >= blind.max() - 1e-12))
        best, action, target = float(blind[chosen]), STOP_AT, int(later[chosen])
        if j >= 0 and target == j:
            action = STOP
        bound = self.expect(self.bound, cell)
        for i in range(j + 1, self.m):
            if bound[i] - self.cost <= best + 1e-12:
                continue  # even knowing everything from i on would not pay for the look
            look = (
                sum(p * self.solve(i, child)[0] for p, child in self.children(cell, i)) - self.cost
            )
            if look > best + 1e-12:
                best, action, target = look, LOOK_AT, i
        self.memo[key] = (best, action, target)
        return self.memo[key]


class CostlyBayesPolicy:
    """`CostlyBayes`'s solution as a stopping policy for `replay`."""

    name = "bayes"
    observed = None

    def __init__(self, solution: CostlyBayes) -> None:
        self.solution = solution
        self.cell = solution.root

    def start(self, allocation: float) -> Decision:
        self.cell = self.solution.root
        return self._act(*self.solution.solve(-1, self.cell)[1:])

    def observe(self, time: float, quality: float | None) -> Decision:
        j = int(np.searchsorted(SYNTHETIC_TIME, time))
        observed = self.solution.observed
        narrowed = []
        for block, (lo, hi) in enumerate(self.cell):
            column = observed[block, lo:hi, j]
            narrowed.append(
                (
                    lo + int(np.searchsorted(column, quality, "left")),
                    lo + int(np.searchsorted(column, quality, "right")),
                )
            )
        self.cell = tuple(narrowed)
        return self._act(*self.solution.solve(j, self.cell)[1:])

    def _act(self, action: int, target: int) -> Decision:
        if action == STOP:
            return Decision.now("the posterior says stop")
        at = float(SYNTHETIC_TIME[target])
        if action == STOP_AT:
            return Decision.later(math.inf, at, "stop later without looking")
        return Decision.later(at, SYNTHETIC_TIME[-1], "look later")


def replay_states(policy: StoppingPolicy, hyp: Hypotheses, states: Array) -> tuple[Array, Array]:
    """Where `policy` stops the run of each state (grid index) and how many looks it takes,
    replayed once per distinct trace (a policy started afresh decides the same on the same
    trace)."""
    unique, inverse = np.unique(hyp.observed[states], axis=0, return_inverse=True)
    stops, looks = np.empty(len(unique), dtype=np.intp), np.empty(len(unique))
    for n, trace in enumerate(unique):  # a policy reads the trace as it goes: one replay each
        result = replay(policy, SYNTHETIC_TIME, trace)
        stops[n], looks[n] = result.stop_index, result.looks
    return stops[inverse.reshape(-1)], looks[inverse.reshape(-1)]


Seen = tuple[tuple[float, float], ...]


class SharedFits(ProjectedStopping):
    """`ProjectedStopping` with its fits shared among the policies of one profile: a fit (and
    so the projected curve) depends on the points seen only, not on the utility."""

    #: Per profile (by identity; kept alive here, so that a later profile cannot take its id):
    #: the fits by deadline and points seen.
    shared: dict[int, tuple[DynamicProfile, dict[tuple[int, Seen], Array]]] = {}

    def projection(self) -> Array:
        profile = self.model.profile
        kept = self.shared.get(id(profile))
        if kept is None or kept[0] is not profile:
            kept = self.shared[id(profile)] = (profile, {})
        fits, key = kept[1], (self.last, tuple(self._seen))
        if key not in fits:
            fits[key] = super().projection()
        return fits[key]


def state_of(fit: FittedStopping) -> str:
    """The state `fit_optimal` chose, short: "history", or "bins x classes"."""
    return fit.state if fit.states == 0 else f"{fit.states} x {fit.entered}"


def history_policy(
    train: QualityTraces, utility: Utility, monitoring: float, input_quality: float = 1.0
) -> HistoryStopping:
    """The history policy learned on the training traces (at their input quality)."""
    inputs = [input_quality] * len(train.input_grids)
    return HistoryStopping(train, utility, monitoring_cost=monitoring, input_quality=inputs)


@frozen
class Outcome:
    """One policy on the test traces: the utility of each, looks paid; what it claimed."""

    utility: Array
    claimed: float | None = None
    claimed_se: float = 0.0

    @property
    def se(self) -> float:
        return float(self.utility.std(ddof=1) / math.sqrt(len(self.utility)))

    def z(self) -> float:
        """|claimed - realised| in standard errors (of the realised mean and the claim's)."""
        assert self.claimed is not None
        return abs(self.claimed - float(self.utility.mean())) / math.hypot(self.se, self.claimed_se)


def synthetic_row(
    hyp: Hypotheses,
    train: QualityTraces,
    profile: DynamicProfile,
    test: Array,
    power: int,
    rate: float,
    monitoring: float,
) -> tuple[float, dict[str, Outcome], Array, str]:
    """The exact Bayes value and every policy's outcome on the test states, with the
    clairvoyant utility of each test run, and the state the fitted optimal policy chose."""
    horizon = float(SYNTHETIC_TIME[-1])
    value, cost = PowerValue(power), TimeCost(rate, horizon)
    utility = Utility(value, cost)
    table = utility(SYNTHETIC_TIME, hyp.quality.T).T  # (H, m): U of each state at each time
    bayes: StoppingPolicy
    if monitoring == 0:
        exact, stops = bayes_every_step(hyp, table)
        bayes = BayesEveryStep(hyp, stops)
    else:
        solution = CostlyBayes(hyp, table, monitoring)
        exact, bayes = solution.value, CostlyBayesPolicy(solution)
    fit = fit_optimal(train, utility, monitoring_cost=monitoring)
    policies: dict[str, Any] = {
        "bayes": bayes,
        "fixed": FixedStopping(profile, value, cost),
        "myopic": MyopicStopping(profile, value, cost, monitoring_cost=monitoring),
        "projected": SharedFits(profile, value, cost),
        "optimal, bin only": OptimalStopping(profile, value, cost, monitoring_cost=monitoring),
        "optimal": fit.policy,
        "history": history_policy(train, utility, monitoring),
    }
    outcomes = {}
    for name, policy in policies.items():
        stops, looks = replay_states(policy, hyp, test)
        got = table[test, stops] - monitoring * looks
        claimed, claimed_se = None, 0.0
        if name == "optimal":  # its promise: the cross-validated utility
            claimed, claimed_se = fit.utility, fit.standard_error
        elif name.startswith("optimal") or name == "history":
            claimed, claimed_se = policy.expected_utility(), policy.standard_error()
        outcomes[name] = Outcome(got, claimed, claimed_se)
    return exact, outcomes, table[test].max(axis=1), state_of(fit)


def _verdict(name: str, outcomes: dict[str, Outcome]) -> str:
    """Whether a policy meets the targets on a row: >= 0.98 of the Bayes policy, not below
    fixed by more than the standard error of the paired difference, its claim within 2 se of
    what it realised."""
    if name not in outcomes:
        return "-"
    got, bayes, fixed = outcomes[name], outcomes["bayes"], outcomes["fixed"]
    failed = []
    share = got.utility.mean() / bayes.utility.mean()
    if share < 0.98:
        failed.append(f"{share:.3f} < 0.98")
    difference = got.utility - fixed.utility
    if difference.mean() < -difference.std(ddof=1) / math.sqrt(len(difference)):
        failed.append("below fixed")
    if got.claimed is not None and got.z() > 2:
        failed.append(f"claim {got.z():.1f} se off")
    return "yes" if not failed else "no: " + ", ".join(failed)


def _claim(outcome: Outcome | None) -> str:
    if outcome is None or outcome.claimed is None:
        return "-"
    claimed = f"{outcome.claimed:.4f}" + (
        f" ({outcome.claimed_se:.4f})" if outcome.claimed_se else ""
    )
    return f"{claimed}, {outcome.utility.mean():.4f} ({outcome.se:.4f}): {outcome.z():.1f}"


SYNTHETIC_POLICIES = ("fixed", "myopic", "projected", "optimal, bin only", "optimal", "history")


def synthetic_section(quick: bool) -> tuple[list[list[str]], list[list[str]], dict[str, int]]:
    """Rows of section A: every policy's share of the Bayes optimum and of the clairvoyant;
    the claims against what was realised, and the targets."""
    shares, claims = [], []
    met = dict.fromkeys(("optimal", "history", "rows"), 0)
    # Quick: one family, one linear and one convex utility (the history policy learns for
    # ~10 s a row on 2,000 traces).
    settings = SYNTHETIC_SETTINGS[::3] if quick else SYNTHETIC_SETTINGS
    for family in list(FAMILIES)[:1] if quick else FAMILIES:
        for view in SYNTHETIC_VIEWS:
            hyp = hypotheses(family, view)
            train, _ = synthetic_traces(hyp, view, family, TRAIN_SEED)
            _, test = synthetic_traces(hyp, view, family, TEST_SEED)
            profile = DynamicProfile.from_traces(train, states=STATES)
            for power, rate in settings:
                for monitoring in SYNTHETIC_MONITORING:
                    exact, outcomes, best, state = synthetic_row(
                        hyp, train, profile, test, power, rate, monitoring
                    )
                    label = f"{family}, {view}, q^{power} - {rate:g} t/T, {monitoring:g} a look"
                    bayes = outcomes["bayes"].utility.mean()
                    shares.append(
                        [
                            label,
                            f"{exact:.4f} / {bayes / best.mean():.3f}",
                            *(
                                f"{outcomes[name].utility.mean() / bayes:.3f}"
                                f" / {outcomes[name].utility.mean() / best.mean():.3f}"
                                if name in outcomes
                                else "-"
                                for name in SYNTHETIC_POLICIES
                            ),
                        ]
                    )
                    check = attrs.evolve(outcomes["bayes"], claimed=exact)
                    verdicts = [_verdict(name, outcomes) for name in ("optimal", "history")]
                    met["rows"] += 1
                    met["optimal"] += verdicts[0] == "yes"
                    met["history"] += verdicts[1] == "yes"
                    claims.append(
                        [
                            label,
                            _claim(check),
                            state,
                            _claim(outcomes["optimal"]),
                            _claim(outcomes.get("history")),
                            *verdicts,
                        ]
                    )
    return shares, claims, met


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help="fewer module traces, and the quick synthetic rows"
    )
    parser.add_argument(
        "--quick-synthetic",
        action="store_true",
        help="section 4 on one family and two utilities (12 rows, not 48)",
    )
    parser.add_argument("--trials", type=int, help="training and test traces (default 400)")
    parser.add_argument(
        "--traces",
        type=Path,
        help="a directory to keep the recorded traces in (anytime-traces/1 files), read back"
        " when they are there with as many trials",
    )
    parser.add_argument(
        "--history",
        action="store_true",
        help="the history policy in section 1 too (it learns for ~5 s a row on 400 traces)",
    )
    parser.add_argument(
        "--part",
        choices=("all", "modules", "synthetic"),
        default="all",
        help="the recorded modules' sections (1-3), the synthetic families' (4), or both",
    )
    args = parser.parse_args()
    print(machine())
    started = time.perf_counter()
    if args.part != "synthetic":
        modules(args, started)
    if args.part != "modules":
        synthetic(args.quick or args.quick_synthetic)
    print(f"(all: {time.perf_counter() - started:.0f} s)")


def modules(args: argparse.Namespace, started: float) -> None:
    """Sections 1-3: the recorded traces of the shipped modules and the stalling one."""
    trials = args.trials or (150 if args.quick else 400)
    data = {}
    for case in CASES:
        data[case.module] = (
            recorded(case, trials, 1, args.traces),
            recorded(case, trials, 2, args.traces),
        )
    print(f"\n(traces recorded in {time.perf_counter() - started:.0f} s)")

    free_rows, costly_rows, guarantee_rows = [], [], []
    for case in CASES:
        # A module that reports its true quality shows the monitor the same in both views.
        views = VIEWS if data[case.module][0].reports != "true" else VIEWS[:1]
        for view in views:
            train, test = (view_of(traces, view) for traces in data[case.module])
            # Runs that end by themselves (2-opt, the ATP) in ended states of their own.
            ends = train.finished is not None and bool(
                (train.end_index() < len(train.time) - 1).any()
            )
            profile = DynamicProfile.from_traces(train, states=STATES, ends=ends)
            label = f"{case.module} ({case.domain}), {view}"
            free_rows.extend(free_looks(case, profile, train, test, label, args.history))
            costly_rows.extend(costly_looks(case, profile, train, test, label))
            guarantee_rows.extend(guaranteed(case, train, test, label))
    print()
    print(
        table(
            [
                "module, what the monitor sees, utility",
                "fixed",
                "myopic",
                "projected",
                "optimal, 10 bins",
                "optimal",
                "history",
                "optimal - best of fixed, myopic (se)",
                "history - best of fixed, myopic (se)",
                "optimal's state",
                "optimal: claimed (se), realised (se): z",
            ],
            free_rows,
        )
    )
    print(
        f"\n(mean utility over {trials} test traces as a fraction of the clairvoyant's; the"
        f" policies come from {trials} training traces of other instances (fixed, myopic,"
        f" projected and 'optimal, 10 bins' on their dynamic profile of {STATES} quality bins,"
        " with a state per bin for the runs that ended by themselves where some did); optimal:"
        " `fit_optimal`, the optimal policy on the state (quality bins x entry-time classes, or the"
        " history) the training traces' 5-fold cross-validation chose, its claim the"
        " cross-validated utility; history: the policy learned on the training runs' histories,"
        " with --history only; target: optimal (and history) >= 0.98 where the fixed policy's"
        " ceiling allows, its lead over fixed and myopic never below minus its standard error, and"
        " its claim within 2 se of what it realised)"
    )
    print()
    print(
        table(
            [
                "module, utility, monitoring cost",
                "look never",
                "look every step",
                "when to look, 10 bins",
                "when to look",
                "looks",
                "beats both",
            ],
            costly_rows,
        )
    )
    print(
        "\n(utility less the monitoring cost of each look, as a fraction of the clairvoyant's"
        " (who pays none); never, every step and 'when to look, 10 bins' on the dynamic profile"
        " of 10 bins, 'when to look' the optimal policy with the monitoring cost on the state"
        " `fit_optimal` chose; looks: the mean number it takes; beats both: it against never and"
        " every step)"
    )
    print()
    print(
        table(
            [
                "module, what the monitor sees",
                "alpha",
                "epsilon",
                "delta",
                "missed (se)",
                "<= alpha + 0.01",
                "time used",
                "time saved",
                "quality at stop",
                "best later",
            ],
            guarantee_rows,
        )
    )
    print(
        "\n(ConformalStopping calibrated on the training traces, replayed on the test traces:"
        " missed, the share of test runs whose true quality would still have risen by more than"
        " epsilon after the stop, which the rule promises to keep below alpha: on average over"
        " calibration sets (delta marginal; one set's miss rate is above alpha about half the"
        " time where the bound is tight), or with probability 1 - delta for the set at hand;"
        " time used, the"
        " total time of the test runs under the rule as a fraction of their total time if each"
        " ran to its end (the allocation, or where it ended by itself), and time saved, one less"
        " that; quality at stop and the best the run reached later, means)"
    )


def synthetic(quick: bool) -> None:
    """Section 4: the synthetic families, against their exact Bayes optimum."""
    started = time.perf_counter()
    shares, claims, met = synthetic_section(quick)
    print()
    print(
        table(
            [
                "family, view, utility, monitoring cost",
                "Bayes: exact value / of clairvoyant",
                *SYNTHETIC_POLICIES,
            ],
            shares,
        )
    )
    print(
        f"\n(each policy's mean utility over {SYNTHETIC_TRIALS} test runs, looks paid, as a"
        " fraction of the Bayes policy's on the same runs / of the clairvoyant's; fixed,"
        " myopic, projected and optimal, bin only are built on the dynamic profile of"
        f" {SYNTHETIC_TRIALS} training runs ({STATES} quality bins: the Markov model of the"
        " reported level), optimal on the state the training runs' cross-validation chose"
        " (`fit_optimal`), history on the training traces)"
    )
    print()
    print(
        table(
            [
                "family, view, utility, monitoring cost",
                "Bayes: exact, realised (se): z",
                "optimal's state",
                "optimal: claimed (se), realised (se): z",
                "history: claimed (se), realised (se): z",
                "optimal meets targets",
                "history meets targets",
            ],
            claims,
        )
    )
    print(
        "\n(optimal's state: quality bins x entry-time classes, or the history; claimed: the"
        " utility a policy promises with its standard error (the optimal policy's cross-validated"
        " utility, the history policy's `expected_utility()` and `standard_error()`; the Bayes"
        " policy's is the exact value of its backward induction); realised: its mean on the test"
        " runs; z: |claimed - realised| over the standard errors of both; targets: >= 0.98 of the"
        " Bayes policy, not below fixed by more than the standard error of the paired"
        f" difference, claim within 2 se. Rows meeting all three: optimal {met['optimal']},"
        f" history {met['history']} of {met['rows']})"
    )
    print(f"(synthetic families: {time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
