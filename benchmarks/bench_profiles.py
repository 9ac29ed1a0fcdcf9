"""Profile benchmarks, printed as side-by-side tables (not a test: nothing here is asserted).

1. The profile builder's throughput, in trials per second, with 1 and 2 worker processes on a
   toy module that does real CPU work for every tick it reports, so parallelism can show.
2. Interpolation throughput: evaluations per second of `profile.distribution` and
   `profile.expected` on one batch of 10^5 random points, against a naive Python loop that
   asks the same profile one point at a time.

Run: .venv/bin/python benchmarks/bench_profiles.py [--trials N] [--repeats N] [--points N]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from tables import table  # benchmarks/tables.py: a script's own folder is on sys.path

from anytime.measure.builder import Instance, build_profile
from anytime.modules import Context, Registry, Result, interruptible
from anytime.profiles import ConditionalPerformanceProfile, default_bins

BENCH = Registry()
WORK = 3_000  # loop iterations of real work per tick


@interruptible("grind", inputs=["x"], registry=BENCH)
def grind(ctx: Context, x: Result, rng: np.random.Generator) -> Iterator[Result]:
    """Improves its estimate by one tick of honest CPU work at a time."""
    total = 0
    while not ctx.expired:
        total += sum(i * i for i in range(WORK))  # the work the tick stands for
        ctx.tick(1)
        q = x.quality * -np.expm1(-ctx.elapsed / 15) * (0.9 + 0.1 * rng.random())
        yield Result(q, q)


class GrindProblems:
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance((None, rng))

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


def best_of(repeats: int, run: Callable[..., object], *args: Any) -> float:
    """The shortest of `repeats` timings of `run(*args)`, in seconds."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        run(*args)
        best = min(best, time.perf_counter() - start)
    return best


def bench_builder(trials: int, repeats: int) -> str:
    grid: dict[str, Any] = dict(time=[0, 10, 20, 40], input_grids=[[0.5, 1.0]], trials=trials)
    total = trials * 2
    seconds: dict[int, list[float]] = {1: [], 2: []}
    profiles = []
    for _ in range(repeats):  # alternate, so a busy moment does not favour one side
        for workers in (1, 2):
            start = time.perf_counter()
            build = build_profile(grind, GrindProblems(), workers=workers, progress=False, **grid)
            seconds[workers].append(time.perf_counter() - start)  # pool start-up included
            profiles.append(build.profile)
    rate = {workers: total / min(times) for workers, times in seconds.items()}
    rows = [
        [
            f"{workers} worker(s)",
            str(total),
            f"{min(seconds[workers]):.2f}",
            f"{rate[workers]:.1f}",
            f"{rate[workers] / rate[1]:.2f}x",
        ]
        for workers in (1, 2)
    ]
    header = [
        "builder (module 'grind', 40 ticks/trial)",
        "trials",
        "best s",
        "trials/s",
        "speed-up",
    ]
    same = all(p == profiles[0] for p in profiles)
    return (
        table(header, rows)
        + f"\n(best of {repeats} alternating runs; identical profile in every run: {same})"
    )


def one_at_a_time(method: Callable[..., Any], q: Any, t: Any) -> Any:
    """The naive way: a Python loop asking for one point at a time."""
    return np.array([method(q[i], t[i]) for i in range(len(t))])


def random_profile(n_inputs: int, rng: np.random.Generator) -> ConditionalPerformanceProfile:
    grids = [np.linspace(0, 1, 11)] * n_inputs
    time_grid = np.linspace(0, 200, 21)
    shape = (*(len(g) for g in grids), len(time_grid))
    probability = rng.dirichlet(np.ones(10), size=shape)
    return ConditionalPerformanceProfile(
        input_grids=grids, time=time_grid, bins=default_bins(10), probability=probability
    )


def bench_interpolation(points: int, loop_points: int) -> str:
    rng = np.random.default_rng(0)
    rows = []
    for n_inputs in (1, 2):
        profile = random_profile(n_inputs, rng)
        q = rng.random((points, n_inputs))
        t = rng.uniform(-10, 220, points)  # a few beyond the grid's ends (clamped)
        for name in ("distribution", "expected"):
            method = getattr(profile, name)
            batch = best_of(5, method, q, t)
            looped = best_of(1, one_at_a_time, method, q[:loop_points], t[:loop_points])
            agree = np.max(np.abs(one_at_a_time(method, q[:50], t[:50]) - method(q[:50], t[:50])))
            vectorised, naive = points / batch, loop_points / looped
            cells = "x".join(str(n) for n in profile.probability.shape)
            rows.append(
                [
                    f"{name}, {n_inputs} input(s), table {cells}",
                    f"{vectorised:,.0f}",
                    f"{naive:,.0f}",
                    f"{vectorised / naive:,.0f}x",
                    f"{agree:.0e}",
                ]
            )
    header = [
        f"interpolation ({points:,} points)",
        "batch evals/s",
        "loop evals/s",
        "ratio",
        "max diff",
    ]
    note = f"(the loop calls the same method once per point, timed over {loop_points:,} points)"
    return table(header, rows) + "\n" + note


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=150, help="trials per cell (2 cells)")
    parser.add_argument("--points", type=int, default=100_000, help="interpolation batch")
    parser.add_argument("--loop-points", type=int, default=2_000, help="naive loop points")
    parser.add_argument("--repeats", type=int, default=3, help="builder runs per side")
    args = parser.parse_args()
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(
        f"Python {platform.python_version()}, numpy {np.__version__},"
        f" {cpus} CPU(s) available, {platform.machine()}"
    )
    print()
    print(bench_builder(args.trials, args.repeats))
    print()
    print(bench_interpolation(args.points, args.loop_points))


if __name__ == "__main__":
    main()
