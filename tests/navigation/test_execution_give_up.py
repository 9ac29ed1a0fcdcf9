"""`execute(give_up=)`: a waypoint the way to which has turned long is given up for the next one
(the task's frames follow plans made before the segment before them was walked, whose
waypoints may lie behind walls the robot has found since); off by default."""

from __future__ import annotations

import numpy as np
import pytest
from anytime_navigation.task import frames
from anytime_navigation.task.execution import execute, optimal_length


def _pocket_world() -> np.ndarray:
    """20 x 20: a wall at x = 10 from the top down to y = 15, and right of it a pocket (x 11-12,
    y 4-6) closed on top (y = 3) and on the right (x = 13, y 3-7), open only below."""
    grid = np.zeros((20, 20), dtype=bool)
    grid[0:16, 10] = True
    grid[3, 11:14] = True
    grid[3:8, 13] = True
    return grid


# A plan made on a map without the wall: straight along y = 5, through the wall (10, 5), whose
# next free waypoint (11, 5) is in the pocket, reachable only round the wall's foot.
PLAN = [(0, 5), (10, 5), (11, 5), (19, 5)]


def test_the_old_robot_goes_round_into_the_pocket_and_out_again():
    executed = execute(PLAN, _pocket_world())
    assert executed.reached
    assert (11, 5) in executed.route  # every reachable waypoint is reached, however far round


def test_a_waypoint_the_way_to_which_turned_long_is_given_up():
    grid = _pocket_world()
    old = execute(PLAN, grid)
    new = execute(PLAN, grid, give_up=2.0)
    assert new.reached
    assert (11, 5) not in new.route and (12, 5) not in new.route  # never into the pocket
    assert new.length < old.length
    optimal = optimal_length(grid, (0, 5), (19, 5))
    assert optimal is not None and optimal <= new.length
    # every step a legal move onto a free cell
    route = np.asarray(new.route)
    assert (np.abs(np.diff(route, axis=0)).sum(axis=1) == 1).all()
    assert not grid[route[:, 1], route[:, 0]].any()


def test_a_near_waypoint_round_a_small_obstacle_is_kept():
    # A short way round (within the slack) is no reason to give a waypoint up.
    grid = np.zeros((12, 12), dtype=bool)
    grid[3:8, 5] = True
    plan = [(0, 5), (6, 5), (11, 5)]
    executed = execute(plan, grid, give_up=2.0)
    assert executed.reached and (6, 5) in executed.route


def test_the_goal_is_never_given_up():
    grid = _pocket_world()
    executed = execute([(0, 5), (11, 5)], grid, give_up=1.0)  # the goal is in the pocket
    assert executed.reached and executed.route[-1] == (11, 5)


def test_give_up_is_off_by_default_and_checked():
    grid = _pocket_world()
    assert execute(PLAN, grid) == execute(PLAN, grid, give_up=None)
    with pytest.raises(ValueError, match="give_up"):
        execute(PLAN, grid, give_up=0.5)


def test_the_frames_give_up():
    assert frames.GIVE_UP is not None and frames.GIVE_UP >= 1.0
