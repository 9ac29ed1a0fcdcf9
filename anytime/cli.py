"""The `anytime` command.

Exit codes: 0 success, 1 bad input (a message naming the file and place, never a traceback),
2 usage errors (argparse's own).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from anytime import __version__
from anytime.compiler import CompileError, compile_file, compiled_to_dict, format_report
from anytime.compiler.compile import ALLOCATOR_NAMES, DEFAULT_INPUT_QUALITY, default_time_grid
from anytime.dsl import format_programs, graph_to_dot, load_schemas, program_to_json
from anytime.errors import AnytimeError, ProfileError
from anytime.library import AnytimeLibrary, LibraryEntry, LibraryError
from anytime.modules import AnytimeModule
from anytime.profiles.builder import (
    BuildError,
    ProfileRequest,
    profile_module,
    registered_problems,
)
from anytime.profiles.io import load_profile, save_profile
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.runtime.calibrate import CalibrationError, calibrate, convert_profile
from anytime.testing import CatalogueError, check_module

EXIT_OK, EXIT_INPUT, EXIT_USAGE = 0, 1, 2


class InputError(AnytimeError):
    """Bad input found by the command itself; the message is printed as it is."""


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    run: Callable[[argparse.Namespace], int] = args.run
    try:
        return run(args)
    except LibraryError as error:
        print(f"anytime: error: {error}", file=sys.stderr)
        return EXIT_INPUT
    except AnytimeError as error:
        print(error, file=sys.stderr)
        return EXIT_INPUT
    except BrokenPipeError:  # the reader went away, e.g. `anytime parse f | head -1`
        return EXIT_OK
    except OSError as error:
        print(f"anytime: error: cannot read '{error.filename}': {error.strerror}", file=sys.stderr)
        return EXIT_INPUT


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="anytime",
        description="Compose anytime algorithms: write program schemas, compile them into "
        "contract algorithms with optimal time allocation, run them under a monitor.",
    )
    parser.add_argument("--version", action="version", version=f"anytime {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

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
        "--library",
        action="store_true",
        help="check every called function against the anytime library (installed plugins and "
        "in-process modules; implied by --profiles)",
    )
    _library_options(parse)
    parse.set_defaults(run=run_parse)

    library = commands.add_parser(
        "library",
        help="list the anytime library's modules, or show one with its profile",
        description="The anytime library: modules of installed plugins (entry-point group "
        "'anytime.plugins'), modules registered in-process, and profile files.",
    )
    library_commands = library.add_subparsers(
        dest="library_command", metavar="COMMAND", required=True
    )
    listing = library_commands.add_parser(
        "list",
        help="every module: name, kind, inputs, profile, origin",
        description="List every module of the library: its name, kind, quality-carrying "
        "inputs, a summary of its profile, and where it was defined.",
    )
    listing.add_argument("--json", action="store_true", help="print a JSON list")
    _library_options(listing)
    listing.set_defaults(run=run_library_list)
    show = library_commands.add_parser(
        "show",
        help="one module: its declaration, profile axes and expected quality",
        description="Show one module: kind, origin, parameters and inputs, its profile's axes "
        "and a table of expected output quality by input quality and time.",
    )
    show.add_argument("name", metavar="NAME", help="the module's name (case-insensitive)")
    show.add_argument("--json", action="store_true", help="print JSON")
    _library_options(show)
    show.set_defaults(run=run_library_show)

    profile = commands.add_parser(
        "profile",
        help="measure a module's conditional performance profile and write it to a file",
        description="Run a module on generated problem instances over its registered grid of "
        "input qualities and times, score every output, and write the measured profile "
        "(histograms with sample counts, means and standard deviations). The same seed gives "
        "the same file, whatever the number of workers.",
    )
    profile.add_argument("module", metavar="MODULE", help="the module's name")
    profile.add_argument(
        "--trials", type=_positive_int, default=100, metavar="N", help="instances per cell (100)"
    )
    where = profile.add_mutually_exclusive_group()
    where.add_argument(
        "--workers", type=_positive_int, default=1, metavar="N", help="local processes (1)"
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the trials on a Dask cluster (needs the 'dask' extra)",
    )
    profile.add_argument("--seed", type=int, default=0, metavar="S", help="root seed (0)")
    profile.add_argument(
        "--clock",
        choices=["work", "wall"],
        default="work",
        help="time axis in reported ticks (work, reproducible) or in seconds (wall)",
    )
    profile.add_argument("--quiet", action="store_true", help="no progress bar")
    profile.add_argument(
        "-o", "--output", metavar="FILE", help="where to write the profile (MODULE.yaml)"
    )
    profile.add_argument("--json", action="store_true", help="print a JSON summary")
    _library_options(profile)
    profile.set_defaults(run=run_profile)

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
    compile_.add_argument(
        "--allocator",
        choices=ALLOCATOR_NAMES,
        default="auto",
        help="auto (default): dp where local compilation is exact, else hill-climbing",
    )
    compile_.add_argument(
        "--time-grid",
        metavar="START:STOP:STEP",
        help="the totals to compile for (default: 0 to the sum of the modules' longest "
        "profiled times, in about 20 steps)",
    )
    compile_.add_argument(
        "--resolution",
        type=float,
        metavar="DT",
        help="allocations are multiples of DT (default: the time grid's STEP)",
    )
    compile_.add_argument(
        "--input-quality",
        metavar="Q,Q,...",
        default=",".join(f"{q:g}" for q in DEFAULT_INPUT_QUALITY),
        help="the grid of program input qualities (default: 0,0.1,...,1)",
    )
    compile_.add_argument(
        "--time-unit",
        choices=["ticks", "seconds"],
        help="the unit the time grid is in; it must be the profiles' unit",
    )
    compile_.add_argument("-o", "--output", metavar="OUT.yaml", help="write the compiled profile")
    compile_.add_argument("--json", action="store_true", help="print the report as JSON")
    compile_.add_argument(
        "--library",
        dest="profiles",
        metavar="DIR",
        action="append",
        default=[],
        help="a directory of profile files (*.yaml), each a module; repeatable",
    )
    compile_.add_argument(
        "--no-plugins", action="store_true", help="do not load the installed plugins"
    )
    compile_.set_defaults(run=run_compile)

    calibrate_ = commands.add_parser(
        "calibrate",
        help="measure a module's ticks per second; convert a profile between ticks and seconds",
        description="Run a module on instances of its registered problem set for a wall-time "
        "budget and report how many ticks it reports per second (the median over runs, with a "
        "95% interval of the median and the range). With --profile, write that profile with "
        "its time axis converted at the measured rate.",
    )
    calibrate_.add_argument("module", metavar="MODULE", help="the module's name")
    calibrate_.add_argument(
        "--seconds",
        type=_positive_float,
        default=1.0,
        metavar="S",
        help="wall-time budget of the measurement (1)",
    )
    calibrate_.add_argument("--seed", type=int, default=0, metavar="S", help="root seed (0)")
    calibrate_.add_argument("--profile", metavar="FILE", help="a profile file to convert")
    calibrate_.add_argument(
        "--to",
        choices=["seconds", "ticks"],
        default="seconds",
        help="the unit to convert the profile's time axis to (seconds)",
    )
    calibrate_.add_argument(
        "-o", "--output", metavar="OUT", help="where to write the converted profile"
    )
    calibrate_.add_argument("--json", action="store_true", help="print JSON")
    _library_options(calibrate_)
    calibrate_.set_defaults(run=run_calibrate, usage_error=calibrate_.error)

    check = commands.add_parser(
        "check",
        help="run the catalogue of checks every anytime module must pass",
        description="Run a module through the catalogue on instances of its registered problem "
        "set, under the work clock: it pickles by reference, every answer is a Result of "
        "quality in [0, 1], no run raises, it honours its deadlines, interrupted it keeps its "
        "best registered result, and its measured profile agrees with its declared one within "
        "sampling error. Exit status 1 when a check fails.",
    )
    check.add_argument("module", metavar="MODULE", help="the module's name")
    check.add_argument(
        "--trials", type=_positive_int, default=20, metavar="N", help="instances per cell (20)"
    )
    check.add_argument("--seed", type=int, default=0, metavar="S", help="root seed (0)")
    check.add_argument("--json", action="store_true", help="print the report as JSON")
    _library_options(check)
    check.set_defaults(run=run_check)
    return parser


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a number >= 1, got {value}")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text}")
    return value


def _library_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--profiles",
        metavar="DIR",
        action="append",
        default=[],
        help="also a directory of profile files (*.yaml), each a module; repeatable",
    )
    parser.add_argument(
        "--no-plugins", action="store_true", help="do not load the installed plugins"
    )


def open_library(args: argparse.Namespace) -> AnytimeLibrary:
    """The library the options describe; plugins that failed to load are warned about."""
    library = AnytimeLibrary.default(profile_dirs=args.profiles, plugins=not args.no_plugins)
    for problem in library.problems:
        print(f"anytime: warning: {problem}", file=sys.stderr)
    return library


def run_parse(args: argparse.Namespace) -> int:
    known = None
    if args.library or args.profiles:
        known = open_library(args).known_functions()
    schemas = load_schemas(args.file, known)
    programs = schemas.programs
    if args.schema is not None:
        if args.schema not in schemas:
            defined = ", ".join(schemas.names)
            raise InputError(
                f"{args.file}: error: no schema named '{args.schema}' (the file defines: {defined})"
            )
        programs = (schemas[args.schema],)
    if args.json:
        print(json.dumps({"schemas": [program_to_json(p) for p in programs]}, indent=2))
    elif args.dot:
        print(graph_to_dot(p.graph for p in programs), end="")
    else:
        print(format_programs(programs), end="")
    return EXIT_OK


def run_profile(args: argparse.Namespace) -> int:
    module = _runnable(args)
    request = ProfileRequest(
        trials=args.trials,
        seed=args.seed,
        workers=args.workers,
        scheduler=args.scheduler,
        clock=args.clock,
        quiet=args.quiet,
    )
    build = profile_module(module, request)
    output = Path(args.output if args.output is not None else f"{module.name}.yaml")
    try:
        save_profile(build.profile, output)
    except OSError as error:
        raise InputError(f"anytime: error: cannot write '{output}': {error.strerror}") from None
    if args.json:
        summary = {
            "module": module.name,
            "file": str(output),
            "trials": build.trials,
            "runs": build.runs,
            "failures": build.failures,
            "overruns": build.overruns,
            "seed": build.seed,
            "seconds": round(build.seconds, 3),
        }
        print(json.dumps(summary, indent=2))
    else:
        print(build.summary())
        print(f"wrote {output}")
    return EXIT_OK


def run_compile(args: argparse.Namespace) -> int:
    library = open_library(args)
    # Calls are checked against the library for the compiled schemas only (by the compiler).
    schemas = load_schemas(args.file)
    if args.schema is not None and args.schema not in schemas:
        defined = ", ".join(schemas.names)
        raise InputError(
            f"{args.file}: error: no schema named '{args.schema}' (the file defines: {defined})"
        )
    if args.output is not None and args.schema is None and len(schemas) > 1:
        raise InputError(
            f"anytime: error: {args.file} defines {len(schemas)} schemas: say which one to "
            "write with --schema NAME"
        )
    if args.time_grid is not None:
        time_grid = _parse_time_grid(args.time_grid)
    else:
        time_grid = default_time_grid(schemas, library, args.schema)
    quality = _parse_numbers(args.input_quality, "--input-quality")
    lines = Path(args.file).read_text(encoding="utf-8-sig").split("\n")
    try:
        compiled = compile_file(
            schemas,
            library,
            time_grid,
            quality,
            schema=args.schema,
            allocator=args.allocator,
            resolution=args.resolution,
            source_lines=lines,
        )
    except CompileError as error:
        message = str(error)
        prefixed = message if ": error: " in message else f"{args.file}: error: {message}"
        raise InputError(prefixed) from None
    wanted = [c for c in compiled if args.schema is None or c.name == args.schema.lower()]
    if args.time_unit is not None:
        for result in wanted:
            if result.profile.time_unit != args.time_unit:
                raise InputError(
                    f"{args.file}: error: schema '{result.name}': the time grid is in "
                    f"{args.time_unit} but its modules' profiles are in "
                    f"{result.profile.time_unit}"
                )
    if args.output is not None:
        try:
            wanted[0].save(args.output)
        except OSError as error:
            raise InputError(
                f"anytime: error: cannot write '{args.output}': {error.strerror}"
            ) from None
    if args.json:
        reports = [compiled_to_dict(c) for c in wanted]
        print(json.dumps(reports[0] if len(reports) == 1 else {"schemas": reports}, indent=2))
    else:
        print("\n".join(format_report(c) for c in wanted), end="")
        if args.output is not None:
            print(f"wrote {args.output}")
    return EXIT_OK


def _parse_numbers(text: str, option: str) -> list[float]:
    try:
        return [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise InputError(
            f"anytime: error: {option}: expected numbers separated by commas, got {text!r}"
        ) from None


def _parse_time_grid(text: str) -> list[float]:
    """START:STOP:STEP, both ends included."""
    parts = text.split(":")
    try:
        start, stop, step = (float(p) for p in parts)
    except ValueError:
        start = stop = step = math.nan
    if not (0 <= start <= stop and step > 0) or len(parts) != 3:
        raise InputError(
            "anytime: error: --time-grid: expected START:STOP:STEP with 0 <= START <= STOP "
            f"and STEP > 0, got {text!r}"
        )
    count = int(math.floor((stop - start) / step + 1e-9)) + 1
    return [start + i * step for i in range(count)]


def _runnable(args: argparse.Namespace) -> AnytimeModule:
    """The module `args.module` names, which must have code to run."""
    entry = open_library(args)[args.module]
    if entry.module is None:
        raise InputError(
            f"anytime: error: module '{entry.name}' has no code to run: it is only a profile "
            f"({entry.origin})"
        )
    return entry.module


def run_calibrate(args: argparse.Namespace) -> int:
    if (args.profile is None) != (args.output is None):
        args.usage_error("--profile FILE and -o OUT go together")
    module = _runnable(args)
    profile = None
    if args.profile is not None:  # checked before the measurement spends its seconds
        profile = load_profile(args.profile)
        if profile.time_unit == args.to:
            other = "ticks" if args.to == "seconds" else "seconds"
            raise InputError(
                f"anytime: error: {args.profile}: time_unit: the profile is already in {args.to}"
                f" (give --to {other} to convert it to {other})"
            )
        if profile.module.lower() != module.name:
            raise InputError(
                f"anytime: error: {args.profile}: module: expected '{module.name}' (the module"
                f" calibrated), got '{profile.module}'"
            )
    try:
        plan = registered_problems(module.name)
        calibration = calibrate(module, args.seconds, measurement=plan, seed=args.seed)
    except (BuildError, CalibrationError) as error:
        raise InputError(f"anytime: error: {error}") from None
    if profile is not None:
        converted = convert_profile(profile, calibration.ticks_per_second, to=args.to)
        try:
            save_profile(converted, args.output)
        except OSError as error:
            raise InputError(
                f"anytime: error: cannot write '{args.output}': {error.strerror}"
            ) from None
    if args.json:
        print(json.dumps(calibration.to_dict() | {"file": args.output}, indent=2))
    else:
        print(calibration.summary())
        if profile is not None:
            print(f"wrote {args.output} (time in {args.to})")
    return EXIT_OK


def run_check(args: argparse.Namespace) -> int:
    module = _runnable(args)
    try:
        plan = registered_problems(module.name)
        report = check_module(module, plan.problems, trials=args.trials, seed=args.seed)
    except (BuildError, CatalogueError) as error:
        raise InputError(f"anytime: error: {error}") from None
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        print(report.format())
    if report.passed:
        return EXIT_OK
    names = ", ".join(check.name for check in report.failed)
    print(
        f"anytime: error: module '{report.module}' fails {len(report.failed)} of"
        f" {len(report.checks)} checks: {names}",
        file=sys.stderr,
    )
    return EXIT_INPUT


def run_library_list(args: argparse.Namespace) -> int:
    library = open_library(args)
    errors: list[str] = []
    rows: list[dict[str, Any]] = []
    for entry in library:
        try:
            profile = entry.profile
        except ProfileError as error:
            errors.append(str(error))
            rows.append(_entry_json(entry, None) | {"profile_error": errors[-1]})
        else:
            rows.append(_entry_json(entry, profile))
    if args.json:
        print(json.dumps(rows, indent=2))
    elif not rows:
        where = ", ".join(source.name for source in library.sources)
        print(f"no modules found (looked in: {where})")
    else:
        table = [["NAME", "KIND", "INPUTS", "PROFILE", "ORIGIN"]]
        for row in rows:
            if row["profile_error"] is not None:
                summary = "unreadable (error below)"
            else:
                summary = row["profile"]["summary"] if row["profile"] else "no profile"
            inputs = ", ".join(row["inputs"]) or "-"
            table.append([row["name"], row["kind"], inputs, summary, row["origin"]])
        print(_format_table(table), end="")
    for message in errors:
        print(message, file=sys.stderr)
    return EXIT_INPUT if errors else EXIT_OK


def run_library_show(args: argparse.Namespace) -> int:
    entry = open_library(args)[args.name]
    profile = entry.profile
    if args.json:
        data = _entry_json(entry, profile, full=True)
        print(json.dumps(data, indent=2))
        return EXIT_OK
    kind = entry.kind if entry.module is not None else f"{entry.kind} (profile only)"
    if entry.module is not None:
        parameters = ", ".join(entry.parameters) or "none"
    else:
        parameters = "not known (profile only: calls are not checked for arity)"
    fields = [
        ["name:", entry.name],
        ["kind:", kind],
        ["origin:", entry.origin],
        ["parameters:", parameters],
        ["inputs:", ", ".join(entry.inputs) or "none"],
    ]
    if profile is None:
        fields.append(["profile:", "none"])
        print(_format_table(fields), end="")
        return EXIT_OK
    file = entry.profile_file
    fields.append(["profile:", str(file) if file is not None else "in memory"])
    axes = [
        [f"input quality ({name})", _numbers(grid)]
        for name, grid in zip(_axis_names(profile), profile.input_grids, strict=True)
    ]
    axes.append([f"time ({profile.time_unit})", _numbers(profile.time)])
    axes.append(["quality bins", f"{_numbers(profile.bins)} ({profile.n_bins} bins)"])
    if profile.samples is not None:
        low, high = int(profile.samples.min()), int(profile.samples.max())
        axes.append(["samples per cell", f"{low}" if low == high else f"{low} to {high}"])
    lines = [_format_table(fields) + "axes:", *_format_table(axes, indent=2).splitlines(), ""]
    lines.extend(_expected_table(profile))
    print("\n".join(lines))
    return EXIT_OK


def profile_summary(profile: ConditionalPerformanceProfile) -> str:
    """One line: '3 input grid pts x 4 times x 4 bins, ticks'."""
    parts = []
    if profile.n_inputs:
        sizes = "x".join(str(len(grid)) for grid in profile.input_grids)
        parts.append(f"{sizes} input grid pts")
    parts.append(f"{len(profile.time)} times")
    parts.append(f"{profile.n_bins} bins")
    measured = ", measured" if profile.samples is not None else ""
    return f"{' x '.join(parts)}, {profile.time_unit}{measured}"


def _entry_json(
    entry: LibraryEntry, profile: ConditionalPerformanceProfile | None, full: bool = False
) -> dict[str, Any]:
    data: dict[str, Any] = {"name": entry.name, "kind": entry.kind, "inputs": list(entry.inputs)}
    if full:
        data["parameters"] = list(entry.parameters)
    data["arity"] = entry.arity
    data["origin"] = entry.origin
    data["profile"] = None
    data["profile_error"] = None
    if profile is None:
        return data
    file = entry.profile_file
    summary: dict[str, Any] = {
        "summary": profile_summary(profile),
        "file": None if file is None else str(file),
        "input_grid_points": [len(grid) for grid in profile.input_grids],
        "times": len(profile.time),
        "bins": profile.n_bins,
        "time_unit": profile.time_unit,
        "measured": profile.samples is not None,
    }
    if full:
        summary["input_grids"] = [grid.tolist() for grid in profile.input_grids]
        summary["time"] = profile.time.tolist()
        summary["quality_bins"] = profile.bins.tolist()
        summary["expected"] = _expected_cells(profile).tolist()
    data["profile"] = summary
    return data


def _expected_cells(profile: ConditionalPerformanceProfile) -> np.ndarray[Any, Any]:
    """Expected quality at every grid cell, shape `profile.cell_shape`."""
    mesh = np.meshgrid(*profile.input_grids, profile.time, indexing="ij")
    q = np.stack(mesh[:-1], axis=-1) if profile.n_inputs else np.zeros((*mesh[-1].shape, 0))
    return np.round(profile.expected(q, mesh[-1]), 12)


def _axis_names(profile: ConditionalPerformanceProfile) -> list[str]:
    if profile.inputs:
        return list(profile.inputs)
    return [f"#{i + 1}" for i in range(profile.n_inputs)]


#: At most this many time columns in `library show`.
SHOWN_TIMES = 6


def _expected_table(profile: ConditionalPerformanceProfile) -> list[str]:
    """Expected quality: rows are input-quality grid points, columns a handful of times."""
    n_times = len(profile.time)
    columns = np.unique(np.round(np.linspace(0, n_times - 1, min(n_times, SHOWN_TIMES))))
    columns = columns.astype(int)
    table = _expected_cells(profile)
    names = _axis_names(profile)
    unit = profile.time_unit
    if profile.n_inputs == 0:
        title = f"expected quality by time ({unit}):"
        rows = [["time", *(f"{profile.time[c]:g}" for c in columns)]]
        rows.append(["quality", *(f"{table[c]:.3f}" for c in columns)])
        return [title, *_format_table(rows, indent=2).splitlines()]
    sizes = {len(grid) for grid in profile.input_grids}
    if profile.n_inputs == 1 or len(sizes) == 1:
        points = range(len(profile.input_grids[0]))
        index = [tuple([i] * profile.n_inputs) for i in points]
        labels = [", ".join(f"{g[i]:g}" for g in profile.input_grids) for i in points]
        note = "" if profile.n_inputs == 1 else "; the diagonal: every input at its i-th grid pt"
    else:
        top = [len(grid) - 1 for grid in profile.input_grids[1:]]
        index = [(i, *top) for i in range(len(profile.input_grids[0]))]
        labels = [f"{profile.input_grids[0][i]:g}" for i in range(len(profile.input_grids[0]))]
        rest = ", ".join(
            f"{name}={grid[-1]:g}"
            for name, grid in zip(names[1:], profile.input_grids[1:], strict=True)
        )
        note = f"; other inputs at their highest grid pt ({rest})"
        names = names[:1]
    title = f"expected quality (rows: {', '.join(names)} quality; columns: time in {unit}{note}):"
    rows = [[f"{', '.join(names)} \\ time", *(f"{profile.time[c]:g}" for c in columns)]]
    for label, cell in zip(labels, index, strict=True):
        rows.append([label, *(f"{table[(*cell, c)]:.3f}" for c in columns)])
    return [title, *_format_table(rows, indent=2).splitlines()]


def _numbers(values: np.ndarray[Any, Any]) -> str:
    return ", ".join(f"{v:g}" for v in values)


def _format_table(rows: Sequence[Sequence[str]], indent: int = 0) -> str:
    """Left-aligned columns two spaces apart; trailing spaces trimmed."""
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = []
    for row in rows:
        cells = [cell.ljust(width) for cell, width in zip(row, widths, strict=True)]
        lines.append((" " * indent + "  ".join(cells)).rstrip() + "\n")
    return "".join(lines)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
