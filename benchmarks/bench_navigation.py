"""Navigation benchmarks: the anytime abstract planner (ATP) against a compiled A*, and that A*
against the pure-Python A* and the peers' A*s, printed as side-by-side tables (not a test:
nothing here is asserted).

The reference (issue 36): every ratio "/ A*" is against the compiled A* (`search.GridAstar`,
numba), the same search as the project's pure-Python A* (`search.find_path`: octile moves, no
corner cutting, the same tie-breaking, so the same paths and expansions; checked here problem by
problem, and against the `.scen` optimal lengths in the last table). The pure-Python A* stays as
a row (first table) and a column (per-kind table). Each A*'s grid is built once per map, like the
ATP's abstraction.

1. ATP against A* on the same problems in one run: random-rectangle worlds of 128 x 128
   (4- and 8-connected) and 512 x 512 (8-connected), start and goal in opposite corners; and the
   512 x 512 MovingAI maps shipped with the domain (8-connected octile, no corner cutting),
   problems from the longest scenario buckets. Per map and ATP configuration: the plan quality
   (optimal length / length of the route `execution.execute` follows on the true map) after the
   first plan and at completion; the ATP's time and node expansions as fractions of A*'s. Two
   configurations: the default (the first plan one segment) and `segment_moves=8` (the first
   plan cut into segments of at most 8 moves: a finer anytime grain). The papers
   report 0.93 expected quality at 27% of A*'s time when run to completion (against their
   A*); issue 6's target is at least 0.95 at no more than 15% on 512 x 512 maps.
2. The compiled A* against `pathfinding`'s `AStarFinder` (octile, diagonal only when both
   orthogonal neighbours are free: the MovingAI rule) on the same MovingAI problems: query
   time, and whether each finds the `.scen` optimal length. An optional dependency: skipped,
   with a line saying so, when it is not installed.
3. Per map kind (issues 17 and 36): the default ATP, and beside it each option of `atp` that
   issue 36 asks to measure (`KIND_CONFIGS`: the door search kept near the first plan, the first
   plan a level higher, a direct search for short problems, one for narrow corridors after
   the first plan, open level-1 segments refined without a ring, and open level-2 segments
   with one ring instead of three; each with its own
   abstraction's build; and the last of them with `follow`, issue 36 item 3: a plan registered
   only when the robot follows it no longer than the last one registered, `following.Follower`
   in the ATP's time; and the options `anytime plan` chooses by the map's size and shape,
   `planner.map_options`, reading it timed with the build), against A* on the longest problems
   of 15 MovingAI maps, the shipped three and twelve
   more in benchmarks/data/movingai/ (random with 20% and 30% of cells blocked, rooms of 16,
   32 and 64,
   mazes of corridor widths 2, 4 and 8, two street maps, a Baldur's Gate II and a Dragon Age
   map): first plan quality and time, final quality mean (min), time and expansions as fractions
   of A*'s, the time with the abstraction's one-off build added, the falls of the anytime curve
   (every plan registered executed), the time on 16 random (mostly short) problems, the
   pure-Python A*'s and the peers' query times against the compiled A*'s (`pathfinding`,
   networkx and tcod, where installed: the `bench` extra), and issue 36's targets. Optimal
   lengths are A*'s: the old-style `.scen` files round theirs to 5 digits (all agree with A*'s
   to that).
4. The compiled A*'s lengths against the `.scen` optimal lengths of the 15 maps: every problem
   in a full run, 200 per map spread over the file with --quick.

Timing: `time.perf_counter`. Each side runs one map's problems as a stream, one after another,
as a planner serving queries on a map does (the grid-pathfinding competition's way): per round
the compiled A* on every problem, the pure-Python A*, then each ATP configuration (ours, then
theirs); one untimed round first, then `--repeats` rounds, each problem's best kept. A stream
follows one garbage collection and runs with the collector off. The planner's runs are short
and cache-bound: run straight after A*, its first run took 1.5x its steady time, and a
collection before each run (which walks the plans the runs before kept) started each cold; with
a collection and its runs interleaved per problem, the caves' options by map read 22-33% of
A*'s time with the build where the stream reads 22%. ATP's time is planning only: its
abstraction (the obstacleness pyramid and the connected components of every block) is built
once per map, timed separately (shown as a fraction of A*'s total time on that map's problems),
and the execution of its plans, which yields the quality, is not timed (and is given up after
`EXECUTION_BUDGET` times the pure-Python A*'s time: the first plan's quality is then unknown).
`pathfinding`'s grid is built once per map and reset before each query, both outside its query
time and shown separately.

Problems: 20 worlds of 128 x 128 per movement, 10 of 512 x 512, the 12 problems of the
longest buckets of each shipped MovingAI map, and 16 per map in the per-kind table (the issue's
count, so the abstraction's build is spread over as many problems); --quick: 5, 2, 2 and 16,
the best of 2 runs (the per-kind table: the best of 3, as issue 36 measured, its executions
given up after 2x the pure-Python A*'s time: its targets sit within a few points of A*'s time,
and with one run of each problem random512-10-0's large-map row read 26.9% and 33.6% of A*'s
time, with the abstraction, on two page runs, of planners that took the same time side by side;
about 25 minutes in all on a 2-core machine; the full run takes longer, three runs of each
problem). Each timed run follows a collection, with the collector off while it runs; what is
alive once set up is frozen (`gc.freeze`): a collection of the whole heap before each run took
most of the time and started each run cold.
Plans are executed keeping to their corridor (`execute(..., keep_to_plan=True)`): they are made
on the map they are followed on.

Run: .venv/bin/python benchmarks/bench_navigation.py [--quick] [--repeats N]
[--maps MAP ... [--configs NAME ...]] (--maps: the per-kind table alone, quick settings, on any
MovingAI maps with their .scen files, its rows `--configs` or all, and the compiled A* on every
problem of their files, or on 200 of each with --quick).
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
from anytime_navigation.planning.following import Follower
from anytime_navigation.planning.planner import (
    DEFAULT_TOP,
    LARGE_MAP_OPTIONS,
    SCATTERED_MAP_OPTIONS,
    SMALL_MAP_OPTIONS,
    SMALL_WALLED_MAP_OPTIONS,
    SPARSE_MAP_OPTIONS,
    WALLED_MAP_OPTIONS,
    MultiPath,
    atp,
    compile_searches,
    made_ahead,
    map_options,
)
from anytime_navigation.planning.search import GridAstar, find_path
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
    ("random 30%", MORE_MAPS / "random512-30-0.map"),  # `map_options`' scattered, dense kind
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

#: The options of maps of solid obstacles before issue 36's walled-map options (a row of the
#: per-kind table): the large-map options with level-2 segments refined straight to the base
#: cells and no door search.
SOLID_MAP_OPTIONS: dict[str, Any] = {
    **LARGE_MAP_OPTIONS,
    "skip_level_1": True,
    "doors": False,
    "direct_width": 12,
}

#: The options of maps of scattered, dense obstacles until issue 36's direct route (a row of the
#: per-kind table): the large-map options with the first plan over blocks of 8 x 8, the direct
#: route for corridors of at most 8 cells per unit of length, no jump points, refined level by
#: level.
REFINED_SCATTERED_OPTIONS: dict[str, Any] = {
    **LARGE_MAP_OPTIONS,
    "top": 3,
    "direct_width": 8,
    "jump_points": False,
}

#: The ATP configurations compared: name -> keyword arguments of `atp`.
CONFIGS: dict[str, dict[str, Any]] = {
    "one segment": {},  # the default
    "segments of 8 moves": {"segment_moves": 8},
}

#: An option value that stands for the map's `following.Follower` (built once per map, like the
#: abstraction; its build timed with it): `atp(follow=...)` registers a plan only when the robot
#: follows it no longer than the last registered one (issue 36 item 3: a monotone curve).
FOLLOW = "the map's Follower"

#: A configuration `{"options": BY_MAP}` stands for `planner.map_options` of the map planned on
#: (`anytime plan`'s default: read once per map, its time with the abstraction's build).
BY_MAP = "the map's options"

#: The per-kind table's ATP configurations, each a row per map beside the default, measured in
#: the same run (issue 36 item 2: every new option of `atp` is kept only if this shows it pays):
#: name -> keyword arguments of `atp`. `top` needs the abstraction built up to that level: each
#: configuration's build is timed apart.
KIND_CONFIGS: dict[str, dict[str, Any]] = {
    "default": {},
    "door_rings=2": {"door_rings": 2},
    "top=4": {"top": 4},
    "top=4, direct=4": {"top": 4, "direct": 4},
    "top=4, direct=4, direct_width=12": {"top": 4, "direct": 4, "direct_width": 12},
    "... and no_ring_when_open=0.05": {
        "top": 4,
        "direct": 4,
        "direct_width": 12,
        "no_ring_when_open": 0.05,
    },
    "... and one_ring_when_open=0.1": {
        "top": 4,
        "direct": 4,
        "direct_width": 12,
        "no_ring_when_open": 0.05,
        "one_ring_when_open": 0.1,
    },
    "... and landmarks=8": {
        key: value
        for key, value in LARGE_MAP_OPTIONS.items()
        if key not in ("no_ring_when_clear", "jump_points")
    },
    "... and no_ring_when_clear=0.7": {
        key: value for key, value in LARGE_MAP_OPTIONS.items() if key != "jump_points"
    },
    "... and jump_points": dict(LARGE_MAP_OPTIONS),  # `anytime plan`'s options
    "... and skip_level_1": {**LARGE_MAP_OPTIONS, "skip_level_1": True},
    "... and doors=False": dict(SOLID_MAP_OPTIONS),  # the options of solid maps until issue 36
    "walled-map options (direct route)": dict(WALLED_MAP_OPTIONS),
    "... searched cell by cell (jump_points=False)": {**WALLED_MAP_OPTIONS, "jump_points": False},
    "small-walled-map options (direct_whole)": dict(SMALL_WALLED_MAP_OPTIONS),
    "sparse-map options (direct_ring_level=2)": dict(SPARSE_MAP_OPTIONS),
    "scattered-map options (direct_via=2, direct_rings=2)": dict(SCATTERED_MAP_OPTIONS),
    "... refined, as until issue 36's direct route": dict(REFINED_SCATTERED_OPTIONS),
    "... and follow (compiled)": {**LARGE_MAP_OPTIONS, "follow": FOLLOW},
    "options by map (map_options)": {"options": BY_MAP},  # `anytime plan`'s default
    "... in steps (direct_steps)": {"options": BY_MAP, "direct_steps": True},
}

#: The papers' result when run to completion, and the issue's target on 512 x 512 maps.
PAPERS = (0.93, 0.27)
TARGET = (0.95, 0.15)
#: Issue 36's targets on every map kind, against the compiled A*: final quality mean and min at
#: most this fraction of A*'s time (totals, the abstraction included); the first plan's quality
#: within this fraction; expansions at most this fraction of A*'s (and, in `bench_kinds`, the
#: random problems in at most A*'s total time, and no fall of the executed quality).
KIND_TARGET = (0.97, 0.93, 0.25)
FIRST_TARGET = (0.85, 0.02)
EXPANSIONS_TARGET = 0.25

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
    falls: int  # registered plans followed worse than the one before (executed quality)
    unknown_steps: int  # steps from plan to plan whose executions went over budget


def best_of(repeats: int, measure: Callable[[], Any], warm: int = 0) -> tuple[float, Any]:
    """The least wall time of `repeats` calls of `measure` after `warm` untimed ones, and the
    last call's value, each after a collection and with the collector off (`main` freezes what
    is alive once set up: a collection then scans what the runs made, not the 140,000 objects
    of the modules loaded, 30 ms a collection, half the run's time)."""
    best, value = math.inf, None
    for run in range(warm + repeats):
        gc.collect()
        gc.disable()
        try:
            begin = time.perf_counter()
            value = measure()
            if run >= warm:
                best = min(best, time.perf_counter() - begin)
        finally:
            gc.enable()
    return best, value


