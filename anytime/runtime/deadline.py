"""Deadlines from critical events (Romanenko, "Decision-making in real time on the basis of
actions planning", steps 1 and 3).

A *critical event* is something undesirable that will happen unless the system acts first (a
moving obstacle reaching the robot's route). Each is estimated by a cheap function of the
current situation, declared like a module with `@critical_event(name, cost_bound=...)`:

    @critical_event("obstacle-arrival", cost_bound=4)
    def obstacle_arrival(ctx, situation):
        ctx.tick(2)            # its own work, on the caller's clock
        return 120.0           # time until the event, or None: no such event

An estimator runs under a contract equal to its declared cost bound (`ctx.allocation`), so it
may read `ctx.remaining` to stay inside it. `deadline_from` runs the estimators one after the
other and gives the *time stock* T_d left for deciding:

    T_d = min over events e of (s_e + t_e) - margin - c

where `s_e` is the clock time when estimator e started, `t_e` the time until its event (as
seen from s_e), and `c` the clock time when the last estimator finished. With one estimator of
cost k this is `t_e - k - margin`: the estimators' own costs are charged against the stock.
No event gives T_d = inf. T_d may be 0 or negative: the event is too close for any
deliberation; the caller decides what a reflex is.

An estimator that reports more work than its bound breaks the promise the deadline rests on.
By default that is a `CostBoundError` naming the estimator, its cost and its bound; with
`strict=False` the cost is charged anyway and the breach is recorded in `Deadline.violations`
(for a running robot, where a late but correct deadline beats no deadline).

`proportional_split` is step 3: T_d(i) = T_d * T_i* / sum_j T_j*, where T_i* is a cheap
lower bound of the time alternative i needs to be concretised.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any, cast

import attrs
import numpy as np
from attrs import field, frozen

from anytime.clocks import Clock
from anytime.errors import AnytimeError
from anytime.modules import AnytimeModule, Context, Registry, contract

__all__ = [
    "EVENTS",
    "CostBoundError",
    "CriticalEvent",
    "Deadline",
    "DeadlineError",
    "Estimate",
    "UnknownEventError",
    "critical_event",
    "deadline_from",
    "proportional_split",
]

_SLACK = 1e-9  # relative rounding tolerated when comparing a cost with its bound


class CostBoundError(AnytimeError, RuntimeError):
    """A critical-event estimator did more work than its declared cost bound."""


class DeadlineError(AnytimeError, ValueError):
    """A time stock cannot be computed or split as asked: a cost bound, margin, time stock or
    lower bound that is negative or not finite, or an estimator that returned no time."""


class UnknownEventError(DeadlineError, KeyError):
    """No critical event is registered under the name asked for; the message lists the known."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


def _cost_bound(value: float) -> float:
    bound = float(value)
    if not 0.0 <= bound < math.inf:
        raise DeadlineError(f"a cost bound must be finite and >= 0, got {value!r}")
    return bound


@frozen(eq=False)
class CriticalEvent(AnytimeModule):
    """A registered estimator: a module `f(ctx, situation) -> float | None` with a cost bound.

    It is a contract module whose allocation is its cost bound, in the unit of the clock it
    runs on (ticks of the work clock). Registered in `EVENTS`, not in the module registry: an
    estimator is not a function schemas call.
    """

    cost_bound: float = field(default=0.0, converter=_cost_bound, kw_only=True)


#: The process-wide registry of critical-event estimators.
EVENTS = Registry()


def critical_event(
    name: str | None = None,
    *,
    cost_bound: float,
    registry: Registry | None = None,
) -> Callable[[Callable[..., float | None]], CriticalEvent]:
    """Declare `f(ctx, situation)` returning the time until its event, or None (no event).

    Args:
        name: the event's name (default: the function's, with '-' for '_').
        cost_bound: an upper bound on its own cost, in the clock's unit (ticks).
        registry: a `Registry` to add it to as well, such as `EVENTS` (default: none, as for
            the module decorators: a plugin lists its events in its `Plugin` object, and
            `deadline_from` takes the event objects themselves).
    """
    bound = _cost_bound(cost_bound)

    def decorate(function: Callable[..., float | None]) -> CriticalEvent:
        # `contract` checks the signature (a context first) and names the offender.
        module = contract(name, inputs=[])(cast(Any, function))
        event = CriticalEvent(**attrs.asdict(module, recurse=False), cost_bound=bound)
        if registry is None:
            return event
        added = registry.add(event)
        assert isinstance(added, CriticalEvent)
        return added

    return decorate


@frozen
class Estimate:
    """One estimator's run: when it started, what it predicted, and what it cost."""

    event: str
    started_at: float
    time_until: float | None
    cost: float
    cost_bound: float

    @property
    def violated(self) -> bool:
        """Whether it cost more than its bound."""
        return self.cost > self.cost_bound * (1.0 + _SLACK) + _SLACK

    @property
    def at(self) -> float:
        """When its event happens on the clock (inf for no event)."""
        return math.inf if self.time_until is None else self.started_at + self.time_until


