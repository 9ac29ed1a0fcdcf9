"""`anytime parse` and `anytime compile`: schema files in, straight-line form or compiled
profiles out."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from typing import Any

from anytime.cli.common import (
    EXIT_OK,
    MAX_LATTICE_POINTS,
    MAX_TIME_POINTS,
    InputError,
    allocation_json,
    check_lattice,
    json_text,
    library_options,
    non_negative_int,
    open_library,
    positive_float,
    quality_list,
    refuse_overwriting_inputs,
    refuse_overwriting_profiles,
    time_grid,
)
from anytime.compiler import (
    CompiledProgram,
    CompileError,
    compile_file,
    format_report,
    save_compiled,
)
from anytime.compiler.allocators import DEFAULT_MEMORY
from anytime.compiler.compile import (
    ALLOCATOR_NAMES,
    DEFAULT_INPUT_QUALITY,
    default_time_grid,
    memory_bytes,
)
from anytime.compiler.explain import (
    Explanation,
    explain,
    format_explanations,
)
from anytime.compiler.report import MAX_ROWS, compiled_to_dict
from anytime.dsl import (
    Program,
    SchemaFile,
    format_programs,
    graph_to_dot,
    load_schemas,
    program_to_json,
)
from anytime.library import AnytimeLibrary
from anytime.vocabulary import UNITS


def add_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parse = commands.add_parser(
        "parse",
        help="check a schema file and print its straight-line form or dataflow graph",
        description="Check a schema file and print each schema in straight-line form "
        "(DSL text that parses back to the same program), as JSON, or as a Graphviz graph.",
    )
    parse.add_argument("file", metavar="FILE", help="a schema file (.any)")
    parse.add_argument("--schema", metavar="NAME", help="only this schema (default: all)")
    output = parse.add_mutually_exclusive_group()
    output.add_argument("--json", action="store_true", help="print JSON")
    output.add_argument("--dot", action="store_true", help="print the dataflow graph as DOT")
    parse.add_argument(
        "--check-calls",
        action="store_true",
        help="check every called function against the anytime library (installed plugins and "
        "in-process modules; implied by --profiles)",
    )
    library_options(parse)
    parse.set_defaults(run=run_parse)

    compile_ = commands.add_parser(
        "compile",
        help="compile a schema: optimal time allocation and the compiled profile",
        description="Compile a schema into a contract algorithm: for every input quality and "
        "total time, the allocation of time among its anytime modules that maximises expected "
        "output quality, with the papers' baselines (equal split, MIN, MAX) and the gap to the "
        "exhaustive optimum. Schemas it calls are compiled first.",
    )
    compile_.add_argument("file", metavar="FILE", help="a schema file (.any)")
    compile_.add_argument("--schema", metavar="NAME", help="only this schema (and its callees)")
    compile_options(compile_)
    compile_.add_argument("-o", "--output", metavar="OUT.yaml", help="write the compiled profile")
    compile_.add_argument("--json", action="store_true", help="print the report as JSON")
    compile_.add_argument(
        "--rows",
        type=non_negative_int,
        default=MAX_ROWS,
        metavar="N",
        help=f"the table shows N totals spread over the time grid, both ends included (default:"
        f" {MAX_ROWS}; 0: every total)",
    )
    compile_.add_argument(
        "--explain",
        nargs="?",
        const=(),
        type=totals,
        metavar="T,T,...",
        help="also say why the splits: at these totals of the time grid (default: a quarter, "
        "half and all of the way up), each module's share and the change in expected quality "
        "one lattice unit more or less for it makes (in --json: the explain list)",
    )
    library_options(compile_)
    compile_.set_defaults(run=run_compile)


def compile_options(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup,
    *,
    time_grid_default: str | None = None,
    resolution_default: str | None = None,
) -> None:
    """How a schema is compiled: --allocator, --time-grid, --resolution, --input-quality,
    --time-unit, --memory and --strict, as `compile_schemas` and `check_time_unit` read them
    (the options of `anytime compile`, shared by the commands that compile a schema). The
    defaults' help text of --time-grid and --resolution can be replaced (`anytime verify`
    takes a problem set's own first)."""
    grid_text = time_grid_default or DEFAULT_GRID_TEXT
    resolution_text = resolution_default or "the time grid's STEP"
    parser.add_argument(
        "--allocator",
        choices=ALLOCATOR_NAMES,
        default="auto",
        help="auto (default): dp where local compilation is exact, else exhaustive where it is "
        "cheap, else multi-start",
    )
    parser.add_argument(
        "--time-grid",
        type=time_grid,
        metavar="START:STOP:STEP",
        help=f"the totals to compile for (default: {grid_text}; at most {MAX_TIME_POINTS:,}"
        " totals)",
    )
    parser.add_argument(
        "--resolution",
        type=positive_float,
        metavar="DT",
        help=f"allocations are multiples of DT (default: {resolution_text}; at most the"
        f" largest total, with at most {MAX_LATTICE_POINTS:,} multiples up to it)",
    )
    parser.add_argument(
        "--input-quality",
        type=quality_list,
        metavar="Q,Q,...",
        default=",".join(f"{q:g}" for q in DEFAULT_INPUT_QUALITY),
        help="the grid of program input qualities, each from 0 to 1 (default: 0,0.1,...,1)",
    )
    parser.add_argument(
        "--time-unit",
        choices=UNITS,
        help="the unit the time grid is in; it must be the profiles' unit",
    )
    parser.add_argument(
        "--memory",
        type=memory_size,
        metavar="SIZE",
        default=DEFAULT_MEMORY,
        help="the most memory a search may hold at once, e.g. 512MB, 1GB, 2GiB (default: 1GB); "
        "it evaluates in chunks within it, and a table that cannot fit is refused up front",
    )
    parser.add_argument(
        "--strict",
        action="store_true",
        help="refuse a table that feeds a module input qualities outside the grid its profile"
        " was measured on (by default a warning: the profile is clamped there)",
    )