def timed(measure: Callable[[], Any]) -> tuple[float, Any]:
    return best_of(1, measure)


def stream(measures: list[Callable[[], Any]]) -> list[tuple[float, Any]]:
    """Each call's wall time and value, one after another after one collection, with the
    collector off throughout: a collection before each call walks what the calls before kept
    (their plans) and empties the caches a short run needs."""
    gc.collect()
    gc.disable()
    try:
        out = []
        for measure in measures:
            begin = time.perf_counter()
            value = measure()
            out.append((time.perf_counter() - begin, value))
        return out
    finally:
        gc.enable()


def abstraction(
    blocked: BoolGrid,
    movement: int,
    top: int | None = None,
    landmarks: int = 0,
    doors: bool = True,
    jump_points: bool = False,
    direct_whole: bool = False,
) -> tuple[Pyramid, Components]:
    """The ATP's description of a map, built once per map: the obstacleness pyramid and the
    connectivity-aware abstraction up to the first-plan level `top` (default: the planner's),
    with what `atp(doors=doors, landmarks=landmarks, jump_points=jump_points,
    direct_whole=direct_whole)` makes of it when first needed (`planner.made_ahead`: the
    level's doors, its landmarks; with jump points at level 0 or with `direct_whole`, the room
    of the search over every cell and the map's jumps)."""
    pyramid = Pyramid.build(blocked)
    level = first_level(top, pyramid)
    components = Components.build(blocked, movement, top=level)
    made_ahead(
        components,
        level,
        {
            "doors": doors,
            "landmarks": landmarks,
            "jump_points": jump_points,
            "direct_whole": direct_whole,
        },
    )
    return pyramid, components


