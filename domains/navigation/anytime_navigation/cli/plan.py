"""`anytime plan`: solve path-finding problems on a MovingAI map with A* or the ATP.

The way MovingAI path-finding results are reported: a map, the first N problems of its scenario
file (or one start and goal), and per problem the length found against the optimal one, the node
expansions and the time. For the ATP the quality is the papers' plan quality, optimal length /
executed length (`execution.execute` follows the plan on the map), after its first plan and when
run to completion. A* is the compiled one (`search.GridAstar`), the baseline of the benchmarks.

Times are honest per problem: what a process pays once (loading the compiled searches from
numba's cache, or compiling them) and what is paid once per map (the ATP's abstraction, A*'s
padded grid) are reported as their own fields, `load_seconds` and `build_seconds`, and are in no
problem's `seconds`.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from attrs import frozen

from anytime.plugin import Context
from anytime.plugin.cli import (
    EXIT_OK,
    CommandGroup,
    InputError,
    ProgressBar,
    format_table,
    json_text,
    positive_int,
)

from ..movingai import MapError, load_map, load_scenarios
from ..planning.abstraction import Pyramid
from ..planning.components import Components
from ..planning.planner import (
    DEFAULT_TOP,
    LARGE_MAP_OPTIONS,
    SCATTERED_MAP_OPTIONS,
    SMALL_MAP_FREE_CELLS,
    SMALL_MAP_OPTIONS,
    SMALL_WALLED_MAP_FREE_CELLS,
    SMALL_WALLED_MAP_OPTIONS,
    SPARSE_MAP_OPTIONS,
    WALLED_MAP_OPTIONS,
    atp,
    compile_searches,
    made_ahead,
    map_options,
    registers_no_fall,
)
from ..planning.search import GridAstar
from ..task.execution import execute, plan_quality
from ..world import BoolGrid, Position, reachable

if TYPE_CHECKING:
    from ..planning.following import Follower  # compiled code: imported when a map is followed

__all__ = ["Problem", "Solution", "add_command", "run_plan"]

_T = TypeVar("_T")

#: `--atp-options`: the keyword arguments of `atp` (and of its abstraction's build) by name;
#: `BY_MAP`, the default, is one of them chosen by the map's shape (`planner.map_options`).
ATP_OPTIONS: dict[str, Mapping[str, Any]] = {
    "large-maps": LARGE_MAP_OPTIONS,
    "scattered-maps": SCATTERED_MAP_OPTIONS,
    "small-maps": SMALL_MAP_OPTIONS,
    "small-walled-maps": SMALL_WALLED_MAP_OPTIONS,
    "sparse-maps": SPARSE_MAP_OPTIONS,
    "walled-maps": WALLED_MAP_OPTIONS,
    "task": {},
}
BY_MAP = "by-map"


def _listed(options: Mapping[str, Any]) -> str:
    """Options as `--help` shows them, name=value (an option on by itself: its name)."""
    return ", ".join(
        name if value is True else f"{name}={value}" for name, value in options.items()
    )


def _changed(options: Mapping[str, Any]) -> str:
    """What `options` change of `LARGE_MAP_OPTIONS`, as `_listed` shows them."""
    return _listed({k: v for k, v in options.items() if LARGE_MAP_OPTIONS.get(k, None) != v})


#: Lengths this close (relative) to a `.scen` optimal count as optimal: old-style files such as
#: `arena.map.scen` print the optimal lengths to 6 significant digits (11.8284 for 11.828427).
_SCEN_PRECISION = 1e-5


@frozen
class Problem:
    """One problem to solve; `optimal` is the `.scen` optimal length when it applies, `where`
    names the problem in messages."""

    start: Position
    goal: Position
    optimal: float | None
    where: str


@frozen
class Solution:
    """What `anytime plan` reports for one problem (the keys of its JSON output)."""

    start: Position
    goal: Position
    length: float
    optimal: float
    expansions: int
    seconds: float
    first_quality: float
    final_quality: float


def add_command(commands: CommandGroup) -> None:
    parser = commands.add_command(
        "plan",
        run=run_plan,
        help="solve path-finding problems on a MovingAI map with A* or the anytime planner",
        description="Solve the first N problems of a MovingAI scenario file (by default "
        "MAP.scen next to the map), or one --start/--goal problem, and print per problem the "
        "length found, the optimal length (the .scen's with 8-connected movement, else A*'s), "
        "node expansions (for the ATP those of all its searches), the wall time of planning "
        "(not of loading the map, loading the compiled searches or building the planner's "
        "description of the map: those are reported once, apart), and the plan "
        "quality (optimal length / length of the route executed on the map) after the first "
        "plan and at completion; the ATP is run to completion. Positions are X,Y = column,row "
        "from the upper-left corner, as in .scen files.",
    )
    parser.add_argument("--map", required=True, metavar="FILE.map", help="a MovingAI .map file")
    parser.add_argument(
        "--scen", metavar="FILE.scen", help="the scenario file (default: FILE.map.scen)"
    )
    parser.add_argument("--start", type=position, metavar="X,Y", help="one problem's start")
    parser.add_argument("--goal", type=position, metavar="X,Y", help="one problem's goal")
    parser.add_argument(
        "--planner",
        choices=["astar", "atp"],
        default="astar",
        help="A* (compiled: the optimal baseline) or the anytime abstract planner (astar)",
    )
    parser.add_argument(
        "--atp-options",
        choices=[BY_MAP, *sorted(ATP_OPTIONS)],
        default=BY_MAP,
        help="the ATP's options: the first plan over blocks of 8 x 8 followed by the shortest "
        "route through its blocks and their neighbours', no refinement level by level "
        f"({_changed(WALLED_MAP_OPTIONS)}), for maps of walls such as rooms, mazes, streets "
        "and caves, and maps of scattered obstacles of moderate density (walled-maps); the "
        "same with the shortest route over the whole map instead, by one jump point search "
        f"of every cell (direct_whole=True), for maps of walls of fewer than "
        f"{SMALL_WALLED_MAP_FREE_CELLS:,} free cells (small-walled-maps); the walled-maps "
        f"options with the neighbours among the blocks of 4 x 4 ({_changed(SPARSE_MAP_OPTIONS)}) "
        "for sparse scattered obstacles (sparse-maps), and through a second plan over blocks "
        f"of 4 x 4 and its neighbours ({_changed(SCATTERED_MAP_OPTIONS)}) for dense ones "
        "(scattered-maps); the options that measured best on MovingAI maps before those "
        f"({_listed(LARGE_MAP_OPTIONS)}), refined level by level, for mazes of narrow "
        "corridors (large-maps); on maps of fewer than "
        f"{SMALL_MAP_FREE_CELLS:,} free cells, where A* answers in about 2 ms or less, one "
        "jump point search of every cell, the optimal route at once "
        f"({_listed(SMALL_MAP_OPTIONS)}) (small-maps); one of those six chosen by the map's "
        "size and shape (by-map), or the planner's defaults, as the navigation task plans its "
        "128 x 128 worlds (task) (by-map)",
    )
    parser.add_argument(
        "--monotone",
        action="store_true",
        help="register a plan of the ATP only when the robot follows it on the map no longer "
        "than the last one registered, so the executed quality never falls (each plan "
        "followed as the quality is measured, compiled; the plans of every option set but "
        "large-maps and task never fall, and are not followed)",
    )
    parser.add_argument(
        "--movement",
        type=int,
        choices=[4, 8],
        default=8,
        help="4- or 8-connected (octile, no corner cutting: the model of the .scen optimal "
        "lengths) (8)",
    )
    parser.add_argument(
        "--limit",
        type=positive_int,
        default=10,
        metavar="N",
        help="solve the first N problems of the scenario file (10)",
    )
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def position(text: str) -> Position:
    """An X,Y option (column, row from the upper-left corner, as in .scen files)."""
    try:
        x, y = (int(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected X,Y (two whole numbers), got {text!r}"
        ) from None
    if x < 0 or y < 0:
        raise argparse.ArgumentTypeError(f"expected X,Y with X, Y >= 0, got {text!r}")
    return (x, y)


def run_plan(args: argparse.Namespace) -> int:
    if (args.start is None) != (args.goal is None):
        args.usage_error("--start and --goal go together")
    if args.start is not None and args.scen is not None:
        args.usage_error("give either --scen or --start/--goal, not both")
    try:
        blocked, width, height = load_map(args.map)
        problems = _problems(args, blocked, width, height)
    except MapError as error:
        raise InputError(error.message, where=f"{error.filename}:{error.line}") from None
    # Paid once, timed apart: loading the compiled searches (once per process), then the
    # planner's description of the map (once per map).
    monotone = args.planner == "atp" and args.monotone
    load_seconds, _ = _timed(lambda: compile_searches((args.movement,), follower=monotone))
    astar: GridAstar | None = None
    described: Described | None = None
    chosen: str | None = None
    if args.planner == "atp":

        def describe() -> Described:
            nonlocal chosen
            chosen = _chosen_options(args.atp_options, blocked)  # the map's shape: read once
            return _described(blocked, args.movement, ATP_OPTIONS[chosen], monotone)

        build_seconds, described = _timed(describe)
    else:
        build_seconds, astar = _timed(lambda: _astar(blocked, args.movement))
    reference = "scen" if problems[0].optimal is not None else "astar"
    if astar is None and reference == "astar":  # the optimal lengths: not the planner's cost
        astar = _astar(blocked, args.movement)
    solutions = []
    enabled = False if args.quiet or len(problems) == 1 else None  # on a terminal's stderr
    with ProgressBar(len(problems), label="plan", unit="problems", enabled=enabled) as bar:
        for problem in problems:
            solutions.append(_solve(problem, astar, blocked, described, args.movement))
            bar.update()
    summary = _summary(solutions, args.planner, args.movement, reference)
    summary["atp_options"] = chosen
    summary["atp_options_by_map"] = args.atp_options == BY_MAP if chosen is not None else None
    summary["monotone"] = None if described is None else _never_falls(described)
    summary["load_seconds"] = load_seconds
    summary["build_seconds"] = build_seconds
    if args.json:
        rows = [_solution_json(solution) for solution in solutions]
        print(json_text({"problems": rows, "summary": summary}))
    else:
        print(_format(solutions, summary), end="")
    return EXIT_OK


def _problems(
    args: argparse.Namespace, blocked: BoolGrid, width: int, height: int
) -> list[Problem]:
    """The problems the options name, each checked: free cells inside the map, goal reachable."""
    if args.start is not None:
        problems = [Problem(args.start, args.goal, None, "")]
        for name, (x, y) in (("--start", args.start), ("--goal", args.goal)):
            if not (0 <= x < width and 0 <= y < height):
                raise InputError(f"{name} {x},{y} is outside the {width}x{height} map '{args.map}'")
            if blocked[y, x]:
                raise InputError(f"{name} {x},{y} is a blocked cell of '{args.map}'")
    else:
        scen = args.scen
        if scen is None:
            scen = os.fspath(args.map) + ".scen"
            if not Path(scen).is_file():
                raise InputError(
                    f"no scenario file '{scen}' next to the map: give --scen "
                    "FILE.scen, or --start X,Y --goal X,Y"
                )
        scenarios = load_scenarios(scen, blocked)[: args.limit]
        if not scenarios:
            raise InputError(f"{scen}: no problems in the scenario file")
        problems = []
        for number, scenario in enumerate(scenarios, 1):
            where = f"{scen}: problem {number}: "
            if (scenario.width, scenario.height) != (width, height):
                raise InputError(
                    f"{where}it is for a {scenario.width}x{scenario.height} map,"
                    f" '{args.map}' is {width}x{height}"
                )
            optimal = scenario.optimal if args.movement == 8 else None
            problems.append(Problem(scenario.start, scenario.goal, optimal, where))
    for problem in problems:
        (sx, sy), (gx, gy) = problem.start, problem.goal
        if not reachable(blocked, problem.start, args.movement)[gy, gx]:
            raise InputError(
                f"{problem.where}the goal {gx},{gy} cannot be reached from the"
                f" start {sx},{sy} on '{args.map}'"
            )
    return problems


def _timed(make: Callable[[], _T]) -> tuple[float, _T]:
    begin = time.perf_counter()
    made = make()
    return time.perf_counter() - begin, made


def _astar(blocked: BoolGrid, movement: int) -> GridAstar:
    return GridAstar(blocked, movement=movement, weight=0.0)


@frozen
class Described:
    """The ATP's description of a map, built once for all its problems, its options, and the
    map's follower when the planner registers only plans followed no longer than the last."""

    pyramid: Pyramid
    components: Components
    options: Mapping[str, Any]
    follower: Follower | None


