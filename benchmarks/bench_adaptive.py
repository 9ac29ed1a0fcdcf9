"""Adaptive re-allocation against the fixed allocation, on the same fresh instances.

    .venv/bin/python benchmarks/bench_adaptive.py [--runs 100] [--quick]

`run_program(..., adaptive=True)` re-splits the time left among the calls still to run when a
call has shown the plan something it did not know (its quality drawn from a stochastic profile
and reported true, no result, time it left unused), keeping a new split only where the
compiler expects it to beat the planned one, and remembering its re-plans per program
(`anytime.compiler.allocators.reallocate.Replanner`). Each instance is run both ways (fixed
then adaptive, alternately, so that load drifts alike), and the programs are:

- the three schemas of the test plugin tests/plugins/estimation_plugin (a third party's:
  estimate a tank's volume by Monte Carlo or read its label, then the side of its cube; a
  chain, a two-input program and a best-of), on fresh tanks, scored against the true side;
- the navigation plugin's `navigate` (sense, then plan with the ATP) and its
  `navigate-two-planners` (a DAG: one sensed map read by the ATP and by A*, the better plan
  kept), on fresh 64 x 64 worlds (128 x 128 without `--quick`), scored as the profiles score
  a plan;
- two DAGs over one shared sensed map of quality 0.15 or 0.95 (the good one more likely the
  longer it senses; tests/compiler/test_shared_results.py), read by two planners whose plans a
  product-like join combines, or a best-of chooses between: here every module draws its
  quality from its own profile, given its inputs' qualities, with one uniform per instance and
  module (common random numbers for the two runs of an instance).

Columns: the mean realised quality of fixed and adaptive runs with their standard errors, the
paired difference adaptive - fixed with its standard error, `diff / se` (target: >= -1, that
is adaptive >= fixed - se; a difference that is the same in every run has se 0 and is shown
as it is), how many re-plans were asked for and how many needed a search (the rest were
remembered), and the wall time of all the adaptive runs' `run_program` calls over the fixed
ones' (target: <= 1.1), with the process's CPU time over the same calls beside it (less moved
by other load on a shared machine; a row where the two runs of every instance are the same
runs, re-plans 0, shows what that load alone does to the ratios). The re-plans are remembered
across the runs of a program, as they are in any process that runs one compiled program more
than once: the first runs pay for the searches (the `searched` column), and the ratios
include them.
"""

from __future__ import annotations

import argparse
import gc
import math
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from anytime_navigation.resources import load_schema_file
from anytime_navigation.task.execution import execute, optimal_length, plan_quality
from anytime_navigation.task.vision import Sensor
from anytime_navigation.world import random_world
from anytime_routing.domain import tour_quality
from anytime_routing.program import compiled_program, fresh_problems
from tables import machine, table

from anytime import AnytimeLibrary, CompiledProgram, LibraryEntry, WorkClock, compile_file
from anytime import load_schemas as load_schema_path
from anytime.compiler import compile_program
from anytime.compiler.allocators.reallocate import replanner
from anytime.dsl import parse_schemas
from anytime.library import RegistrySource
from anytime.modules import Context, Registry, Result, interruptible
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.runtime import Budget, run_program

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "plugins" / "estimation_plugin"))  # the test plugin
sys.path.insert(0, str(ROOT / "tests" / "compiler"))  # the shared-map profiles

import anytime_estimation as estimation  # noqa: E402
from bench_promises import fresh_tanks  # noqa: E402
from test_shared_results import TOTALS, joined, planner, sensed_map  # noqa: E402

SEED_BASE = 30_000  # instances apart from the profiles' and the promise benchmark's

#: One instance: (program, budget index, run index) -> (its inputs, its scorer of an answer).
Instance = Callable[[CompiledProgram, int, int], tuple[list[Any], Callable[[Any], float]]]


def tanks(compiled: CompiledProgram, j: int, i: int) -> tuple[list[Any], Callable[[Any], float]]:
    """A fresh tank (two for two-tank-side; labelled, readable or not, for
    labelled-tank-side), scored against its true side."""
    rng = np.random.default_rng([SEED_BASE, len(compiled.name), j, i])
    made, truth = fresh_tanks(compiled.name, rng)
    return made, lambda value: estimation.quality(value, truth)


def worlds(size: int) -> Instance:
    def instance(
        compiled: CompiledProgram, j: int, i: int
    ) -> tuple[list[Any], Callable[[Any], float]]:
        seed = SEED_BASE + 1000 * j + i
        world = random_world(size, seed=seed, movement=4)
        sensor = Sensor(world.blocked, seed=seed, movement=4)

        def score(plan: Any) -> float:
            if plan is None:
                return 0.0
            executed = execute(plan, world.blocked, movement=4)
            best = optimal_length(world.blocked, world.start, world.goal, movement=4)
            return plan_quality(executed.length, best)

        return [world.start, world.goal, sensor], score

    return instance


