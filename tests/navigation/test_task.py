"""The navigation task: a small world runs to the goal and its numbers are consistent."""

from __future__ import annotations

import math

import attrs
import numpy as np
import pytest
from anytime_navigation.task.calibration import task_value
from anytime_navigation.task.frame_program import navigation_program
from anytime_navigation.task.frames import run_task
from anytime_navigation.task.model import FrameState, NavigationTask, TaskModel, optimal_utility
from anytime_navigation.world import random_world
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.plugin.compose import DeadlineValue


@pytest.fixture(scope="module")
def program():
    return navigation_program()


@pytest.mark.parametrize("policy", ["monitored", "min", "max"])
def test_task_reaches_goal_consistently(program, policy):
    compiled, trace = program
    task = NavigationTask(random_world(32, seed=3), radius=8, seed=3)
    report = run_task(task, compiled, trace, policy=policy)
    assert report.reached and report.route[-1] == task.world.goal
    assert report.route[0] == task.world.start
    assert report.frames > 1
    assert math.isclose(report.utility, report.value - report.energy)
    assert report.route_length >= report.optimal_length - 1e-9
    best, _ = optimal_utility(task, report.optimal_length)
    assert report.optimal_utility == best
    assert math.isclose(
        report.prediction_error,
        abs(report.utility - report.predicted_utility) / abs(report.predicted_utility),
    )


def test_fixed_policy_needs_a_contract(program):
    compiled, trace = program
    with pytest.raises(ValueError, match="contract"):
        run_task(NavigationTask(random_world(16, seed=0)), compiled, trace, policy="fixed")


# --- the monitor's model of the task ------------------------------------------------------------


@pytest.fixture(scope="module")
def model(program):
    compiled, _ = program
    return TaskModel(NavigationTask(random_world(32, seed=3), radius=8), compiled.profile)


def test_later_frames_are_stretched_by_at_least_the_shortest_route(model):
    factor = model.later_factor(model.profile.time)
    assert np.all(factor >= 1.0)
    assert factor[0] == 1.0 / model.floor  # nothing planned: every plan at the floor


@settings(max_examples=50, deadline=None)
@given(
    remaining=st.floats(1.0, 500.0),
    step=st.floats(1.0, 64.0),
    speed=st.sampled_from([0.05, 0.1, 0.15, 0.2]),
    contract=st.sampled_from([200.0, 600.0, 1000.0]),
)
def test_the_plan_being_made_stretches_only_its_own_frame(model, remaining, step, speed, contract):
    # Without a deadline the plan's frames go at the slowest speed, whatever the state's (the
    # speed of a segment walked meanwhile: none here).
    untimed = attrs.evolve(model, task=attrs.evolve(model.task, value=DeadlineValue(1.0, 0, 0)))
    state = FrameState(0.0, remaining, speed, step, waiting=True)
    c, q = np.array([[contract]]), np.array([[1.0, 0.5]])
    cost = np.asarray(untimed.cost(state, c, q)).reshape(-1)
    this = min(remaining, step)
    slowest = float(model.task.energy(min(model.task.speeds)))
    assert math.isclose(cost[1] - cost[0], slowest * this, rel_tol=1e-9)


@settings(max_examples=50, deadline=None)
@given(now=st.floats(0.0, 3000.0), cells=st.floats(0.0, 200.0))
def test_the_last_segments_speed_is_the_best_of_the_grid(model, now, cells):
    task = model.task
    best = model.last_speed(now, cells)
    utilities = {
        v: float(task.value(now + cells / v)) - float(task.energy(v)) * cells for v in task.speeds
    }
    assert utilities[best] == max(utilities.values())


def test_each_frame_records_the_prediction_its_decision_logged(program):
    compiled, trace = program
    task = NavigationTask(random_world(32, seed=3), radius=8, seed=3)
    report = run_task(task, compiled, trace)
    logged = [event.data["predicted_utility"] for event in report.log.of_kind("contract")]
    assert [r.predicted_utility for r in report.records] == logged[: report.frames]
    assert report.records[0].predicted_utility == report.predicted_utility
    last = report.records[-1]
    assert last.speed == TaskModel(task).last_speed(last.exec_start, len(last.route) - 1)


def test_the_later_factor_needs_a_profile():
    model = TaskModel(NavigationTask(random_world(16, seed=0)))
    with pytest.raises(ValueError) as error:
        model.later_factor(np.array([600.0]))
    assert str(error.value) == "the task model has no profile: later frames are not modelled"


@pytest.mark.parametrize(
    ("movement", "position", "expected"),
    [
        (4, (0, 0), 16.0),  # toward the far corner: the window's edge is r away on both axes
        (4, (31, 0), 8.0),  # straight down
        (4, (28, 29), 5.0),  # the goal is inside the window
        (8, (0, 0), 8.0 * math.sqrt(2.0)),
        (4, (31, 31), 1.0),  # on the goal: at least one cell
    ],
    ids=["diagonal", "axis", "near-goal", "octile", "on-goal"],
)
def test_the_first_frames_progress_is_a_straight_line_to_the_windows_edge(
    movement, position, expected
):
    world = random_world(32, seed=3)
    task = NavigationTask(attrs.evolve(world, movement=movement), radius=8)
    assert TaskModel(task).first_step(position) == pytest.approx(expected)


def test_a_declined_adjustment_keeps_the_speed(program):
    compiled, trace = program
    # A world where one is declined: the benchmark's deadline on a 64 x 64 world.
    task = NavigationTask(random_world(64, seed=4), radius=16, seed=4, value=task_value(64))
    report = run_task(task, compiled, trace)
    said = [a for r in report.records for a in r.adjustments]
    assert set(said) <= {"faster", "slower", "hold", "faster declined", "slower declined"}
    assert "faster declined" in said
    contracts = report.log.of_kind("contract")
    for record in report.records[:-1]:  # the next frame's decision chose this one's speed
        if all(a.endswith(("hold", "declined")) for a in record.adjustments):
            assert record.speed == contracts[record.index + 1].data["speed"]