def _chosen_options(name: str, blocked: BoolGrid) -> str:
    """The name of the options `--atp-options NAME` plans `blocked` with."""
    if name != BY_MAP:
        return name
    options = map_options(blocked)
    return next(key for key, value in ATP_OPTIONS.items() if value is options)


def _described(
    blocked: BoolGrid, movement: int, options: Mapping[str, Any], monotone: bool
) -> Described:
    pyramid = Pyramid.build(blocked)
    # A map smaller than the options' first level plans from its pyramid's top.
    top = min(options.get("top", DEFAULT_TOP), pyramid.top)
    components = Components.build(blocked, movement, top=top)
    made_ahead(components, top, options)  # with the abstraction, once per map
    follower = None
    if monotone:
        from ..planning.following import Follower

        follower = Follower(blocked, movement)
    return Described(pyramid, components, {**options, "top": top}, follower)


def _never_falls(described: Described) -> bool:
    """Whether no registered plan is followed longer than the one before: each is followed
    (`--monotone`), or the options register none that could be (`registers_no_fall`)."""
    return described.follower is not None or registers_no_fall(described.options)


def _solve(
    problem: Problem,
    astar: GridAstar | None,
    blocked: BoolGrid,
    described: Described | None,
    movement: int,
) -> Solution:
    """Plan, timing the planner alone; execute the ATP's first and final plans for quality.
    `astar` is the planner when `described` is None, else the reference of the optimal
    lengths where the problems have none (None: they have)."""
    if described is None:
        assert astar is not None
        begin = time.perf_counter()
        found = astar.find_path(problem.start, problem.goal)
        seconds = time.perf_counter() - begin
        assert found is not None  # reachability was checked
        optimal = found.length if problem.optimal is None else problem.optimal
        quality = _quality(found.length, optimal)
        return Solution(
            problem.start,
            problem.goal,
            found.length,
            optimal,
            found.expansions,
            seconds,
            quality,
            quality,
        )
    ctx = Context()
    if described.follower is not None:
        described.follower.reset()  # nothing of the last problem's routes
    begin = time.perf_counter()
    plans = atp(
        ctx,
        problem.start,
        problem.goal,
        described.pyramid,
        movement=movement,
        components=described.components,
        follow=described.follower,
        **described.options,
    )
    first = last = next(plans).value
    for result in plans:
        last = result.value
    seconds = time.perf_counter() - begin
    if problem.optimal is not None:
        optimal = problem.optimal
    else:
        assert astar is not None
        reference = astar.find_path(problem.start, problem.goal)
        assert reference is not None  # reachability was checked
        optimal = reference.length
    # The map planned on is the map followed: the robot keeps to the plan's corridor.
    final = execute(last, blocked, movement=movement, keep_to_plan=True)
    return Solution(
        problem.start,
        problem.goal,
        final.length,
        optimal,
        int(ctx.ticks),
        seconds,
        _quality(execute(first, blocked, movement=movement, keep_to_plan=True).length, optimal),
        _quality(final.length, optimal),
    )


