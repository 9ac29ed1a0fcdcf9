"""The frame monitor: inter-frame contract choice against closed-form optima, the intra-frame
rule's cases, deadline values, the event log's JSON lines, and the error messages."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from attrs import frozen
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.typing import ArrayLike

from anytime.profiles import Exponential, new_profile, tabulate
from anytime.profiles.profile import Array, ConditionalPerformanceProfile
from anytime.runtime.monitor import (
    Adjustment,
    ContractDecision,
    DeadlineValue,
    EventLog,
    Monitor,
    MonitorError,
    MonitorEvent,
)

#: Contract times 0, 0.01, ..., 10: the grid of the closed-form tests.
STEP = 0.01
TIMES = np.round(np.arange(0, 10 + STEP / 2, STEP), 10)

Model = Callable[[Any, Array, Array], ArrayLike]


@frozen
class Models:
    """A value model and a cost model from two functions of (state, contract, quality)."""

    value_fn: Model
    cost_fn: Model = lambda state, t, q: 0.0

    def value(self, state: Any, contract: Array, quality: Array) -> ArrayLike:
        return self.value_fn(state, contract, quality)

    def cost(self, state: Any, contract: Array, quality: Array) -> ArrayLike:
        return self.cost_fn(state, contract, quality)


def monitor(profile: ConditionalPerformanceProfile, models: Models, **kwargs: Any) -> Monitor[Any]:
    return Monitor(profile, models, models, **kwargs)


def exponential(rate: float) -> ConditionalPerformanceProfile:
    """The deterministic profile q(t) = 1 - exp(-rate t) on `TIMES`."""
    return tabulate(Exponential(rate=rate), TIMES, module="exp")


# --- inter-frame: the contract time -------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(
    rate=st.floats(0.5, 3.0),
    exponent=st.floats(0.2, 8.0),
    cost=st.floats(0.1, 5.0),
)
def test_linear_value_and_cost_of_time_choose_the_closed_form_optimum(
    rate: float, exponent: float, cost: float
) -> None:
    # U(t) = V (1 - exp(-a t)) - c t is concave with its maximum at t* = ln(V a / c) / a; draw
    # a t* and take V = c exp(a t*) / a.
    best = exponent / rate
    assume(best < TIMES[-1] - STEP)
    value = cost * math.exp(exponent) / rate
    models = Models(lambda s, t, q: value * q, lambda s, t, q: cost * t)
    decision = monitor(exponential(rate), models).choose_contract(None)
    assert abs(decision.contract - best) <= STEP
    on_grid = value * -np.expm1(-rate * TIMES) - cost * TIMES
    assert decision.expected_utility == pytest.approx(on_grid.max(), rel=1e-12)
    assert decision.expected_quality == pytest.approx(-math.expm1(-rate * decision.contract))
    assert decision.expected_cost == pytest.approx(cost * decision.contract)
    assert decision.expected_utility == decision.expected_value - decision.expected_cost


def test_expectation_is_over_the_quality_distribution() -> None:
    # Success (quality in the upper bin) with probability p(t) = 1 - exp(-t); a value of V only
    # on success, so E[value] = V p(t) though the value is a step in quality: t* = ln(V / c).
    p = -np.expm1(-TIMES)
    profile = new_profile(
        time=TIMES, bins=[0.0, 0.5, 1.0], probability=np.stack([1 - p, p], axis=-1)
    )
    models = Models(lambda s, t, q: np.where(q >= 0.5, 10.0, 0.0), lambda s, t, q: 1.0 * t)
    decision = monitor(profile, models).choose_contract(None)
    assert abs(decision.contract - math.log(10.0)) <= STEP
    assert decision.expected_value == pytest.approx(10 * -math.expm1(-decision.contract))
    assert decision.expected_quality == pytest.approx(0.25 + 0.5 * -math.expm1(-decision.contract))


@frozen
class Frame:
    """The state of the deadline tests: the time now and the length of the route left."""

    now: float
    length: float


def completion(state: Frame, contract: Array, quality: Array) -> Array:
    """Plan for `contract`, then drive the plan at unit speed: it is length / quality long."""
    return state.now + contract + state.length / np.maximum(quality, 1e-9)


def test_a_missed_deadline_chooses_the_earliest_expected_completion() -> None:
    # Completion t + L / (1 - exp(-a t)) is least where (1 - x)^2 = L a x, x = exp(-a t).
    rate, length = 1.0, 2.0
    b = 2 + length * rate
    best = -math.log((b - math.sqrt(b * b - 4)) / 2) / rate  # 1.317
    value = DeadlineValue(full=10.0, deadline=3.0, decay=1.0)
    models = Models(lambda s, t, q: value(completion(s, t, q)))
    decision = monitor(exponential(rate), models).choose_contract(Frame(now=0.5, length=length))
    assert abs(decision.contract - best) <= STEP
    least = 0.5 + best + length / -math.expm1(-rate * best)  # 4.55, so 1.55 late
    assert decision.expected_value == pytest.approx(10.0 - (least - 3.0), abs=1e-3)


def test_ties_go_to_the_smallest_contract_time() -> None:
    # A generous deadline: every contract that finishes by it is worth the full value.
    state = Frame(now=0.0, length=2.0)
    value = DeadlineValue(full=10.0, deadline=8.0, decay=1.0)
    models = Models(lambda s, t, q: value(completion(s, t, q)))
    decision = monitor(exponential(1.0), models).choose_contract(state)
    finish = completion(state, TIMES, -np.expm1(-TIMES))
    assert decision.contract == TIMES[np.argmax(finish <= 8.0)]
    assert decision.expected_utility == 10.0
    flat = monitor(exponential(1.0), Models(lambda s, t, q: 1.0)).choose_contract(None)
    assert flat.contract == TIMES[0]


def test_the_decision_carries_its_curves_over_the_grid() -> None:
    grid = [1.0, 2.0, 4.0]
    models = Models(lambda s, t, q: 10 * q, lambda s, t, q: t)
    decision = monitor(exponential(1.0), models, grid=grid).choose_contract(None)
    quality = -np.expm1(-np.array(grid))
    assert isinstance(decision, ContractDecision)
    np.testing.assert_array_equal(decision.grid, grid)
    np.testing.assert_allclose(decision.quality_curve, quality)
    np.testing.assert_allclose(decision.value_curve, 10 * quality)
    np.testing.assert_allclose(decision.cost_curve, grid)
    np.testing.assert_allclose(decision.utility_curve, 10 * quality - grid)
    assert decision.contract == 2.0
    assert not decision.utility_curve.flags.writeable


def test_the_default_grid_is_the_profiles_time_grid() -> None:
    profile = exponential(1.0)
    np.testing.assert_array_equal(monitor(profile, Models(lambda s, t, q: q)).grid, profile.time)


def test_input_qualities_condition_the_profile() -> None:
    # q(t, q_in) = q_in (1 - exp(-t)): with V q - t the optimum is t* = ln(V q_in).
    profile = tabulate(
        lambda t, q: q * -np.expm1(-t), TIMES, input_grids=[[0.0, 0.5, 1.0]], inputs=["map"]
    )
    models = Models(lambda s, t, q: 20 * q, lambda s, t, q: t)
    m = monitor(profile, models, input_quality=[1.0])
    assert abs(m.choose_contract(None).contract - math.log(20.0)) <= STEP
    half = m.choose_contract(None, input_quality=[0.5]).contract
    assert abs(half - math.log(10.0)) <= STEP


# --- deadline values ----------------------------------------------------------------------------


def test_deadline_value_is_full_then_decays_linearly_to_zero() -> None:
    value = DeadlineValue(full=10.0, deadline=5.0, decay=2.0)
    np.testing.assert_array_equal(
        value([0.0, 5.0, 6.0, 7.5, 10.0, 100.0, math.inf]), [10, 10, 8, 5, 0, 0, 0]
    )
    assert value(3.0).shape == ()
    assert np.all(DeadlineValue(4.0, 1.0, 0.0)([0.0, 2.0, math.inf]) == 4.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"full": -1.0}, "deadline value: full must be a finite number >= 0, got -1.0"),
        ({"decay": -0.5}, "deadline value: decay must be a finite number >= 0, got -0.5"),
        ({"deadline": math.nan}, "deadline value: deadline must be a finite number, got nan"),
    ],
    ids=["negative-full", "negative-decay", "nan-deadline"],
)
def test_deadline_value_rejects_bad_parameters(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(MonitorError, match=f"^{message}$"):
        DeadlineValue(**{"full": 1.0, "deadline": 1.0, "decay": 1.0, **kwargs})


# --- intra-frame: the pace of execution ---------------------------------------------------------

#: Expected quality t / 10: at elapsed 5 the plan should be 0.5; with contract 10, execution 0.5.
LINEAR = tabulate(lambda t: t / 10, [0.0, 10.0])
PLAN = {"ahead": 0.8, "on-schedule": 0.5, "behind": 0.2}
EXECUTION = {"ahead": 0.9, "on-schedule": 0.5, "behind": 0.1}


@pytest.mark.parametrize(
    ("planning", "execution", "expected"),
    [
        ("ahead", "behind", Adjustment.FASTER),
        ("behind", "ahead", Adjustment.SLOWER),
        ("ahead", "ahead", Adjustment.HOLD),
        ("behind", "behind", Adjustment.HOLD),
        ("on-schedule", "on-schedule", Adjustment.HOLD),
        ("ahead", "on-schedule", Adjustment.HOLD),
        ("on-schedule", "behind", Adjustment.HOLD),
        ("behind", "on-schedule", Adjustment.HOLD),
        ("on-schedule", "ahead", Adjustment.HOLD),
    ],
    ids=lambda v: str(v),
)
def test_the_intra_frame_rule(planning: str, execution: str, expected: Adjustment) -> None:
    log = EventLog()
    m = monitor(LINEAR, Models(lambda s, t, q: q), log=log)
    assert m.adjust(5.0, PLAN[planning], EXECUTION[execution], 10.0) is expected
    (event,) = log
    assert (event.data["planning"], event.data["execution"]) == (planning, execution)
    assert event.data["expected_quality"] == pytest.approx(0.5)
    assert event.data["scheduled_progress"] == 0.5


def test_within_the_tolerance_is_on_schedule() -> None:
    m = monitor(LINEAR, Models(lambda s, t, q: q))
    assert m.adjust(5.0, 0.54, 0.46, 10.0) is Adjustment.HOLD
    assert m.adjust(5.0, 0.54, 0.46, 10.0, tolerance=0.01) is Adjustment.FASTER
    assert m.adjust(5.0, 0.46, 0.54, 10.0, tolerance=0.01) is Adjustment.SLOWER
    assert m.adjust(4.0, 0.4, 0.4, 10.0, tolerance=0.0) is Adjustment.HOLD


def test_after_the_contract_execution_should_be_done() -> None:
    m = monitor(LINEAR, Models(lambda s, t, q: q))
    assert m.adjust(12.0, 1.0, 1.0, 10.0, tolerance=0.0) is Adjustment.HOLD
    assert m.adjust(12.0, 1.0, 0.9, 10.0, tolerance=0.0) is Adjustment.HOLD  # plan on schedule
    assert m.adjust(3.0, 0.9, 0.1, 4.0) is Adjustment.FASTER


def test_the_plan_is_compared_with_the_conditional_expectation() -> None:
    profile = tabulate(lambda t, q: q * t / 10, [0.0, 10.0], input_grids=[[0.0, 1.0]])
    m = monitor(profile, Models(lambda s, t, q: q), input_quality=[0.5])
    assert m.adjust(5.0, 0.4, 0.1, 10.0) is Adjustment.FASTER  # expected 0.25
    assert m.adjust(5.0, 0.4, 0.1, 10.0, input_quality=[1.0]) is Adjustment.HOLD  # 0.5


# --- the event log ------------------------------------------------------------------------------


def test_every_decision_is_logged_with_its_time() -> None:
    log = EventLog()
    m = monitor(exponential(1.0), Models(lambda s, t, q: 10 * q, lambda s, t, q: t), log=log)
    decision = m.choose_contract(None, now=12.5)
    m.adjust(1.0, 0.9, 0.1, decision.contract, now=13.5)
    m.adjust(2.0, 0.5, 0.5, decision.contract)
    assert [(e.time, e.kind) for e in log] == [
        (12.5, "contract"),
        (13.5, "adjust"),
        (2.0, "adjust"),
    ]
    assert log[0].data == {
        "contract": decision.contract,
        "expected_quality": decision.expected_quality,
        "expected_value": decision.expected_value,
        "expected_cost": decision.expected_cost,
        "expected_utility": decision.expected_utility,
        "input_quality": [],
    }
    assert log[1].data["adjustment"] == "faster"
    assert len(log.of_kind("adjust")) == 2


def test_the_log_round_trips_through_json_lines(tmp_path: Path) -> None:
    log = EventLog()
    m = monitor(LINEAR, Models(lambda s, t, q: q), log=log)
    m.choose_contract(None, now=0.0)
    m.adjust(5.0, 0.8, 0.1, 10.0, now=5.0)
    log.record(6.0, "note", {"array": np.array([1.0, 2.0]), "n": np.int64(3), "pair": (1, 2)})
    text = log.to_jsonl()
    lines = text.splitlines()
    assert len(lines) == 3 and text.endswith("\n")
    assert json.loads(lines[2]) == {
        "time": 6.0,
        "kind": "note",
        "array": [1.0, 2.0],
        "n": 3,
        "pair": [1, 2],
    }
    assert [json.loads(line) for line in lines] == log.as_dicts()
    assert EventLog.from_jsonl(text) == log
    path = tmp_path / "events.jsonl"
    log.write_jsonl(path)
    assert EventLog.read_jsonl(path) == log


def test_events_reserve_time_and_kind() -> None:
    with pytest.raises(
        MonitorError, match=r"^event: data may not use the reserved key\(s\) \['time'\]$"
    ):
        MonitorEvent(1.0, "note", {"time": 2.0})


# --- errors -------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((-1.0, 0.5, 0.5, 10.0), "monitor: elapsed must be a finite number >= 0, got -1.0"),
        ((1.0, 0.5, 0.5, 0.0), "monitor: contract must be a finite number > 0, got 0.0"),
        ((1.0, 0.5, 0.5, -2.0), "monitor: contract must be a finite number > 0, got -2.0"),
        ((1.0, 0.5, 1.5, 10.0), "monitor: progress must be in [0, 1], got 1.5"),
        ((1.0, 0.5, -0.1, 10.0), "monitor: progress must be in [0, 1], got -0.1"),
        ((1.0, 1.2, 0.5, 10.0), "monitor: plan_quality must be in [0, 1], got 1.2"),
    ],
    ids=[
        "negative-elapsed",
        "zero-contract",
        "negative-contract",
        "progress-over",
        "progress-under",
        "quality",
    ],
)
def test_adjust_rejects_bad_arguments(args: tuple[float, ...], message: str) -> None:
    m = monitor(LINEAR, Models(lambda s, t, q: q))
    with pytest.raises(MonitorError, match=f"^{re.escape(message)}$"):
        m.adjust(*args)
    with pytest.raises(ValueError):
        m.adjust(*args)


def test_adjust_rejects_a_negative_tolerance() -> None:
    m = monitor(LINEAR, Models(lambda s, t, q: q))
    with pytest.raises(
        MonitorError, match=r"^monitor: tolerance must be a finite number >= 0, got -0.1$"
    ):
        m.adjust(1.0, 0.5, 0.5, 10.0, tolerance=-0.1)


CONDITIONAL = tabulate(lambda t, q: q * t / 10, [0.0, 10.0], input_grids=[[0.0, 1.0]])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {},
            "monitor: the profile has 1 quality-carrying input(s);"
            " input_quality must give one quality each",
        ),
        ({"input_quality": [0.5, 0.5]}, "monitor: expected 1 input quality(ies), got 2"),
        ({"input_quality": [1.5]}, "monitor: input qualities must be in [0, 1], got [1.5]"),
        ({"grid": []}, "monitor: grid must be a non-empty list of times, got shape [0]"),
        (
            {"input_quality": [1.0], "grid": [0.0, 2.0, 1.0]},
            "monitor: grid must be increasing, got 2 then 1",
        ),
        (
            {"input_quality": [1.0], "grid": [-1.0, 2.0]},
            "monitor: grid times must be finite numbers >= 0",
        ),
    ],
    ids=[
        "no-input-quality",
        "too-many",
        "out-of-range",
        "empty-grid",
        "decreasing-grid",
        "negative-grid",
    ],
)
def test_the_monitor_rejects_bad_settings(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(MonitorError, match=f"^{re.escape(message)}$"):
        monitor(CONDITIONAL, Models(lambda s, t, q: q), **kwargs)


def test_models_must_answer_with_finite_values_of_the_right_shape() -> None:
    wrong = monitor(exponential(1.0), Models(lambda s, t, q: np.zeros(3)), grid=[1.0, 2.0])
    with pytest.raises(
        MonitorError,
        match=re.escape(
            "monitor: the value model answered with shape [3],"
            " which does not broadcast to (grid, bins) [2, 10]"
        ),
    ):
        wrong.choose_contract(None)
    nan = monitor(exponential(1.0), Models(lambda s, t, q: q, lambda s, t, q: np.nan * t))
    with pytest.raises(
        MonitorError, match=r"^monitor: the cost model answered with NaN or infinity$"
    ):
        nan.choose_contract(None)
