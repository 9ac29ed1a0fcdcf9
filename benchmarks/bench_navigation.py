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
3. Per map kind (issue 17): the default ATP against A* on the longest problems of 14 MovingAI
   maps, the shipped three and eleven more in benchmarks/data/movingai/ (random with 20% of
   cells blocked, rooms of 16, 32 and 64, mazes of corridor widths 2, 4 and 8, two street maps,
   a Baldur's Gate II and a Dragon Age map): first plan quality and time, final quality mean
   (min), time and expansions as fractions of A*'s, the time with the abstraction's one-off
   build added, the peers' query times against ours (`pathfinding`, networkx and tcod, where
   installed: the `bench` extra), and issue 17's targets. Optimal lengths are our A*'s: the
   old-style `.scen` files round theirs to 5 digits (all agree with A*'s to that).

Timing: `time.perf_counter`, the garbage collector paused, the sides interleaved per problem
(A*, then each ATP configuration; ours, then theirs), the best of `--repeats` runs per problem
and side. ATP's time is planning only: its abstraction (the obstacleness pyramid and the
connected components of every block) is built once per map, timed
separately (shown as a fraction of A*'s total time on that map's problems), and the execution
of its plans, which yields the quality, is not timed (and is given up after `EXECUTION_BUDGET`
times A*'s time: the first plan's quality is then unknown). `pathfinding`'s grid is built once
per map and reset before each query, both outside its query time and shown separately.