#: What --time-grid is by default (`default_time_grid`).
DEFAULT_GRID_TEXT = "0 to the sum of the modules' longest profiled times, in about 20 steps"


def check_time_unit(
    compiled: Sequence[CompiledProgram], time_unit: str | None, filename: str
) -> None:
    """--time-unit, when given, must be the unit of the compiled programs' profiles."""
    if time_unit is None:
        return
    for result in compiled:
        if result.profile.time_unit != time_unit:
            raise InputError(
                f"schema '{result.name}': the time grid is in "
                f"{time_unit} but its modules' profiles are in "
                f"{result.profile.time_unit}",
                where=filename,
            )


def memory_size(text: str) -> int:
    """The --memory option: a size in bytes or with a unit (a usage error otherwise)."""
    try:
        return memory_bytes(text)
    except CompileError as error:
        raise argparse.ArgumentTypeError(str(error).removeprefix("memory: ")) from None


def totals(text: str) -> tuple[float, ...]:
    """An option type: T,T,... totals >= 0, at most `MAX_TIME_POINTS` of them."""
    parts = [part for part in text.split(",") if part.strip()]
    if not parts:
        raise argparse.ArgumentTypeError("expected at least one total")
    if len(parts) > MAX_TIME_POINTS:
        raise argparse.ArgumentTypeError(
            f"{len(parts):,} totals, more than the limit of {MAX_TIME_POINTS:,}"
        )
    return tuple(_total(part, text) for part in parts)


def _total(part: str, text: str) -> float:
    try:
        value = float(part)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected totals separated by commas, got {text!r}"
        ) from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected finite totals >= 0, got {text!r}")
    return value


def run_parse(args: argparse.Namespace) -> int:
    known = None
    if args.check_calls or args.profiles:
        known = open_library(args).known_functions()
    schemas = load_schemas(args.file, known)
    programs = schemas.programs
    if args.schema is not None:
        check_schema_name(schemas, args.schema)
        programs = (schemas[args.schema],)
    if args.json:
        print(json_text({"schemas": [parse_json(p) for p in programs]}))
    elif args.dot:
        print(graph_to_dot(p.graph for p in programs), end="")
    else:
        print(format_programs(programs), end="")
    return EXIT_OK


def run_compile(args: argparse.Namespace) -> int:
    refuse_overwriting_inputs(args.output, args.file)
    library = open_library(args)
    refuse_overwriting_profiles(args.output, library)
    # Calls are checked against the library for the compiled schemas only (by the compiler).
    schemas = load_schemas(args.file)
    check_schema_name(schemas, args.schema)
    if args.output is not None and args.schema is None and len(schemas) > 1:
        raise InputError(
            f"{args.file} defines {len(schemas)} schemas: say which one to write with --schema NAME"
        )
    compiled = compile_schemas(
        schemas,
        library,
        args.time_grid,
        schema=args.schema,
        allocator=args.allocator,
        input_quality=args.input_quality,
        resolution=args.resolution,
        memory=args.memory,
        strict=args.strict,
    )
    wanted = [c for c in compiled if args.schema is None or c.name == args.schema.lower()]
    check_time_unit(wanted, args.time_unit, args.file)
    if args.output is not None:
        try:
            save_compiled(wanted[0], args.output)
        except OSError as error:
            raise InputError(f"cannot write '{args.output}': {error.strerror}") from None
    explained = {c.name: explain_totals(c, args.explain, args.file) for c in wanted}
    if args.json:
        reports = [
            compile_json(c, None if args.explain is None else explained[c.name]) for c in wanted
        ]
        print(json_text(reports[0] if len(reports) == 1 else {"schemas": reports}))
    else:
        texts = [format_report(c, args.rows) for c in wanted]
        if args.explain is not None:
            texts = [
                t + "\n" + format_explanations(c, explained[c.name])
                for t, c in zip(texts, wanted, strict=True)
            ]
        print("\n".join(texts), end="")
        if args.output is not None:
            print(f"wrote {args.output}")
    return EXIT_OK