@frozen
class Deadline:
    """The time stock for a decision.

    Attributes:
        t_d: the time stock T_d, from `computed_at` (inf when no event is predicted; <= 0 when
            the event is too close to deliberate).
        event: the name of the event that set it (None when none is predicted).
        computed_at: the clock time when it was computed (after the estimators ran).
        margin: the safety margin taken off.
        estimates: every estimator's run, in order.
    """

    t_d: float
    event: str | None
    computed_at: float
    margin: float = 0.0
    estimates: tuple[Estimate, ...] = ()

    @property
    def at(self) -> float:
        """The clock time by which the decision must be made."""
        return self.computed_at + self.t_d

    @property
    def violations(self) -> tuple[Estimate, ...]:
        """The estimators that cost more than their bound (only with `strict=False`)."""
        return tuple(e for e in self.estimates if e.violated)

    def remaining(self, clock: Clock) -> float:
        """What is left of the stock now."""
        return self.at - clock.now()


def _resolve(estimator: CriticalEvent | str, registry: Registry) -> CriticalEvent:
    if isinstance(estimator, CriticalEvent):
        return estimator
    found = registry.get(estimator)
    if not isinstance(found, CriticalEvent):
        known = ", ".join(sorted(m.name for m in registry)) or "none"
        raise UnknownEventError(f"unknown critical event '{estimator}' (known: {known})")
    return found


def deadline_from(
    situation: Any,
    estimators: Iterable[CriticalEvent | str],
    clock: Clock,
    *,
    margin: float = 0.0,
    strict: bool = True,
    registry: Registry | None = None,
) -> Deadline:
    """Run the estimators on `situation` on `clock` and compute the time stock T_d.

    Args:
        situation: whatever the estimators read (the framework does not look inside).
        estimators: registered estimators, or their names in `registry` (default `EVENTS`).
        clock: the clock their work is charged on (and T_d is measured in).
        margin: a safety margin (>= 0) taken off T_d.
        strict: raise `CostBoundError` when an estimator exceeds its bound (default); else
            record it in `Deadline.violations`.

    Raises:
        CostBoundError: with `strict`, an estimator cost more than its bound.
        UnknownEventError: an estimator's name is not registered in `registry`.
        DeadlineError: a negative margin, or an estimator returned NaN or a negative time.
    """
    margin = float(margin)
    if not 0.0 <= margin < math.inf:
        raise DeadlineError(f"margin must be finite and >= 0, got {margin!r}")
    source = registry if registry is not None else EVENTS
    estimates: list[Estimate] = []
    for estimator in estimators:
        event = _resolve(estimator, source)
        ctx = Context(allocation=event.cost_bound, clock=clock)
        value = event.function(ctx, situation)
        estimate = Estimate(
            event=event.name,
            started_at=ctx.start,
            time_until=None if value is None else float(value),
            cost=ctx.elapsed,
            cost_bound=event.cost_bound,
        )
        if estimate.time_until is not None and not estimate.time_until >= 0.0:
            raise DeadlineError(
                f"critical event '{event.name}' ({event.origin}) returned {value!r}; "
                "expected a time >= 0 or None"
            )
        if strict and estimate.violated:
            raise CostBoundError(
                f"critical event '{event.name}' ({event.origin}) cost {estimate.cost:g} "
                f"{clock.unit}, more than its declared cost bound of {event.cost_bound:g}"
            )
        estimates.append(estimate)
    computed_at = clock.now()
    first = min(estimates, key=lambda e: e.at, default=None)
    if first is None or first.time_until is None:
        return Deadline(math.inf, None, computed_at, margin, tuple(estimates))
    return Deadline(
        first.at - margin - computed_at, first.event, computed_at, margin, tuple(estimates)
    )


def proportional_split(t_d: float, lower_bounds: Sequence[float]) -> tuple[float, ...]:
    """Split the time stock among alternatives in proportion to their lower bounds T_i*:
    T_d(i) = T_d * T_i* / sum_j T_j* (Romanenko, step 3). The shares sum to T_d.

    When every bound is 0 the split is equal. The shares may fall short of the bounds (when
    T_d < sum T_j*): the caller decides whether an alternative is then worth starting.

    Raises:
        DeadlineError: T_d negative or infinite, no bounds, or a bound negative or infinite.
    """
    total_time = float(t_d)
    if not 0.0 <= total_time < math.inf:
        raise DeadlineError(f"the time stock must be finite and >= 0, got {t_d!r}")
    bounds = np.asarray(lower_bounds, dtype=np.float64)
    if bounds.ndim != 1 or bounds.size == 0:
        raise DeadlineError(f"expected a non-empty list of lower bounds, got {lower_bounds!r}")
    if not (np.isfinite(bounds).all() and (bounds >= 0.0).all()):
        raise DeadlineError(f"lower bounds must be finite and >= 0, got {lower_bounds!r}")
    total = float(bounds.sum())
    weights = bounds / total if total > 0.0 else np.full(bounds.size, 1.0 / bounds.size)
    return tuple(float(share) for share in total_time * weights)