Problems: 20 worlds of 128 x 128 per movement, 10 of 512 x 512, the 12 problems of the
longest buckets of each shipped MovingAI map, and 16 per map in the per-kind table (the issue's
count, so the abstraction's build is spread over as many problems); --quick: 5, 2, 2 and 16,
the best of 2 runs (the per-kind table: 1 run, executions given up after 2x A*'s time; 24
minutes in all on a 2-core machine, most of it the peers' A*s, `pathfinding` alone more than
half; the full run takes longer, three runs of each problem). Plans are
executed keeping to their corridor (`execute(..., keep_to_plan=True)`): they are made on the
map they are followed on.

Run: .venv/bin/python benchmarks/bench_navigation.py [--quick] [--repeats N] [--maps MAP ...]
(--maps: the per-kind table alone, quick settings, on any MovingAI maps with their .scen files).
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
from anytime_navigation.movingai import MapError, Scenario, load_problems
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import DEFAULT_TOP, MultiPath, atp, compile_searches
from anytime_navigation.planning.search import find_path
from anytime_navigation.task.execution import Execution, execute, plan_quality, waypoints
from anytime_navigation.world import SQRT2, BoolGrid, Position, random_world
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
#: More MovingAI maps, of the kinds the shipped sample lacks (benchmarks/data/movingai/README.md).
MORE_MAPS = Path(__file__).resolve().parent / "data" / "movingai"
MOVINGAI = tuple(MAPS / f"{name}.map" for name in ("8room_000", "maze512-1-0", "random512-10-0"))

#: The per-kind table's maps, (kind, map file): the shipped sample's 512 x 512 maps and more.
KINDS: tuple[tuple[str, Path], ...] = (
    ("random 10%", MAPS / "random512-10-0.map"),
    ("random 20%", MORE_MAPS / "random512-20-0.map"),
    ("rooms of 8", MAPS / "8room_000.map"),
    ("rooms of 16", MORE_MAPS / "16room_000.map"),
    ("rooms of 32", MORE_MAPS / "32room_000.map"),
    ("rooms of 64", MORE_MAPS / "64room_000.map"),
    ("maze, width 1", MAPS / "maze512-1-0.map"),
    ("maze, width 2", MORE_MAPS / "maze512-2-0.map"),
    ("maze, width 4", MORE_MAPS / "maze512-4-0.map"),
    ("maze, width 8", MORE_MAPS / "maze512-8-0.map"),
    ("street", MORE_MAPS / "Berlin_0_512.map"),
    ("street", MORE_MAPS / "Boston_0_512.map"),
    ("game (Baldur's Gate II)", MORE_MAPS / "AR0011SR.map"),
    ("game (Dragon Age)", MORE_MAPS / "brc202d.map"),
)

#: The ATP configurations compared: name -> keyword arguments of `atp`.
CONFIGS: dict[str, dict[str, Any]] = {
    "one segment": {},  # the default
    "segments of 8 moves": {"segment_moves": 8},
}

#: The papers' result when run to completion, and the issue's target on 512 x 512 maps.
PAPERS = (0.93, 0.27)
TARGET = (0.95, 0.15)
#: Issue 17's targets on every map kind: final quality mean and min at most this fraction of
#: A*'s time (totals, the abstraction included); the first plan's quality within this fraction.
KIND_TARGET = (0.97, 0.93, 0.12)
FIRST_TARGET = (0.85, 0.02)

#: Executing a plan is given up after this many times A*'s time on the problem: on the maze,
#: obstacle avoidance along the coarse first plan takes a minute or more per problem, hundreds
#: of times A*'s work.
EXECUTION_BUDGET = 10

#: networkx's A* (pure Python, a second or more per query on 512 x 512) races ours on the first
#: few of each map's problems only.
NETWORKX_PROBLEMS = 4


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
    abstraction_seconds: float  # building the abstractions of its maps, once per map


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


def abstraction(blocked: BoolGrid, movement: int) -> tuple[Pyramid, Components]:
    """The ATP's description of a map, built once per map: the obstacleness pyramid and the
    connectivity-aware abstraction up to the default first-plan level."""
    pyramid = Pyramid.build(blocked)
    return pyramid, Components.build(blocked, movement, top=min(DEFAULT_TOP, pyramid.top))


def corner_suite(size: int, movement: int, worlds: int, repeats: int) -> Suite:
    problems, pyramid = [], 0.0
    for seed in range(worlds):
        world = random_world(size, seed=seed, movement=movement)
        problems.append(Problem(world.blocked, world.start, world.goal, None))
        pyramid += best_of(repeats, partial(abstraction, world.blocked, movement))[0]
    name = f"random rectangles {size}, {movement}-connected"
    return Suite(name, movement, problems, size >= 512, pyramid)


def longest(scenarios: list[Scenario], count: int) -> list[Scenario]:
    """`count` problems from the longest buckets: the last buckets' problems, longest first."""
    return sorted(scenarios, key=lambda s: (-s.bucket, -s.optimal))[:count]


def movingai_suite(path: Path, count: int, repeats: int) -> Suite:
    """The `count` longest problems of a MovingAI map, optimal lengths from A* (the old-style
    `.scen` files round theirs to 5 digits; the files were checked against A*)."""
    blocked, _, _, scenarios = load_problems(path)
    chosen = longest(scenarios, count)
    problems = [Problem(blocked, s.start, s.goal, None) for s in chosen]
    pyramid = best_of(repeats, lambda: abstraction(blocked, 8))[0]
    buckets = f"buckets {min(s.bucket for s in chosen)}-{max(s.bucket for s in chosen)}"
    return Suite(f"{path.stem} ({buckets}), 8-connected", 8, problems, True, pyramid)


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
    problem: Problem,
    pyramid: Pyramid,
    components: Components,
    movement: int,
    repeats: int,
    configs: dict[str, dict[str, Any]] = CONFIGS,
    budget: float = EXECUTION_BUDGET,
) -> tuple[float, int, dict[str, AtpRun]]:
    """A*'s best time and expansions, and each ATP configuration's run, interleaved; executing
    a plan is given up after `budget` times A*'s time."""
    astar_best = math.inf
    astar = None
    best: dict[str, list[float]] = {name: [math.inf, math.inf] for name in configs}
    outcome: dict[str, tuple[Context, MultiPath, MultiPath, int]] = {}
    for _ in range(repeats):
        seconds, astar = timed(
            lambda: find_path(
                problem.blocked, problem.start, problem.goal, movement=movement, weight=0.0
            )
        )
        astar_best = min(astar_best, seconds)
        for name, options in configs.items():
            ctx = Context()

            def plan(ctx: Context = ctx, options: dict[str, Any] = options) -> Any:
                plans = atp(
                    ctx,
                    problem.start,
                    problem.goal,
                    pyramid,
                    movement=movement,
                    components=components,
                    **options,
                )
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
                with time_budget(budget * astar_best):
                    routes[key] = execute(  # planned on the map followed: its corridor holds
                        plan, problem.blocked, movement=movement, keep_to_plan=True
                    )
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


