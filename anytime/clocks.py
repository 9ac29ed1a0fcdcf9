"""Clocks: where a module's time comes from.

`WorkClock` counts the units of work modules report with `ctx.tick(n)`: deterministic and
machine-independent, so tests and measured profiles do not depend on how busy the machine is.
`WallClock` is `time.perf_counter`. A profile records which unit its time axis is in.
"""

from __future__ import annotations

import threading
import time
from typing import Protocol

from anytime.vocabulary import Unit

__all__ = ["Clock", "Unit", "WallClock", "WorkClock"]


class Clock(Protocol):
    unit: Unit

    def now(self) -> float:
        """The current time in this clock's unit."""
        ...

    def advance(self, n: float) -> None:
        """Report `n` units of work (only a work clock moves on this)."""
        ...


class WorkClock:
    """Time = the number of work units reported so far (thread-safe)."""

    unit: Unit = "ticks"

    def __init__(self) -> None:
        self._ticks = 0.0
        self._lock = threading.Lock()

    def now(self) -> float:
        return self._ticks

    def advance(self, n: float) -> None:
        with self._lock:
            self._ticks += n


class WallClock:
    """Time = seconds of `time.perf_counter` since the clock was made."""

    unit: Unit = "seconds"

    def __init__(self) -> None:
        self._start = time.perf_counter()

    def now(self) -> float:
        return time.perf_counter() - self._start

    def advance(self, n: float) -> None:
        pass
