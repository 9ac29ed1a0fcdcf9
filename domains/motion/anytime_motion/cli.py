"""`anytime motion`: compile a motion schema, run it on one problem under a budget on the work
clock, and report the compiled expectation against the realised quality, beside MoveIt's even
split and all the time to the planners."""

from __future__ import annotations

import argparse
from typing import Any

from anytime.plugin.cli import (
    EXIT_OK,
    CommandGroup,
    InputError,
    allocation_json,
    float_in_range,
    format_table,
    int_in_range,
    json_text,
    owned_directory,
    random_seed,
)
from anytime.plugin.figures import require_matplotlib

from .domain import OBSTACLES
from .program import (
    RESOLUTIONS,
    SCHEMAS,
    SPLITS,
    TIME_GRIDS,
    Motion,
    compiled_program,
    move,
    problem_for,
)

__all__ = ["add_commands", "run_motion"]

MAX_OBSTACLES = 40
MAX_BUDGET = 100_000.0
DEFAULT_BUDGET = 4000.0


def add_commands(commands: CommandGroup) -> None:
    parser = commands.add_command(
        "motion",
        run=run_motion,
        help="plan a robot's path under a time budget with a compiled motion schema (OMPL)",
        description="Draw a motion problem (obstacles, balls and boxes, in the unit box, a start "
        "and a goal), compile the schema against the motion plugin's measured profiles, run it "
        "with the budget on the work clock (ticks: ray casts and validity checks), and print the "
        "compiled expectation, the realised quality (the reference path's cost over the path's, "
        "0 when it collides with the true obstacles), the allocation, the time used and the "
        "status; beside it, MoveIt's even split among the modules and all the time to the "
        f"planners. The profiles were measured on {OBSTACLES} obstacles in 2-D: other problems "
        "run, but the expectation is for those.",
    )
    parser.add_argument(
        "--obstacles",
        type=int_in_range(0, MAX_OBSTACLES),
        default=OBSTACLES,
        metavar="N",
        help=f"obstacles ({OBSTACLES})",
    )
    parser.add_argument(
        "--dimension", type=int_in_range(2, 3), default=2, metavar="D", help="2 or 3 (2)"
    )
    parser.add_argument(
        "--seed", type=random_seed, default=0, metavar="S", help="the problem's seed (0)"
    )
    parser.add_argument(
        "--budget",
        type=float_in_range(0.0, MAX_BUDGET),
        default=DEFAULT_BUDGET,
        metavar="TICKS",
        help=f"ticks of work, a multiple of the schemas' lattice, 250 ticks ({DEFAULT_BUDGET:g})",
    )
    parser.add_argument(
        "--schema", choices=SCHEMAS, default="move", help="the packaged schema (move)"
    )
    parser.add_argument("--out", metavar="DIR", help="write the figures (PNG) to DIR")
    parser.add_argument("--json", action="store_true", help="print JSON")


def _grid(schema: str, budget: float) -> tuple[float, ...]:
    return tuple(sorted(set(TIME_GRIDS[schema]) | {budget}))


def run_motion(args: argparse.Namespace) -> int:
    resolution = RESOLUTIONS[args.schema]
    steps = args.budget / resolution
    if abs(steps - round(steps)) > 1e-9:
        raise InputError(
            f"--budget {args.budget:g}: expected a multiple of {resolution:g} ticks (the"
            " allocation lattice of the compiled schema)"
        )
    if args.out is not None:
        require_matplotlib()  # say so before the run, not after
    program = compiled_program(args.schema, _grid(args.schema, args.budget))
    problem = problem_for(args.obstacles, args.dimension, args.seed)
    runs = {split: move(program, problem, args.budget, split) for split in SPLITS}
    j = list(program.profile.time).index(args.budget)
    expected = float(program.expected[j])
    if args.out is not None:
        written = _figures(args, program, problem, runs)
    if args.json:
        print(json_text(_json(args, expected, runs)))
        return EXIT_OK
    print(_text(args, expected, runs), end="")
    if args.out is not None:
        print(f"wrote {', '.join(written)}")
    return EXIT_OK


def _json(args: argparse.Namespace, expected: float, runs: dict[str, Motion]) -> dict[str, Any]:
    run = runs["compiled"]
    return {
        "schema": args.schema,
        "budget": args.budget,
        "time_unit": "ticks",
        "allocation": allocation_json(list(run.allocation), list(run.allocation.values())),
        "expected_quality": round(expected, 6),
        "realised_quality": round(run.quality, 6),
        "time_used": run.record.time_used,
        "status": run.record.status.value,
        "path_cost": None if run.path is None else round(run.path.cost, 6),
        "reference_cost": round(run.reference_cost, 6),
        "comparison": {
            split: {
                "allocation": allocation_json(
                    list(other.allocation), list(other.allocation.values())
                ),
                "realised_quality": round(other.quality, 6),
                "time_used": other.record.time_used,
                "status": other.record.status.value,
            }
            for split, other in runs.items()
            if split != "compiled"
        },
        "obstacles": args.obstacles,
        "dimension": args.dimension,
        "seed": args.seed,
    }


def _realised(run: Motion) -> str:
    if run.path is None:
        return "0.000 (no path in the time)"
    if run.quality == 0:
        return f"0.000 (path {run.path.cost:.4f} collides with the true obstacles)"
    return f"{run.quality:.3f} (path {run.path.cost:.4f}, reference {run.reference_cost:.4f})"


def _text(args: argparse.Namespace, expected: float, runs: dict[str, Motion]) -> str:
    head = (
        f"{args.schema}: {args.obstacles} obstacles in {args.dimension}-D, seed {args.seed},"
        f" budget {args.budget:g} ticks\n"
    )
    rows = []
    names = {"compiled": "compiled", "even": "even (MoveIt)", "planner": "all to the planner"}
    for split, run in runs.items():
        allocation = ", ".join(f"{m} {t:g}" for m, t in run.allocation.items())
        rows.append([names[split], "allocation", allocation])
        if split == "compiled":
            rows.append(["", "expected", f"{expected:.3f} (compiled)"])
        rows.append(["", "realised", _realised(run)])
        rows.append(["", "time used", f"{run.record.time_used:g} of {args.budget:g} ticks"])
        rows.append(["", "status", run.record.status.value])
    return head + format_table(rows, indent=2)


def _figures(
    args: argparse.Namespace, program: Any, problem: Any, runs: dict[str, Motion]
) -> list[str]:
    from .figures import write_figures  # matplotlib: the `plot` extra

    with owned_directory(args.out, owns=("paths.png", "quality.png")) as out:
        return write_figures(out.fresh(), program, problem, runs, args.budget)
