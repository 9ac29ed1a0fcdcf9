"""`HistoryStopping`: stopping learned from traces, on the run's history.

It must tell apart runs that the quality they show now cannot (one that stalled early from one
about to improve, one that converged and ended from one still running), promise what it then
realises on fresh runs, and reduce to the best fixed stop when looks cost more than they tell.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stopping_models import Linear, traces

from anytime.profiles.dynamic import DynamicProfile, QualityTraces
from anytime.runtime import (
    HistoryStopping,
    OptimalStopping,
    PolicyError,
    Utility,
    assess,
    clairvoyant,
    replay,
)


def kinds(
    curves: list[list[float]], copies: int, finished: list[float] | None = None
) -> QualityTraces:
    """`copies` runs of each curve (qualities at ticks 0, 1, 2, ...), one kind after the other."""
    quality = np.repeat(np.array(curves, dtype=np.float64), copies, axis=0)
    ended = None if finished is None else np.repeat(np.array(finished), copies)
    return QualityTraces(
        module="kinds",
        time=np.arange(quality.shape[1], dtype=np.float64),
        quality=quality,
        scored=np.ones(quality.shape, bool),
        finished=ended,
    )


def realised(
    policy: HistoryStopping | OptimalStopping, recorded: QualityTraces, model: Linear
) -> np.ndarray:
    """What the policy realises on each trace (looks paid), replayed as the executor runs it."""
    utility = Utility(model, model)(recorded.time, recorded.quality.T).T
    cost = getattr(policy, "monitoring_cost", 0.0)
    ends = recorded.end_index()
    values = []
    for i in range(recorded.trials):
        r = replay(policy, recorded.time, recorded.observed[i], ended=int(ends[i]))
        values.append(utility[i, r.stop_index] - cost * r.looks)
    return np.array(values)


@given(
    st.lists(st.floats(0.0, 0.2), min_size=3, max_size=12),
    st.floats(0.0, 0.2),
)
@settings(max_examples=40, deadline=None)
def test_runs_of_one_kind_stop_where_the_best_time_is(steps: list[float], rate: float) -> None:
    """When every run is the same curve, the history says all there is: the policy stops where
    the utility of that curve is highest, the clairvoyant's stop, and promises exactly that."""
    curve = np.minimum(np.cumsum(steps), 1.0)
    recorded = kinds([list(curve)], 6)
    model = Linear(1.0, rate)
    policy = HistoryStopping(recorded, Utility(model, model))
    best = clairvoyant(recorded.time, recorded.quality, Utility(model, model))
    np.testing.assert_allclose(realised(policy, recorded, model), best, atol=1e-9)
    assert policy.expected_utility() == pytest.approx(float(best[0]), abs=1e-9)


def test_a_run_that_stalled_early_is_told_from_one_about_to_improve() -> None:
    """Two kinds of run show the same quality from tick 3 to 6: one got there at tick 1 and
    never improves, the other got there at tick 3 and jumps at 7. The quality now cannot tell
    them apart (the Markov policy waits for both, or stops both); the history can."""
    stalled = [0.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]
    late = [0.0, 0.2, 0.3, 0.5, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0]
    recorded = kinds([stalled, late], 20)
    model = Linear(1.0, 0.03)
    utility = Utility(model, model)
    history = HistoryStopping(recorded, utility)
    best = clairvoyant(recorded.time, recorded.quality, utility)
    np.testing.assert_allclose(realised(history, recorded, model), best, atol=1e-9)
    markov = OptimalStopping(DynamicProfile.from_traces(recorded, states=3), model, model)
    assert realised(markov, recorded, model).mean() < best.mean() - 0.01
    # The Markov policy on (level, when the run reached it) tells them apart too.
    entered = DynamicProfile.from_traces(recorded, states=3, entered=[0, 1, 2, 3, 10])
    np.testing.assert_allclose(
        realised(OptimalStopping(entered, model, model), recorded, model), best, atol=1e-9
    )


def test_a_run_that_ended_is_not_mistaken_for_one_still_running() -> None:
    """Runs of one kind converge and return at tick 3; runs of the other are at the same
    quality there and go on improving. A run still running at tick 3 is of the second kind."""
    converged = [0.0, 0.3, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]
    running = [0.0, 0.3, 0.5, 0.5, 0.7, 0.8, 0.9, 1.0]
    recorded = kinds([converged, running], 20, finished=[3.0, 7.0])
    model = Linear(1.0, 0.05)
    utility = Utility(model, model)
    values = realised(HistoryStopping(recorded, utility), recorded, model)
    assert values[20:] == pytest.approx(np.full(20, 1.0 - 0.05 * 7))  # the running ones run on
    assert values[:20] == pytest.approx(np.full(20, 0.5 - 0.05 * 3))  # the converged ones end
    # The Markov policy on a profile with ended states learns it too; on the level alone it
    # averages the running runs with the ended ones and stops them at 0.5.
    ends = OptimalStopping(DynamicProfile.from_traces(recorded, states=3, ends=True), model, model)
    assert realised(ends, recorded, model) == pytest.approx(values)
    assert ends.expected_utility() == pytest.approx(values.mean())
    level = OptimalStopping(DynamicProfile.from_traces(recorded, states=3), model, model)
    assert realised(level, recorded, model).mean() < values.mean() - 0.05


