"""The navigation task: a small world runs to the goal and its numbers are consistent."""

from __future__ import annotations

import math

import pytest
from anytime_navigation.frame_program import navigation_program
from anytime_navigation.frames import run_task
from anytime_navigation.task import NavigationTask, optimal_utility
from anytime_navigation.world import random_world


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