def first_level(top: int | None, pyramid: Pyramid) -> int:
    """The level of the first plan `atp` makes with `top=top` on the pyramid's map."""
    return min(DEFAULT_TOP, pyramid.top) if top is None else top


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


def run_atp(ctx: Context, plans: Iterator[Any]) -> tuple[float, list[MultiPath]]:
    """Run the planner to completion: (seconds to the first plan, every plan registered)."""
    begin = time.perf_counter()
    registered = [next(plans).value]
    first_seconds = time.perf_counter() - begin
    for result in plans:
        registered.append(result.value)
    return first_seconds, registered


@frozen
class Baseline:
    """The A*s on one problem: the compiled one's (the reference) best time and expansions, and
    the pure-Python one's best time (the same search: the same expansions)."""

    seconds: float
    expansions: int
    python_seconds: float


@frozen
class Timed:
    """One problem's times: the compiled A*'s best and its path, the pure-Python A*'s best,
    and per configuration its best [time, first plan time] and its last run (context, plans)."""

    compiled: float
    found: Any
    python: float
    best: dict[str, list[float]]
    outcome: dict[str, tuple[Context, list[MultiPath]]]


def plan_once(
    ctx: Context,
    problem: Problem,
    pyramid: Pyramid,
    components: dict[int, Components],
    movement: int,
    options: dict[str, Any],
    follower: Follower | None,
) -> tuple[float, list[MultiPath]]:
    """The ATP with `options` on `problem`, run to completion (`components` by the level of
    its first plan; `follower`: the map's, reset first, for a `FOLLOW` configuration)."""
    if options.get("follow") == FOLLOW:
        assert follower is not None, "the map's follower is built with its abstraction"
        follower.reset()  # nothing kept from the last run: each run pays its own
        options = {**options, "follow": follower}
    plans = atp(
        ctx,
        problem.start,
        problem.goal,
        pyramid,
        movement=movement,
        components=components[first_level(options.get("top"), pyramid)],
        **options,
    )
    return run_atp(ctx, plans)