class Draws:
    """An instance of the shared-map programs: one uniform per module (two: a bin and no
    result), so that its fixed and adaptive runs draw alike."""

    def __init__(self, seed: int) -> None:
        self.seed = seed

    def uniforms(self, name: str) -> tuple[float, float]:
        rng = np.random.default_rng([self.seed, *name.encode()])
        first, second = rng.random(2)
        return float(first), float(second)


def draw(profile: ConditionalPerformanceProfile, q: list[float], t: float, u: Draws, name: str):
    """A quality drawn from `profile` at input qualities `q` and time `t` (None: no result),
    as tests/compiler/program_sampler.py draws it."""
    qs, ts = np.asarray([q], dtype=np.float64).reshape(1, -1), np.asarray([t])
    dist, reps = profile.distribution(qs, ts)[0], profile.representatives(qs, ts)[0]
    first, second = u.uniforms(name)
    cdf = np.cumsum(dist)
    pick = min(int(np.searchsorted(cdf, first * cdf[-1], side="left")), len(dist) - 1)
    none = float(profile.no_result(qs, ts)[0])
    if pick == 0 and second * (dist[0] if dist[0] > 0 else 1.0) < none:
        return None
    return float(reps[pick])


def sampling(name: str, profile: ConditionalPerformanceProfile) -> Callable[..., Iterator[Result]]:
    """What a module does: use its allocation, answer with a quality drawn from its profile
    given its inputs' (the last argument is the instance)."""

    def run(ctx: Context, inputs: list[Result], draws: Draws) -> Iterator[Result]:
        ctx.tick(ctx.allocation)
        quality = draw(profile, [a.quality for a in inputs], ctx.allocation, draws, name)
        if quality is not None:
            yield Result(quality, quality)  # its value its quality, for the score

    return run


SHARED = """
(defschema diamond (w) (setf m (sense w)) (join (plan1 m w) (plan2 m w) w))
(defschema choose (w) (setf m (sense w)) (best-of (plan1 m w) (plan2 m w)))
"""


def shared_map_programs() -> list[CompiledProgram]:
    registry = Registry()
    profiles = {
        "sense": sensed_map(),
        "plan1": planner("plan1", 0.08, True),
        "plan2": planner("plan2", 0.06, True),
        "join": joined(),
    }
    sense, plan1, plan2, combine = (sampling(name, p) for name, p in profiles.items())

    def sense_(ctx: Context, w: Draws) -> Iterator[Result]:
        yield from sense(ctx, [], w)

    def plan1_(ctx: Context, m: Result, w: Draws) -> Iterator[Result]:
        yield from plan1(ctx, [m], w)

    def plan2_(ctx: Context, m: Result, w: Draws) -> Iterator[Result]:
        yield from plan2(ctx, [m], w)

    def join_(ctx: Context, a: Result, b: Result, w: Draws) -> Iterator[Result]:
        yield from combine(ctx, [a, b], w)

    for name, function, inputs in (
        ("sense", sense_, []),
        ("plan1", plan1_, ["m"]),
        ("plan2", plan2_, ["m"]),
        ("join", join_, ["a", "b"]),
    ):
        interruptible(name, inputs=inputs, profile=profiles[name], registry=registry)(function)
    library = AnytimeLibrary([RegistrySource(registry)])
    schemas = parse_schemas(SHARED)
    return [compile_program(schemas[name], library, TOTALS) for name in ("diamond", "choose")]


def maps(compiled: CompiledProgram, j: int, i: int) -> tuple[list[Any], Callable[[Any], float]]:
    """An instance of a shared-map program, scored by the quality its output drew."""
    return [Draws(SEED_BASE + 1000 * j + i)], lambda value: value


def deliveries(count: int) -> Instance:
    """The routing plugin's fresh problems (`count` of them, the same at every budget), scored
    by the true quality of the tours against the reference delivery's length."""
    problems = fresh_problems(np.random.default_rng([SEED_BASE, 7]), count)

    def instance(
        compiled: CompiledProgram, j: int, i: int
    ) -> tuple[list[Any], Callable[[Any], float]]:
        world, (_, length) = problems[i % count]
        return [
            world.orders,
            world.sites,
        ], lambda tours: tour_quality(tours, length) if length is not None else 0.0

    return instance


