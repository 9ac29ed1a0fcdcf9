"""How a run is driven and what it is given: a run mode (`Soft`, `Hard`, `Isolated`) and a
`Budget` (the allocation, the clock it is counted on, and the caller's stop event).

A mode is one value, not a set of flags that travel together: `run`, `run_program`, the profile
builder, the catalogue and the command line all take one.

- `Soft()` runs the module in the caller's thread and checks the deadline each time it
  reports work or registers a result: the cheapest, and exact on the work clock.
- `Hard(poll=...)` runs it in a worker thread and answers at the deadline even if the module
  never looks at its context (Python cannot kill a thread: a stuck module keeps its thread).
- `Isolated(watchdog=..., limits=...)` runs it in a child process of its own, which answers at
  the deadline as `Hard` does and survives whatever the module does (a crash, a hang, a
  `sys.exit`): nothing it started outlives the run.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

from attrs import Factory, field, frozen

from anytime.clocks import Clock, WorkClock
from anytime.isolation import WATCHDOG, IsolationError, Limits


def _positive(name: str) -> Callable[[Any, Any, float], None]:
    def check(instance: Any, attribute: Any, value: float) -> None:
        if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
            raise IsolationError(
                f"{type(instance).__name__}: {name}: expected a positive"
                f" number of seconds, got {value!r}"
            )

    return check


@frozen
class Soft:
    """In the caller's thread; the deadline is checked whenever the module reports work or
    registers a result."""


@frozen
class Hard:
    """In a worker thread; the caller answers at the deadline whatever the module does.

    Attributes:
        poll: on a clock that is not the wall clock, how often (seconds) the caller looks at it.
    """

    poll: float = field(default=0.001, validator=_positive("poll"))


@frozen
class Isolated:
    """In a child process of its own (see `anytime.isolation`).

    Attributes:
        watchdog: wall-clock seconds after which a run that has not answered fails (status
            `failed`) and its process is ended, whatever its own clock says.
        limits: the run's memory and CPU limits, or None.
    """

    watchdog: float = field(default=WATCHDOG, validator=_positive("watchdog"))
    limits: Limits | None = None


RunMode = Soft | Hard | Isolated
SOFT = Soft()
ISOLATED = Isolated()


@frozen
class Budget:
    """What a run is given: `allocation` time on `clock` (a fresh work clock by default), and
    the caller's `stop` event, which interrupts the run when set from any thread.

    A bare number where a budget is expected is the allocation on a fresh work clock.
    """

    allocation: float = field(default=math.inf, converter=float)
    clock: Clock = Factory(WorkClock)
    stop: threading.Event | None = None


def budget_of(budget: Budget | float) -> Budget:
    """`budget`, or a number made the allocation of a fresh budget."""
    return budget if isinstance(budget, Budget) else Budget(budget)
