"""The ATP's options chosen by the map's shape (issue 36): `MapShape` reads how scattered and
how dense a map's obstacles are, and `map_options` plans maps of scattered, dense obstacles with
`SCATTERED_MAP_OPTIONS`, maps of solid obstacles (thick walls, blocks of buildings) with
`SOLID_MAP_OPTIONS`, every other with `LARGE_MAP_OPTIONS`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import load_map
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.planner import (
    LARGE_MAP_OPTIONS,
    SCATTERED_MAP_OPTIONS,
    SOLID_MAP_OPTIONS,
    MapShape,
    atp,
    map_follows,
    map_options,
)
from anytime_navigation.resources import data_file
from anytime_navigation.task.execution import execute
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from anytime.modules import Context


def _grid(rows: str) -> np.ndarray:
    return np.array([[c == "@" for c in row] for row in rows.split()], dtype=bool)


def test_one_lone_obstacle() -> None:
    """One blocked cell among free ones: lone (no blocked neighbour), and every cell is beside
    a free one."""
    shape = MapShape.of(_grid(".... .@.. .... ...."))
    assert shape == MapShape(1 / 15, 1 / 16, 0.0)


def test_obstacles_that_touch_are_not_lone() -> None:
    """Two blocked cells side by side are not lone; touching by a corner, both are (4-neighbours
    only); the outside counts as blocked, so a cell at the edge is not lone."""
    assert MapShape.of(_grid("..... .@@.. .....")).lone_obstacles_per_free_cell == 0.0
    assert MapShape.of(_grid("..... .@... ..@.. .....")) == MapShape(2 / 18, 2 / 20, 0.0)
    assert MapShape.of(_grid("@.... ..... .....")).lone_obstacles_per_free_cell == 0.0


def test_blocked_far_from_free_cells_is_not_counted() -> None:
    """A thick wall's inside is not beside any free cell: only its rim counts as blocked near
    free cells, and the rest is solid (the outside counts as blocked)."""
    blocked = np.zeros((6, 6), dtype=bool)
    blocked[:, 2:] = True  # columns 2-5 blocked: column 2 is beside a free cell, 3-5 are not
    assert MapShape.of(blocked) == MapShape(0.0, 6 / 18, 18 / 24)


def test_a_map_without_free_cells() -> None:
    assert MapShape.of(np.ones((3, 3), dtype=bool)) == MapShape(0.0, 1.0, 1.0)


def test_a_map_without_blocked_cells() -> None:
    assert MapShape.of(np.zeros((3, 3), dtype=bool)) == MapShape(0.0, 0.0, 0.0, 1.0)


def test_free_cells_in_clear_blocks() -> None:
    """Blocks of 16 x 16 from the corner, the last ones cut by the map's edge: a blocked cell
    takes its block's free cells out of open ground, and only its block's."""
    blocked = np.zeros((20, 40), dtype=bool)  # blocks of 16 x 16, 16 x 8, 4 x 16 and 4 x 8
    blocked[2, 20] = True  # in the second block of the first row of blocks
    assert MapShape.of(blocked).free_in_clear_blocks == (800 - 256) / 799
    blocked[18, 36] = True  # in the last, cut block: 4 x 8 cells
    assert MapShape.of(blocked).free_in_clear_blocks == (800 - 256 - 32) / 798
    assert MapShape.of(blocked).open  # 0.64 >= `MapShape.OPEN`


def test_open_ground_is_followed() -> None:
    """`map_follows`: the maps of open ground, rooms 32 cells wide, are planned following each
    plan; a random map, rooms 8 wide and solid blocks with no clear block between them not."""
    rooms = np.zeros((128, 128), dtype=bool)
    rooms[::32, :] = rooms[:, ::32] = True
    assert MapShape.of(rooms).free_in_clear_blocks == pytest.approx(0.26, abs=0.01)
    assert map_follows(rooms)
    small = np.zeros((128, 128), dtype=bool)
    small[::8, :] = small[:, ::8] = True
    assert not map_follows(small)
    assert not map_follows(_random(0.10))


@given(arrays(np.bool_, st.tuples(st.integers(1, 12), st.integers(1, 12))))
def test_the_shape_is_the_same_turned_or_mirrored(blocked: np.ndarray) -> None:
    shape = MapShape.of(blocked)
    assert shape.lone_obstacles_per_free_cell >= 0.0
    assert 0.0 <= shape.blocked_near_free <= 1.0
    assert 0.0 <= shape.solid_obstacles <= 1.0
    for turned in (blocked.T, blocked[::-1], blocked[:, ::-1], np.rot90(blocked)):
        assert MapShape.of(turned) == shape


def _random(share: float, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).random((128, 128)) < share


def _blocks(seed: int = 0) -> np.ndarray:
    """A town of solid blocks: 40 rectangles of 6-20 cells a side on 128 x 128."""
    rng = np.random.default_rng(seed)
    blocked = np.zeros((128, 128), dtype=bool)
    for x, y, w, h in rng.integers((0, 0, 6, 6), (120, 120, 21, 21), size=(40, 4)):
        blocked[y : y + h, x : x + w] = True
    return blocked


@pytest.mark.parametrize(
    ("blocked", "options"),
    [
        (_random(0.10), LARGE_MAP_OPTIONS),  # scattered, not dense
        (_random(0.20), LARGE_MAP_OPTIONS),
        (_random(0.25), SCATTERED_MAP_OPTIONS),
        (_random(0.35), SCATTERED_MAP_OPTIONS),
        (np.zeros((64, 64), dtype=bool), LARGE_MAP_OPTIONS),  # open ground
        (_blocks(), SOLID_MAP_OPTIONS),
        (_blocks() | _random(0.02), SOLID_MAP_OPTIONS),  # a few scattered among them
    ],
)
def test_maps_get_the_options_of_their_shape(blocked: np.ndarray, options: object) -> None:
    assert map_options(blocked) is options


@pytest.mark.parametrize(
    ("name", "options"),
    [
        ("random512-10-0", LARGE_MAP_OPTIONS),
        ("8room_000", LARGE_MAP_OPTIONS),
        ("maze512-1-0", LARGE_MAP_OPTIONS),
        ("arena", SOLID_MAP_OPTIONS),
    ],
)
def test_the_shipped_maps_options(name: str, options: object) -> None:
    """Random 10% is scattered but not dense (0.100 blocked near free cells); rooms of 8 and
    the maze have no lone obstacles and walls one cell thick; the arena's walls are solid (0.86
    of its blocked cells have no free neighbour)."""
    blocked = load_map(Path(str(data_file("maps", f"{name}.map"))))[0]
    shape = MapShape.of(blocked)
    assert (shape.solid_obstacles >= MapShape.SOLID) == (options is SOLID_MAP_OPTIONS)
    assert map_options(blocked) is options


def test_the_scattered_options_plan_to_the_goal() -> None:
    """Planned with the scattered-map options to completion, a dense random map's plan is
    followed to the goal, no shorter than the straight line."""
    blocked = _random(0.3, seed=4)
    blocked[2, 2] = blocked[125, 125] = False
    plans = list(
        atp(Context(), (2, 2), (125, 125), Pyramid.build(blocked), movement=8,
            **SCATTERED_MAP_OPTIONS)
    )  # fmt: skip
    run = execute(plans[-1].value, blocked, movement=8, keep_to_plan=True)
    assert run.reached
    assert run.length >= 123 * np.sqrt(2)


def test_the_solid_options_plan_to_the_goal() -> None:
    """Planned with the solid-map options to completion, a town's plan is followed to the goal,
    no shorter than the straight line."""
    blocked = _blocks(seed=1)
    start, goal = (1, 126), (126, 1)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    plans = list(
        atp(Context(), start, goal, Pyramid.build(blocked), movement=8, **SOLID_MAP_OPTIONS)
    )
    run = execute(plans[-1].value, blocked, movement=8, keep_to_plan=True)
    assert run.reached
    assert run.length >= 125 * np.sqrt(2)