def parse_json(program: Program) -> dict[str, Any]:
    """A program as `parse --json` prints it: `program_to_json` with the names every command
    uses (`schema` for its name, `parameters` for all its inputs, as `library show` has them)."""
    data = program_to_json(program)
    renamed = {"name": "schema", "inputs": "parameters"}
    return {renamed.get(key, key): value for key, value in data.items()}


def compile_json(
    compiled: CompiledProgram, explanations: Sequence[Explanation] | None = None
) -> dict[str, Any]:
    """The report as `compile --json` prints it: `compiled_to_dict`, with `explain` only when
    asked for."""
    report = compiled_to_dict(compiled)
    if explanations is not None:
        report["explain"] = [explain_json(e) for e in explanations]
    return report


def explain_json(explanation: Explanation) -> dict[str, Any]:
    """One explanation as `compile --explain --json` prints it: its split as an allocation,
    each module's margins keyed as the allocation is."""
    names = [m.module for m in explanation.modules]
    allocation = allocation_json(names, [m.share for m in explanation.modules])
    # `Move` names a module, not its call: a module called more than once keeps its bare name
    keys = {name: key for name, key in zip(names, allocation, strict=True) if name == key}
    move = explanation.best_move
    return {
        "budget": explanation.total,
        "input_quality": list(explanation.input_quality),
        "unit": explanation.unit,
        "expected_quality": explanation.expected,
        "unused": explanation.unused,
        "allocation": allocation,
        "margins": [
            {
                "module": key,
                "gain": m.gain,
                "loss": m.loss,
                "at_ceiling": m.at_ceiling,
                "note": m.note,
            }
            for key, m in zip(allocation, explanation.modules, strict=True)
        ],
        "best_move": None
        if move is None
        else {
            "from": keys.get(move.source, move.source),
            "to": keys.get(move.target, move.target),
            "change": move.change,
        },
    }


def explain_totals(
    compiled: CompiledProgram, chosen: Sequence[float] | None, filename: str
) -> list[Explanation]:
    """The explanations `--explain` asks for (none without it); a total off the time grid is
    an input error naming the file."""
    if chosen is None:
        return []
    try:
        return list(explain(compiled, chosen or None))
    except CompileError as error:
        raise InputError(f"schema '{compiled.name}': {error}", where=filename) from None


def check_schema_name(schemas: SchemaFile, name: str | None) -> None:
    """A schema name given on the command line must be one the file defines."""
    if name is not None and name not in schemas:
        defined = ", ".join(schemas.names)
        raise InputError(
            f"no schema named '{name}' (the file defines: {defined})", where=schemas.filename
        )


def one_schema(schemas: SchemaFile, name: str | None, purpose: str) -> str:
    """The schema a command works on: `name` (one the file defines), else the file's only
    one; a file of several without a name is an input error saying `purpose` ("to verify")."""
    check_schema_name(schemas, name)
    if name is not None:
        return name
    if len(schemas) != 1:
        raise InputError(
            f"{schemas.filename} defines {len(schemas)} schemas: say which one {purpose} with"
            " --schema NAME",
        )
    return schemas.names[0]


def compile_schemas(
    schemas: SchemaFile,
    library: AnytimeLibrary,
    time_grid: Sequence[float] | None,
    *,
    schema: str | None,
    allocator: str,
    input_quality: Sequence[float] = DEFAULT_INPUT_QUALITY,
    resolution: float | None = None,
    memory: int = DEFAULT_MEMORY,
    strict: bool = False,
) -> list[CompiledProgram]:
    """`compile_file` as the commands run it: the time grid given (by the `time_grid` option
    type) or the default, a lattice too large refused up front (a usage error), compile errors
    as input errors naming the file. Errors at a place show the line from the file's source
    (`schemas.source`, kept since it was read: the file is not read again)."""
    if time_grid is not None:
        grid = list(time_grid)
    else:
        grid = default_time_grid(schemas, library, schema)
    check_lattice(grid, resolution)
    try:
        return compile_file(
            schemas,
            library,
            grid,
            input_quality,
            schema=schema,
            allocator=allocator,
            resolution=resolution,
            memory=memory,
            strict=strict,
        )
    except CompileError as error:
        raise InputError(str(error), where=error.where or schemas.filename) from None
