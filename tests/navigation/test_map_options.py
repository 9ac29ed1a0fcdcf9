"""The ATP's options chosen by the map's shape (issue 36): `MapShape` reads how scattered and
how dense a map's obstacles are, and `map_options` plans small maps with `SMALL_MAP_OPTIONS`
(one search of every cell), other maps of walls (no scattered obstacles:
rooms, mazes, streets, caves) with `SMALL_WALLED_MAP_OPTIONS` (the direct route over the whole
map) or `WALLED_MAP_OPTIONS` (through the first plan's corridor) as they have fewer free cells
than `SMALL_WALLED_MAP_FREE_CELLS` or not (dense walls, narrow mazes, with
`LARGE_MAP_OPTIONS`), maps of scattered obstacles with `SPARSE_MAP_OPTIONS`,
`WALLED_MAP_OPTIONS` or `SCATTERED_MAP_OPTIONS` as they are sparse, neither or dense."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import load_map
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import (
    LARGE_MAP_OPTIONS,
    SCATTERED_MAP_OPTIONS,
    SMALL_MAP_FREE_CELLS,
    SMALL_MAP_OPTIONS,
    SMALL_WALLED_MAP_FREE_CELLS,
    SMALL_WALLED_MAP_OPTIONS,
    SPARSE_MAP_OPTIONS,
    WALLED_MAP_OPTIONS,
    MapShape,
    atp,
    map_options,
    registers_no_fall,
)
from anytime_navigation.planning.search import GridAstar
from anytime_navigation.resources import data_file
from anytime_navigation.task.execution import execute
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from anytime.modules import Context


def _grid(rows: str) -> np.ndarray:
    return np.array([[c == "@" for c in row] for row in rows.split()], dtype=bool)


def test_one_lone_obstacle() -> None:
    """One blocked cell among free ones: lone (no blocked neighbour), and every cell is beside
    a free one."""
    shape = MapShape.of(_grid(".... .@.. .... ...."))
    assert shape == MapShape(1 / 15, 1 / 16)


def test_obstacles_that_touch_are_not_lone() -> None:
    """Two blocked cells side by side are not lone; touching by a corner, both are (4-neighbours
    only); the outside counts as blocked, so a cell at the edge is not lone."""
    assert MapShape.of(_grid("..... .@@.. .....")).lone_obstacles_per_free_cell == 0.0
    assert MapShape.of(_grid("..... .@... ..@.. .....")) == MapShape(2 / 18, 2 / 20)
    assert MapShape.of(_grid("@.... ..... .....")).lone_obstacles_per_free_cell == 0.0


def test_blocked_far_from_free_cells_is_not_counted() -> None:
    """A thick wall's inside is not beside any free cell: only its rim counts as blocked near
    free cells (the outside counts as blocked)."""
    blocked = np.zeros((6, 6), dtype=bool)
    blocked[:, 2:] = True  # columns 2-5 blocked: column 2 is beside a free cell, 3-5 are not
    assert MapShape.of(blocked) == MapShape(0.0, 6 / 18)


def test_a_map_without_free_cells() -> None:
    assert MapShape.of(np.ones((3, 3), dtype=bool)) == MapShape(0.0, 1.0)


def test_a_map_without_blocked_cells() -> None:
    assert MapShape.of(np.zeros((3, 3), dtype=bool)) == MapShape(0.0, 0.0)


@given(arrays(np.bool_, st.tuples(st.integers(1, 12), st.integers(1, 12))))
def test_the_shape_is_the_same_turned_or_mirrored(blocked: np.ndarray) -> None:
    shape = MapShape.of(blocked)
    assert shape.lone_obstacles_per_free_cell >= 0.0
    assert 0.0 <= shape.blocked_near_free <= 1.0
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
        (_random(0.10), SPARSE_MAP_OPTIONS),  # scattered, sparse
        (_random(0.15), SPARSE_MAP_OPTIONS),
        (_random(0.20), WALLED_MAP_OPTIONS),  # neither sparse nor dense
        (_random(0.25), SCATTERED_MAP_OPTIONS),
        (_random(0.35), SCATTERED_MAP_OPTIONS),
        (np.zeros((128, 128), dtype=bool), SMALL_WALLED_MAP_OPTIONS),  # open: nothing scattered
        (_blocks(), SMALL_WALLED_MAP_OPTIONS),
        (np.zeros((256, 256), dtype=bool), WALLED_MAP_OPTIONS),  # 65,536 free cells
        (_blocks() | _random(0.02), SPARSE_MAP_OPTIONS),  # obstacles scattered among them
    ],
)
def test_maps_get_the_options_of_their_shape(blocked: np.ndarray, options: object) -> None:
    assert map_options(blocked) is options


@pytest.mark.parametrize(
    ("name", "options"),
    [
        ("random512-10-0", SPARSE_MAP_OPTIONS),
        ("8room_000", WALLED_MAP_OPTIONS),
        ("maze512-1-0", LARGE_MAP_OPTIONS),
        ("arena", SMALL_MAP_OPTIONS),
    ],
)
def test_the_shipped_maps_options(name: str, options: object) -> None:
    """Random 10% is scattered and sparse (0.100 blocked near free cells); rooms of 8, the
    maze and the arena have no lone obstacle: maps of walls, the maze's dense (its corridors
    are one cell wide: half the cells beside a free one are blocked). The arena is small
    (2,054 free cells)."""
    blocked = load_map(Path(str(data_file("maps", f"{name}.map"))))[0]
    shape = MapShape.of(blocked)
    assert shape.scattered == (name == "random512-10-0")
    assert shape.dense == (name == "maze512-1-0")
    assert shape.sparse or name != "random512-10-0"
    assert map_options(blocked) is options


def test_small_maps_are_searched_whole() -> None:
    """A map of fewer than `SMALL_MAP_FREE_CELLS` free cells gets `SMALL_MAP_OPTIONS`, whatever
    its shape; one more free cell, the options of its shape."""
    blocked = np.ones((128, 128), dtype=bool)
    blocked.ravel()[: SMALL_MAP_FREE_CELLS - 1] = False  # open ground, rows of it
    assert map_options(blocked) is SMALL_MAP_OPTIONS
    blocked.ravel()[SMALL_MAP_FREE_CELLS - 1] = False
    assert map_options(blocked) is SMALL_WALLED_MAP_OPTIONS
    assert map_options(_random(0.3)[:64, :64]) is SMALL_MAP_OPTIONS  # scattered, dense, small


def test_small_maps_of_walls_take_the_route_over_the_whole_map() -> None:
    """A map of walls of fewer than `SMALL_WALLED_MAP_FREE_CELLS` free cells gets
    `SMALL_WALLED_MAP_OPTIONS`; one more free cell, `WALLED_MAP_OPTIONS`. Scattered obstacles
    keep their options however few the free cells."""
    blocked = np.ones((256, 256), dtype=bool)
    blocked.ravel()[: SMALL_WALLED_MAP_FREE_CELLS - 1] = False  # open ground, rows of it
    assert map_options(blocked) is SMALL_WALLED_MAP_OPTIONS
    blocked.ravel()[SMALL_WALLED_MAP_FREE_CELLS - 1] = False
    assert map_options(blocked) is WALLED_MAP_OPTIONS
    assert map_options(_random(0.25)) is SCATTERED_MAP_OPTIONS


@settings(max_examples=20, deadline=None)
@given(
    share=st.sampled_from([0.0, 0.1, 0.2, 0.3, 0.4]),
    seed=st.integers(0, 2**16),
    movement=st.sampled_from([4, 8]),
)
def test_the_small_map_options_register_the_optimal_route_alone(
    share: float, seed: int, movement: int
) -> None:
    """With the small-map options the planner registers one plan, of cells, as long as the
    compiled A*'s route (by jump points with octile moves), followed as planned, quality 1."""
    blocked = np.random.default_rng(seed).random((64, 64)) < share
    start, goal = (1, 62), (62, 2)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    found = GridAstar(blocked, movement=movement, weight=0.0).find_path(start, goal)
    if found is None:
        return  # walled off: planned across the walls (`atp`), and not followed
    plans = list(
        atp(Context(), start, goal, Pyramid.build(blocked), movement=movement,
            **SMALL_MAP_OPTIONS)
    )  # fmt: skip
    assert len(plans) == 1 and plans[0].quality == 1.0
    assert [segment.level for segment in plans[0].value.segments] == [0]
    run = execute(plans[0].value, blocked, movement=movement, keep_to_plan=True)
    assert run.reached and run.expansions == 0
    assert math.isclose(run.length, found.length)


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


