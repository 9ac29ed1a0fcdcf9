"""The `anytime` command.

Exit codes: 0 success, 1 bad input (a message naming the file and place, never a traceback),
2 usage errors (one line, argparse's own included), 130 interrupted (Ctrl-C), 143 terminated
(SIGTERM, handled like Ctrl-C). Each group of subcommands lives in its own module.

Plugins add subcommands of their own: a `Plugin` (see `anytime.plugin`) with `add_commands`
set receives a `CommandGroup` and adds each command with `add_command(name, help=..., run=...)`.
Their errors are handled like the framework's: an `AnytimeError` (`InputError` for what the
command checks itself) is a one-line message and exit 1, a `UsageError` exit 2; the message is
given without a prefix, which `describe` adds. A plugin whose commands fail to load is warned
about on stderr and the other commands still work.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import threading
import warnings
from collections.abc import Callable, Sequence
from typing import NoReturn, TextIO

from anytime import __version__
from anytime.cli import library, measure, plot, schemas, verify
from anytime.cli.common import (
    EXIT_INPUT,
    EXIT_OK,
    EXIT_USAGE,
    UNLOADED_PLUGINS,
    InputError,
    UsageError,
)
from anytime.errors import AnytimeError, SchemaError, interrupt_behind
from anytime.launch import interrupted, sigterm_interrupts
from anytime.library import Plugin, PluginSource, discover_plugins
from anytime.text import did_you_mean

__all__ = ["InputError", "UsageError", "build_parser", "describe", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command `argv` (default: the process's arguments) and return its exit status.

    The one place errors are turned into messages (`describe`): whatever a command (a plugin's
    too) raises ends as one line on standard error (a schema error adds its source line and a
    caret), never a traceback. Ctrl-C ends any command with `anytime: interrupted` and status
    130, SIGTERM likewise with `anytime: terminated` and 143; the files it writes are written
    atomically, so it leaves no half-written output. Usage errors (argparse's and `UsageError`)
    exit 2.
    """
    with sigterm_interrupts(), warnings.catch_warnings():
        warnings.showwarning = _warning_line
        return _main(argv)


