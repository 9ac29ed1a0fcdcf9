"""What every subcommand shares: exit codes, the input error, option types, the library."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence

from anytime.errors import AnytimeError
from anytime.library import AnytimeLibrary

EXIT_OK, EXIT_INPUT, EXIT_USAGE = 0, 1, 2
#: Ctrl-C: the shell's status for a process ended by SIGINT (128 + 2).
EXIT_INTERRUPTED = 130


class InputError(AnytimeError):
    """Bad input found by the command itself; the message is printed as it is."""


class UsageError(InputError):
    """Options that do not go together, found after parsing (argparse cannot check them):
    printed as it is, exit status 2 like argparse's own usage errors."""


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a number >= 1, got {value}")
    return value


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text}")
    return value


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


def open_library(args: argparse.Namespace) -> AnytimeLibrary:
    """The library the options describe; plugins that failed to load are warned about."""
    library = AnytimeLibrary.default(profile_dirs=args.profiles, plugins=not args.no_plugins)
    for problem in library.problems:
        print(f"anytime: warning: {problem}", file=sys.stderr)
    return library


def format_table(rows: Sequence[Sequence[str]], indent: int = 0) -> str:
    """Left-aligned columns two spaces apart; trailing spaces trimmed."""
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = []
    for row in rows:
        cells = [cell.ljust(width) for cell, width in zip(row, widths, strict=True)]
        lines.append((" " * indent + "  ".join(cells)).rstrip() + "\n")
    return "".join(lines)
