"""Deadlines from critical events: the arithmetic of T_d, cost bounds, proportional split."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from anytime.clocks import WorkClock
from anytime.errors import AnytimeError
from anytime.modules import ModuleError, Registry
from anytime.runtime.deadline import (
    CostBoundError,
    CriticalEvent,
    DeadlineError,
    UnknownEventError,
    critical_event,
    deadline_from,
    proportional_split,
)


def _event(name: str, until: float | None, cost: float, bound: float, registry: Registry):
    @critical_event(name, cost_bound=bound, registry=registry)
    def estimate(ctx, situation):
        ctx.tick(cost)
        return until

    return estimate


def test_one_event_charges_its_cost_and_the_margin() -> None:
    registry = Registry()
    event = _event("arrival", 100.0, 3, 5, registry)
    clock = WorkClock()
    clock.advance(10)
    deadline = deadline_from(None, [event], clock, margin=7)
    assert isinstance(event, CriticalEvent) and "arrival" in registry
    assert deadline.t_d == 100 - 3 - 7
    assert (deadline.event, deadline.computed_at, deadline.at) == ("arrival", 13.0, 103.0)
    assert clock.now() == 13


def test_each_event_is_measured_from_when_it_was_estimated() -> None:
    registry = Registry()
    first = _event("far", 50.0, 2, 2, registry)
    _event("near", 40.0, 4, 4, registry)
    clock = WorkClock()
    deadline = deadline_from(None, ["far", "near"], clock, registry=registry)
    # far: 0 + 50 - 6 = 44; near: 2 + 40 - 6 = 36
    assert (deadline.t_d, deadline.event) == (36.0, "near")
    assert [e.cost for e in deadline.estimates] == [2.0, 4.0]
    assert first.cost_bound == 2.0


def test_no_event_gives_an_infinite_stock() -> None:
    deadline = deadline_from(None, [_event("none", None, 1, 1, Registry())], WorkClock())
    assert deadline.t_d == math.inf and deadline.event is None


def test_exceeding_the_cost_bound_is_an_error_naming_the_estimator() -> None:
    greedy = _event("greedy", 10.0, 9, 5, Registry())
    with pytest.raises(
        CostBoundError,
        match=r"critical event 'greedy' .* cost 9 ticks, more than its declared cost bound of 5",
    ):
        deadline_from(None, [greedy], WorkClock())


def test_or_a_recorded_violation_when_not_strict() -> None:
    greedy = _event("greedy", 10.0, 9, 5, Registry())
    deadline = deadline_from(None, [greedy], WorkClock(), strict=False)
    assert deadline.t_d == 1.0
    assert [v.event for v in deadline.violations] == ["greedy"]


def test_bad_estimators_and_arguments() -> None:
    with pytest.raises(ModuleError, match="first parameter must be the context"):
        critical_event("x", cost_bound=1, registry=Registry())(lambda situation: 1.0)
    with pytest.raises(DeadlineError) as bound:
        critical_event("x", cost_bound=-1)
    assert str(bound.value) == "a cost bound must be finite and >= 0, got -1"
    with pytest.raises(DeadlineError, match="expected a time >= 0 or None"):
        deadline_from(None, [_event("neg", -1.0, 0, 0, Registry())], WorkClock())
    with pytest.raises(UnknownEventError) as unknown:
        deadline_from(None, ["nope"], WorkClock(), registry=Registry())
    assert str(unknown.value) == "unknown critical event 'nope' (known: none)"  # not quoted
    with pytest.raises(DeadlineError) as margin:
        deadline_from(None, [], WorkClock(), margin=-1)
    assert str(margin.value) == "margin must be finite and >= 0, got -1.0"


def test_deadline_errors_are_in_the_tree_and_what_they_resemble() -> None:
    """Caught as the framework's errors (the command line's AnytimeError) or as the builtin
    they resemble, as before they were in the tree."""
    assert issubclass(DeadlineError, AnytimeError) and issubclass(DeadlineError, ValueError)
    assert issubclass(UnknownEventError, DeadlineError) and issubclass(UnknownEventError, KeyError)


def test_proportional_split_by_hand() -> None:
    assert proportional_split(100.0, [1, 3]) == (25.0, 75.0)
    assert proportional_split(9.0, [0, 0, 0]) == (3.0, 3.0, 3.0)
    with pytest.raises(DeadlineError) as bounds:
        proportional_split(1.0, [-1.0])
    assert str(bounds.value) == "lower bounds must be finite and >= 0, got [-1.0]"
    with pytest.raises(DeadlineError) as empty:
        proportional_split(1.0, [])
    assert str(empty.value) == "expected a non-empty list of lower bounds, got []"
    with pytest.raises(DeadlineError) as stock:
        proportional_split(math.inf, [1.0])
    assert str(stock.value) == "the time stock must be finite and >= 0, got inf"


bounds = st.lists(st.floats(0.0, 1e6, allow_subnormal=False), min_size=1, max_size=10)


@given(st.floats(0.0, 1e6), bounds)
def test_proportional_split_sums_to_t_d_and_is_proportional(t_d: float, lower: list[float]) -> None:
    shares = proportional_split(t_d, lower)
    assert math.isclose(sum(shares), t_d, rel_tol=1e-9, abs_tol=1e-6)
    total = sum(lower)
    for share, bound in zip(shares, lower, strict=True):
        expected = t_d * (bound / total) if total > 0 else t_d / len(lower)
        assert math.isclose(share, expected, rel_tol=1e-9, abs_tol=1e-6)
