"""What every subcommand shares: exit codes, the input error, option types, the library."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from anytime.compiler.report import allocation_json as allocation_json  # re-exported
from anytime.errors import InputError as InputError  # defined with the other errors: re-exported
from anytime.errors import UsageError as UsageError
from anytime.isolation import ISOLATIONS, WATCHDOG
from anytime.launch import EXIT_INTERRUPTED as EXIT_INTERRUPTED  # re-exported
from anytime.library import (
    AnytimeLibrary,
    PluginSource,
    ProfileDirectory,
    RegistrySource,
    discover_plugins,
)
from anytime.runtime.modes import SOFT, Isolated, RunMode

EXIT_OK, EXIT_INPUT, EXIT_USAGE = 0, 1, 2


def _whole_at_least(text: str, least: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"expected a number >= {least}, got {value}")
    return value


def positive_int(text: str) -> int:
    return _whole_at_least(text, 1)


def non_negative_int(text: str) -> int:
    """A whole number >= 0 (a count where 0 means 'all' or 'none')."""
    return _whole_at_least(text, 0)


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


# --- option types with limits: every number checked when it is parsed (argparse's exit 2) ----

#: The largest seed (numpy's generators take any integer >= 0; a 64-bit one is plenty).
MAX_SEED = 2**64 - 1
#: The most instances per cell `anytime profile` and `anytime check` run (their tables grow
#: with it; the defaults are 100 and 20).
MAX_TRIALS = 100_000
#: The most local worker processes.
MAX_WORKERS = 256
#: The most totals a --time-grid may have (the default grid has about 20).
MAX_TIME_POINTS = 10_000
#: The most multiples of the resolution up to the largest total (the lattice allocations are
#: on; the compiler's tables grow with it: 20,000 points take about 250 MB for navigation.any).
MAX_LATTICE_POINTS = 20_000
#: The most program input qualities in --input-quality (a grid for each quality input).
MAX_QUALITY_POINTS = 101
#: The longest --watchdog (seconds): a day.
MAX_WATCHDOG = 86_400.0


def _whole(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def int_in_range(minimum: int, maximum: int) -> Callable[[str], int]:
    """An option type: a whole number from `minimum` to `maximum` (both included)."""

    def parse(text: str) -> int:
        value = _whole(text)
        if not minimum <= value <= maximum:
            raise argparse.ArgumentTypeError(
                f"expected a whole number from {minimum} to {maximum}, got {text}"
            )
        return value

    parse.__name__ = "whole number"  # argparse's name for the type in its own messages
    return parse


def float_in_range(minimum: float, maximum: float) -> Callable[[str], float]:
    """An option type: a finite number > `minimum` and <= `maximum`."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not minimum < value <= maximum:
            raise argparse.ArgumentTypeError(
                f"expected a number > {minimum:g} and <= {maximum:g}, got {text}"
            )
        return value

    parse.__name__ = "number"
    return parse


def random_seed(text: str) -> int:
    """An option type: a random seed, a whole number from 0 to `MAX_SEED`."""
    value = _whole(text)
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(
            f"expected a whole number >= 0 (at most 2**64 - 1), got {text}"
        )
    return value


#: Option types: instances per cell, local worker processes.
trial_count = int_in_range(1, MAX_TRIALS)
worker_count = int_in_range(1, MAX_WORKERS)


def time_grid(text: str) -> tuple[float, ...]:
    """An option type: START:STOP:STEP, both ends included, at most `MAX_TIME_POINTS` totals."""
    parts = text.split(":")
    try:
        start, stop, step = (float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected START:STOP:STEP (three numbers), got {text!r}"
        ) from None
    if not all(math.isfinite(x) for x in (start, stop, step)):
        raise argparse.ArgumentTypeError(f"expected finite numbers, got {text!r}")
    if not (0 <= start <= stop and step > 0):
        raise argparse.ArgumentTypeError(
            f"expected START:STOP:STEP with 0 <= START <= STOP and STEP > 0, got {text!r}"
        )
    ratio = (stop - start) / step + 1e-9  # inf for a step too small to divide by
    if ratio >= MAX_TIME_POINTS:
        many = f"{math.floor(ratio) + 1:,}" if math.isfinite(ratio) else "infinitely many"
        raise argparse.ArgumentTypeError(
            f"{text!r} has {many} totals, more than the limit of {MAX_TIME_POINTS:,}: give a "
            "larger STEP"
        )
    return tuple(start + i * step for i in range(math.floor(ratio) + 1))