@frozen
class Measured:
    """A suite's measurements: A*'s best time and expansions per problem, and each ATP
    configuration's runs in the same order."""

    astar_times: list[float]
    astar_expansions: list[int]
    runs: dict[str, list[AtpRun]]


def measure_suite(
    suite: Suite,
    repeats: int,
    configs: dict[str, dict[str, Any]] = CONFIGS,
    budget: float = EXECUTION_BUDGET,
) -> Measured:
    described: dict[int, tuple[Pyramid, Components]] = {}
    measured = Measured([], [], {name: [] for name in configs})
    for problem in suite.problems:
        key = id(problem.blocked)
        if key not in described:
            described[key] = abstraction(problem.blocked, suite.movement)
        pyramid, components = described[key]
        seconds, expansions, runs = measure_problem(
            problem, pyramid, components, suite.movement, repeats, configs, budget
        )
        measured.astar_times.append(seconds)
        measured.astar_expansions.append(expansions)
        for name, run in runs.items():
            measured.runs[name].append(run)
    return measured


def bench_atp(suites: list[Suite], repeats: int) -> str:
    rows = []
    for suite in suites:
        measured = measure_suite(suite, repeats)
        for name, config_runs in measured.runs.items():
            rows.append(
                atp_row(suite, name, measured.astar_times, measured.astar_expansions, config_runs)
            )
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
        "abstraction / A*",
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
        " expansions; refinements: mean per problem; abstraction / A*: building the pyramid and\n"
        " the components, once per map, / total A* time on the map's problems (not in the ATP\n"
        " time);\n"
        " first plan exec. exp.: the obstacle-avoidance expansions executing the first plan on\n"
        " the true map takes, / total A* expansions (the final plan is followed with none);\n"
        f" an execution is given up after {EXECUTION_BUDGET}x A*'s time: 'k over' = first plans\n"
        " whose quality is not known, left out of the means;\n"
        f" target on 512 x 512: final q mean >= {quality_target} and time / A* (mean) <= "
        f"{time_target:.0%};\n the papers: {papers_quality} at {papers_time:.0%})"
    )
    return table(header, rows) + "\n" + note


@frozen
class Summary:
    """One configuration's runs on a suite, summed up against A*'s."""

    first_quality: str  # the mean; "(k over)": first plans whose execution went over budget
    first_mean: float | None  # None: every first plan's execution went over budget
    first_execution: str  # obstacle-avoidance expansions executing the first plans / A*'s
    first_time: float  # mean over problems of time to the first plan / A* time
    final_mean: float
    final_min: float
    time_mean: float  # mean over problems of ATP time / A* time
    time_totals: float  # total ATP time / total A* time
    expansions: float  # total ATP expansions / total A* expansions
    refinements: float  # mean per problem


def summarise(astar_times: list[float], astar_expansions: list[int], runs: list[AtpRun]) -> Summary:
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
    final = [r.final_quality for r in runs]
    return Summary(
        first_quality=first_q,
        first_mean=statistics.fmean(firsts) if firsts else None,
        first_execution=first_exec,
        first_time=statistics.fmean(
            r.first_seconds / a for r, a in zip(runs, astar_times, strict=True)
        ),
        final_mean=statistics.fmean(final),
        final_min=min(final),
        time_mean=statistics.fmean(r.seconds / a for r, a in zip(runs, astar_times, strict=True)),
        time_totals=sum(r.seconds for r in runs) / sum(astar_times),
        expansions=sum(r.expansions for r in runs) / sum(astar_expansions),
        refinements=statistics.fmean(r.refinements for r in runs),
    )


def atp_row(
    suite: Suite,
    name: str,
    astar_times: list[float],
    astar_expansions: list[int],
    runs: list[AtpRun],
) -> list[str]:
    summary = summarise(astar_times, astar_expansions, runs)
    if suite.large:
        met = summary.final_mean >= TARGET[0] and summary.time_mean <= TARGET[1]
        target = "yes" if met else "NO"
    else:
        target = "-"
    return [
        suite.name,
        name,
        str(len(runs)),
        summary.first_quality,
        f"{summary.final_mean:.3f}",
        f"{summary.final_min:.3f}",
        f"{summary.time_mean:.1%}",
        f"{summary.time_totals:.1%}",
        f"{summary.first_time:.1%}",
        f"{summary.expansions:.1%}",
        f"{summary.refinements:.0f}",
        f"{suite.abstraction_seconds / sum(astar_times):.1%}",
        summary.first_execution,
        target,
    ]


