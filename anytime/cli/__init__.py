"""The `anytime` command.

Exit codes: 0 success, 1 bad input (a message naming the file and place, never a traceback),
2 usage errors (argparse's own). Each group of subcommands lives in its own module.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from anytime import __version__
from anytime.cli import library, measure, schemas
from anytime.cli.common import EXIT_INPUT, EXIT_OK, EXIT_USAGE, InputError
from anytime.errors import AnytimeError
from anytime.library import LibraryError

__all__ = ["InputError", "build_parser", "main"]


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
    for group in (schemas, library, measure):
        group.add_commands(commands)
    return parser