def quality_list(text: str) -> tuple[float, ...]:
    """An option type: Q,Q,... input qualities in [0, 1], at most `MAX_QUALITY_POINTS`."""
    try:
        values = tuple(float(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas, got {text!r}"
        ) from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one quality")
    if not all(0 <= q <= 1 for q in values):  # NaN fails too
        raise argparse.ArgumentTypeError(f"expected qualities from 0 to 1, got {text!r}")
    if len(values) > MAX_QUALITY_POINTS:
        raise argparse.ArgumentTypeError(
            f"{len(values)} qualities, more than the limit of {MAX_QUALITY_POINTS}"
        )
    return values


def check_lattice(grid: Sequence[float], resolution: float | None) -> None:
    """A usage error when the allocations' lattice (the multiples of the resolution up to the
    largest total) would have more than `MAX_LATTICE_POINTS` points, or none but 0 (a
    resolution larger than the largest total)."""
    if not grid:
        return
    steps = [b - a for a, b in zip(grid, grid[1:], strict=False) if b > a]
    dt = resolution if resolution is not None else (min(steps) if steps else grid[0] or 1.0)
    if resolution is not None and resolution > max(grid) > 0:
        # no allocation but zero fits under the largest total: every module would get nothing
        raise UsageError(
            f"--resolution {resolution:g}: larger than the largest total of the time grid,"
            f" {max(grid):g}, so every allocation would be 0; give at most {max(grid):g}"
        )
    points = max(grid) / dt + 1
    if points > MAX_LATTICE_POINTS:
        many = f"{points:,.0f}" if points < 1e15 else f"{points:.2g}"
        many = many if math.isfinite(points) else "infinitely many"
        if resolution is not None:
            cause, fix = f"--resolution {resolution:g}", "a larger --resolution"
        else:
            cause, fix = f"the time grid's step {dt:g}", "--resolution DT or a coarser --time-grid"
        raise UsageError(
            f"{cause}: allocations on its multiples up to"
            f" {max(grid):g} make a lattice of {many} points, more than the limit of"
            f" {MAX_LATTICE_POINTS:,}; give {fix}"
        )


def refuse_overwriting_inputs(
    output: str | os.PathLike[str] | None, *inputs: str | os.PathLike[str] | None
) -> None:
    """An output file that is one of the command's input files (the same path, or the same file
    by another path) is refused before any work: `-o schema.any` would replace the schema with
    the compiled profile."""
    if output is None:
        return
    for given in inputs:
        if given is not None and _same_file(Path(output), Path(given)):
            raise InputError(
                f"the output '{output}' is an input of this command; give another file"
            )


def refuse_overwriting_profiles(
    output: str | os.PathLike[str] | None, library: AnytimeLibrary
) -> None:
    """An output file that is the profile file of a module of the library the command reads is
    refused before any work: `compile -o profiles/plan.yaml` would replace that module's
    measured profile with the compiled program."""
    if output is None:
        return
    for entry in library:
        if entry.profile_file is not None and _same_file(Path(output), entry.profile_file):
            raise InputError(
                f"the output '{output}' is the profile file of module '{entry.name}', an input"
                " of this command; give another file"
            )


def refuse_colliding_outputs(outputs: Mapping[str, str | os.PathLike[str] | None]) -> None:
    """Two outputs of one command (named by what they are) that are the same file are refused
    before any work: the one written last would replace the other."""
    seen: list[tuple[str, Path]] = []
    for what, given in outputs.items():
        if given is None:
            continue
        for other, path in seen:
            if _same_file(Path(given), path):
                raise InputError(f"{what} '{given}' is also {other}; give another file")
        seen.append((what, Path(given)))


def _same_file(one: Path, other: Path) -> bool:
    """The same path once resolved (symbolic links, `.`), or the same existing file (a hard
    link, another mount)."""
    if one.resolve() == other.resolve():
        return True
    with contextlib.suppress(OSError):
        return one.exists() and other.exists() and one.samefile(other)
    return False


def library_options(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """`--profiles DIR` (repeatable) and `--no-plugins`: the options of every command that reads
    the anytime library (`args.profiles`, `args.no_plugins`, as `open_library` reads them)."""
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


def worker_options(parser: argparse.ArgumentParser, what: str) -> None:
    """--workers N or --scheduler ADDRESS (one of them); `what` the work, as "run the trials"."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=worker_count,
        default=1,
        metavar="N",
        help=f"local processes (1; at most {MAX_WORKERS})",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help=f"{what} on a Dask cluster (needs the 'dask' extra)",
    )


def isolation_options(
    parser: argparse.ArgumentParser, what: str, crash: str = "", bound: str = ""
) -> None:
    """--isolation and --watchdog: how every `what` (a trial, a run) is run; `run_mode`
    makes them the one run mode the functions below the command line take. `crash`: what
    becomes of a `what` that crashes or hangs (default: it fails alone); `bound`: what else
    bounds the watchdog, if anything."""
    crash = crash or f"a {what} that crashes or hangs fails alone"
    parser.add_argument(
        "--isolation",
        choices=ISOLATIONS,
        default="process",
        help=f"run every {what} in a child process of its own (process, the default: {crash})"
        " or in this one (none: faster)",
    )
    parser.add_argument(
        "--watchdog",
        type=float_in_range(0.001, MAX_WATCHDOG),
        default=WATCHDOG,
        metavar="SECONDS",
        help=f"wall-clock seconds an isolated {what} may take before it counts as failed"
        f" ({WATCHDOG:g}{bound})",
    )


def run_mode(args: argparse.Namespace) -> RunMode:
    """The run mode of --isolation and --watchdog (see `isolation_options`):
    `Isolated(watchdog=...)` for process, `SOFT` for none."""
    if args.isolation == "process":
        return Isolated(watchdog=args.watchdog)
    return SOFT


#: The installed plugins (entry-point names) that had not imported when the command line
#: stopped waiting for them (see `anytime.cli.PLUGIN_SECONDS`): the library leaves them out.
UNLOADED_PLUGINS: set[str] = set()


def open_library(args: argparse.Namespace) -> AnytimeLibrary:
    """The library the options describe; plugins that failed to load are warned about, and
    those that had not imported in time (`UNLOADED_PLUGINS`, warned about then) are left out:
    importing one again here would wait for it."""
    if args.no_plugins or not UNLOADED_PLUGINS:
        library = AnytimeLibrary.default(profile_dirs=args.profiles, plugins=not args.no_plugins)
    else:
        registered = RegistrySource()  # the process-wide registry, as `default` takes it
        found = [ep for ep in discover_plugins() if ep.name not in UNLOADED_PLUGINS]
        library = AnytimeLibrary(
            [
                PluginSource(found, registry=registered.registry),
                registered,
                *(ProfileDirectory(path) for path in args.profiles),
            ]
        )
    for problem in library.problems:
        print(f"anytime: warning: {problem}", file=sys.stderr)
    return library


def json_text(data: Any, *, indent: int | None = 2) -> str:
    """`data` as JSON that any parser reads: JSON has no NaN or Infinity, so a float that is
    not finite is written as null. Values must be plain (numpy scalars are a bug where they are
    made, and raise TypeError here)."""
    return json.dumps(_finite(data), indent=indent, allow_nan=False)


def _finite(data: Any) -> Any:
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {key: _finite(value) for key, value in data.items()}
    if isinstance(data, list | tuple):
        return [_finite(value) for value in data]
    return data


def format_table(rows: Sequence[Sequence[str]], indent: int = 0) -> str:
    """Left-aligned columns two spaces apart; trailing spaces trimmed."""
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = []
    for row in rows:
        cells = [cell.ljust(width) for cell, width in zip(row, widths, strict=True)]
        lines.append((" " * indent + "  ".join(cells)).rstrip() + "\n")
    return "".join(lines)
