"""The monitor's prediction of the task's utility is the median of its model's distribution
(over the training worlds when the task is presented), the point of least expected absolute
error; the contract is still chosen on the expected utility."""

from __future__ import annotations

import numpy as np
import pytest
from anytime_navigation.task.calibration import task_value
from anytime_navigation.task.frame_program import navigation_program
from anytime_navigation.task.frames import _TaskRun, run_task
from anytime_navigation.task.model import FirstDecision, NavigationTask, weighted_median
from anytime_navigation.world import random_world


def test_weighted_median():
    assert weighted_median([3.0, 1.0, 2.0], [1.0, 1.0, 1.0]) == 2.0
    assert weighted_median([1.0, 2.0, 3.0], [0.2, 0.2, 0.6]) == 3.0
    assert weighted_median([1.0, 2.0, 3.0], [0.5, 0.0, 0.5]) == 1.0  # the smallest at a half
    assert weighted_median([5.0, -1.0], [0.0, 1.0]) == -1.0
    with pytest.raises(ValueError, match="positive weight"):
        weighted_median([1.0], [0.0])


@pytest.fixture(scope="module")
def program():
    return navigation_program()


def test_the_prediction_is_the_median_over_the_training_worlds(program):
    compiled, trace = program
    seed = 11
    world = random_world(64, seed=seed)
    task = NavigationTask(world, radius=16, value=task_value(64), seed=seed)
    run = _TaskRun(task, compiled, trace, "monitored", None, "work", (), None)
    decision, _ = run.decide(0.0, world.start, np.zeros_like(run.truth), None)
    assert isinstance(decision, FirstDecision)
    # a few training worlds in which the robot wandered pull the mean below the median
    assert decision.median_utility > decision.expected_utility
    report = run_task(task, compiled, trace, policy="monitored")
    assert report.predicted_utility == decision.median_utility
    assert report.records[0].predicted_utility == decision.median_utility
    assert report.records[0].contract == decision.contract
    later = [r.predicted_utility for r in report.records[1:]]
    assert later and all(np.isfinite(later))