def time_stream(
    problems: list[Problem],
    astar: GridAstar,
    pyramid: Pyramid,
    components: dict[int, Components],
    movement: int,
    repeats: int,
    configs: dict[str, dict[str, Any]],
    follower: Follower | None,
) -> list[Timed]:
    """Each side's times on one map's `problems` run as a stream, one after another, as a
    planner serving queries on a map runs them (the grid-pathfinding competition's way): per
    round, the compiled A* on every problem, the pure-Python A*, then each configuration; one
    untimed round first (the pure-Python A* skips it), then `repeats`, each problem's best
    kept. So each timed run follows a run of its own side on the same map."""
    n, blocked = len(problems), problems[0].blocked
    compiled, python, found = [math.inf] * n, [math.inf] * n, [None] * n
    best = {name: [[math.inf, math.inf] for _ in problems] for name in configs}
    outcome: dict[str, list[Any]] = {name: [None] * n for name in configs}
    for round_ in range(1 + repeats):
        astars = [partial(astar.find_path, p.start, p.goal) for p in problems]
        for i, (seconds, found[i]) in enumerate(stream(astars)):
            compiled[i] = min(compiled[i], seconds) if round_ else compiled[i]
        pures = [
            partial(find_path, blocked, p.start, p.goal, movement=movement, weight=0)
            for p in problems
        ]
        for i, (seconds, pure) in enumerate(stream(pures) if round_ else []):  # slow: no warm-up
            assert pure == found[i], "the compiled A* is the pure-Python A*, step for step"
            python[i] = min(python[i], seconds)
        for name, options in configs.items():
            contexts = [Context() for _ in problems]
            plans = [
                partial(plan_once, ctx, p, pyramid, components, movement, options, follower)
                for ctx, p in zip(contexts, problems, strict=True)
            ]
            for i, (seconds, (first_seconds, registered)) in enumerate(stream(plans)):
                if round_:
                    kept = best[name][i]
                    best[name][i] = [min(kept[0], seconds), min(kept[1], first_seconds)]
                outcome[name][i] = (contexts[i], registered)
    return [
        Timed(
            compiled[i],
            found[i],
            python[i],
            {name: best[name][i] for name in configs},
            {name: outcome[name][i] for name in configs},
        )
        for i in range(n)
    ]


def judge_problem(
    problem: Problem,
    times: Timed,
    movement: int,
    budget: float = EXECUTION_BUDGET,
    every_plan: bool = False,
    executed: bool = True,
) -> tuple[Baseline, dict[str, AtpRun]]:
    """One problem's A* baseline and each configuration's run, its plans executed on the map:
    executing a plan is given up after `budget` times the pure-Python A*'s time (the budget
    the benchmark gave before the compiled A* was its reference). `every_plan`: execute every
    plan registered, to count the falls of the executed quality (else the first and the last
    only). `executed` False: no plan executed (times only; the qualities are NaN)."""
    found, python_best, best, outcome = times.found, times.python, times.best, times.outcome
    compiled_best = times.compiled
    assert found is not None, "the benchmark's problems are solvable"
    optimal = found.length if problem.optimal is None else problem.optimal
    runs = {}
    routes: dict[tuple[Any, ...], Execution | None] = {}  # the configurations' first plans agree

    def route(plan: MultiPath) -> Execution | None:
        key = tuple(waypoints(plan))
        if key not in routes:
            # a fully refined plan is followed without search: never given up (a pause of the
            # process could otherwise outlast the budget of a short problem)
            limited = (
                time_budget(budget * python_best) if plan.refinable else contextlib.nullcontext()
            )
            try:
                with limited:
                    routes[key] = execute(  # planned on the map followed: its corridor holds
                        plan, problem.blocked, movement=movement, keep_to_plan=True
                    )
            except OverBudget:
                routes[key] = None
        return routes[key]

    for name, (ctx, registered) in outcome.items():
        if not executed:
            runs[name] = AtpRun(
                seconds=best[name][0],
                first_seconds=best[name][1],
                expansions=int(ctx.ticks),
                refinements=len(registered) - 1,
                first_quality=None,
                final_quality=math.nan,
                first_execution=None,
                falls=0,
                unknown_steps=0,
            )
            continue
        first_route, final_route = route(registered[0]), route(registered[-1])
        assert final_route is not None, "the last plan is followed within the budget"
        # (with `follow` the last plan registered may not be fully refined: a later one that
        # was not followed shorter is not registered)
        assert registered[-1].refinable or final_route.expansions == 0, (
            "a fully refined plan is followed without search"
        )
        falls = unknown = 0
        if every_plan:
            lengths = [route(plan) for plan in registered]
            for before, after in zip(lengths, lengths[1:], strict=False):
                if before is None or after is None:
                    unknown += 1
                else:
                    falls += after.length > before.length * (1 + 1e-9)
        runs[name] = AtpRun(
            seconds=best[name][0],
            first_seconds=best[name][1],
            expansions=int(ctx.ticks),
            refinements=len(registered) - 1,
            first_quality=None if first_route is None else quality(first_route.length, optimal),
            final_quality=quality(final_route.length, optimal),
            first_execution=None if first_route is None else first_route.expansions,
            falls=falls,
            unknown_steps=unknown,
        )
    return Baseline(compiled_best, found.expansions, python_best), runs


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
    """A suite's measurements: the compiled A*'s best time and expansions per problem, the
    pure-Python A*'s best time, and each ATP configuration's runs in the same order."""

    astar_times: list[float]
    astar_expansions: list[int]
    python_times: list[float]
    runs: dict[str, list[AtpRun]]