def _quality(length: float, optimal: float) -> float:
    """Plan quality, optimal / length; a length equal to a `.scen` optimal to the file's
    precision is optimal."""
    if math.isclose(length, optimal, rel_tol=_SCEN_PRECISION):
        return 1.0
    return plan_quality(length, optimal)


def _length_ratio(solution: Solution) -> float:
    if math.isclose(solution.length, solution.optimal, rel_tol=_SCEN_PRECISION):
        return 1.0
    return solution.length / solution.optimal


def _summary(
    solutions: list[Solution], planner: str, movement: int, reference: str
) -> dict[str, Any]:
    n = len(solutions)
    return {
        "planner": planner,
        "movement": movement,
        "optimal_from": reference,
        "problem_count": n,
        "mean_length_ratio": sum(_length_ratio(s) for s in solutions) / n,
        "expansions": sum(s.expansions for s in solutions),
        "seconds": sum(s.seconds for s in solutions),
        "mean_first_quality": sum(s.first_quality for s in solutions) / n,
        "mean_final_quality": sum(s.final_quality for s in solutions) / n,
    }


def _solution_json(solution: Solution) -> dict[str, Any]:
    return {
        "start": list(solution.start),
        "goal": list(solution.goal),
        "route_length": solution.length,
        "optimal_length": solution.optimal,
        "expansions": solution.expansions,
        "seconds": solution.seconds,
        "first_quality": solution.first_quality,
        "final_quality": solution.final_quality,
    }


