"""Jump point search over a corridor of base cells (`corridor_search.jump_search`, issue 36):
the refinement's level-0 search with the cheapest costs of A* over every cell
(`corridor_search.search`), on the same moves (octile, no corner cutting: a diagonal needs both
straight cells free on the map, in the corridor or not), and `atp(jump_points=True)`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from anytime_navigation.planning import corridor_search
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp
from anytime_navigation.planning.search import SearchLimit
from anytime_navigation.task.execution import execute
from anytime_navigation.world import random_world
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.modules import Context

NONE = np.zeros(0, dtype=np.int64)


def _searches(
    components: Components, corridor: Any, sources: Any, source_costs: Any, targets: Any,
    target_costs: Any,
) -> tuple[tuple[Any, float, int], tuple[Any, float, int]]:  # fmt: skip
    """(A* over every cell, jump point search) over `corridor` (level-0 nodes)."""
    base = components.levels[0]
    assert base.grid is not None and base.padded is not None
    wide = base.grid.shape[1] + 2
    local = components._scratch[0]
    args = (np.asarray(sources), np.asarray(source_costs, dtype=float))
    ends = (np.asarray(targets), np.asarray(target_costs, dtype=float))
    every = corridor_search.search(
        corridor, local, NONE, NONE, np.zeros(0), base.padded, wide, base.block, base.centre, 8,
        *args, *ends, np.zeros((0, 0)),
    )  # fmt: skip
    cells = components._cells
    before = cells.copy()
    jumps = corridor_search.jump_search(
        corridor, local, base.padded, cells, wide, base.block, base.centre, *args, *ends
    )
    assert (local == -1).all()  # the scratch left as it was
    assert (cells == before).all() and (cells == (base.padded >= 0)).all()
    return every, jumps


@st.composite
def corridors(draw: Any) -> tuple[Any, ...]:
    """A map, a corridor of its free cells (every one, or a random part, some twice), sources
    and targets in it with costs (zero or not)."""
    side = draw(st.sampled_from([8, 16, 32]))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    blocked = rng.random((side, side)) < draw(st.floats(0.0, 0.45))
    components = Components.build(blocked, 8, top=2)
    count = len(components.levels[0])
    if count < 2:
        corridor = np.arange(count, dtype=np.int64)
    elif draw(st.booleans()):
        corridor = np.arange(count, dtype=np.int64)
    else:
        corridor = np.flatnonzero(rng.random(count) < draw(st.floats(0.4, 1.0)))
    if len(corridor) < 1:
        corridor = np.arange(count, dtype=np.int64)
    corridor = np.concatenate([corridor, corridor[: draw(st.integers(0, 3))]])
    ends = []
    for _ in range(2):
        chosen = rng.choice(corridor, size=draw(st.integers(1, 4)))
        costs = rng.uniform(0.0, 2.0, len(chosen)) * draw(st.sampled_from([0.0, 1.0]))
        ends.append((chosen, costs))
    return blocked, components, corridor, *ends[0], *ends[1]


@settings(max_examples=300, deadline=None)
@given(corridors())
def test_jump_points_find_the_cheapest_cost_by_a_legal_path(case: tuple[Any, ...]) -> None:
    """The same cost as A* over every cell (inf with no path, then no path); the path found runs
    from a source to a target by legal moves between cells of the corridor, and its cost (its
    ends' costs and its moves) is the cost returned."""
    blocked, components, corridor, sources, source_costs, targets, target_costs = case
    if not len(components.levels[0]):
        return
    (_, every_cost, _), (path, cost, expansions) = _searches(
        components, corridor, sources, source_costs, targets, target_costs
    )
    # the same to rounding: equal paths may add their moves in another order
    assert math.isclose(cost, every_cost, rel_tol=1e-12) or cost == every_cost
    if cost == math.inf:
        assert len(path) == 0
        return
    block = components.levels[0].block
    assert expansions <= len(set(corridor.tolist()))
    walked = min(c for s, c in zip(sources, source_costs, strict=True) if s == path[0])
    walked += min(c for t, c in zip(targets, target_costs, strict=True) if t == path[-1])
    inside = set(corridor.tolist())
    assert set(path.tolist()) <= inside
    for a, b in zip(path[:-1], path[1:], strict=True):
        (ax, ay), (bx, by) = block[a], block[b]
        dx, dy = bx - ax, by - ay
        assert max(abs(dx), abs(dy)) == 1
        if dx and dy:  # no corner cutting, judged on the map
            assert not blocked[ay, bx] and not blocked[by, ax]
        walked += math.sqrt(2.0) if dx and dy else 1.0
    assert math.isclose(walked, cost, rel_tol=1e-12)


def _open_components(side: int) -> Components:
    return Components.build(np.zeros((side, side), dtype=bool), 8, top=2)


def test_an_open_diagonal_is_one_jump() -> None:
    """Across an open 8 x 8 map from corner to corner: the diagonal, every cell of it; one
    expansion (the start: the scan meets the goal), where A* over every cell expands the
    diagonal's cells but the last."""
    components = _open_components(8)
    grid = components.cell
    corridor = np.arange(64, dtype=np.int64)
    every, (path, cost, expansions) = _searches(
        components, corridor, [grid[0, 0]], [0.0], [grid[7, 7]], [0.0]
    )
    assert path.tolist() == [grid[i, i] for i in range(8)]
    assert math.isclose(cost, every[1]) and math.isclose(cost, 7 * math.sqrt(2.0))
    assert (expansions, every[2]) == (1, 7)


def test_a_corner_outside_the_corridor_may_be_passed() -> None:
    """A free cell outside the corridor is not entered, but a diagonal passes its corner: from
    (0, 1) to (1, 0) with (0, 0) and (1, 1) free but outside it, one diagonal move."""
    components = _open_components(8)
    grid = components.cell
    corridor = np.array([grid[1, 0], grid[0, 1]], dtype=np.int64)
    _, (path, cost, _) = _searches(components, corridor, [grid[1, 0]], [0.0], [grid[0, 1]], [0.0])
    assert path.tolist() == [grid[1, 0], grid[0, 1]]
    assert cost == math.sqrt(2.0)


def test_no_path_through_the_corridor() -> None:
    """Two cells of the corridor apart, with no corridor cell between: no path, cost inf."""
    components = _open_components(8)
    grid = components.cell
    corridor = np.array([grid[0, 0], grid[0, 5]], dtype=np.int64)
    _, (path, cost, _) = _searches(components, corridor, [grid[0, 0]], [0.0], [grid[0, 5]], [0.0])
    assert len(path) == 0 and cost == math.inf


def _plans(seed: int, **options: Any) -> tuple[list[Any], Any]:
    world = random_world(64, seed=seed, movement=8)
    pyramid = Pyramid.build(world.blocked)
    components = Components.build(world.blocked, 8, top=3)
    ctx = Context()
    plans = [
        r.value
        for r in atp(
            ctx, world.start, world.goal, pyramid, movement=8, components=components, top=3,
            **options,
        )
    ]  # fmt: skip
    return plans, (world, ctx.elapsed)


def _length(route: tuple[tuple[int, int], ...]) -> float:
    return sum(
        math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(route[:-1], route[1:], strict=True)
    )


def test_the_planner_with_jump_points_plans_as_long_for_less_work() -> None:
    """`atp(jump_points=True)` (with `skip_level_1`, its refinements to the base cells at every
    level-2 segment): as many plans, each fully refined route as long as without it (ties may
    go another way), every plan followed to the goal, and fewer expansions over the run."""
    for seed in (1, 4, 7):
        usual, (world, usual_work) = _plans(seed, skip_level_1=True)
        jumped, (_, work) = _plans(seed, skip_level_1=True, jump_points=True)
        assert len(jumped) == len(usual)
        final, usual_final = jumped[-1].base_route(), usual[-1].base_route()
        assert final is not None and usual_final is not None
        assert math.isclose(_length(final), _length(usual_final), rel_tol=1e-9)
        assert work < usual_work
        for plan in jumped:
            assert execute(plan, world.blocked, movement=8).reached


def test_the_corridor_search_by_jump_points() -> None:
    """`Components.corridor(0, ..., jump_points=True)` (the direct route's search): a path as
    cheap as A*'s over the same corridor, its cells each a move apart, fewer expansions; above
    level 0 or with 4-connected moves the option changes nothing."""
    world = random_world(64, seed=3, movement=8)
    components = Components.build(world.blocked, 8, top=3)
    every = np.arange(len(components.levels[0]), dtype=np.int64)
    ends = [components.node(world.start, 0)], [components.node(world.goal, 0)]
    usual = components.corridor(0, every, *ends)
    jumped = components.corridor(0, every, *ends, jump_points=True)
    assert usual is not None and jumped is not None
    assert math.isclose(jumped.cost, usual.cost, rel_tol=1e-12)
    assert jumped.expansions < usual.expansions
    cells = components.levels[0].block[np.array(jumped.nodes)]
    assert (np.abs(np.diff(cells, axis=0)).max(axis=1) == 1).all()
    top = components.levels[3]
    nodes = np.arange(len(top), dtype=np.int64)
    high = [components.node(world.start, 3)], [components.node(world.goal, 3)]
    assert components.corridor(3, nodes, *high, jump_points=True) == components.corridor(
        3, nodes, *high
    )
    world4 = random_world(64, seed=3, movement=4)
    four = Components.build(world4.blocked, 4, top=2)
    cells4 = np.arange(len(four.levels[0]), dtype=np.int64)
    ends4 = [four.node(world4.start, 0)], [four.node(world4.goal, 0)]
    found4 = four.corridor(0, cells4, *ends4)
    assert found4 is not None
    assert four.corridor(0, cells4, *ends4, jump_points=True) == found4


def _direct_work(blocked: np.ndarray, **options: Any) -> tuple[float, float]:
    """The work of `atp`'s direct route (a first plan of at most 256 nodes at level 2, then one
    base search) from corner to corner, and the route's length followed."""
    components, pyramid = Components.build(blocked, 8, top=2), Pyramid.build(blocked)
    free = np.argwhere(~blocked)
    start, goal = tuple(free[0, ::-1].tolist()), tuple(free[-1, ::-1].tolist())  # (x, y)
    ctx = Context()
    plans = list(
        atp(
            ctx, start, goal, pyramid, movement=8, components=components, top=2, direct=256,
            **options,
        )
    )  # fmt: skip
    run = execute(plans[0].value, blocked, movement=8)
    assert len(plans) == 1 and run.reached
    return ctx.elapsed, run.length


def test_the_direct_route_jumps_through_any_corridor() -> None:
    """With `jump_points`, the direct route's search is by jump points, as long a route: across
    open ground far fewer expansions, and along a corridor one cell wide, where every turn is
    a jump point, fewer (the straight runs between turns are scanned, not expanded)."""
    open_ground = np.zeros((32, 32), dtype=bool)
    usual, length = _direct_work(open_ground)
    jumped, jumped_length = _direct_work(open_ground, jump_points=True)
    assert jumped_length == length
    assert jumped <= usual / 4
    winding = np.zeros((32, 32), dtype=bool)  # rows of walls, each open at alternate ends
    winding[1::2, :] = True
    winding[1:-1:4, -1] = winding[3:-1:4, 0] = False
    usual, length = _direct_work(winding)
    jumped, jumped_length = _direct_work(winding, jump_points=True)
    assert jumped_length == length
    assert jumped < usual


@settings(max_examples=150, deadline=None)
@given(
    side=st.sampled_from([8, 16, 32]),
    seed=st.integers(0, 2**32 - 1),
    share=st.floats(0.0, 0.45),
)
def test_the_search_over_every_cell_by_jump_points(side: int, seed: int, share: float) -> None:
    """`Components.path` at level 0 by jump points (`whole_jump_search`, its room kept): the
    cost of A* over every cell, by a path of legal moves from the source to the target, and
    the room left as it found it, so that three searches in a row on one map each find what a
    fresh search finds; no path (no route joins them) is said, not searched for ever."""
    rng = np.random.default_rng(seed)
    blocked = rng.random((side, side)) < share
    components = Components.build(blocked, 8, top=2)
    count = len(components.levels[0])
    if count < 2:
        return
    cells, *kept = components.whole_room()
    before = [cells.copy(), *(array.copy() for array in kept[:4])]
    block = components.levels[0].block
    for source, target in rng.integers(0, count, size=(3, 2)).tolist():
        every = components.corridor(0, np.arange(count), [source], [target])
        if every is None:
            with pytest.raises(AssertionError, match="no path between cells"):
                components.path(0, source, target, jump_points=True)
        else:
            found = components.path(0, source, target, jump_points=True)
            assert math.isclose(found.cost, every.cost, rel_tol=1e-12)
            assert found.nodes[0] == source and found.nodes[-1] == target
            walked = 0.0
            for a, b in zip(found.nodes[:-1], found.nodes[1:], strict=True):
                (ax, ay), (bx, by) = block[a], block[b]
                dx, dy = bx - ax, by - ay
                assert max(abs(dx), abs(dy)) == 1
                if dx and dy:  # no corner cutting
                    assert not blocked[ay, bx] and not blocked[by, ax]
                walked += math.sqrt(2.0) if dx and dy else 1.0
            assert math.isclose(walked, found.cost, rel_tol=1e-12)
            assert found.expansions <= count
        after = [cells, *kept[:4]]
        for was, now in zip(before, after, strict=True):
            np.testing.assert_array_equal(was, now)


@settings(max_examples=60, deadline=None)
@given(
    side=st.sampled_from([8, 16, 32]),
    seed=st.integers(0, 2**32 - 1),
    share=st.floats(0.0, 0.45),
)
def test_the_maps_jumps_are_the_straight_scans(side: int, seed: int, share: float) -> None:
    """`jump_distances`, the table the search over every cell reads its straight jumps off:
    each free cell's entry is what a scan from it finds over the whole map (`_straight_jump`,
    every free cell in the corridor): the moves to the first jump point, or minus the moves
    before the wall when there is none."""
    blocked = np.random.default_rng(seed).random((side, side)) < share
    components = Components.build(blocked, 8, top=2)
    if not len(components.levels[0]):
        return
    cells, *_, jumps = components.whole_room()
    wide = side + 2
    for at in np.flatnonzero(cells != corridor_search.CELL_BLOCKED).tolist():
        for m, (step, across) in enumerate(((1, wide), (-1, wide), (wide, 1), (-wide, 1))):
            found = corridor_search._straight_jump(cells, at, step, across)
            if found >= 0:
                assert jumps[at, m] == (found - at) // step
            else:
                free = 0
                while cells[at + (free + 1) * step] != corridor_search.CELL_BLOCKED:
                    free += 1
                assert jumps[at, m] == -free


def test_the_search_over_every_cell_stops_at_its_limit() -> None:
    """Given fewer jump points to settle than it needs, the search over every cell stops
    there (`SearchLimit`, its work the limit), leaves its room as it found it, and the next
    search finds what a search without a limit finds."""
    blocked = np.zeros((32, 32), dtype=bool)
    blocked[4:28:6, 2:30] = True  # walls across, open at both ends
    components = Components.build(blocked, 8, top=2)
    cells, *kept = components.whole_room()
    before = [cells.copy(), *(array.copy() for array in kept[:4])]
    source, target = components.node((0, 0), 0), components.node((31, 31), 0)
    whole = components.path(0, source, target, jump_points=True)
    assert whole.expansions > 2
    with pytest.raises(SearchLimit) as stopped:
        components.path(0, source, target, limit=2, jump_points=True)
    assert stopped.value.expansions == 2
    for was, now in zip(before, [cells, *kept[:4]], strict=True):
        np.testing.assert_array_equal(was, now)
    again = components.path(0, source, target, jump_points=True)
    assert again.nodes == whole.nodes and again.cost == whole.cost