def _warning_line(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """A warning as one line, as the commands' own warnings are (no file, line or source)."""
    print(f"anytime: warning: {message}", file=sys.stderr)


def _main(argv: Sequence[str] | None) -> int:
    command: str | None = None
    try:
        parser = build_parser(plugins=_wants_plugins(sys.argv[1:] if argv is None else argv))
        args = parser.parse_args(argv)
        command = args.command
        if command is None:
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        run: Callable[[argparse.Namespace], int] = args.run
        code = run(args)
        sys.stdout.flush()  # an error writing the output is reported here, not at exit
        return code
    except KeyboardInterrupt as interrupt:
        return interrupted(interrupt)
    except BrokenPipeError:  # the reader went away, e.g. `anytime parse f | head -1`
        _drop_stdout()
        return EXIT_OK
    except Exception as error:
        behind = interrupt_behind(error)
        if behind is not None:
            return interrupted(behind)
        internal = not isinstance(error, AnytimeError | OSError | MemoryError)
        if internal and os.environ.get("ANYTIME_TRACEBACK"):
            raise
        if isinstance(error, OSError) and error.filename is None:
            _drop_stdout()  # writing standard output failed: a full disk, a closed terminal
        print(describe(error, command), file=sys.stderr)
        return EXIT_USAGE if isinstance(error, UsageError) else EXIT_INPUT


def describe(error: Exception, command: str | None = None) -> str:
    """The message `main` prints for `error`, raised by the command `command`:

    - a schema error: its diagnostics, `FILE:LINE:COL: error: MESSAGE` with the source line
      and a caret under the place;
    - a usage error: `anytime COMMAND: error: MESSAGE`, as argparse's own;
    - an error about a file (`AnytimeError.where`): `WHERE: error: MESSAGE`;
    - any other error of the tree, or a file that cannot be read or written:
      `anytime: error: MESSAGE`;
    - anything else is a bug: `anytime: internal error: TYPE: FIRST LINE (...)`.
    """
    if isinstance(error, SchemaError):
        return str(error)
    if isinstance(error, UsageError):
        return f"anytime{f' {command}' if command else ''}: error: {error}"
    if isinstance(error, AnytimeError):
        return f"{error.where or 'anytime'}: error: {error}"
    if isinstance(error, OSError):
        if error.filename is None:
            return f"anytime: error: cannot write the output: {error.strerror or error}"
        return f"anytime: error: cannot read '{error.filename}': {error.strerror or error}"
    if isinstance(error, MemoryError):
        return "anytime: error: out of memory"
    head = (str(error).splitlines() or [""])[0]
    return (
        f"anytime: internal error: {type(error).__name__}: {head} (a bug; please report it;"
        " ANYTIME_TRACEBACK=1 shows the traceback)"
    )


def _drop_stdout() -> None:
    """Point standard output at the null device, so that flushing it again when Python exits
    cannot fail a second time (with 'Exception ignored ... BrokenPipeError')."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # not a real file (captured in tests)
        return
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, fd)
    os.close(null)


class _Parser(argparse.ArgumentParser):
    """argparse's parser, whose usage errors are one line: `anytime CMD: error: MESSAGE`,
    exit status 2 (`anytime CMD --help` has the usage)."""

    def error(self, message: str) -> NoReturn:
        # A mistyped command or choice: name the nearest one (argparse 3.11 lists them all).
        wrong = _INVALID_CHOICE.match(message)
        if wrong is not None:
            choices = re.findall(r"'([^']*)'", wrong["choices"])
            hint = did_you_mean(wrong["given"], choices)
            if hint:
                message = f"{wrong['argument']}: invalid choice: '{wrong['given']}'{hint}"
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


#: argparse's message for a value that is not one of the choices.
_INVALID_CHOICE = re.compile(
    r"^(?P<argument>argument [^:]+): invalid choice: '(?P<given>[^']*)' \(choose from"
    r" (?P<choices>.*)\)$"
)


#: Seconds the command waits for the installed plugins to import (to add their commands) before
#: it goes on without the rest: a plugin that hangs at import must not hang `--help`.
PLUGIN_SECONDS = 10.0


def _wants_plugins(argv: Sequence[str]) -> bool:
    """False when `--no-plugins` is among the options (before a `--`): then no plugin is
    imported at all, its commands neither."""
    for arg in argv:
        if arg == "--":
            return True
        if arg == "--no-plugins":
            return False
    return True


def _installed_plugins() -> tuple[Plugin, ...]:
    """The installed plugins that import within `PLUGIN_SECONDS`, in a thread the command
    waits for: one still importing then is warned about by name and left to go on (a command
    that reads the library leaves it and those after it out, `UNLOADED_PLUGINS`).
    A plugin that fails to import is reported by the library that loads it (`open_library`)."""
    UNLOADED_PLUGINS.clear()
    found = discover_plugins()
    done: list[tuple[Plugin, ...]] = []  # what each entry point imported so far gave

    def load() -> None:
        for entry_point in found:
            done.append(PluginSource([entry_point]).load().plugins)

    thread = threading.Thread(target=load, name="anytime:plugins", daemon=True)
    thread.start()
    thread.join(PLUGIN_SECONDS)
    imported = list(done)  # the thread may go on: what had come by now
    if thread.is_alive():
        late = found[len(imported) :]
        UNLOADED_PLUGINS.update(entry_point.name for entry_point in late)
        if late:
            print(
                f"anytime: warning: plugin '{late[0].name}' ({late[0].value}) did not finish"
                f" importing in {PLUGIN_SECONDS:g} s: it and the plugins after it are left out"
                " (--no-plugins runs without plugins)",
                file=sys.stderr,
            )
    return tuple(plugin for plugins in imported for plugin in plugins)


def build_parser(plugins: bool = True) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = _Parser(  # its subcommands are _Parsers too
        prog="anytime",
        description="Compose anytime algorithms: write program schemas, compile them into "
        "contract algorithms with optimal time allocation, run them under a monitor.",
    )
    parser.add_argument("--version", action="version", version=f"anytime {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    for group in (schemas, verify, library, measure, plot):
        group.add_commands(commands)
    for plugin in _installed_plugins() if plugins else ():
        if plugin.add_commands is None:
            continue
        try:
            plugin.add_commands(_Commands(commands))
        except (Exception, SystemExit) as error:  # one plugin's must not break the command
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
