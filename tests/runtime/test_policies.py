"""Stopping policies on dynamic profiles: the optimal policy is optimal on its own model.

Hypothesis draws small dynamic profiles (from random non-decreasing traces, the module
reporting its true quality or an estimate), a utility (a value per unit of quality less a cost
per unit of time) and a monitoring cost; every policy's expected utility is computed exactly on
the profile's Markov chain by `evaluate`, which enumerates the chain's state paths.
"""

from __future__ import annotations

import math
from typing import Any

import attrs
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stopping_models import Linear, ending, traces

from anytime.profiles.dynamic import DynamicProfile, QualityTraces
from anytime.runtime import (
    Decision,
    FixedStopping,
    MonitorError,
    MyopicStopping,
    OptimalStopping,
    PolicyError,
    ProjectedStopping,
    Replay,
    Utility,
    clairvoyant,
    evaluate,
    replay,
)
from anytime.runtime.policies import solve

SETTINGS = settings(max_examples=60, deadline=None)
TOLERANCE = 1e-9


@st.composite
def problems(draw: st.DrawFn) -> tuple[DynamicProfile, Linear, float]:
    m = draw(st.integers(2, 5))
    reports = draw(st.sampled_from(["true", "estimate"]))
    seed = draw(st.integers(0, 10**6))
    recorded = traces(seed, m, draw(st.integers(1, 25)), reports)
    # The state: the bin alone, or the bin and the class of the time the run entered it; with
    # runs that end by themselves in states of their own, or not.
    entered = draw(st.sampled_from([None, 2, 3]))
    ends = draw(st.booleans())
    if ends:
        recorded = ending(recorded, seed)
    states = draw(st.integers(1, 3 if entered is None else 2))
    profile = DynamicProfile.from_traces(recorded, states=states, entered=entered, ends=ends)
    model = Linear(draw(st.floats(0.5, 20)), draw(st.floats(0.0, 0.5)))
    allocation = draw(st.sampled_from([math.inf, 0.0, 15.0, 20.0, 35.0]))
    return profile, model, allocation


def policies(profile: DynamicProfile, model: Linear, cost: float = 0.0) -> dict[str, Any]:
    args = (profile, model, model)
    return {
        "fixed": FixedStopping(*args),
        "myopic": MyopicStopping(*args, monitoring_cost=cost),
        "every step": OptimalStopping(*args),
        "projected": ProjectedStopping(*args),
    }


@given(problems(), st.one_of(st.just(0.0), st.floats(0.01, 2.0)))
@SETTINGS
def test_the_optimal_policy_is_at_least_as_good_as_every_other_on_its_model(
    problem: tuple[DynamicProfile, Linear, float], cost: float
) -> None:
    """Without a monitoring cost against the others; with one, choosing when to look against
    looking at every step ("every step", myopic, projected) and never looking (fixed)."""
    profile, model, allocation = problem
    optimal = OptimalStopping(profile, model, model, monitoring_cost=cost)
    best = optimal.expected_utility(allocation)
    exact = evaluate(optimal, optimal.model, allocation, monitoring_cost=cost)
    assert exact.expected_utility == pytest.approx(best)
    for name, policy in policies(profile, model, cost).items():
        other = evaluate(policy, optimal.model, allocation, monitoring_cost=cost)
        assert other.expected_utility <= best + TOLERANCE * max(1, abs(best)), name


@given(problems())
@SETTINGS
def test_free_looks_make_looking_every_step_optimal(
    problem: tuple[DynamicProfile, Linear, float],
) -> None:
    """With a vanishing monitoring cost the policy that also chooses when to look (and may stop
    later without looking) is worth what looking at every grid time is."""
    profile, model, allocation = problem
    policy = OptimalStopping(profile, model, model)
    last = policy.model.last(allocation)
    every = solve(policy.model, last, 0.0)
    choosing = solve(policy.model, last, 1e-12)
    np.testing.assert_allclose(choosing.value, every.value, rtol=1e-9, atol=1e-9)
    assert choosing.expected_utility == pytest.approx(every.expected_utility, abs=1e-9)


@given(problems(), st.floats(0.0, 1.0))
@SETTINGS
def test_the_vectorised_expected_utilities_are_the_exact_ones(
    problem: tuple[DynamicProfile, Linear, float], cost: float
) -> None:
    profile, model, allocation = problem
    for policy in (
        FixedStopping(profile, model, model),
        MyopicStopping(profile, model, model, monitoring_cost=cost),
    ):
        charged = 0.0 if isinstance(policy, FixedStopping) else cost
        exact = evaluate(policy, policy.model, allocation, monitoring_cost=charged)
        assert policy.expected_utility(allocation) == pytest.approx(exact.expected_utility)