def measure_suite(
    suite: Suite,
    repeats: int,
    configs: dict[str, dict[str, Any]] = CONFIGS,
    budget: float = EXECUTION_BUDGET,
    every_plan: bool = False,
    executed: bool = True,
) -> Measured:
    measured = Measured([], [], [], {name: [] for name in configs})
    maps: dict[int, list[Problem]] = {}  # the problems of each map, in order
    for problem in suite.problems:
        maps.setdefault(id(problem.blocked), []).append(problem)
    for problems in maps.values():
        blocked = problems[0].blocked
        astar = GridAstar(blocked, movement=suite.movement, weight=0.0)  # once per map
        pyramid = Pyramid.build(blocked)
        tops = {first_level(options.get("top"), pyramid) for options in configs.values()}
        built = {top: abstraction(blocked, suite.movement, top)[1] for top in tops}
        for options in configs.values():  # what each makes ahead too, like the abstraction
            level = first_level(options.get("top"), pyramid)
            made_ahead(built[level], level, options)
        follows = any(options.get("follow") == FOLLOW for options in configs.values())
        follower = Follower(blocked, suite.movement) if follows else None
        streamed = time_stream(
            problems, astar, pyramid, built, suite.movement, repeats, configs, follower
        )
        for problem, times in zip(problems, streamed, strict=True):
            baseline, runs = judge_problem(
                problem, times, suite.movement, budget, every_plan, executed
            )
            measured.astar_times.append(baseline.seconds)
            measured.astar_expansions.append(baseline.expansions)
            measured.python_times.append(baseline.python_seconds)
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
        python = statistics.fmean(
            p / a for p, a in zip(measured.python_times, measured.astar_times, strict=True)
        )
        rows.append(
            [
                suite.name,
                "pure-Python A*",
                str(len(measured.python_times)),
                *["1.000"] * 3,
                f"{python:.1%}",
                f"{sum(measured.python_times) / sum(measured.astar_times):.1%}",
                "-",
                "100.0%",  # the same search: the same expansions
                *["-"] * 4,
            ]
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
        "(A*: the compiled A* (search.GridAstar, numba), the same search as the pure-Python A*\n"
        " (search.find_path: the same paths and expansions; its row: its time / the compiled\n"
        " A*'s); each A*'s grid is built once per map, outside its time;\n"
        " q: plan quality = optimal length / executed length, per problem, then the mean or the\n"
        " minimum; time / A* (mean): the mean over problems of ATP time / A* time, each the best\n"
        f" of {repeats} rounds of the map's problems after an untimed one; (totals): total ATP\n"
        " time / total A* time; first plan time: to the first yield; expansions / A*: total\n"
        " ATP expansions (of all its searches) / total A* expansions; refinements: mean per\n"
        " problem;\n"
        " abstraction / A*: building the pyramid and the components, once per map, / total A*\n"
        " time on the map's problems (not in the ATP time);\n"
        " first plan exec. exp.: the obstacle-avoidance expansions executing the first plan on\n"
        " the true map takes, / total A* expansions (the final plan is followed with none);\n"
        f" an execution is given up after {EXECUTION_BUDGET}x the pure-Python A*'s time: 'k over'"
        " = first plans\n"
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
    astar = GridAstar(blocked, movement=8, weight=0.0)
    ours, theirs, resets = [], [], []
    ours_optimal = theirs_optimal = 0
    for scenario in chosen:
        (sx, sy), (gx, gy) = scenario.start, scenario.goal
        best_ours = best_theirs = math.inf
        for _ in range(repeats):
            seconds, found = timed(partial(astar.find_path, scenario.start, scenario.goal))
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
        return f"the compiled A* against pathfinding's: skipped, {NO_PATHFINDING}"
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
        f"(ours: the compiled A*; query time, each the best of {repeats} runs; ours excludes\n"
        " building its padded grid (once per map), theirs excludes building the grid (once per\n"
        " map) and resetting it before each query, both shown as multiples of our mean query\n"
        " time; optimal: the length equals the .scen optimal to 1e-8)"
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
    astar = GridAstar(blocked, movement=8, weight=0.0)
    ours = theirs = 0.0
    optimal = 0
    for scenario in chosen:
        best_ours, best_theirs = math.inf, math.inf
        for _ in range(repeats):
            seconds, _ = timed(partial(astar.find_path, scenario.start, scenario.goal))
            best_ours = min(best_ours, seconds)
            seconds, route = timed(partial(query, scenario.start, scenario.goal))
            best_theirs = min(best_theirs, seconds)
        ours += best_ours
        theirs += best_theirs
        optimal += math.isclose(route_length(route), scenario.optimal, rel_tol=1e-4)
    return theirs / ours, optimal


# --- 3. per map kind ---------------------------------------------------------------------------


def random_problems(scenarios: list[Scenario], count: int) -> list[Scenario]:
    """`count` problems of the file drawn at random (seeded: the same every run), mostly short:
    where a planner's fixed costs show."""
    rng = np.random.default_rng(36)
    chosen = rng.choice(len(scenarios), size=min(count, len(scenarios)), replace=False)
    return [scenarios[i] for i in sorted(chosen.tolist())]


def for_map(configs: dict[str, dict[str, Any]], blocked: BoolGrid) -> dict[str, dict[str, Any]]:
    """`configs` on the map `blocked`: a `BY_MAP` configuration made `planner.map_options`'
    (with its other options on top)."""
    return {
        name: {**map_options(blocked), **{k: v for k, v in options.items() if k != "options"}}
        if options.get("options") == BY_MAP
        else options
        for name, options in configs.items()
    }


def shown(name: str, options: dict[str, Any], blocked: BoolGrid) -> str:
    """A configuration's name in a table; a `BY_MAP` one's says which options the map chose."""
    if options.get("options") != BY_MAP:
        return name
    chosen = map_options(blocked)
    kinds = (
        (SCATTERED_MAP_OPTIONS, "scattered"),
        (SPARSE_MAP_OPTIONS, "sparse"),
        (WALLED_MAP_OPTIONS, "walled"),
        (LARGE_MAP_OPTIONS, "large"),
        (SMALL_MAP_OPTIONS, "small"),
        (SMALL_WALLED_MAP_OPTIONS, "small walled"),
    )
    which = next(kind for named, kind in kinds if named is chosen)
    return f"{name}: {which}-map options"


def bench_kinds(
    count: int,
    repeats: int,
    budget: float,
    kinds: tuple[tuple[str, Path], ...] = KINDS,
    configs: dict[str, dict[str, Any]] = KIND_CONFIGS,
) -> str:
    """The ATP's `configs` (the default first) against the compiled A* on the `count` longest
    problems of each map of `KINDS` (every plan registered executed, to count the falls of the
    anytime curve) and on `count` random ones, with the pure-Python A* and the peers' A*s per
    query where they are installed (in the default's row); executing a plan is given up after
    `budget` times the pure-Python A*'s time."""
    peer = pathfinding_finder()
    quality_mean, quality_min, time_target = KIND_TARGET
    first_quality, first_time = FIRST_TARGET
    rows = []
    for kind, path in kinds:
        blocked, width, height, scenarios = load_problems(path)
        chosen = for_map(configs, blocked)
        suite = movingai_suite(path, count, repeats)
        measured = measure_suite(suite, repeats, chosen, budget, every_plan=True)
        astar_total = sum(measured.astar_times)
        short = Suite(
            suite.name,
            8,
            [Problem(blocked, s.start, s.goal, None) for s in random_problems(scenarios, count)],
            True,
            0.0,
        )
        shorts = measure_suite(short, repeats, chosen, budget, executed=False)  # times only
        python = sum(measured.python_times) / astar_total
        peer_ratio = "-"
        if peer is not None:
            run = race_pathfinding(peer, blocked, width, height, longest(scenarios, count), 1)
            peer_ratio = f"{sum(run.theirs) / sum(run.ours):.2f}"
        others = []
        for make, problems in ((networkx_query, NETWORKX_PROBLEMS), (tcod_query, count)):
            raced = race_peer(make, blocked, longest(scenarios, problems), 1)
            others.append("-" if raced is None else f"{raced[0]:.2f} ({raced[1]}/{problems})")
        pyramid = Pyramid.build(blocked)
        builds: dict[tuple[int, int, bool, bool, bool], float] = {}
        for index, (name, options) in enumerate(chosen.items()):
            top = first_level(options.get("top"), pyramid)
            key = (
                top,
                options.get("landmarks") or 0,
                options.get("doors", True),
                bool(options.get("jump_points")),
                bool(options.get("direct_whole")),
            )
            if key not in builds:  # the abstraction up to the first plan's level, once per map
                builds[key] = best_of(repeats, partial(abstraction, blocked, 8, *key), warm=1)[0]
            build = builds[key]
            if configs[name].get("options") == BY_MAP:  # and reading the map's shape
                build += best_of(repeats, partial(map_options, blocked), warm=1)[0]
            if options.get("follow") == FOLLOW:  # and the follower's, once per map
                build += best_of(repeats, partial(Follower, blocked, 8), warm=1)[0]
            runs = measured.runs[name]
            summary = summarise(measured.astar_times, measured.astar_expansions, runs)
            with_abstraction = (sum(r.seconds for r in runs) + build) / astar_total
            random_ratio = sum(r.seconds for r in shorts.runs[name]) / sum(shorts.astar_times)
            falls = sum(r.falls for r in runs)
            steps = sum(r.refinements for r in runs)
            unknown = sum(r.unknown_steps for r in runs)
            fell = f"{falls}/{steps}" + (f" ({unknown} over)" if unknown else "")
            met = (
                summary.final_mean >= quality_mean
                and summary.final_min >= quality_min
                and with_abstraction <= time_target
                and summary.first_mean is not None
                and summary.first_mean >= first_quality
                and summary.first_time <= first_time
                and summary.expansions <= EXPANSIONS_TARGET
                and random_ratio <= 1.0
                and falls == 0
            )
            rows.append(
                [
                    path.stem if index == 0 else "",
                    kind if index == 0 else "",
                    shown(name, configs[name], blocked),
                    str(len(runs)),
                    summary.first_quality,
                    f"{summary.first_time:.1%}",
                    f"{summary.final_mean:.3f} ({summary.final_min:.3f})",
                    f"{summary.time_mean:.1%}",
                    f"{summary.time_totals:.1%}",
                    f"{with_abstraction:.1%}",
                    f"{summary.expansions:.1%}",
                    fell,
                    f"{random_ratio:.1%}",
                    *([f"{python:.2f}", peer_ratio, *others] if index == 0 else [""] * 4),
                    "yes" if met else "NO",
                ]
            )
    header = [
        "map",
        "kind",
        "ATP",
        "problems",
        "first q",
        "first plan time / A*",
        "final q mean (min)",
        "time / A* (mean)",
        "time / A* (totals)",
        "with abstraction / A* (totals)",
        "expansions / A*",
        "falls",
        f"{count} random: time / A* (totals)",
        "pure-Python A* / A*",
        "pathfinding / A*",
        "networkx / A* (optimal)",
        "tcod / A* (optimal)",
        "issue 36 target",
    ]
    peers = (
        "networkx / A*, tcod / A*: likewise (networkx's astar_path on the map's graph,\n"
        f" octile heuristic, on the first {NETWORKX_PROBLEMS} problems; tcod's AStar, in C, which\n"
        " cuts corners: its routes can be shorter than the optimum), with how many of their\n"
        " routes are optimal; their graphs and grids are built once per map, outside the query\n"
        " time ('-': not installed)"
    )
    if peer is None:
        peers = f"pathfinding: '-', {NO_PATHFINDING};\n {peers}"
    note = (
        f"(A*: the compiled A*; ATP: the default (the first plan one segment {DEFAULT_TOP} levels\n"
        " up, searched again through the doors) and, below it, atp's options\n"
        " (issue 36 item 2), each measured in the same run: door_rings=R: the door search keeps\n"
        " to the first plan's nodes and those R edges from them; top=L: the first plan L levels\n"
        " up, the abstraction built up to L; direct=D: a first plan of at most D nodes is\n"
        " followed by one base search through its cells and its neighbours' instead of the\n"
        " refinements; direct_width=W: likewise after the first plan when those cells are at\n"
        " most W per unit of its length (a narrow corridor); no_ring_when_open=T (with the\n"
        " row above's options): a level-1 segment of mean obstacleness at most T is refined\n"
        " through its own nodes' cells, without a ring of neighbours; one_ring_when_open=T\n"
        " (with the row above's options): a level-2 segment of mean obstacleness at most T is\n"
        " refined with one ring of neighbouring nodes, not three; landmarks=N (with the row\n"
        " above's options): the first plan's search\n"
        " bounded by N landmarks' distances (ALT; made with the abstraction, in its build);\n"
        " no_ring_when_clear=S (with the row above's options): a level-2 segment at least S\n"
        " of whose nodes are clear 4 x 4 blocks is refined through its own nodes' children,\n"
        " without rings;\n"
        " jump_points (with the row above's options: planner.LARGE_MAP_OPTIONS, anytime plan's):\n"
        " the searches over the base cells from one source are jump point searches (the same\n"
        " costs; expansions: the jump points expanded);\n"
        " skip_level_1 (with the row above's options): a level-2 segment is refined straight to\n"
        " the base cells, through its own nodes' cells;\n"
        " doors=False (with the row above's options: anytime plan's on maps of solid\n"
        " obstacles until issue 36): the first plan is not searched again through the doors\n"
        " (nor are they built);\n"
        " walled-map options (planner.WALLED_MAP_OPTIONS, anytime plan's on maps of walls):\n"
        " the first plan over blocks of 8 x 8, then the direct route through its nodes' and\n"
        " their neighbours' cells, no refinement level by level (anytime plan's also on maps\n"
        " of scattered obstacles of moderate density);\n"
        " ... searched cell by cell: the same without jump points (the options of maps of\n"
        " scattered obstacles until jump points read a byte a cell);\n"
        " small-walled-map options (planner.SMALL_WALLED_MAP_OPTIONS, anytime plan's on maps of\n"
        " walls of fewer than 50,000 free cells): the walled-map options with the direct route\n"
        " over the whole map (direct_whole), one jump point search of every cell, its straight\n"
        " jumps read off the map's table (made with the build);\n"
        " sparse-map options (planner.SPARSE_MAP_OPTIONS, anytime plan's on maps of sparse\n"
        " scattered obstacles): the walled-map options with the neighbours among the blocks\n"
        " of 4 x 4 (direct_ring_level=2), not of 8 x 8;\n"
        " scattered-map options (planner.SCATTERED_MAP_OPTIONS, anytime plan's on maps of\n"
        " scattered, dense obstacles): the walled-map options with the corridor through a\n"
        " second plan over blocks of 4 x 4 and two rings of its neighbours, and the first\n"
        " plan's cells with one ring;\n"
        " ... refined (anytime plan's on those maps until issue 36's direct route): the\n"
        " large-map options with top=3, direct_width=8, no jump points;\n"
        " follow (with the jump_points row's\n"
        " options): a plan is registered only when the robot follows it no longer than the\n"
        " last one registered (following.Follower: execute's length, compiled; its calls in the\n"
        " ATP's time, its build, once per map, with the abstraction's); options by map: the\n"
        " options planner.map_options chooses by the map's size and shape (anytime plan's),\n"
        " and ... in steps: the same with direct_steps (the direct route registered through the\n"
        " first plan's cells and a ring of neighbours at level 1, 2, .. up to its own); the\n"
        f" {count} problems of the longest buckets per map, octile without\n"
        " corner cutting, optimal lengths from A*; each side runs the map's problems as a\n"
        f" stream, an untimed round and {repeats} timed, each problem's best kept; columns as in\n"
        " the first table,\n"
        f" but an execution is given up after {budget:g}x the pure-Python A*'s time;\n"
        " with abstraction: (total ATP time + building its abstraction once) / total A* time;\n"
        " falls: steps from a registered plan to the next whose executed quality falls / all\n"
        " such steps ('k over': steps not judged, an execution over budget);\n"
        f" {count} random: total ATP time / total A* time on {count} problems drawn at random\n"
        " from the file (seeded), mostly short;\n"
        " pure-Python A* / A* and the peers (in the default's row): its total time / the compiled\n"
        " A*'s on the longest problems\n"
        " (the same search: the same paths and expansions);\n"
        " pathfinding / A*: its total query time / the compiled A*'s on the same problems, as in\n"
        f" the second table;\n {peers};\n"
        " the peers here one run of each problem, side by side with one of the compiled A*'s\n"
        " (they take 4 to 300 times its time: a best of 3 would add minutes a map, not a digit);\n"
        f" issue 36 target: final q mean >= {quality_mean} and min >= {quality_min} with\n"
        f" abstraction <= {time_target:.0%} (stretch: 12%), first q >= {first_quality} at first"
        f" plan time <= {first_time:.0%},\n expansions <= {EXPANSIONS_TARGET:.0%}, the random"
        " problems at most A*'s total time, no falls)"
    )
    return table(header, rows) + "\n" + note


def check_scenarios(paths: list[Path], per_map: int | None) -> str:
    """The compiled A*'s lengths against the `.scen` optimal lengths of the benchmark's maps:
    every problem of each file (`per_map` None), or `per_map` of them spread evenly over it
    (so over every bucket)."""
    rows = []
    for path in paths:
        blocked, _, _, scenarios = load_problems(path)
        chosen = scenarios if per_map is None else scenarios[:: max(1, len(scenarios) // per_map)]
        astar = GridAstar(blocked, movement=8, weight=0.0)
        optimal = 0
        for scenario in chosen:
            found = astar.find_path(scenario.start, scenario.goal)
            # to the file's precision: 5 or 6 significant digits in the old-style files, 2
            # decimals in AR0011SR's
            optimal += found is not None and math.isclose(
                found.length, scenario.optimal, rel_tol=1e-5, abs_tol=0.005
            )
        rows.append([path.stem, f"{len(scenarios)}", f"{len(chosen)}", f"{optimal}/{len(chosen)}"])
    which = "every problem" if per_map is None else f"about {per_map} problems spread evenly"
    note = (
        f"(the compiled A* on {which} of each map's .scen file: optimal = its length is the\n"
        " file's optimal length to the file's precision: 1e-5 relative, 0.005 absolute)"
    )
    return table(["map", "problems in the file", "checked", "optimal"], rows) + "\n" + note


def compiled_searches() -> str:
    """Load the planner's compiled searches (`corridor_search`, numba), or compile them, before
    anything is timed: a cost paid once per process, said here and left out of the tables."""
    seconds, _ = timed(compile_searches)
    return (
        f"(the planner's, the follower's and the A*'s compiled searches loaded in {seconds:.2f} s,"
        " once per process: not in the times below)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer problems: about 25 minutes")
    parser.add_argument(
        "--repeats",
        type=int,
        help="runs per problem and side, the best kept (3; quick: 2, its per-kind table 3)",
    )
    parser.add_argument(
        "--maps",
        nargs="+",
        type=Path,
        metavar="MAP",
        help="only the per-kind table, on these MovingAI .map files (each with its .scen beside)",
    )
    parser.add_argument(
        "--configs",
        nargs="+",
        choices=list(KIND_CONFIGS),
        metavar="NAME",
        help="with --maps: only these rows of the per-kind table (default: all of "
        f"{', '.join(repr(name) for name in KIND_CONFIGS)})",
    )
    args = parser.parse_args()
    if args.configs and not args.maps:
        parser.error("--configs goes with --maps")
    began = time.perf_counter()
    print(compiled_searches())
    gc.collect()
    gc.freeze()  # the modules loaded: no collection before a timed run scans them again
    if args.maps:  # maps of the user's: the per-kind table alone, on those that load
        given = []
        for path in args.maps:
            try:
                load_problems(path)
            except (OSError, MapError) as error:
                print(f"{path}: left out, {error}")
            else:
                given.append(("given", path))
        configs = {name: KIND_CONFIGS[name] for name in args.configs or KIND_CONFIGS}
        print(bench_kinds(16, args.repeats or 3, 2, tuple(given), configs))
        print()
        print(check_scenarios([path for _, path in given], 200 if args.quick else None))
        print(f"\n(the whole run took {time.perf_counter() - began:.0f} s)")
        return
    small, large, count, per_kind = (5, 2, 2, 16) if args.quick else (20, 10, 12, 16)
    repeats = args.repeats if args.repeats is not None else 2 if args.quick else 3
    # the per-kind table: the best of 3 (--quick too: its targets are within a few points of A*'s
    # time); --quick: its first plans' executions given up sooner
    kind_repeats = args.repeats if args.repeats is not None else 3
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
    # The compiled A* is the reference: its lengths against the .scen optima of every map used
    # (every problem in a full run; --quick: a spread sample, the files hold 100,000 problems).
    print(check_scenarios([path for _, path in KINDS], 200 if args.quick else None))
    print()
    print(f"(the whole run took {time.perf_counter() - began:.0f} s)")


if __name__ == "__main__":
    main()
