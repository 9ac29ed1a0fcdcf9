"""`anytime deliver`: compile a routing schema, run it on one delivery problem under a
budget on the work clock, and report the compiled expectation against the realised quality."""

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

from .domain import CUSTOMERS, DEPOTS, EXACT_NODES
from .program import (
    RESOLUTIONS,
    SCHEMAS,
    TIME_GRIDS,
    Delivery,
    compiled_program,
    deliver,
    world_for,
)

__all__ = ["add_commands", "run_deliver"]

#: The most customers and depots `anytime deliver` takes.
MAX_CUSTOMERS = 2000
MAX_BUDGET = 10_000.0


def add_commands(commands: CommandGroup) -> None:
    parser = commands.add_command(
        "deliver",
        run=run_deliver,
        help="plan delivery tours under a time budget with a compiled routing schema",
        description="Draw a delivery problem (customers in the unit square with demand shares "
        "hidden behind an order log, and depots to place), compile the schema against the "
        "routing plugin's measured profiles, run it with the budget on the work clock, and "
        "print the compiled expectation, the realised quality (the reference tours' length over "
        "the tours', the reference being the optimal tours of the best of 30 k-means restarts "
        "on the true demand), the allocation, the time used and the status. The profiles were "
        f"measured on {CUSTOMERS} customers and {DEPOTS} depots: other sizes run, but the "
        "expectation is for that size.",
    )
    parser.add_argument(
        "--customers",
        type=int_in_range(1, MAX_CUSTOMERS),
        default=CUSTOMERS,
        metavar="N",
        help=f"customers ({CUSTOMERS})",
    )
    parser.add_argument(
        "--depots",
        type=int_in_range(1, MAX_CUSTOMERS),
        default=DEPOTS,
        metavar="N",
        help=f"depots ({DEPOTS})",
    )
    parser.add_argument(
        "--seed", type=random_seed, default=0, metavar="S", help="the problem's seed (0)"
    )
    parser.add_argument(
        "--budget",
        type=float_in_range(0.0, MAX_BUDGET),
        default=60.0,
        metavar="TICKS",
        help="ticks of work, a multiple of the schemas' lattice, 2 ticks (60)",
    )
    parser.add_argument(
        "--schema", choices=SCHEMAS, default="deliver", help="the packaged schema (deliver)"
    )
    parser.add_argument("--adaptive", action="store_true", help="re-allocate as modules finish")
    parser.add_argument("--out", metavar="DIR", help="write the figures (PNG) to DIR")
    parser.add_argument("--json", action="store_true", help="print JSON")


def _grid(schema: str, budget: float) -> tuple[float, ...]:
    return tuple(sorted(set(TIME_GRIDS[schema]) | {budget}))


def run_deliver(args: argparse.Namespace) -> int:
    if args.depots > args.customers:
        raise InputError(f"--depots {args.depots}: more depots than customers ({args.customers})")
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
    world = world_for(args.customers, args.depots, args.seed)
    run = deliver(program, world, args.budget, adaptive=args.adaptive)
    j = list(program.profile.time).index(args.budget)
    expected = float(program.expected[j])
    allocation = allocation_json(program.modules, run.record.allocations)
    if args.out is not None:
        written = _figures(args, program, world, run)
    if args.json:
        print(json_text(_json(args, expected, allocation, run)))
        return EXIT_OK
    print(_text(args, expected, allocation, run), end="")
    if args.out is not None:
        print(f"wrote {', '.join(written)}")
    return EXIT_OK


def _json(
    args: argparse.Namespace, expected: float, allocation: dict[str, float], run: Delivery
) -> dict[str, Any]:
    return {
        "schema": args.schema,
        "budget": args.budget,
        "time_unit": "ticks",
        "allocation": allocation,
        "expected_quality": round(expected, 6),
        "realised_quality": None if run.quality is None else round(run.quality, 6),
        "time_used": run.record.time_used,
        "status": run.record.status.value,
        "customers": args.customers,
        "depots": args.depots,
        "seed": args.seed,
    }


def _text(
    args: argparse.Namespace, expected: float, allocation: dict[str, float], run: Delivery
) -> str:
    head = (
        f"{args.schema}: {args.customers} customers, {args.depots} depots, seed {args.seed},"
        f" budget {args.budget:g} ticks{' (adaptive)' if args.adaptive else ''}\n"
    )
    split = ", ".join(f"{m} {t:g}" for m, t in allocation.items())
    if run.tours is None:
        realised = "no tours (no result in the time)"
    elif run.quality is None:
        realised = (
            f"tours {run.tours.length:.4f}; no reference (a depot has more than {EXACT_NODES}"
            " stops: pip install 'anytime-routing[measure]' for LKH)"
        )
    else:
        realised = (
            f"{run.quality:.3f} (tours {run.tours.length:.4f}, reference"
            f" {run.reference_length:.4f})"
        )
    rows = [
        ["allocation", split],
        ["expected", f"{expected:.3f} (compiled)"],
        ["realised", realised],
        ["time used", f"{run.record.time_used:g} of {args.budget:g} ticks"],
        ["status", run.record.status.value],
    ]
    return head + format_table(rows, indent=2)


def _figures(args: argparse.Namespace, program: Any, world: Any, run: Delivery) -> list[str]:
    from .figures import write_figures  # matplotlib: the `plot` extra

    with owned_directory(args.out, owns=("tours.png", "quality.png")) as out:
        return write_figures(out.fresh(), program, world, run, args.budget, args.adaptive)