class Recorder:
    """Wraps a policy and keeps every decision it makes."""

    def __init__(self, policy: Any) -> None:
        self.policy, self.name, self.observed = policy, policy.name, policy.observed
        self.decisions: list[Decision] = []

    def start(self, allocation: float) -> Decision:
        self.decisions.append(self.policy.start(allocation))
        return self.decisions[-1]

    def observe(self, time: float, quality: float | None) -> Decision:
        self.decisions.append(self.policy.observe(time, quality))
        return self.decisions[-1]


@given(problems(), st.floats(0.0, 1.0), st.integers(0, 10**6), st.floats(0, 50))
@SETTINGS
def test_a_policy_never_stops_after_the_deadline(
    problem: tuple[DynamicProfile, Linear, float], cost: float, seed: int, allocation: float
) -> None:
    profile, model, _ = problem
    trace = traces(seed, len(profile.time), 1).quality[0]
    every = {
        **policies(profile, model, cost),
        "optimal": OptimalStopping(profile, model, model, monitoring_cost=cost),
    }
    for name, policy in every.items():
        watched = Recorder(policy)
        stopped = replay(watched, profile.time, trace, allocation=allocation)
        assert profile.time[stopped.stop_index] <= max(allocation, profile.time[0]), name
        going_on = [d for d in watched.decisions if not d.stop]
        assert all(d.stop_at <= allocation for d in going_on), name


def test_replay_follows_the_decisions_on_the_grid() -> None:
    class Script:
        name, observed = "script", None

        def start(self, allocation: float) -> Decision:
            return Decision.later(5, allocation, "look at 5")

        def observe(self, time: float, quality: float | None) -> Decision:
            return Decision.later(math.inf, 25, "stop at 25 without looking")

    time = [0, 10, 20, 30, 40]
    result = replay(Script(), time, [0, 0, 0.5, 0.6, 0.7], scored=[0, 0, 1, 1, 1])
    assert (result.stop_index, result.looks) == (3, 1)  # looked at 20 (the first answer after 5)
    assert replay(Script(), time, [0.1] * 5, allocation=15) == Replay(1, 1)  # at the deadline
    # A run whose module returned at 20 is over there: no look at 20, no stop at 25.
    assert replay(Script(), time, [0, 0, 0.5, 0.6, 0.7], scored=[0, 0, 1, 1, 1], ended=2) == (
        Replay(2, 0)
    )


def test_the_clairvoyant_utility_is_the_best_point_of_each_trace() -> None:
    model = Linear(10, 0.1)
    utility = Utility(model, model)
    quality = np.array([[0.0, 0.5, 0.9], [0.2, 0.3, 0.35]])
    np.testing.assert_allclose(clairvoyant([0, 10, 20], quality, utility), [7.0, 2.0])


def test_the_projection_fits_a_saturating_curve() -> None:
    recorded = traces(0, 8, 20)
    model = Linear(10, 0.05)
    policy = ProjectedStopping(DynamicProfile.from_traces(recorded, states=4), model, model)
    policy.start(math.inf)
    time = recorded.time
    curve = 0.9 - 0.8 * np.exp(-0.05 * time)
    for t, q in zip(time[:4], curve[:4], strict=True):
        policy.observe(float(t), float(q))
    np.testing.assert_allclose(policy.projection(), curve, atol=1e-3)


# --- bad input ----------------------------------------------------------------------------


def test_bad_arguments_are_clear_errors() -> None:
    profile = DynamicProfile.from_traces(traces(0, 3, 5), states=2)
    model = Linear(1, 0)
    with pytest.raises(PolicyError) as error:
        OptimalStopping(profile, model, model, monitoring_cost=-1)
    assert str(error.value) == "optimal: monitoring_cost must be a finite number >= 0, got -1"
    with pytest.raises(PolicyError) as error:
        FixedStopping(profile, model, model).start(-1.0)
    assert str(error.value) == "fixed: allocation must be a number >= 0, got -1.0"
    with pytest.raises(PolicyError) as error:
        MyopicStopping("profile", model, model)  # type: ignore[arg-type]
    assert str(error.value) == "stopping: expected a DynamicProfile, got str"
    with pytest.raises(PolicyError) as error:
        ProjectedStopping(profile, model, model, points=1)
    assert str(error.value) == "projected: points must be >= 2, got 1"
    blind = DynamicProfile.from_traces(
        QualityTraces(
            module="blind", time=[0, 1], quality=[[0.2, 0.4]], scored=[[1, 1]], reports="none"
        )
    )
    with pytest.raises(PolicyError) as error:
        ProjectedStopping(blind, model, model)
    assert str(error.value) == (
        "projected: the profile's module reports nothing of its quality; there is no trace"
        " to project"
    )
    with pytest.raises(PolicyError) as error:
        evaluate(
            FixedStopping(profile, model, model),
            FixedStopping(profile, model, model).model,
            max_paths=3,
        )
    assert str(error.value) == "evaluate: the model has 2^3 state paths, more than max_paths (3)"
    with pytest.raises(PolicyError) as error:
        replay(FixedStopping(profile, model, model), [0, 1], [0.5])
    assert str(error.value) == (
        "replay: expected time, observed and scored of one shape (m,), got [2], [1] and [2]"
    )


