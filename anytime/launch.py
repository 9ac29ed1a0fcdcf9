"""The `anytime` command's entry point: a Ctrl-C while the framework and its plugins are still
being imported (most of a second) ends like one during a command, with one line and status 130,
not a traceback. Importing this module imports nothing else of the framework."""

from __future__ import annotations

import sys

#: Ctrl-C: the shell's status for a process ended by SIGINT (128 + 2).
EXIT_INTERRUPTED = 130


def main() -> int:
    try:
        from anytime.cli import main as run
    except KeyboardInterrupt:
        print("anytime: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return run()
