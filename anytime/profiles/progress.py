"""A one-line progress bar for long measurements: done / total, rate and time left.

It draws on a terminal only (by default, when the stream is a TTY), redrawing in place at most
ten times a second, so piping the output to a file or a CI log stays clean.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

_WIDTH = 24  # characters of the bar itself
_REDRAW = 0.1  # seconds between redraws


def _duration(seconds: float) -> str:
    seconds = max(0, round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class ProgressBar:
    """`label [#####-----] done/total unit  rate/s  ETA m:ss` on `stream`.

    Args:
        total: how many units the whole job has.
        label: what is being measured (a module's name).
        unit: what a unit is called ("trials").
        stream: where to draw (standard error by default).
        enabled: draw or not; by default, only when `stream` is a terminal.
    """

    def __init__(
        self,
        total: int,
        *,
        label: str = "",
        unit: str = "trials",
        stream: TextIO | None = None,
        enabled: bool | None = None,
    ) -> None:
        self.total = max(0, total)
        self.label = label
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty is not None and isatty())
        self.enabled = enabled
        self.done = 0
        self._start = time.perf_counter()
        self._drawn = -_REDRAW
        self._drawn_done = -1
        self._closed = False

    def update(self, n: int = 1) -> None:
        """Count `n` more units done (redraws if enough time has passed)."""
        self.done += n
        now = time.perf_counter()
        if self.enabled and (now - self._drawn >= _REDRAW or self.done >= self.total):
            self._drawn = now
            self._draw(now)

    def line(self, now: float | None = None) -> str:
        """The text of the bar as it stands."""
        elapsed = (time.perf_counter() if now is None else now) - self._start
        fraction = self.done / self.total if self.total else 1.0
        filled = min(_WIDTH, int(fraction * _WIDTH))
        bar = "#" * filled + "-" * (_WIDTH - filled)
        rate = self.done / elapsed if elapsed > 0 else 0.0
        if self.done >= self.total:
            eta = f"in {_duration(elapsed)}"
        elif rate > 0:
            eta = f"ETA {_duration((self.total - self.done) / rate)}"
        else:
            eta = "ETA ?"
        head = f"{self.label} " if self.label else ""
        return f"{head}[{bar}] {self.done}/{self.total} {self.unit}  {rate:.1f}/s  {eta}"

    def _draw(self, now: float) -> None:
        self._drawn_done = self.done
        self.stream.write("\r" + self.line(now) + "\x1b[K")
        self.stream.flush()

    def close(self) -> None:
        """Draw the final state and end the line (once)."""
        if self._closed:
            return
        self._closed = True
        if self.enabled:
            if self._drawn_done != self.done:
                self._draw(time.perf_counter())
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
