"""The run hook: an `Observer` watches one run of `anytime.runtime.run`.

It sees each result the run keeps, looks at the run at times it asks for on the run's clock,
may stop the run, and sees its record at the end. Stopping policies, the catalogue's checks,
the profile builder's traces and a domain's frame loop are observers: nobody wraps a module's
function to watch it, and nobody re-implements registration or deadlines.

At each of its calls before the end an observer may answer with a `Decision` (None keeps the
schedule it has): stop now, or go on with the time of its next look and the time to stop at
without looking. A look is taken at the first report of work (`ctx.tick`) or registered result
at or after the time asked, so on the work clock it comes at the tick that reaches that time,
whether or not the module registers anything there. A stop time becomes the module's
allocation (its context shows it), and results registered after it do not count.

Under `Isolated`, `started`, `registered` and `look` run where the module runs, on the child
process's copy of the observer; `ended` runs in the caller with the record.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from attrs import field, frozen

from anytime.errors import AnytimeError

if TYPE_CHECKING:
    from anytime.modules import AnytimeModule, Result
    from anytime.runtime.executor import RunRecord


class PolicyError(AnytimeError, ValueError):
    """A stopping policy (or another observer) was given or gave something out of range; the
    message says what."""


def _time(name: str) -> Any:
    """An attrs validator: a time >= 0 (infinite: never)."""

    def check(instance: object, attribute: object, value: float) -> None:
        if not value >= 0:  # NaN too
            raise PolicyError(f"decision: {name} must be a time >= 0, got {value!r}")

    return check


@frozen
class Decision:
    """What an observer (a stopping policy) says at a look.

    Attributes:
        stop: stop the run now.
        look_at: when not stopping, the time of the next look (infinite: never look again).
        stop_at: when not stopping, the time to stop at without looking (at the latest).
        reason: a short why, for the event log.
    """

    stop: bool
    look_at: float = field(default=math.inf, converter=float, validator=_time("look_at"))
    stop_at: float = field(default=math.inf, converter=float, validator=_time("stop_at"))
    reason: str = ""

    @classmethod
    def now(cls, reason: str) -> Decision:
        return cls(True, reason=reason)

    @classmethod
    def later(cls, look_at: float, stop_at: float, reason: str) -> Decision:
        return cls(False, float(look_at), float(stop_at), reason)


class Observer:
    """Watches one run; override what you need (each default does nothing).

    Attributes:
        label: how a run's error names the observer when one of its calls raises (the run
            then fails, its best result kept).
    """

    label = "observer"

    def started(
        self, module: AnytimeModule, args: Sequence[Any], allocation: float
    ) -> Decision | None:
        """Before the module starts, with the arguments it is given and the run's allocation.
        An exception raised here reaches the caller of `run` (the observer cannot watch this
        module)."""
        return None

    def registered(self, elapsed: float, result: Result) -> Decision | None:
        """A result the run keeps (registered in time), at `elapsed` since the start."""
        return None

    def look(self, elapsed: float, best: Result | None) -> Decision | None:
        """At the time of a look the observer asked for: the run's answer so far."""
        return None

    def ended(self, record: RunRecord) -> None:
        """The run's record, in the caller."""
