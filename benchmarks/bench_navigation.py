"""Navigation benchmarks: the anytime abstract planner (ATP) against A*, and our A* against the
`pathfinding` package's, printed as side-by-side tables (not a test: nothing here is asserted).

1. ATP against A* on the same problems in one run: random-rectangle worlds of 128 x 128
   (4- and 8-connected) and 512 x 512 (8-connected), start and goal in opposite corners; and the
   512 x 512 MovingAI maps shipped with the domain (8-connected octile, no corner cutting),
   problems from the longest scenario buckets. Per map and ATP configuration: the plan quality
   (optimal length / length of the route `execution.execute` follows on the true map) after the
   first plan and at completion; the ATP's time and node expansions as fractions of A*'s. Two
   configurations: the default (the first plan one segment) and `segment_moves=8` (the first
   plan cut into segments of at most 8 moves: a finer anytime grain). The papers
   report 0.93 expected quality at 27% of A*'s time when run to completion; the issue's target
   is at least 0.95 at no more than 15% on 512 x 512 maps.
2. Our A* (`search.find_path`, weight 0) against `pathfinding`'s `AStarFinder` (octile, diagonal
   only when both orthogonal neighbours are free: the MovingAI rule) on the same MovingAI
   problems: query time, and whether each finds the `.scen` optimal length. An optional
   dependency: skipped, with a line saying so, when it is not installed.

Timing: `time.perf_counter`, the garbage collector paused, the sides interleaved per problem
(A*, then each ATP configuration; ours, then theirs), the best of `--repeats` runs per problem
and side. ATP's time is planning only: its abstraction pyramid is built once per map, timed
separately (shown as a fraction of A*'s total time on that map's problems), and the execution
of its plans, which yields the quality, is not timed (and is given up after `EXECUTION_BUDGET`
times A*'s time: the first plan's quality is then unknown). `pathfinding`'s grid is built once
per map and reset before each query, both outside its query time and shown separately.

Problems: 20 worlds of 128 x 128 per movement, 10 of 512 x 512, and the 12 problems of the
longest buckets of each MovingAI map; --quick: 5, 2 and 2, the best of 2 runs (under a minute;
the full run takes about five).

Run: .venv/bin/python benchmarks/bench_navigation.py [--quick] [--repeats N]
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import signal
import statistics
import time
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from anytime_navigation.abstraction import Pyramid
from anytime_navigation.execution import Execution, execute, plan_quality, waypoints
from anytime_navigation.movingai import Scenario, load_problems
from anytime_navigation.planner import MultiPath, atp
from anytime_navigation.search import find_path
from anytime_navigation.world import BoolGrid, Position, random_world
from attrs import frozen
from tables import machine, table  # benchmarks/tables.py: a script's own folder is on sys.path

from anytime.modules import Context

MAPS = (
    Path(__file__).resolve().parent.parent
    / "domains"
    / "navigation"
    / "anytime_navigation"
    / "maps"
)
MOVINGAI = ("8room_000", "maze512-1-0", "random512-10-0")

#: The ATP configurations compared: name -> keyword arguments of `atp`.
CONFIGS: dict[str, dict[str, Any]] = {
    "one segment": {},  # the default
    "segments of 8 moves": {"segment_moves": 8},
}

#: The papers' result when run to completion, and the issue's target on 512 x 512 maps.
PAPERS = (0.93, 0.27)
TARGET = (0.95, 0.15)

#: Executing a plan is given up after this many times A*'s time on the problem: on the maze,
#: obstacle avoidance along the coarse first plan takes a minute or more per problem, hundreds
#: of times A*'s work.
EXECUTION_BUDGET = 10


@frozen
class Problem:
    """One query on one map; `optimal` is the `.scen` optimal length (None: A*'s)."""

    blocked: BoolGrid
    start: Position
    goal: Position
    optimal: float | None


@frozen
class Suite:
    """The problems of one row group: one map, or random worlds of one size."""

    name: str
    movement: int
    problems: list[Problem]
    large: bool  # 512 x 512: the target applies
    pyramid_seconds: float  # building the pyramids of its maps, once per map


@frozen
class AtpRun:
    """One configuration's measurements on one problem."""

    seconds: float
    first_seconds: float
    expansions: int
    refinements: int
    first_quality: float | None  # None: its execution went over budget
    final_quality: float
    first_execution: int | None  # obstacle-avoidance expansions executing the first plan


def best_of(repeats: int, measure: Callable[[], Any]) -> tuple[float, Any]:
    """The least wall time of `repeats` calls of `measure` and the last call's value."""
    best, value = math.inf, None
    for _ in range(repeats):
        gc.collect()
        gc.disable()
        try:
            begin = time.perf_counter()
            value = measure()
            best = min(best, time.perf_counter() - begin)
        finally:
            gc.enable()
    return best, value


def timed(measure: Callable[[], Any]) -> tuple[float, Any]:
    return best_of(1, measure)


def corner_suite(size: int, movement: int, worlds: int, repeats: int) -> Suite:
    problems, pyramid = [], 0.0
    for seed in range(worlds):
        world = random_world(size, seed=seed, movement=movement)
        problems.append(Problem(world.blocked, world.start, world.goal, None))
        pyramid += best_of(repeats, partial(Pyramid.build, world.blocked))[0]
    name = f"random rectangles {size}, {movement}-connected"
    return Suite(name, movement, problems, size >= 512, pyramid)


def longest(scenarios: list[Scenario], count: int) -> list[Scenario]:
    """`count` problems from the longest buckets: the last buckets' problems, longest first."""
    return sorted(scenarios, key=lambda s: (-s.bucket, -s.optimal))[:count]


def movingai_suite(name: str, count: int, repeats: int) -> Suite:
    blocked, _, _, scenarios = load_problems(MAPS / f"{name}.map")
    chosen = longest(scenarios, count)
    problems = [Problem(blocked, s.start, s.goal, s.optimal) for s in chosen]
    pyramid = best_of(repeats, lambda: Pyramid.build(blocked))[0]
    buckets = f"buckets {min(s.bucket for s in chosen)}-{max(s.bucket for s in chosen)}"
    return Suite(f"{name} ({buckets}), 8-connected", 8, problems, True, pyramid)


def run_atp(ctx: Context, plans: Iterator[Any]) -> tuple[float, MultiPath, MultiPath, int]:
    """Run the planner to completion: (seconds to the first plan, first, last, refinements)."""
    begin = time.perf_counter()
    first = last = next(plans).value
    first_seconds = time.perf_counter() - begin
    refinements = 0
    for result in plans:
        last = result.value
        refinements += 1
    return first_seconds, first, last, refinements


def measure_problem(
    problem: Problem, pyramid: Pyramid, movement: int, repeats: int
) -> tuple[float, int, dict[str, AtpRun]]:
    """A*'s best time and expansions, and each ATP configuration's run, interleaved."""
    astar_best = math.inf
    astar = None
    best: dict[str, list[float]] = {name: [math.inf, math.inf] for name in CONFIGS}
    outcome: dict[str, tuple[Context, MultiPath, MultiPath, int]] = {}
    for _ in range(repeats):
        seconds, astar = timed(
            lambda: find_path(
                problem.blocked, problem.start, problem.goal, movement=movement, weight=0.0
            )
        )
        astar_best = min(astar_best, seconds)
        for name, options in CONFIGS.items():
            ctx = Context()

            def plan(ctx: Context = ctx, options: dict[str, Any] = options) -> Any:
                plans = atp(ctx, problem.start, problem.goal, pyramid, movement=movement, **options)
                return run_atp(ctx, plans)

            seconds, (first_seconds, first, last, refinements) = timed(plan)
            best[name] = [min(best[name][0], seconds), min(best[name][1], first_seconds)]
            outcome[name] = (ctx, first, last, refinements)
    assert astar is not None, "the benchmark's problems are solvable"
    optimal = astar.length if problem.optimal is None else problem.optimal
    runs = {}
    routes: dict[tuple[Any, ...], Execution | None] = {}  # the configurations' first plans agree

    def route(plan: MultiPath) -> Execution | None:
        key = tuple(waypoints(plan))
        if key not in routes:
            try:
                with time_budget(EXECUTION_BUDGET * astar_best):
                    routes[key] = execute(plan, problem.blocked, movement=movement)
            except OverBudget:
                routes[key] = None
        return routes[key]

    for name, (ctx, first, last, refinements) in outcome.items():
        first_route, final_route = route(first), route(last)
        assert final_route is not None, "a fully refined plan is followed without search"
        runs[name] = AtpRun(
            seconds=best[name][0],
            first_seconds=best[name][1],
            expansions=int(ctx.ticks),
            refinements=refinements,
            first_quality=None if first_route is None else quality(first_route.length, optimal),
            final_quality=quality(final_route.length, optimal),
            first_execution=None if first_route is None else first_route.expansions,
        )
    return astar_best, astar.expansions, runs


class OverBudget(Exception):
    """An execution ran longer than its budget."""


@contextlib.contextmanager
def time_budget(seconds: float) -> Iterator[None]:
    """Raise `OverBudget` in the block after `seconds` of wall time (a SIGALRM timer; no
    budget where there is none)."""
    if not hasattr(signal, "setitimer"):
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise OverBudget

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def quality(length: float, optimal: float) -> float:
    """Plan quality; a length equal to the optimal to 1e-9 (float rounding) is optimal."""
    return 1.0 if math.isclose(length, optimal, rel_tol=1e-9) else plan_quality(length, optimal)


def bench_atp(suites: list[Suite], repeats: int) -> str:
    rows = []
    for suite in suites:
        pyramids: dict[int, Pyramid] = {}
        astar_times, astar_expansions = [], []
        runs: dict[str, list[AtpRun]] = {name: [] for name in CONFIGS}
        for problem in suite.problems:
            key = id(problem.blocked)
            if key not in pyramids:
                pyramids[key] = Pyramid.build(problem.blocked)
            seconds, expansions, measured = measure_problem(
                problem, pyramids[key], suite.movement, repeats
            )
            astar_times.append(seconds)
            astar_expansions.append(expansions)
            for name, run in measured.items():
                runs[name].append(run)
        for name, config_runs in runs.items():
            rows.append(atp_row(suite, name, astar_times, astar_expansions, config_runs))
    header = [
        "map",
        "ATP",
        "problems",
        "first q",
        "final q mean",
        "final q min",
        "time / A* (mean)",
        "time / A* (totals)",
        "first plan time / A*",
        "expansions / A*",
        "refinements",
        "pyramid / A*",
        "first plan exec. exp. / A*",
        "target met",
    ]
    quality_target, time_target = TARGET
    papers_quality, papers_time = PAPERS
    note = (
        "(q: plan quality = optimal length / executed length, per problem, then the mean or the\n"
        " minimum; time / A* (mean): the mean over problems of ATP time / A* time, each the best\n"
        f" of {repeats} runs; (totals): total ATP time / total A* time; first plan time: to the\n"
        " first yield; expansions / A*: total ATP expansions (of all its searches) / total A*\n"
        " expansions; refinements: mean per problem; pyramid / A*: building the abstraction\n"
        " pyramid, once per map, / total A* time on the map's problems (not in the ATP time);\n"
        " first plan exec. exp.: the obstacle-avoidance expansions executing the first plan on\n"
        " the true map takes, / total A* expansions (the final plan is followed with none);\n"
        f" an execution is given up after {EXECUTION_BUDGET}x A*'s time: 'k over' = first plans\n"
        " whose quality is not known, left out of the means;\n"
        f" target on 512 x 512: final q mean >= {quality_target} and time / A* (mean) <= "
        f"{time_target:.0%};\n the papers: {papers_quality} at {papers_time:.0%})"
    )
    return table(header, rows) + "\n" + note


def atp_row(
    suite: Suite,
    name: str,
    astar_times: list[float],
    astar_expansions: list[int],
    runs: list[AtpRun],
) -> list[str]:
    time_ratios = [r.seconds / a for r, a in zip(runs, astar_times, strict=True)]
    firsts = [r.first_quality for r in runs if r.first_quality is not None]
    over = len(runs) - len(firsts)
    first_q = f"{statistics.fmean(firsts):.3f}" if firsts else "-"
    first_work = [r.first_execution for r in runs if r.first_execution is not None]
    finished = [
        a for r, a in zip(runs, astar_expansions, strict=True) if r.first_execution is not None
    ]
    first_exec = f"{sum(first_work) / sum(finished):.1%}" if finished else "-"
    if over:
        first_q += f" ({over} over)"
        first_exec = f"{first_exec} ({over} over)"
    first_ratios = [r.first_seconds / a for r, a in zip(runs, astar_times, strict=True)]
    final = [r.final_quality for r in runs]
    mean_time = statistics.fmean(time_ratios)
    if suite.large:
        met = statistics.fmean(final) >= TARGET[0] and mean_time <= TARGET[1]
        target = "yes" if met else "NO"
    else:
        target = "-"
    return [
        suite.name,
        name,
        str(len(runs)),
        first_q,
        f"{statistics.fmean(final):.3f}",
        f"{min(final):.3f}",
        f"{mean_time:.1%}",
        f"{sum(r.seconds for r in runs) / sum(astar_times):.1%}",
        f"{statistics.fmean(first_ratios):.1%}",
        f"{sum(r.expansions for r in runs) / sum(astar_expansions):.1%}",
        f"{statistics.fmean(r.refinements for r in runs):.0f}",
        f"{suite.pyramid_seconds / sum(astar_times):.1%}",
        first_exec,
        target,
    ]


# --- 2. our A* against pathfinding's ----------------------------------------------------------


def route_length(path: list[Position]) -> float:
    diagonals = sum(
        1 for a, b in zip(path, path[1:], strict=False) if a[0] != b[0] and a[1] != b[1]
    )
    return len(path) - 1 - diagonals + math.sqrt(2.0) * diagonals


def bench_pathfinding(count: int, repeats: int) -> str:
    try:
        from pathfinding.core.diagonal_movement import (  # type: ignore[import-untyped]
            DiagonalMovement,
        )
        from pathfinding.core.grid import Grid  # type: ignore[import-untyped]
        from pathfinding.finder.a_star import AStarFinder  # type: ignore[import-untyped]
    except ImportError:
        return (
            "our A* against pathfinding's: skipped, the package 'pathfinding' is not installed"
            " (.venv/bin/pip install pathfinding)"
        )
    rows = []
    for name in MOVINGAI:
        blocked, width, height, scenarios = load_problems(MAPS / f"{name}.map")
        chosen = longest(scenarios, count)
        matrix = (~blocked[:height, :width]).astype(np.int8)  # 1: walkable
        build, grid = timed(partial(Grid, matrix=matrix))
        finder = AStarFinder(diagonal_movement=DiagonalMovement.only_when_no_obstacle)
        ours, theirs, resets = [], [], []
        ours_optimal = theirs_optimal = 0
        for scenario in chosen:
            (sx, sy), (gx, gy) = scenario.start, scenario.goal
            best_ours = best_theirs = math.inf
            for _ in range(repeats):
                ours_query = partial(
                    find_path, blocked, scenario.start, scenario.goal, movement=8, weight=0.0
                )
                seconds, found = timed(ours_query)
                best_ours = min(best_ours, seconds)
                reset, _ = timed(grid.cleanup)
                resets.append(reset)
                grid.dirty = False  # cleaned above: find_path would clean it again
                start, goal = grid.node(sx, sy), grid.node(gx, gy)
                seconds, (path, _) = timed(partial(finder.find_path, start, goal, grid))
                best_theirs = min(best_theirs, seconds)
            ours.append(best_ours)
            theirs.append(best_theirs)
            ours_optimal += math.isclose(found.length, scenario.optimal, rel_tol=1e-8)
            their_length = route_length([(node.x, node.y) for node in path])
            theirs_optimal += math.isclose(their_length, scenario.optimal, rel_tol=1e-8)
        n = len(chosen)
        rows.append(
            [
                name,
                str(n),
                f"{statistics.fmean(t / o for t, o in zip(theirs, ours, strict=True)):.2f}",
                f"{sum(theirs) / sum(ours):.2f}",
                f"{ours_optimal}/{n}",
                f"{theirs_optimal}/{n}",
                f"{build / statistics.fmean(ours):.2f}",
                f"{statistics.fmean(resets) / statistics.fmean(ours):.2f}",
            ]
        )
    header = [
        "map (8-connected)",
        "problems",
        "theirs / ours (mean)",
        "theirs / ours (totals)",
        "ours optimal",
        "theirs optimal",
        "their grid build / our query",
        "their grid reset / our query",
    ]
    note = (
        f"(query time, each the best of {repeats} runs; ours includes setting up its per-query\n"
        " arrays, theirs excludes building the grid (once per map) and resetting it before each\n"
        " query, both shown as multiples of our mean query time; optimal: the length equals the\n"
        " .scen optimal to 1e-8)"
    )
    return table(header, rows) + "\n" + note


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer problems: under a minute")
    parser.add_argument(
        "--repeats", type=int, help="runs per problem and side, the best kept (3; quick: 2)"
    )
    args = parser.parse_args()
    began = time.perf_counter()
    small, large, count = (5, 2, 2) if args.quick else (20, 10, 12)
    repeats = args.repeats if args.repeats is not None else 2 if args.quick else 3
    print(machine())
    print()
    suites = [
        corner_suite(128, 4, small, repeats),
        corner_suite(128, 8, small, repeats),
        corner_suite(512, 8, large, repeats),
        *(movingai_suite(name, count, repeats) for name in MOVINGAI),
    ]
    print(bench_atp(suites, repeats))
    print()
    print(bench_pathfinding(count, repeats))
    print()
    print(f"(the whole run took {time.perf_counter() - began:.0f} s)")


if __name__ == "__main__":
    main()