def test_a_model_of_the_wrong_shape_is_named() -> None:
    class Wrong:
        def value(self, state: Any, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
            return np.zeros((7, 7))

        def cost(self, state: Any, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
            return np.zeros(1)

    profile = DynamicProfile.from_traces(traces(0, 3, 5), states=2)
    with pytest.raises(MonitorError) as error:
        OptimalStopping(profile, Wrong(), Wrong())
    assert str(error.value) == (
        "monitor: the value model answered with shape [7, 7], which does not broadcast to"
        " (grid, bins) [3, 2]"
    )


def test_a_profile_over_input_qualities_is_read_at_the_given_ones() -> None:
    base = traces(1, 3, 10)
    stacked = QualityTraces(
        module="walk",
        time=base.time,
        quality=np.stack([base.quality * 0.5, base.quality]),
        scored=np.stack([base.scored, base.scored]),
        input_grids=[[0.0, 1.0]],
        inputs=["x"],
    )
    profile = DynamicProfile.from_traces(stacked, bins=[0, 0.25, 0.5, 0.75, 1])
    model = Linear(10, 0.01)
    low = OptimalStopping(profile, model, model, input_quality=[0.0])
    high = OptimalStopping(profile, model, model, input_quality=[1.0])
    assert low.expected_utility() < high.expected_utility()
    with pytest.raises(Exception) as error:
        OptimalStopping(profile, model, model)
    assert str(error.value) == "walk: expected 1 input quality, got 0"


def test_watching_a_module_that_reports_nothing_is_worth_no_more_than_not_looking() -> None:
    recorded = traces(2, 5, 30)
    blind = QualityTraces(
        module="walk",
        time=recorded.time,
        quality=recorded.quality,
        scored=recorded.scored,
        reports="none",
    )
    profile = DynamicProfile.from_traces(blind)
    model = Linear(10, 0.1)
    assert profile.n_states == 1
    assert OptimalStopping(profile, model, model).expected_utility() == pytest.approx(
        FixedStopping(profile, model, model).expected_utility()
    )


def test_a_decision_names_a_time() -> None:
    with pytest.raises(PolicyError) as error:
        Decision.later(math.nan, 10, "why")
    assert str(error.value) == "decision: look_at must be a time >= 0, got nan"
    with pytest.raises(PolicyError) as error:
        Decision(False, stop_at=-1)
    assert str(error.value) == "decision: stop_at must be a time >= 0, got -1.0"


# --- a state that remembers when the run entered its bin --------------------------------------


class Convex:
    """U = q^8 - 0.2 t / 31: only the best answers are worth much."""

    def value(self, state: Any, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return quality**8

    def cost(self, state: Any, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return 0.2 * contract / 31


def quantised_runs(seed: int, trials: int) -> QualityTraces:
    """q(t) = 1 - exp(-rate t), the rate drawn per run (log-uniform on [0.02, 1]); the module
    reports q floored to tenths, so the level alone does not say how fast a run is."""
    rng = np.random.default_rng(seed)
    rates = np.exp(rng.uniform(np.log(0.02), 0.0, trials))
    time = np.arange(32.0)
    quality = 1.0 - np.exp(-np.outer(rates, time))
    return QualityTraces(
        module="quantised",
        time=time,
        quality=quality,
        scored=np.ones(quality.shape, bool),
        estimate=np.floor(quality * 10) / 10,
        reports="estimate",
    )


def realised(policy: OptimalStopping, runs: QualityTraces, utility: Utility) -> np.ndarray:
    worth = utility(runs.time, runs.quality.T).T
    stops = [replay(policy, runs.time, runs.observed[i]).stop_index for i in range(runs.trials)]
    return worth[np.arange(runs.trials), stops]


def test_when_a_run_entered_its_level_makes_a_quantised_report_a_state_to_promise_on() -> None:
    """On the level alone the policy promises more than it realises on fresh runs (by over 3
    standard errors) and is beaten by a fixed stop; with the class of the time the run entered
    its level it realises more than both, within 2 standard errors of its promise."""
    training, fresh = quantised_runs(1, 2000), quantised_runs(2, 2000)
    model = Convex()
    utility = Utility(model, model)
    got, fixed = {}, None
    for entered in (None, 8):
        profile = DynamicProfile.from_traces(training, states=10, entered=entered)
        policy = OptimalStopping(profile, model, model)
        values = realised(policy, fresh, utility)
        se = math.hypot(values.std(ddof=1) / math.sqrt(len(values)), policy.standard_error())
        got[entered] = (values.mean(), abs(policy.expected_utility() - values.mean()) / se)
        fixed = realised(FixedStopping(profile, model, model), fresh, utility).mean()
    assert got[None][1] > 3 and got[None][0] < fixed
    assert got[8][1] < 2 and got[8][0] > fixed + 0.05 and got[8][0] > got[None][0] + 0.05


def test_the_standard_error_is_the_spread_at_the_stops_over_the_runs_learned_from() -> None:
    """On a model whose runs all stop at once, what is realised is the utility then: its
    standard deviation over the square root of the profile's runs."""
    recorded = traces(3, 4, 50)
    profile = DynamicProfile.from_traces(recorded, states=3, entered=2)
    model = Linear(1.0, 10.0)  # time costs far more than quality is worth: stop at once
    policy = OptimalStopping(profile, model, model)
    worth = Utility(model, model)(recorded.time, recorded.quality.T).T[:, 0]
    assert policy.plan().first == (2, 0) and (policy.plan().action[0] == 0).all()
    # The model's spread is over bins' mean qualities, not each run's: close, not equal.
    assert policy.standard_error() == pytest.approx(worth.std() / math.sqrt(50), rel=0.2)
    unknown = attrs.evolve(profile, samples=0)
    assert OptimalStopping(unknown, model, model).standard_error() == math.inf


def test_with_costly_looks_it_promises_what_it_does_when_a_skipped_look_cannot_see_the_class() -> (
    None
):
    """Looks cost 0.005: the policy skips grid times and, after a skip, takes the most probable
    entry class; what it promises is the exact value of that on its model, and fresh runs
    realise it within 2 standard errors, above the fixed stop."""
    training, fresh = quantised_runs(1, 2000), quantised_runs(2, 2000)
    model = Convex()
    utility = Utility(model, model)
    profile = DynamicProfile.from_traces(training, states=10, entered=8)
    policy = OptimalStopping(profile, model, model, monitoring_cost=0.005)
    plan = policy.plan()
    assert (plan.action == 2).any() and (plan.target > np.arange(32)[:, None] + 1).any()
    worth = utility(fresh.time, fresh.quality.T).T
    got = []
    for i in range(fresh.trials):
        r = replay(policy, fresh.time, fresh.observed[i])
        got.append(worth[i, r.stop_index] - 0.005 * r.looks)
    values = np.array(got)
    se = math.hypot(values.std(ddof=1) / math.sqrt(len(values)), policy.standard_error())
    assert abs(policy.expected_utility() - values.mean()) < 2 * se
    fixed = realised(FixedStopping(profile, model, model), fresh, utility).mean()
    assert values.mean() > fixed + 0.02


@given(
    st.integers(0, 10**6),
    st.integers(2, 6),
    st.integers(1, 30),
    st.sampled_from(["true", "estimate"]),
    st.integers(1, 4),
    st.sampled_from([None, 2]),
    st.floats(0.0, 0.5),
)
@SETTINGS
def test_the_fixed_stops_value_with_runs_that_end_is_the_traces_own(
    seed: int, m: int, trials: int, reports: str, states: int, entered: int | None, rate: float
) -> None:
    """Without looking, the value of stopping at each grid time is the mean over the recorded
    runs of U where each is then (at that time, or where it ended by itself): a linear utility
    needs no model, so the profile's must be exact, whatever its bins and classes. (An ended
    state's true quality is that of the runs that ended then, not of every run that ended
    before, which the runs that ended later would skew.)"""
    recorded = ending(traces(seed, m, trials, reports), seed)
    profile = DynamicProfile.from_traces(recorded, states=states, entered=entered, ends=True)
    model = Linear(1.0, rate)
    policy = FixedStopping(profile, model, model)
    worth = Utility(model, model)(recorded.time, recorded.quality.T).T  # (trials, m)
    end = recorded.end_index()
    held = np.minimum(np.arange(m), end[:, None])
    expected = worth[np.arange(trials)[:, None], held].mean(axis=0)
    np.testing.assert_allclose(policy.model.blind(m - 1), expected, atol=TOLERANCE)
