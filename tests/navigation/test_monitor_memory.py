"""What the robot saw around itself stays known: the cells next to the cells it stood on keep
their true state in its map whatever vision reads later, and obstacle avoidance remembers the
blocked ones from frame to frame."""

from __future__ import annotations

import numpy as np
import pytest
from anytime_navigation.task.calibration import task_value
from anytime_navigation.task.frame_program import navigation_program
from anytime_navigation.task.frames import _near, run_task
from anytime_navigation.task.model import NavigationTask
from anytime_navigation.world import random_world


@pytest.fixture(scope="module")
def program():
    return navigation_program()


def test_near_is_the_cells_within_one_move():
    near = _near([(0, 0), (3, 2)], (5, 6))
    expected = np.zeros((5, 6), dtype=bool)
    expected[0:2, 0:2] = True
    expected[1:4, 2:5] = True
    assert (near == expected).all()


@pytest.mark.parametrize("policy, contract", [("fixed", 400.0), ("monitored", None)])
def test_what_the_robot_saw_around_itself_stays_in_its_map(program, policy, contract):
    compiled, trace = program
    seed = 7
    world = random_world(64, seed=seed)
    task = NavigationTask(world, radius=16, value=task_value(64), seed=seed)
    report = run_task(task, compiled, trace, policy=policy, contract=contract)
    truth = np.asarray(world.blocked, dtype=bool)
    assert report.frames > 2
    walked: list[tuple[int, int]] = []
    for record in report.records:
        if walked:  # vision read this frame's window afresh, with its errors
            seen = _near(walked, truth.shape)
            assert (record.known[seen] == truth[seen]).all()
        walked += record.route
