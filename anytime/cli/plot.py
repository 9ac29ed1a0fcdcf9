"""`anytime plot`: a profile, a compiled program or a schema as a figure (PNG by default).

- A profile file (`anytime-profile/1`): its performance profile, or its conditional profile as
  one curve per input quality (the papers' Figures 4, 5, 7, 9).
- A compiled program written by `anytime compile -o` (a profile file that also carries
  `modules` and `allocation`): its expected quality against total time, with the baselines and
  a best-of's dependence band the file holds (as a schema's), over the allocation of that time
  among its modules.
- A schema file (`.any`): the schema is compiled as `anytime compile` does, and drawn against
  equal split, MIN and MAX (Figures 8, 10), over its allocation.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from anytime.cli.common import (
    EXIT_OK,
    InputError,
    library_options,
    open_library,
    refuse_overwriting_inputs,
)
from anytime.cli.schemas import (
    check_schema_name,
    check_time_unit,
    compile_options,
    compile_schemas,
)
from anytime.compiler.storage import stored_curves
from anytime.dsl import load_schemas
from anytime.plot import (
    MissingMatplotlibError,
    PlotError,
    plot_allocation,
    plot_compiled,
    plot_profile,
    require_matplotlib,
)
from anytime.profiles.io import read_profile_file
from anytime.profiles.profile import Array, ConditionalPerformanceProfile

#: Suffix of schema files; anything else is read as a profile file.
SCHEMA_SUFFIX = ".any"


def add_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    plot = commands.add_parser(
        "plot",
        help="draw a profile, a compiled program or a compiled schema as a figure",
        description="Draw a figure (needs matplotlib: pip install 'anytime-compose[plot]'). "
        "FILE is a profile file (its expected quality against time, one curve per input "
        "quality), a compiled program written by `anytime compile -o` (its expected quality "
        "and its time allocation per module), or a schema file (.any), compiled as `anytime "
        "compile` does; a compiled program is drawn against the baselines equal split, MIN and "
        "MAX and, with a best-of, the band its expected quality spans if the alternatives "
        "depend on each other.",
    )
    plot.add_argument("file", metavar="FILE", help="a profile file (.yaml) or a schema file (.any)")
    plot.add_argument(
        "-o",
        "--output",
        metavar="OUT.png",
        help="the image to write; its suffix names the format (default: FILE's name with .png,"
        " in the current directory)",
    )
    plot.add_argument("--title", metavar="T", help="the figure's title (default: a description)")
    schema = plot.add_argument_group(
        "schema files (.any), compiled as `anytime compile` compiles them"
    )
    schema.add_argument("--schema", metavar="NAME", help="the schema to compile and draw")
    compile_options(schema)
    library_options(schema)
    plot.set_defaults(run=run_plot)


#: The options only a schema file takes, and their defaults (given otherwise: an error).
SCHEMA_ONLY = {
    "schema": None,
    "time_grid": None,
    "resolution": None,
    "allocator": "auto",
    "time_unit": None,
    "strict": False,
}


def run_plot(args: argparse.Namespace) -> int:
    source = Path(args.file)
    # Here, not next to FILE: a shipped profile lives in the installed package.
    output = Path(args.output) if args.output is not None else Path(source.stem + ".png")
    refuse_overwriting_inputs(output, source)
    try:
        require_matplotlib()  # before any work
        if source.suffix.lower() == SCHEMA_SUFFIX:
            _plot_schema(args, output)
        else:
            for option, default in SCHEMA_ONLY.items():
                if getattr(args, option) != default:
                    flag = "--" + option.replace("_", "-")
                    raise InputError(
                        f"{flag} is for schema files ({SCHEMA_SUFFIX}), and "
                        f"{args.file} is read as a profile file"
                    )
            _plot_profile_file(args.file, output, args.title)
    except (MissingMatplotlibError, PlotError) as error:
        raise InputError(str(error)) from None
    except OSError as error:
        if Path(error.filename or "") == output or error.filename is None:
            raise InputError(f"cannot write '{output}': {error.strerror or error}") from None
        raise
    print(f"wrote {output}")
    return EXIT_OK


def _plot_profile_file(filename: str, output: Path, title: str | None) -> None:
    profile, fields = read_profile_file(filename)
    table = _allocation_table(filename, profile, fields)
    if table is None:
        plot_profile(profile, output, title=title)
    else:
        modules, allocation = table
        baselines, dependence = stored_curves(filename, profile, fields)
        plot_allocation(
            profile,
            modules,
            allocation,
            output,
            baselines=baselines or None,
            title=title,
            dependence=dependence,
        )


def _plot_schema(args: argparse.Namespace, output: Path) -> None:
    library = open_library(args)
    schemas = load_schemas(args.file)
    if args.schema is None:
        if len(schemas) > 1:
            raise InputError(
                f"{args.file} defines {len(schemas)} schemas: say which one "
                f"to draw with --schema NAME (one of {', '.join(schemas.names)})"
            )
        name = schemas.names[0]
    else:
        check_schema_name(schemas, args.schema)
        name = args.schema.lower()
    compiled = compile_schemas(
        schemas,
        library,
        args.time_grid,
        schema=name,
        allocator=args.allocator,
        input_quality=args.input_quality,
        resolution=args.resolution,
        memory=args.memory,
        strict=args.strict,
    )
    wanted = next(c for c in compiled if c.name == name)
    check_time_unit([wanted], args.time_unit, args.file)
    plot_compiled(wanted, output, title=args.title)


def _allocation_table(
    filename: str, profile: ConditionalPerformanceProfile, data: Mapping[Any, Any]
) -> tuple[Sequence[str], Array] | None:
    """A compiled program's `modules` and `allocation` fields (of the file's mapping `data`),
    checked against its profile; None for a plain profile. (`read_profile_file` has read the
    file through the one safe loader and validated the rest of it.)"""
    if "allocation" not in data and "modules" not in data:
        return None
    for field in ("modules", "allocation"):
        if field not in data:
            other = "allocation" if field == "modules" else "modules"
            _fail(filename, field, f"missing field (a compiled program has it with {other})")
    modules = data["modules"]
    if not isinstance(modules, list) or not all(isinstance(m, str) and m for m in modules):
        _fail(filename, "modules", f"expected a list of module names, got {modules!r}")
    expected = (*profile.cell_shape, len(modules))
    try:
        allocation = np.asarray(data["allocation"], dtype=np.float64)
    except (TypeError, ValueError):
        allocation = None
    if allocation is None or allocation.shape != expected:
        got = "a ragged or non-numeric table" if allocation is None else list(allocation.shape)
        _fail(
            filename,
            "allocation",
            f"expected a table of shape {list(expected)} (input grids, time, one per module), "
            f"got {got}",
        )
    if not np.all(np.isfinite(allocation)) or np.any(allocation < 0):
        _fail(filename, "allocation", "expected finite times >= 0")
    return modules, allocation


def _fail(filename: str, field: str, problem: str) -> NoReturn:
    raise InputError(f"{os.fspath(filename)}: {field}: {problem}")