def _format(solutions: list[Solution], summary: dict[str, Any]) -> str:
    rows = [
        ["#", "START", "GOAL", "LENGTH", "OPTIMAL", "EXPANSIONS", "SECONDS", "FIRST Q", "FINAL Q"]
    ]
    for number, s in enumerate(solutions, 1):
        rows.append(
            [
                str(number),
                f"{s.start[0]},{s.start[1]}",
                f"{s.goal[0]},{s.goal[1]}",
                f"{s.length:.4f}",
                f"{s.optimal:.4f}",
                str(s.expansions),
                f"{s.seconds:.4f}",
                f"{s.first_quality:.4f}",
                f"{s.final_quality:.4f}",
            ]
        )
    source = "the .scen file" if summary["optimal_from"] == "scen" else "A*"
    what = "abstraction" if summary["planner"] == "atp" else "padded grid"
    count = summary["problem_count"]
    problems = "problem" if count == 1 else "problems"
    planner = summary["planner"]
    if summary["atp_options"] is not None:
        how = ", chosen by the map" if summary["atp_options_by_map"] else ""
        monotone = ", monotone" if summary["monotone"] else ""
        planner += f" ({summary['atp_options']} options{how}{monotone})"
    line = (
        f"{count} {problems}, {planner}, {summary['movement']}-connected"
        f" (optimal lengths from {source}): mean length / optimal"
        f" {summary['mean_length_ratio']:.4f}, {summary['expansions']} expansions,"
        f" {summary['seconds']:.3f} s planning, mean quality first"
        f" {summary['mean_first_quality']:.4f} final {summary['mean_final_quality']:.4f}\n"
        f"once: {summary['load_seconds']:.3f} s loading the compiled searches,"
        f" {summary['build_seconds']:.3f} s building the {what} (not in the times above)\n"
    )
    return format_table(rows) + line