def test_only_the_direct_route_after_the_first_plan_registers_no_fall() -> None:
    for options in (
        WALLED_MAP_OPTIONS,
        SMALL_WALLED_MAP_OPTIONS,
        SPARSE_MAP_OPTIONS,
        SCATTERED_MAP_OPTIONS,
    ):
        assert registers_no_fall(options)
    assert registers_no_fall(SMALL_MAP_OPTIONS)  # one plan of cells
    assert registers_no_fall({**LARGE_MAP_OPTIONS, "top": 0})
    for options in (LARGE_MAP_OPTIONS, {**SCATTERED_MAP_OPTIONS, "direct_width": 8}, {}):
        assert not registers_no_fall(options)


def test_the_walled_options_never_fall() -> None:
    """Planned with the walled-map options to completion, a town's plans are the first plan and
    the direct route through its corridor: that route is followed to the goal, no shorter than
    the straight line, and no longer than the first plan (followed on its map, the first plan
    keeps to cells the route is the shortest through)."""
    blocked = _blocks(seed=1)
    start, goal = (1, 126), (126, 1)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    plans = list(
        atp(Context(), start, goal, Pyramid.build(blocked), movement=8, **WALLED_MAP_OPTIONS)
    )
    first, final = (execute(p.value, blocked, movement=8, keep_to_plan=True) for p in plans)
    assert final.reached
    assert 125 * np.sqrt(2) <= final.length <= first.length
    assert all(segment.level == 0 for segment in plans[-1].value.segments)


