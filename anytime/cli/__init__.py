"""The `anytime` command.

Exit codes: 0 success, 1 bad input (a message naming the file and place, never a traceback),
2 usage errors (argparse's own). Each group of subcommands lives in its own module.

Plugins add subcommands of their own: a `Plugin` (see `anytime.plugin`) with `add_commands`
set receives a `CommandGroup` and adds each command with `add_command(name, help=..., run=...)`.
Their errors are handled like the framework's: an `AnytimeError` (`InputError` for what the
command checks itself) is a one-line message and exit 1, a `UsageError` exit 2. A plugin whose
commands fail to load is warned about on stderr and the other commands still work.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from anytime import __version__
from anytime.cli import library, measure, plot, schemas
from anytime.cli.common import EXIT_INPUT, EXIT_OK, EXIT_USAGE, InputError, UsageError
from anytime.errors import AnytimeError
from anytime.library import LibraryError, load_plugins

__all__ = ["InputError", "UsageError", "build_parser", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    run: Callable[[argparse.Namespace], int] = args.run
    try:
        return run(args)
    except UsageError as error:
        print(error, file=sys.stderr)
        return EXIT_USAGE
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
    for group in (schemas, library, measure, plot):
        group.add_commands(commands)
    plugins, _ = load_plugins()  # a plugin that fails to load is reported by the library
    for plugin in plugins:
        if plugin.add_commands is None:
            continue
        try:
            plugin.add_commands(_Commands(commands))
        except Exception as error:  # one plugin's failure must not break the command line
            print(
                f"anytime: warning: commands of plugin '{plugin.name}' not loaded:"
                f" {type(error).__name__}: {error}",
                file=sys.stderr,
            )
    return parser


class _Commands:
    """The `CommandGroup` a plugin's `add_commands` receives: argparse's subparsers, behind the
    public protocol."""

    def __init__(self, commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
        self._commands = commands

    def add_command(
        self,
        name: str,
        *,
        help: str,
        run: Callable[[argparse.Namespace], int],
        description: str | None = None,
    ) -> argparse.ArgumentParser:
        parser = self._commands.add_parser(name, help=help, description=description)
        parser.set_defaults(run=run, usage_error=parser.error)
        return parser
