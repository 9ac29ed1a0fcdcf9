"""`execute(believed=, penalty=)`: obstacle avoidance plans around the obstacles of the robot's
map (costly, not impassable) rather than with the free-space assumption alone; the frames use
it for a plan that runs through cells blocked on its own map (`frames._crosses_its_map`)."""

from __future__ import annotations

import numpy as np
import pytest
from anytime_navigation.planning.planner import MultiPath, Segment
from anytime_navigation.task import frames
from anytime_navigation.task.execution import execute
from anytime_navigation.task.frames import _crosses_its_map


def _wall_world() -> np.ndarray:
    """24 x 24: a wall 6 cells thick (x 10-15) from y = 4 down to the bottom edge: the way past
    it is above (a penalty of 8 per cell makes crossing it, 48, dearer than the way round)."""
    grid = np.zeros((24, 24), dtype=bool)
    grid[4:, 10:16] = True
    return grid


# A plan made on a map without the wall, through it at (12, 18), toward the goal below it.
PLAN = [(4, 18), (12, 18), (20, 18)]


def test_the_free_space_robot_feels_down_the_wall_first():
    executed = execute(PLAN, _wall_world())
    assert executed.reached
    assert max(y for _, y in executed.route) > 19  # tried the wall's foot: it has none


def test_the_robot_that_read_the_wall_goes_round_above_at_once():
    grid = _wall_world()
    free_space = execute(PLAN, grid)
    read = execute(PLAN, grid, believed=grid, penalty=8.0)
    assert read.reached
    assert max(y for _, y in read.route) <= 18
    assert read.length < free_space.length


def test_a_false_reading_is_crossed_at_its_cost():
    grid = np.zeros((10, 10), dtype=bool)
    believed = np.zeros_like(grid)
    believed[2:8, 5] = True  # read blocked, in truth free
    executed = execute([(2, 5), (8, 5)], grid, believed=believed, penalty=1.0)
    assert executed.route == tuple((x, 5) for x in range(2, 9))  # 1 extra beats a detour of 6


def test_believed_is_off_by_default_and_checked():
    grid = _wall_world()
    assert execute(PLAN, grid) == execute(PLAN, grid, believed=None)
    assert execute(PLAN, grid) == execute(PLAN, grid, believed=grid, penalty=0.0)
    with pytest.raises(ValueError, match="penalty"):
        execute(PLAN, grid, believed=grid, penalty=-1.0)
    with pytest.raises(ValueError, match="believed"):
        execute(PLAN, grid, believed=grid[:5], penalty=1.0)


def test_a_plan_crossing_its_own_map():
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[3, 4] = True
    cells = [(x, 3) for x in range(8)]
    through = MultiPath((0, 3), (7, 3), (Segment(0, cells),))
    assert _crosses_its_map(through, blocked, (0, 3), (7, 3))
    coarse = MultiPath((0, 3), (7, 3), (Segment(1, [(0, 1), (1, 1), (2, 1), (3, 1)]),))
    assert not _crosses_its_map(coarse, blocked, (0, 3), (7, 3))  # a block is not a cell
    blocked[3, 4] = False
    blocked[3, 0] = blocked[3, 7] = True  # the start and goal count as free: the planner's
    assert not _crosses_its_map(through, blocked, (0, 3), (7, 3))
    assert not _crosses_its_map(None, blocked, (0, 3), (7, 3))


def test_the_frames_use_it():
    assert frames.PENALTY > 0