# --- 2. our A* against pathfinding's ----------------------------------------------------------


def route_length(path: list[Position]) -> float:
    diagonals = sum(
        1 for a, b in zip(path, path[1:], strict=False) if a[0] != b[0] and a[1] != b[1]
    )
    return len(path) - 1 - diagonals + math.sqrt(2.0) * diagonals


@frozen
class PeerRun:
    """Our A* against `pathfinding`'s on one map's problems, interleaved: the best query time
    of each per problem, grid resets, optimal counts and the grid's one-off build time."""

    ours: list[float]
    theirs: list[float]
    resets: list[float]
    ours_optimal: int
    theirs_optimal: int
    build: float


def pathfinding_finder() -> Any | None:
    """`pathfinding`'s (Grid class, A* finder with the MovingAI movement rule), or None when
    the optional package is not installed."""
    try:
        from pathfinding.core.diagonal_movement import (  # type: ignore[import-untyped]
            DiagonalMovement,
        )
        from pathfinding.core.grid import Grid  # type: ignore[import-untyped]
        from pathfinding.finder.a_star import AStarFinder  # type: ignore[import-untyped]
    except ImportError:
        return None
    return Grid, AStarFinder(diagonal_movement=DiagonalMovement.only_when_no_obstacle)


def race_pathfinding(
    peer: Any, blocked: BoolGrid, width: int, height: int, chosen: list[Scenario], repeats: int
) -> PeerRun:
    grid_class, finder = peer
    matrix = (~blocked[:height, :width]).astype(np.int8)  # 1: walkable
    build, grid = timed(partial(grid_class, matrix=matrix))
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
    return PeerRun(ours, theirs, resets, ours_optimal, theirs_optimal, build)


NO_PATHFINDING = "the package 'pathfinding' is not installed (.venv/bin/pip install pathfinding)"


