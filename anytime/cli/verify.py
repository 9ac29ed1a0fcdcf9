"""`anytime verify`: compile a schema and check its promise by running it on fresh problems."""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from concurrent.futures import Executor
from contextlib import contextmanager

from anytime.cli.common import (
    EXIT_INPUT,
    EXIT_OK,
    MAX_TRIALS,
    int_in_range,
    json_text,
    library_options,
    open_library,
    random_seed,
    worker_options,
)
from anytime.cli.schemas import (
    check_time_unit,
    compile_options,
    compile_schemas,
    one_schema,
    totals,
)
from anytime.dsl import load_schemas
from anytime.measure.builder import dask_executor
from anytime.verification import (
    SIGMAS,
    TOLERANCE,
    format_verification,
    verification_to_dict,
    verify,
)

#: The most runs per budget.
MAX_RUNS = MAX_TRIALS


def add_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = commands.add_parser(
        "verify",
        help="check a compiled schema's promise: run it on fresh problems at every budget",
        description="Compile a schema as `anytime compile` does, run the compiled program on "
        "fresh problems of the program problem set a plugin declares for it, at every total of "
        "the table (the smallest included), on the work clock, and compare the realised mean "
        "quality with the promised one. A budget fails when |realised - promised| > "
        f"max({TOLERANCE:g}, {SIGMAS:g} se) or a run uses more than its budget. Exit status 1 "
        "when a budget fails. The same seed gives the same result, whatever the number of "
        "workers.",
    )
    parser.add_argument("file", metavar="FILE", help="a schema file (.any)")
    parser.add_argument(
        "--schema", metavar="NAME", help="the schema to verify (default: the file's only one)"
    )
    parser.add_argument(
        "--runs",
        type=int_in_range(1, MAX_RUNS),
        default=100,
        metavar="N",
        help=f"fresh problems per budget (100; at most {MAX_RUNS})",
    )
    parser.add_argument(
        "--budgets",
        type=totals,
        metavar="T,T,...",
        help="only these totals of the compiled table (default: all of them)",
    )
    worker_options(parser, "run the program")
    parser.add_argument("--seed", type=random_seed, default=0, metavar="S", help="root seed (0)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    compile_options(
        parser.add_argument_group("compiling the schema, as for compile"),
        time_grid_default="the problem set's, else as for compile",
        resolution_default="the problem set's, else as for compile",
    )
    library_options(parser)
    parser.set_defaults(run=run_verify)


def run_verify(args: argparse.Namespace) -> int:
    library = open_library(args)
    schemas = load_schemas(args.file)
    name = one_schema(schemas, args.schema, "to verify")
    problems = library.program_problems(name)  # before compiling: a LibraryError says why
    grid = args.time_grid if args.time_grid is not None else problems.time_grid
    resolution = args.resolution
    if resolution is None and args.time_grid is None:
        resolution = problems.resolution
    compiled = compile_schemas(
        schemas,
        library,
        grid,
        schema=name,
        allocator=args.allocator,
        input_quality=args.input_quality,
        resolution=resolution,
        memory=args.memory,
        strict=args.strict,
    )
    (program,) = [c for c in compiled if c.name == name.lower()]
    check_time_unit([program], args.time_unit, args.file)
    with _executor(args.scheduler) as executor:
        result = verify(
            program,
            problems,
            runs=args.runs,
            budgets=args.budgets,
            workers=args.workers,
            seed=args.seed,
            executor=executor,
            progress=False if args.quiet else None,
        )
    if args.json:
        print(json_text(verification_to_dict(result)))
    else:
        print(format_verification(result), end="")
    return EXIT_OK if result.passed else EXIT_INPUT


@contextmanager
def _executor(scheduler: str | None) -> Iterator[Executor | None]:
    if scheduler is None:
        yield None
    else:
        with dask_executor(scheduler) as executor:
            yield executor
