"""The `anytime` command's entry point: a Ctrl-C while the framework and its plugins are still
being imported (most of a second) ends like one during a command, with one line and status 130,
not a traceback. Importing this module imports nothing else of the framework.

SIGTERM (what `timeout`, systemd and CI runners send) is handled like Ctrl-C: it raises
`Terminated`, a `KeyboardInterrupt`, in the main thread, so every clean-up an interrupt runs
(worker processes stopped, temporary files removed) runs for it too; the command then ends with
`anytime: terminated` and status 143."""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

#: Ctrl-C: the shell's status for a process ended by SIGINT (128 + 2).
EXIT_INTERRUPTED = 130
#: The shell's status for a process ended by SIGTERM (128 + 15).
EXIT_TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """The process was sent SIGTERM (raised by the handler `sigterm_interrupts` installs)."""


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise Terminated


@contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """While the block runs, SIGTERM raises `Terminated` in the main thread (elsewhere, where
    Python cannot install handlers, it does nothing). The earlier handler is put back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    earlier = signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, earlier)


def interrupted(interrupt: KeyboardInterrupt) -> int:
    """Say why the command stops, on stderr, and return its exit status."""
    if isinstance(interrupt, Terminated) or isinstance(interrupt.__cause__, Terminated):
        print("anytime: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    print("anytime: interrupted", file=sys.stderr)
    return EXIT_INTERRUPTED


def main() -> int:
    with sigterm_interrupts():
        try:
            from anytime.cli import main as run
        except KeyboardInterrupt as interrupt:
            return interrupted(interrupt)
        return run()