@settings(max_examples=16, deadline=None)
@given(
    share=st.sampled_from([0.08, 0.12, 0.18, 0.21, 0.3]),
    seed=st.integers(0, 2**16),
    corridor=st.sampled_from(
        [{"direct_ring_level": level} for level in (1, 2, 3)]
        + [{"direct_via": via, "direct_rings": rings} for via in (1, 2) for rings in (0, 2)]
    ),
)
def test_the_direct_route_through_scattered_obstacles_never_falls(
    share: float, seed: int, corridor: dict[str, int]
) -> None:
    """On a random map of scattered obstacles, the direct route through the first plan's blocks
    and their neighbours at any level (`direct_ring_level`), or through a second plan's
    (`direct_via`), is followed to the goal no longer than the first plan: the corridor holds
    every cell the first plan is followed through."""
    blocked = _random(share, seed)
    start, goal = (2, 125), (125, 3)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    if not Components.build(blocked, 8, top=3).connected(start, goal):
        return  # a wall of obstacles between them: planned across it, and not followed
    options = {**WALLED_MAP_OPTIONS, **corridor}
    plans = list(atp(Context(), start, goal, Pyramid.build(blocked), movement=8, **options))
    assert len(plans) == 2
    first, final = (execute(p.value, blocked, movement=8, keep_to_plan=True) for p in plans)
    assert first.reached and final.reached
    assert final.length <= first.length
    assert plans[-1].value.base_route() is not None


@settings(max_examples=12, deadline=None)
@given(
    share=st.sampled_from([0.0, 0.1, 0.2, 0.3]),
    seed=st.integers(0, 2**16),
    options=st.sampled_from([WALLED_MAP_OPTIONS, SPARSE_MAP_OPTIONS, SCATTERED_MAP_OPTIONS]),
)
def test_the_direct_route_in_steps_never_falls(
    share: float, seed: int, options: dict[str, object]
) -> None:
    """With `direct_steps`, the direct route is registered through corridors with the ring of
    neighbours at level 1, then 2, up to the options' own: each route is followed to the goal
    no longer than the plan before it, and the last is as long as the route made at once."""
    blocked = _random(share, seed) if share else _blocks(seed=seed % 8)
    start, goal = (2, 125), (125, 3)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    if not Components.build(blocked, 8, top=3).connected(start, goal):
        return  # a wall of obstacles between them: planned across it, and not followed
    pyramid = Pyramid.build(blocked)
    stepped = list(atp(Context(), start, goal, pyramid, movement=8, **options, direct_steps=True))
    at_once = list(atp(Context(), start, goal, pyramid, movement=8, **options))
    steps = 2 if options is SPARSE_MAP_OPTIONS else 3  # rings at 1 (and 2) below the own
    assert len(stepped) == 1 + steps and len(at_once) == 2
    runs = [execute(p.value, blocked, movement=8, keep_to_plan=True) for p in stepped]
    assert all(run.reached for run in runs)
    lengths = [run.length for run in runs]
    assert all(b <= a + 1e-9 for a, b in zip(lengths, lengths[1:], strict=False))
    final = execute(at_once[-1].value, blocked, movement=8, keep_to_plan=True)
    assert math.isclose(lengths[-1], final.length)


@settings(max_examples=16, deadline=None)
@given(seed=st.integers(0, 2**16), steps=st.booleans())
def test_the_route_over_the_whole_map_is_the_optimal_one(seed: int, steps: bool) -> None:
    """With the small-walled-map options, a town's plans are the first plan and the route over
    the whole map (with `direct_steps`, the corridors' routes between): its length is the
    compiled A*'s, followed as planned, and no plan is followed longer than the one before."""
    blocked = _blocks(seed=seed % 16)
    start, goal = (1, 126), (126, 1)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    found = GridAstar(blocked, movement=8, weight=0.0).find_path(start, goal)
    if found is None:
        return  # walled off: planned across the walls (`atp`), and not followed
    plans = list(
        atp(Context(), start, goal, Pyramid.build(blocked), movement=8,
            **SMALL_WALLED_MAP_OPTIONS, direct_steps=steps)
    )  # fmt: skip
    runs = [execute(p.value, blocked, movement=8, keep_to_plan=True) for p in plans]
    assert all(run.reached for run in runs)
    assert math.isclose(runs[-1].length, found.length)
    assert plans[-1].quality == 1.0
    lengths = [run.length for run in runs]
    assert all(b <= a + 1e-9 for a, b in zip(lengths, lengths[1:], strict=False))