def test_what_it_promises_is_what_fresh_runs_realise() -> None:
    """The expected utility it states (leave-one-out on its training runs) is within two
    standard errors of what it realises on runs it was not trained on, with a noisy estimate
    for a report and a cost per look."""
    training, fresh = traces(1, 12, 400, "estimate"), traces(2, 12, 400, "estimate")
    model = Linear(1.0, 0.004)
    for cost in (0.0, 0.01):
        policy = HistoryStopping(training, Utility(model, model), monitoring_cost=cost)
        values = realised(policy, fresh, model)
        se = math.hypot(values.std(ddof=1) / math.sqrt(len(values)), policy.standard_error())
        assert abs(policy.expected_utility() - values.mean()) < 2 * se, cost


def test_looks_that_cost_more_than_they_tell_are_not_taken() -> None:
    """When a look costs more than anything it could reveal, the policy stops at the best
    fixed time without looking, and promises that time's mean utility."""
    recorded = traces(3, 10, 200)
    model = Linear(1.0, 0.002)
    utility = Utility(model, model)
    policy = HistoryStopping(recorded, utility, monitoring_cost=10.0)
    decision = policy.start(math.inf)
    mean = utility(recorded.time, recorded.quality.T).T.mean(axis=0)
    assert (decision.look_at, decision.stop_at) == (math.inf, recorded.time[int(np.argmax(mean))])
    assert policy.expected_utility() == pytest.approx(mean.max())


def test_bad_arguments_are_named() -> None:
    recorded = traces(1, 5, 10)
    model = Linear(1.0, 0.0)
    utility = Utility(model, model)
    with pytest.raises(PolicyError) as error:
        HistoryStopping("traces", utility)  # type: ignore[arg-type]
    assert str(error.value) == "history: expected QualityTraces to learn from, got str"
    with pytest.raises(PolicyError) as error:
        HistoryStopping(recorded.select([0]), utility)
    assert str(error.value) == "history: expected at least 2 training traces, got 1"
    with pytest.raises(PolicyError) as error:
        HistoryStopping(recorded, utility, neighbours=0)
    assert str(error.value) == "history: neighbours must be an integer >= 1, got 0"
    with pytest.raises(PolicyError) as error:
        HistoryStopping(recorded, utility, monitoring_cost=-1)
    assert str(error.value) == "history: monitoring_cost must be a finite number >= 0, got -1"
    with pytest.raises(PolicyError) as error:
        HistoryStopping(recorded, utility, input_quality=[0.5])
    assert str(error.value) == (
        "history: the traces have 0 input-quality axes, got 1 input qualities"
    )
    with pytest.raises(PolicyError) as error:
        HistoryStopping(recorded, utility).start(-1)
    assert str(error.value) == "history: allocation must be a number >= 0, got -1"


def test_assess_scores_a_policy_as_replaying_each_run_does() -> None:
    """`assess` is the replay of every run, scored at its stop, looks paid, against the best
    each run allowed (up to its own end)."""
    recorded = kinds([[0.0, 0.3, 0.5, 0.5, 0.5], [0.0, 0.2, 0.4, 0.6, 0.9]], 3, [2.0, 4.0])
    model = Linear(1.0, 0.05)
    utility = Utility(model, model)
    policy = HistoryStopping(recorded, utility, monitoring_cost=0.01)
    got = assess(policy, recorded, utility, monitoring_cost=0.01)
    values = realised(policy, recorded, model)
    assert (got.utility, got.runs) == (pytest.approx(values.mean()), 6)
    assert got.standard_error == pytest.approx(values.std(ddof=1) / math.sqrt(6))
    assert got.clairvoyant == pytest.approx((0.5 - 0.05 * 2 + 0.9 - 0.05 * 4) / 2)
    assert got.fraction == pytest.approx(got.utility / got.clairvoyant)
    with pytest.raises(PolicyError) as error:
        assess(policy, recorded, utility, allocation=-1.0)
    assert str(error.value) == "assess: allocation must be a number >= 0, got -1.0"


def test_tied_neighbours_are_the_first_runs() -> None:
    """Runs whose reports are alike (here, identical) are equally near: each run's nearest are
    the first of the others in run order, whatever numpy's selection would pick, so a policy's
    promise does not change with numpy's version or the machine."""
    recorded = kinds([[0.0, 0.5, 0.5, 1.0], [0.0, 0.2, 0.6, 0.9]], 12)
    model = Linear(1.0, 0.05)
    policy = HistoryStopping(recorded, Utility(model, model))
    members, order = policy._neighbourhood(2)
    assert members.tolist() == list(range(24))
    for row, run in enumerate(members.tolist()):
        same_kind = range(12) if run < 12 else range(12, 24)
        others = [r for r in same_kind if r != run]
        width = min(order.shape[1], len(others))
        assert members[order[row, :width]].tolist() == others[:width]