def bench_pathfinding(count: int, repeats: int) -> str:
    peer = pathfinding_finder()
    if peer is None:
        return f"our A* against pathfinding's: skipped, {NO_PATHFINDING}"
    rows = []
    for path in MOVINGAI:
        blocked, width, height, scenarios = load_problems(path)
        chosen = longest(scenarios, count)
        run = race_pathfinding(peer, blocked, width, height, chosen, repeats)
        n = len(chosen)
        rows.append(
            [
                path.stem,
                str(n),
                f"{statistics.fmean(t / o for t, o in zip(run.theirs, run.ours, strict=True)):.2f}",
                f"{sum(run.theirs) / sum(run.ours):.2f}",
                f"{run.ours_optimal}/{n}",
                f"{run.theirs_optimal}/{n}",
                f"{run.build / statistics.fmean(run.ours):.2f}",
                f"{statistics.fmean(run.resets) / statistics.fmean(run.ours):.2f}",
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


def networkx_query(blocked: BoolGrid) -> Callable[[Position, Position], list[Position]] | None:
    """networkx's A* on the grid's graph (free cells, the MovingAI moves: octile, no corner
    cutting; the graph built here, once per map), octile heuristic; None when networkx is not
    installed."""
    try:
        import networkx as nx  # type: ignore[import-untyped]
    except ImportError:
        return None
    graph = nx.Graph()
    free = ~np.asarray(blocked, dtype=bool)
    side = free.shape[0]
    for (dx, dy), weight in (((1, 0), 1.0), ((0, 1), 1.0), ((1, 1), SQRT2), ((-1, 1), SQRT2)):
        ys, xs = np.nonzero(free)
        nx_, ny = xs + dx, ys + dy
        inside = (nx_ >= 0) & (nx_ < side) & (ny < side)
        xs, ys, nx_, ny = xs[inside], ys[inside], nx_[inside], ny[inside]
        legal = free[ny, nx_]
        if dx and dy:
            legal &= free[ys, nx_] & free[ny, xs]
        graph.add_weighted_edges_from(
            zip(
                zip(xs[legal].tolist(), ys[legal].tolist(), strict=True),
                zip(nx_[legal].tolist(), ny[legal].tolist(), strict=True),
                [weight] * int(legal.sum()),
                strict=True,
            )
        )

    def octile(a: Position, b: Position) -> float:
        dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
        return float(max(dx, dy) + (SQRT2 - 1.0) * min(dx, dy))

    def query(start: Position, goal: Position) -> list[Position]:
        found: list[Position] = nx.astar_path(graph, start, goal, heuristic=octile)
        return found

    return query


def tcod_query(blocked: BoolGrid) -> Callable[[Position, Position], list[Position]] | None:
    """tcod's A* (libtcod, C; diagonal moves cost sqrt 2 and may cut corners: its lengths can
    be shorter than the MovingAI optimum); None when tcod is not installed."""
    try:
        import tcod.path
    except ImportError:
        return None
    finder = tcod.path.AStar((~np.asarray(blocked, dtype=bool)).astype(np.int8).T, SQRT2)

    def query(start: Position, goal: Position) -> list[Position]:
        return [start, *finder.get_path(*start, *goal)]

    return query


def race_peer(
    make: Callable[[BoolGrid], Callable[[Position, Position], list[Position]] | None],
    blocked: BoolGrid,
    chosen: list[Scenario],
    repeats: int,
) -> tuple[float, int] | None:
    """A peer's total query time over our A*'s on the same problems (interleaved, the best of
    `repeats` per problem and side) and how many of its routes are optimal; None when the peer
    is not installed."""
    query = make(blocked)
    if query is None:
        return None
    ours = theirs = 0.0
    optimal = 0
    for scenario in chosen:
        best_ours, best_theirs = math.inf, math.inf
        for _ in range(repeats):
            seconds, _ = timed(
                partial(find_path, blocked, scenario.start, scenario.goal, movement=8, weight=0.0)
            )
            best_ours = min(best_ours, seconds)
            seconds, route = timed(partial(query, scenario.start, scenario.goal))
            best_theirs = min(best_theirs, seconds)
        ours += best_ours
        theirs += best_theirs
        optimal += math.isclose(route_length(route), scenario.optimal, rel_tol=1e-4)
    return theirs / ours, optimal


# --- 3. per map kind ---------------------------------------------------------------------------


def bench_kinds(
    count: int, repeats: int, budget: float, kinds: tuple[tuple[str, Path], ...] = KINDS
) -> str:
    """The default ATP against A* on the `count` longest problems of each map of `KINDS`, with
    `pathfinding`'s A* per query where it is installed; executing a plan is given up after
    `budget` times A*'s time."""
    peer = pathfinding_finder()
    default = {"one segment": CONFIGS["one segment"]}
    rows = []
    for kind, path in kinds:
        suite = movingai_suite(path, count, repeats)
        measured = measure_suite(suite, repeats, default, budget)
        runs = measured.runs["one segment"]
        summary = summarise(measured.astar_times, measured.astar_expansions, runs)
        astar_total = sum(measured.astar_times)
        with_abstraction = (sum(r.seconds for r in runs) + suite.abstraction_seconds) / astar_total
        peer_ratio = "-"
        if peer is not None:
            blocked, width, height, scenarios = load_problems(path)
            run = race_pathfinding(peer, blocked, width, height, longest(scenarios, count), repeats)
            peer_ratio = f"{sum(run.theirs) / sum(run.ours):.2f}"
        others = []
        blocked, _, _, scenarios = load_problems(path)
        for make, problems in ((networkx_query, NETWORKX_PROBLEMS), (tcod_query, count)):
            raced = race_peer(make, blocked, longest(scenarios, problems), repeats)
            others.append("-" if raced is None else f"{raced[0]:.2f} ({raced[1]}/{problems})")
        quality_mean, quality_min, time_target = KIND_TARGET
        first_quality, first_time = FIRST_TARGET
        met = (
            summary.final_mean >= quality_mean
            and summary.final_min >= quality_min
            and with_abstraction <= time_target
            and summary.first_mean is not None
            and summary.first_mean >= first_quality
            and summary.first_time <= first_time
        )
        rows.append(
            [
                path.stem,
                kind,
                str(len(runs)),
                summary.first_quality,
                f"{summary.first_time:.1%}",
                f"{summary.final_mean:.3f} ({summary.final_min:.3f})",
                f"{summary.time_mean:.1%}",
                f"{summary.time_totals:.1%}",
                f"{with_abstraction:.1%}",
                f"{summary.expansions:.1%}",
                peer_ratio,
                *others,
                "yes" if met else "NO",
            ]
        )
    header = [
        "map",
        "kind",
        "problems",
        "first q",
        "first plan time / A*",
        "final q mean (min)",
        "time / A* (mean)",
        "time / A* (totals)",
        "with abstraction / A* (totals)",
        "expansions / A*",
        "pathfinding / our A*",
        "networkx / our A* (optimal)",
        "tcod / our A* (optimal)",
        "issue 17 target",
    ]
    peers = (
        "networkx / our A*, tcod / our A*: likewise (networkx's astar_path on the map's graph,\n"
        f" octile heuristic, on the first {NETWORKX_PROBLEMS} problems; tcod's AStar, in C, which\n"
        " cuts corners: its routes can be shorter than the optimum), with how many of their\n"
        " routes are optimal; their graphs and grids are built once per map, outside the query\n"
        " time ('-': not installed)"
    )
    if peer is None:
        peers = f"pathfinding: '-', {NO_PATHFINDING};\n {peers}"
    note = (
        f"(the default ATP, the first plan one segment; the {count} problems of the longest\n"
        " buckets per map, octile without corner cutting, optimal lengths from our A*; A* and\n"
        f" the ATP interleaved, each the best of {repeats} run(s); columns as in the first table,\n"
        f" but an execution is given up after {budget:g}x A*'s time;\n"
        " with abstraction: (total ATP time + building the abstraction once) / total A* time;\n"
        " pathfinding / our A*: its total query time / ours on the same problems, as in the\n"
        f" second table;\n {peers};\n"
        f" issue 17 target: final q mean >= {quality_mean} and min >= {quality_min} with\n"
        f" abstraction <= {time_target:.0%}, first q >= {first_quality} at first plan time <= "
        f"{first_time:.0%})"
    )
    return table(header, rows) + "\n" + note


def compiled_searches() -> str:
    """Load the planner's compiled searches (`corridor_search`, numba), or compile them, before
    anything is timed: a cost paid once per process, said here and left out of the tables."""
    seconds, _ = timed(compile_searches)
    return (
        f"(the planner's compiled searches loaded in {seconds:.2f} s, once per process:"
        " not in the times below)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer problems: about 25 minutes")
    parser.add_argument(
        "--repeats", type=int, help="runs per problem and side, the best kept (3; quick: 2)"
    )
    parser.add_argument(
        "--maps",
        nargs="+",
        type=Path,
        metavar="MAP",
        help="only the per-kind table, on these MovingAI .map files (each with its .scen beside)",
    )
    args = parser.parse_args()
    began = time.perf_counter()
    print(compiled_searches())
    if args.maps:  # maps of the user's: the per-kind table alone, on those that load
        given = []
        for path in args.maps:
            try:
                load_problems(path)
            except (OSError, MapError) as error:
                print(f"{path}: left out, {error}")
            else:
                given.append(("given", path))
        print(bench_kinds(16, args.repeats or 1, 2, tuple(given)))
        print(f"\n(the whole run took {time.perf_counter() - began:.0f} s)")
        return
    small, large, count, per_kind = (5, 2, 2, 16) if args.quick else (20, 10, 12, 16)
    repeats = args.repeats if args.repeats is not None else 2 if args.quick else 3
    # --quick: the per-kind table's problems once each, their first plans' executions given up
    # sooner
    kind_repeats = args.repeats if args.repeats is not None else 1 if args.quick else repeats
    kind_budget = 2 if args.quick else EXECUTION_BUDGET
    print(machine())
    print()
    suites = [
        corner_suite(128, 4, small, repeats),
        corner_suite(128, 8, small, repeats),
        corner_suite(512, 8, large, repeats),
        *(movingai_suite(path, count, repeats) for path in MOVINGAI),
    ]
    print(bench_atp(suites, repeats))
    print()
    print(bench_pathfinding(count, repeats))
    print()
    print(bench_kinds(per_kind, kind_repeats, kind_budget))
    print()
    print(f"(the whole run took {time.perf_counter() - began:.0f} s)")


if __name__ == "__main__":
    main()
