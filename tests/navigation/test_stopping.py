"""The navigation task's `stopping` policy: the monitor's contract as an upper bound, the
planner stopped within it by optimal stopping over its dynamic profile, with the task model's
utility."""

from __future__ import annotations

import attrs
import numpy as np
import pytest
from anytime_navigation.task.frame_program import PlanTrace, navigation_program
from anytime_navigation.task.frames import _TaskRun, run_task
from anytime_navigation.task.model import FrameState, FromPlannerStart, NavigationTask, TaskModel
from anytime_navigation.world import random_world
from hypothesis import given, settings
from hypothesis import strategies as st


@pytest.fixture(scope="module")
def program():
    return navigation_program()


def stuck_task():
    """A 128 x 128 world (docs/navigation.md's) where planning, not walking, takes two frames'
    time: the policy stops those planners before their contract."""
    return NavigationTask(random_world(128, seed=4), radius=32, seed=4)


@pytest.fixture(scope="module")
def report(program):
    compiled, trace = program
    return run_task(stuck_task(), compiled, trace, policy="stopping")


def test_the_planners_dynamic_profile_is_shipped(program):
    _, trace = program
    dynamic = trace.dynamic
    assert dynamic.module == "find-path"
    assert dynamic.observed == "estimate"
    assert dynamic.inputs == ("domain",)


def test_the_stopping_policy_needs_a_dynamic_profile(program):
    compiled, _ = program
    task = NavigationTask(random_world(16, seed=0))
    with pytest.raises(ValueError) as error:
        run_task(task, compiled, PlanTrace(), policy="stopping")
    assert str(error.value) == (
        "the stopping policy needs the planner's dynamic profile (find-path.dynamic.yaml beside"
        " find-path.yaml; `anytime profile find-path --dynamic` measures it)"
    )


def test_the_task_is_done(report):
    assert report.reached and report.policy == "stopping"
    assert report.utility == pytest.approx(report.value - report.energy)


def test_every_frame_has_its_decisions_in_the_event_log(report):
    events = report.log.of_kind("stopping")
    frames = {e.data["frame"] for e in events}
    assert frames == {r.index for r in report.records}
    assert {e.data["policy"] for e in events} == {"optimal"}
    for record in report.records:
        mine = [e for e in events if e.data["frame"] == record.index]
        start = report.log.of_kind("contract")[record.index].time
        # Logged at task times within the frame's planning, the last one saying why it ended.
        assert all(start <= e.time <= start + record.contract + 1e-9 for e in mine)
        assert [e.time for e in mine] == sorted(e.time for e in mine)
        stops = [e for e in mine if e.data["decision"] == "stop"]
        assert (record.stopped_at is not None) == bool(stops)
        if record.stopped_at is not None:
            assert stops == [mine[-1]]
            assert mine[-1].time == pytest.approx(start + record.stopped_at)


def test_a_planner_is_never_stopped_after_its_contract(report):
    assert all(r.stopped_at is None or r.stopped_at <= r.contract + 1e-9 for r in report.records)


def test_where_the_policy_stops_planners_early(report):
    stopped = [(r.index, r.contract, r.stopped_at) for r in report.records if r.stopped_at]
    assert stopped == [(2, 1000.0, 947.0), (3, 1000.0, 908.0)]
    reasons = [e.data["reason"] for e in report.log.of_kind("stopping") if e.data["frame"] == 2]
    assert reasons == [
        "expected utility 767.717",
        "going on is worth 767.722",
        "going on is worth 767.916",
        "stopping now is worth 767.74, going on less",
    ]


def test_a_planner_stopped_early_ends_its_frames_planning(program, report):
    compiled, trace = program
    monitored = run_task(stuck_task(), compiled, trace, policy="monitored")
    assert report.predicted_utility == monitored.predicted_utility
    assert report.records[0].contract == monitored.records[0].contract
    # Frame 2's planner, stopped at 947 ticks instead of its contract of 1000 while the robot
    # walks frame 1's segment (800 ticks), ends frame 1 53 ticks sooner; frame 3's, stopped at
    # 908 against a walk of 920, ends frame 2 80 ticks sooner: the later frames start that
    # much sooner, and so does the task end. The utility is the same: the value is the full
    # 1000 at either time.
    ahead = [b.start - a.start for a, b in zip(report.records, monitored.records, strict=True)]
    assert ahead == [0.0, 0.0, 0.0, 53.0, 133.0, 133.0]
    assert report.completion_time == monitored.completion_time - 133.0
    assert report.utility == monitored.utility


@pytest.fixture(scope="module")
def model(program):
    compiled, _ = program
    return TaskModel(NavigationTask(random_world(64, seed=1), radius=16), compiled.profile)


@settings(max_examples=30, deadline=None)
@given(
    offset=st.floats(0, 600),
    time=st.floats(0, 2000),
    quality=st.floats(0.0, 1.0),
    waiting=st.booleans(),
)
def test_the_planners_time_is_the_programs_less_the_sensing(model, offset, time, quality, waiting):
    state = FrameState(100.0, 90.0, 0.1, 30.0, waiting, 12.0, 1.1)
    shifted = FromPlannerStart(model, offset)
    t, q = np.array([time]), np.array([quality])
    assert shifted.value(state, t, q) == model.value(state, offset + t, q)
    assert shifted.cost(state, t, q) == model.cost(state, offset + t, q)


def test_the_policys_utility_is_the_task_models(program):
    compiled, trace = program
    task = NavigationTask(random_world(64, seed=1), radius=16, seed=1)
    run = _TaskRun(task, compiled, trace, "stopping", None, "work", (), None)
    state = FrameState(0.0, 120.0, 0.1, 30.0, True)
    policy = run.stopper(state, 0.9, 200.0)
    times = policy.model.time
    utility = policy.model.utility(times, np.full((len(times), 1), 0.8))[:, 0]
    # The policy's quality is its plan's: the model reads it as a plan's, not the route's.
    plans = attrs.evolve(run.model, route_quality=False)
    assert run.model.route_quality  # a calibrated size
    expected = [plans.utility(state, 200.0 + t, 0.8) for t in times]
    assert utility == pytest.approx(expected, rel=1e-12)