def test_a_costly_search_of_the_whole_map_gives_way_to_the_corridor(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """When the search of the whole map would settle more jump points than the corridor has
    cells over `WHOLE_ROUTE_RATIO`, it stops and the corridor is searched: the plans are the
    walled-map options', and the stopped search's work is counted besides."""
    from anytime_navigation.planning import planner

    blocked = _blocks(seed=3)
    start, goal = (1, 126), (126, 1)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    pyramid = Pyramid.build(blocked)
    corridor_ctx, whole_ctx = Context(), Context()
    corridor = list(atp(corridor_ctx, start, goal, pyramid, movement=8, **WALLED_MAP_OPTIONS))
    monkeypatch.setattr(planner, "WHOLE_ROUTE_RATIO", 1e9)  # no jump point to settle
    whole = list(atp(whole_ctx, start, goal, pyramid, movement=8, **SMALL_WALLED_MAP_OPTIONS))
    assert [p.value for p in whole] == [p.value for p in corridor]
    assert whole_ctx.ticks == corridor_ctx.ticks  # a limit of no jump point: no work
    monkeypatch.setattr(planner, "WHOLE_ROUTE_RATIO", 200.0)
    some_ctx = Context()
    some = list(atp(some_ctx, start, goal, pyramid, movement=8, **SMALL_WALLED_MAP_OPTIONS))
    assert [p.value for p in some] == [p.value for p in corridor]
    assert some_ctx.ticks > corridor_ctx.ticks


def test_direct_whole_needs_the_direct_route() -> None:
    blocked = _random(0.1)
    blocked[1, 1] = blocked[120, 120] = False
    plans = atp(
        Context(), (1, 1), (120, 120), Pyramid.build(blocked), movement=8, direct_whole=True
    )
    with pytest.raises(
        ValueError,
        match=r"^direct_whole needs direct or direct_width: it searches the direct route$",
    ):
        next(plans)


def test_direct_steps_need_the_direct_route() -> None:
    blocked = _random(0.1)
    blocked[1, 1] = blocked[120, 120] = False
    plans = atp(
        Context(), (1, 1), (120, 120), Pyramid.build(blocked), movement=8, direct_steps=True
    )
    with pytest.raises(
        ValueError,
        match=r"^direct_steps needs direct_width: it steps the route after the first plan$",
    ):
        next(plans)


def test_the_ring_one_level_lower_searches_fewer_cells() -> None:
    """The sparse-map options' corridor (the ring of neighbours at level 2) is narrower than the
    walled-map options' (at level 3): fewer expansions, a route no shorter."""
    blocked = _random(0.1, seed=3)
    start, goal = (1, 1), (126, 120)
    blocked[start[1], start[0]] = blocked[goal[1], goal[0]] = False
    pyramid = Pyramid.build(blocked)
    ticks, lengths = [], []
    for options in (WALLED_MAP_OPTIONS, SPARSE_MAP_OPTIONS):
        ctx = Context()
        route = list(atp(ctx, start, goal, pyramid, movement=8, **options))[-1].value
        ticks.append(ctx.elapsed)
        lengths.append(execute(route, blocked, movement=8, keep_to_plan=True).length)
    assert ticks[1] < ticks[0]
    assert lengths[1] >= lengths[0]


def test_the_ring_level_must_be_a_level() -> None:
    blocked = _random(0.1)
    blocked[1, 1] = blocked[120, 120] = False
    plans = atp(
        Context(), (1, 1), (120, 120), Pyramid.build(blocked), movement=8, direct_ring_level=0
    )
    with pytest.raises(ValueError, match=r"^direct_ring_level must be >= 1 or None, got 0$"):
        next(plans)


def test_the_second_plan_is_below_the_first() -> None:
    """`direct_via` must be a level; at or above the first plan's level (a small map's top),
    there is no second plan: the same plans as without it."""
    blocked = _random(0.3, seed=4)
    blocked[0, 0] = blocked[127, 127] = False
    pyramid = Pyramid.build(blocked)

    def plans(**options: int) -> list[object]:
        found = atp(Context(), (0, 0), (127, 127), pyramid, movement=8, top=3, **options)
        return [result.value for result in found]

    with pytest.raises(ValueError, match=r"^direct_via must be >= 1 or None, got 0$"):
        plans(direct_width=math.inf, direct_via=0)
    alone = plans(direct_width=math.inf)
    assert plans(direct_width=math.inf, direct_via=3) == alone
    assert plans(direct_width=math.inf, direct_via=4) == alone