def compare(
    compiled: CompiledProgram, instance: Instance, totals: list[float], runs: int
) -> tuple[str, list[str]]:
    """The table of one program, and its summary row."""
    rows, worst, walls, cpus = [], math.inf, [0.0, 0.0], [0.0, 0.0]
    planner = replanner(compiled.model, compiled.resolution)
    for mode in (0, 1):  # warm up (imports, first-call caches): untimed, and not counted
        inputs, _ = instance(compiled, len(compiled.profile.time), runs)
        budget = Budget(float(totals[0]), clock=WorkClock())
        run_program(compiled, inputs, budget, adaptive=bool(mode))
    for total in totals:
        j = int(np.searchsorted(compiled.profile.time, total))
        quality = np.zeros((2, runs))
        wall, cpu = [0.0, 0.0], [0.0, 0.0]
        asked, searched = planner.asked, planner.searches
        for i in range(runs):
            for mode in (i % 2, 1 - i % 2):  # who goes first alternates
                inputs, score = instance(compiled, j, i)
                budget = Budget(float(total), clock=WorkClock())
                started, processed = time.perf_counter(), time.process_time()
                record = run_program(compiled, inputs, budget, adaptive=bool(mode))
                wall[mode] += time.perf_counter() - started
                cpu[mode] += time.process_time() - processed
                value = record.result.value if record.result is not None else None
                quality[mode, i] = score(value) if record.result is not None else 0.0
        means = quality.mean(axis=1)
        ses = quality.std(axis=1, ddof=1) / math.sqrt(runs)
        diff = quality[1] - quality[0]
        se = float(diff.std(ddof=1) / math.sqrt(runs))
        ratio = (
            diff.mean() / se
            if se > 0
            else (0.0 if diff.mean() == 0 else math.copysign(math.inf, diff.mean()))
        )
        worst = min(worst, ratio)
        for k in (0, 1):
            walls[k] += wall[k]
            cpus[k] += cpu[k]
        rows.append(
            [
                f"{total:g}",
                f"{means[0]:.4f} ± {ses[0]:.4f}",
                f"{means[1]:.4f} ± {ses[1]:.4f}",
                f"{diff.mean():+.4f} ± {se:.4f}",
                f"{ratio:+.2f}" if se > 0 else "-",
                f"{planner.asked - asked}",
                f"{planner.searches - searched}",
                f"{wall[1] / wall[0]:.2f}",
                f"{cpu[1] / cpu[0]:.2f}",
            ]
        )
    header = [
        "T",
        "fixed",
        "adaptive",
        "adaptive - fixed",
        "diff / se",
        "re-plans",
        "searched",
        "wall ratio",
        "cpu ratio",
    ]
    summary = [
        compiled.name,
        f"{len(totals)}",
        f"{worst:+.2f}",
        "yes" if worst >= -1 else "NO",
        f"{walls[1] / walls[0]:.2f}",
        "yes" if walls[1] <= 1.1 * walls[0] else "NO",
        f"{cpus[1] / cpus[0]:.2f}",
    ]
    return table(header, rows), summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100, help="instances per budget")
    parser.add_argument("--quick", action="store_true", help="fewer instances, smaller worlds")
    args = parser.parse_args()
    runs = 60 if args.quick else args.runs
    size = 64 if args.quick else 128
    print(machine())
    library = AnytimeLibrary()
    for module in estimation.PLUGIN.modules:
        library.add(LibraryEntry.of_module(module))
    tank_programs = compile_file(
        load_schema_path(estimation.SCHEMA_FILE), library, range(0, 41, 4), resolution=2
    )
    navigation = compile_file(
        load_schema_file("navigation.any"), AnytimeLibrary.default(), np.arange(0.0, 3001.0, 250.0)
    )
    chosen = [p for p in navigation if p.name in ("navigate", "navigate-two-planners")]
    cases: list[tuple[str, CompiledProgram, Instance, list[float], int]] = [
        *(
            (
                f"{p.name} (estimation test plugin), fresh tanks",
                p,
                tanks,
                [8, 16, 24, 32, 40],
                10 * runs,
            )
            for p in tank_programs
        ),
        *(
            (
                f"{p.name} (navigation plugin), fresh {size}x{size} worlds",
                p,
                worlds(size),
                [250, 500, 750, 1000],
                max(10, runs // 2),
            )
            for p in chosen
        ),
        *(
            (
                f"{p.name} over one shared sensed map, modules drawing from their profiles",
                p,
                maps,
                [20, 40, 60, 80],
                4 * runs,
            )
            for p in shared_map_programs()
        ),
    ]
    routing = compiled_program("deliver-best")
    cases.append(
        (
            "deliver-best (routing plugin: a DAG with a best-of), fresh problems",
            routing,
            deliveries(max(10, runs // 2)),
            [16, 32, 48, 64],
            max(10, runs // 2),
        )
    )
    summaries = []
    for title, compiled, instance, totals, n in cases:
        # What is loaded by now is kept out of the collector's way: a full collection over
        # it, landing in one mode's run by chance, would otherwise weigh on that mode alone.
        gc.collect()
        gc.freeze()
        started = time.perf_counter()
        rows, summary = compare(compiled, instance, totals, n)
        summaries.append(summary)
        print()
        print(f"{title}, {n} per budget, {time.perf_counter() - started:.0f} s")
        print()
        print(rows)
    print()
    print("Every program: the worst diff / se over its budgets (target >= -1) and the wall-time")
    print("ratio of all its adaptive runs to all its fixed runs (target <= 1.1).")
    print()
    header = [
        "program",
        "budgets",
        "worst diff / se",
        ">= fixed - se",
        "wall ratio",
        "<= 1.1x",
        "cpu ratio",
    ]
    print(table(header, summaries))


if __name__ == "__main__":
    main()
