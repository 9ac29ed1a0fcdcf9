"""`anytime navigate`: run one navigation task frame by frame under a policy (see
`anytime_navigation.task.model` for the model and the definitions of the reported quantities)."""

from __future__ import annotations

import argparse
import sys
import threading
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from anytime.plugin.cli import (
    EXIT_OK,
    CommandGroup,
    InputError,
    ProgressBar,
    UsageError,
    int_in_range,
    json_text,
    owned_directory,
    positive_float,
    random_seed,
    write_atomic,
)
from anytime.plugin.compose import DeadlineValue
from anytime.plugin.figures import require_matplotlib

from ..movingai import MapError, load_map
from ..obstacles.moving import MovingObstacle, random_obstacles
from ..planning.planner import compile_searches
from ..task.frame_program import navigation_program
from ..task.frames import NO_DYNAMIC_PROFILE, run_task
from ..task.model import POLICIES, NavigationTask, TaskReport
from ..world import World, is_power_of_two, random_world, reachable
from .plan import position

__all__ = ["add_command", "run_navigate"]


#: The largest world side (--size) and sensor radius (--radius).
MAX_SIDE = 4096
#: The most moving obstacles.
MAX_OBSTACLES = 1000


def _size(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if not (8 <= value <= MAX_SIDE and is_power_of_two(value)):
        raise argparse.ArgumentTypeError(
            f"expected a power of two from 8 to {MAX_SIDE}, got {text}"
        )
    return value


def add_command(commands: CommandGroup) -> None:
    navigate = commands.add_command(
        "navigate",
        run=run_navigate,
        help="run a navigation task frame by frame under the monitor (or a fixed policy)",
        description="Run a navigation task: the robot senses a window around itself, plans with "
        "the compiled schema 'navigate' (the plugin's packaged schemas/navigation.any), and moves"
        " frame by frame to the "
        "goal; the monitor chooses each frame's contract time and the speed. Prints frames, "
        "completion time, energy, value and utility, against the utility predicted at the start "
        "and a clairvoyant bound.",
    )
    navigate.add_argument(
        "--size",
        type=_size,
        default=128,
        help=f"world side, a power of two from 8 to {MAX_SIDE} (128)",
    )
    navigate.add_argument("--seed", type=random_seed, default=0, help="world and vision seed")
    navigate.add_argument("--map", metavar="FILE.map", help="a MovingAI map instead of a world")
    navigate.add_argument("--start", type=position, metavar="X,Y", help="start (with --map)")
    navigate.add_argument("--goal", type=position, metavar="X,Y", help="goal (with --map)")
    navigate.add_argument(
        "--radius",
        type=int_in_range(1, MAX_SIDE),
        help="sensor radius in cells (default: a quarter of the side)",
    )
    navigate.add_argument(
        "--deadline",
        type=positive_float,
        metavar="TICKS",
        help="full value until then (default: 6000 * side / 128)",
    )
    navigate.add_argument(
        "--policy",
        choices=POLICIES,
        default="monitored",
        help="monitored (default); fixed, min, max: a fixed contract; stopping: the monitor's"
        " contract as an upper bound, each frame's planner stopped within it by optimal stopping"
        " over its dynamic profile",
    )
    navigate.add_argument(
        "--contract", type=positive_float, metavar="TICKS", help="contract time of --policy fixed"
    )
    navigate.add_argument(
        "--clock",
        choices=["work", "wall"],
        default="work",
        help="time in reported ticks of work (work: reproducible, the default) or in seconds of"
        " the wall clock (wall: read as ticks at a rate measured once; the shipped profiles and"
        " the prediction are of the work clock, and a frame's fixed costs, which no tick"
        " counts, outlast the monitor's contracts there)",
    )
    navigate.add_argument(
        "--moving-obstacles",
        type=int_in_range(0, MAX_OBSTACLES),
        default=0,
        metavar="K",
        help="K moving obstacles (from the seed); the robot decides how to overcome each one "
        "with the compiled schema 'overcome-obstacle' (the plugin's packaged"
        " schemas/obstacles.any)",
    )
    navigate.add_argument(
        "--profiles",
        metavar="DIR",
        action="append",
        default=[],
        help="also a directory of profile files (*.yaml): a find-path or get-domain-description "
        "profile there replaces the shipped one; repeatable",
    )
    navigate.add_argument(
        "--out",
        metavar="DIR",
        help="write frame figures, a GIF, events.jsonl into DIR (an earlier run's there are "
        "deleted first; refused while another run writes there)",
    )
    navigate.add_argument(
        "--compare",
        action="store_true",
        help="also run the task under the fixed policies min and max (the shortest and the "
        "longest contract; each a whole run more) and report them beside it",
    )
    navigate.add_argument("--json", action="store_true", help="print the result as JSON")
    navigate.add_argument("--quiet", action="store_true", help="no progress bars")


#: How long the planner's searches may take to load before `navigate` says what it is doing.
NOTICE_SECONDS = 3.0


def _ready_searches(say: bool) -> None:
    """Load (or, the first time after an install, compile) the planner's searches before the
    run, saying so when it takes long: otherwise the first frame seems to hang."""
    done = threading.Event()

    def notice() -> None:
        if not done.wait(NOTICE_SECONDS):
            print(
                "anytime: loading the planner's compiled searches (the first run after an install"
                " compiles them: about 20 to 60 seconds, once)",
                file=sys.stderr,
                flush=True,
            )

    if say:
        threading.Thread(target=notice, daemon=True).start()
    try:
        compile_searches()
    finally:
        done.set()


def _world(args: argparse.Namespace) -> tuple[World, str]:
    """The task's world, and how the summary names it."""
    if args.map is None:
        if args.start is not None or args.goal is not None:
            raise UsageError("--start and --goal need --map")
        return random_world(args.size, seed=args.seed), f"{args.size}x{args.size} world"
    try:
        blocked, width, height = load_map(args.map)
    except MapError as error:
        raise InputError(error.message, where=f"{error.filename}:{error.line}") from None
    except OSError as error:
        raise InputError(f"cannot read '{args.map}': {error.strerror}") from None
    free = ~blocked[:height, :width]
    cells = np.argwhere(free)
    if cells.size == 0:
        raise InputError(f"{args.map}: the map has no free cell")
    start = args.start or (int(cells[0][1]), int(cells[0][0]))
    goal = args.goal or (int(cells[-1][1]), int(cells[-1][0]))
    for name, (x, y) in (("start", start), ("goal", goal)):
        if not (0 <= x < width and 0 <= y < height):
            raise InputError(f"the {name} {x},{y} is outside the {width}x{height} map")
        if blocked[y, x]:
            raise InputError(f"the {name} {x},{y} is a blocked cell")
    if not reachable(blocked, start)[goal[1], goal[0]]:
        raise InputError(
            f"the goal {goal[0]},{goal[1]} cannot be reached from the start {start[0]},{start[1]}"
        )
    return World(blocked, start, goal), f"{width}x{height} map {Path(args.map).name}"


def run_navigate(args: argparse.Namespace) -> int:
    if args.policy == "fixed" and args.contract is None:
        raise UsageError("--policy fixed needs --contract TICKS")
    if args.out is not None:
        require_matplotlib()  # the figures need the plot extra: say so before the run, not after
    world, described = _world(args)
    side = world.blocked.shape[0]
    deadline = args.deadline if args.deadline is not None else 6000.0 * side / 128
    task = NavigationTask(
        world,
        radius=args.radius or side // 4,
        value=DeadlineValue(1000.0, deadline, 0.25 * 128 / side),
        seed=args.seed,
    )
    warnings: list[str] = []
    compiled, trace = navigation_program(args.profiles, warn=warnings.append)
    for warning in warnings:
        print(f"anytime: warning: {warning}", file=sys.stderr)
    if args.policy == "stopping" and not trace.dynamic:
        raise InputError(NO_DYNAMIC_PROFILE)
    obstacles: tuple[MovingObstacle, ...] = ()
    if args.moving_obstacles:
        try:
            obstacles = random_obstacles(world, args.moving_obstacles, args.seed)
        except ValueError as error:
            raise InputError(f"--moving-obstacles: {error}") from None
    bars = False if args.quiet else None  # progress on a terminal's stderr, unless --quiet
    _ready_searches(say=not args.quiet)

    def run(policy: str, contract: float | None = None) -> TaskReport:
        with ProgressBar(None, label=f"navigate ({policy})", unit="frames", enabled=bars) as bar:
            return run_task(
                task,
                compiled,
                trace,
                policy=policy,
                contract=contract,
                clock=args.clock,
                obstacles=obstacles,
                on_frame=lambda _: bar.update(),
            )

    written: list[str] = []
    with ExitStack() as stack:
        # the directory is taken before the run: a second run into it is refused at once
        out = None if args.out is None else stack.enter_context(owned_directory(args.out, OUTPUTS))
        report = run(args.policy, args.contract)
        comparison: dict[str, TaskReport] = {}
        if args.compare:
            for policy in ("min", "max"):
                if policy != args.policy:
                    comparison[policy] = run(policy)
        if out is not None:
            written = _outputs(report, task, out.fresh(), bars)
    if args.json:
        result = navigate_json(report)
        if comparison:
            result["comparison"] = {
                name: navigate_json(other) for name, other in comparison.items()
            }
        print(json_text(result))
    else:
        print(_summary(report, comparison, described), end="")
        if written:
            pngs = [w for w in written if w.endswith(".png")]
            print(
                f"wrote {len(pngs)} frame pictures, the animation and events.jsonl in "
                f"{Path(args.out)}"
            )
    return EXIT_OK


#: `TaskReport.as_json`'s keys as `navigate --json` names them: what the monitor expected
#: before the run beside what the run realised, as `deliver --json` and `verify --json` have
#: them (docs/cli.md, "JSON output").
JSON_NAMES = {"predicted_utility": "expected_utility", "utility": "realised_utility"}

#: What a run without moving obstacles has of their counts (`as_json` leaves them out).
NO_OBSTACLES = {"moving_obstacles": 0, "decisions": 0, "collisions": 0, "evasions": 0}


def navigate_json(report: TaskReport) -> dict[str, Any]:
    """A run as `navigate --json` prints it: every key always there, times in ticks (the wall
    clock reads in tick-equivalents)."""
    data = NO_OBSTACLES | {JSON_NAMES.get(k, k): v for k, v in report.as_json().items()}
    data["time_unit"] = "ticks"
    first = {key: data.pop(key) for key in JSON_ORDER if key in data}
    return first | data  # a key `as_json` gains goes last


#: The order of `navigate --json`'s keys.
JSON_ORDER = (
    "seed size policy time_unit frames completion_time route_length optimal_length energy"
    " value expected_utility realised_utility prediction_error optimal_utility utility_ratio"
    " moving_obstacles decisions collisions evasions"
).split()


#: What `navigate --out DIR` writes, and so deletes there before a run writes anew.
OUTPUTS = ("frame-*.png", "run.gif", "events.jsonl")


def _outputs(report: TaskReport, task: NavigationTask, out: Path, bars: bool | None) -> list[str]:
    """Write the run's event log, and its figures if matplotlib is there; return the paths."""
    write_atomic(out / "events.jsonl", report.log.to_jsonl())
    written = [str(out / "events.jsonl")]
    try:
        from ..task.frame_figures import write_frames
    except ImportError as error:  # matplotlib is the optional `plot` extra
        print(f"anytime: warning: no figures ({error}); install the 'plot' extra", file=sys.stderr)
        return written
    with ProgressBar(
        len(report.records), label="navigate figures", unit="frames", enabled=bars
    ) as bar:
        written.extend(write_frames(report, task, out, on_frame=lambda _: bar.update()))
    return written


def _summary(report: TaskReport, comparison: dict[str, TaskReport], described: str) -> str:
    r = report
    lines = [
        f"navigation task: {described}, seed {r.seed}, policy {r.policy}",
        f"  frames           {r.frames}",
        f"  completion time  {r.completion_time:.0f} ticks",
        f"  route length     {r.route_length:.1f} (optimal {r.optimal_length:.1f})",
        f"  energy           {r.energy:.1f}",
        f"  value            {r.value:.1f}",
        f"  utility          {r.utility:.1f}  (= value - energy)",
        f"  predicted        {r.predicted_utility:.1f}  (error {100 * r.prediction_error:.1f}%)",
        f"  clairvoyant      {r.optimal_utility:.1f}  (ratio {r.utility_ratio:.3f})",
    ]
    if r.moving_obstacles:
        lines.append(
            f"  obstacles        {r.moving_obstacles} moving: {r.decisions} decisions, "
            f"{r.collisions} collisions, {r.evasions} evasions"
        )
    for name, other in comparison.items():
        lines.append(
            f"  policy {name:<9} utility {other.utility:.1f} in {other.frames} frames, "
            f"{other.completion_time:.0f} ticks"
        )
    return "\n".join(lines) + "\n"
