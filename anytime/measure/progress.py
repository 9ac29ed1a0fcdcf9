"""Progress bars for long commands, drawn by tqdm on standard error.

A bar draws on a terminal only (by default, when its stream is a TTY) and is silent otherwise,
so piping the output to a file or a CI log stays clean; `enabled=False` (a command's `--quiet`)
silences it on a terminal too. `ProgressBar` counts units of work (trials, runs, frames,
problems; `total=None` when the count is not known in advance); `timed_progress` fills a bar
over a wall-time budget (a calibration's seconds).
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

from tqdm import tqdm  # type: ignore[import-untyped]  # (types-tqdm is not a dev dependency)

__all__ = ["ProgressBar", "timed_progress"]

#: Seconds between redraws.
REDRAW = 0.1
#: The bars' formats, with the count's unit and the rate always in units per second.
_COUNTED = "{l_bar}{bar}| {n_fmt}/{total_fmt}{unit} [{elapsed}<{remaining}, {rate_noinv_fmt}]"
_UNCOUNTED = "{desc}: {n_fmt}{unit} [{elapsed}, {rate_noinv_fmt}]"


def on_terminal(stream: TextIO) -> bool:
    """Whether `stream` is a terminal (where bars are drawn by default)."""
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty is not None and isatty())
    except ValueError:  # a closed stream
        return False


class ProgressBar:
    """`label: 40%|####      | 48/120 [00:02<00:03, 20.1 trials/s]` on `stream`.

    Args:
        total: how many units the whole job has (None: not known; the bar counts up).
        label: what is being done (a module's name).
        unit: what a unit is called ("trials").
        stream: where to draw (standard error by default).
        enabled: draw or not; by default, only when `stream` is a terminal.
    """

    def __init__(
        self,
        total: int | None,
        *,
        label: str = "",
        unit: str = "trials",
        stream: TextIO | None = None,
        enabled: bool | None = None,
    ) -> None:
        self.total = None if total is None else max(0, total)
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = on_terminal(self.stream) if enabled is None else enabled
        self._done = 0
        self._bar = tqdm(
            total=self.total,
            desc=label or None,
            unit=f" {unit}",
            bar_format=_COUNTED if self.total is not None else _UNCOUNTED,
            file=self.stream,
            disable=not self.enabled,
            mininterval=REDRAW,
            dynamic_ncols=True,
        )

    @property
    def done(self) -> int:
        """Units counted so far."""
        return self._done

    def update(self, n: int = 1) -> None:
        """Count `n` more units done (redrawn at most every `REDRAW` seconds)."""
        self._done += n
        self._bar.update(n)

    def close(self) -> None:
        """Draw the final state and end the line (once)."""
        self._bar.close()

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextmanager
def timed_progress(
    seconds: float,
    *,
    label: str = "",
    stream: TextIO | None = None,
    enabled: bool | None = None,
) -> Iterator[None]:
    """A bar filling over `seconds` of wall time while the block runs (drawn by a thread)."""
    stream = stream if stream is not None else sys.stderr
    if not (on_terminal(stream) if enabled is None else enabled):
        yield
        return
    bar = tqdm(
        total=seconds,
        desc=label or None,
        file=stream,
        bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}",
        mininterval=REDRAW,
        dynamic_ncols=True,
    )
    stop = threading.Event()
    start = time.perf_counter()

    def draw() -> None:
        while not stop.wait(REDRAW):
            bar.n = min(seconds, time.perf_counter() - start)
            bar.refresh()

    thread = threading.Thread(target=draw, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        bar.n = min(seconds, time.perf_counter() - start)
        bar.close()
