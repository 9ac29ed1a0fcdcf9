"""The doors of a level and the first plan's search over them (`doors`), against straightforward
references: the doors as the mean midpoints of the legal moves between two nodes, the route as
Dijkstra's algorithm over the directed doors in pure Python."""

from __future__ import annotations

import heapq
import math
from typing import Any

import numpy as np
import pytest
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.doors import CROSSING, Doors
from anytime_navigation.planning.planner import atp
from anytime_navigation.planning.search import SearchLimit
from grid_moves import draw_free_pair, legal_moves  # tests/navigation/grid_moves.py
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.plugin import Context

maps = st.builds(
    lambda seed, density, side: np.random.default_rng(seed).random((side, side)) < density,
    st.integers(0, 2**31),
    st.floats(0.0, 0.5),
    st.sampled_from([8, 16, 32]),
)


def _distance(dx: float, dy: float, movement: int) -> float:
    dx, dy = abs(dx), abs(dy)
    return dx + dy if movement == 4 else max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)


def _doors(blocked: np.ndarray, grid: np.ndarray, movement: int) -> dict[tuple[int, int], tuple]:
    """(u, v) -> the mean midpoint of the legal moves between nodes u and v, one move at a time."""
    found: dict[tuple[int, int], list[tuple[float, float]]] = {}
    for (x, y), (nx, ny) in legal_moves(blocked, movement):
        u, v = int(grid[y, x]), int(grid[ny, nx])
        if u != v:
            middle = ((x + nx + 1) / 2, (y + ny + 1) / 2)
            found.setdefault((u, v), []).append(middle)
            found.setdefault((v, u), []).append(middle)
    return {pair: tuple(np.mean(points, axis=0)) for pair, points in found.items()}


def _reference_route(
    doors: dict[tuple[int, int], tuple], start: tuple[int, int], goal: tuple[int, int], grid, m
) -> float:
    """Dijkstra over the directed doors: start -> door, door -> door, door -> goal, each door
    crossed costing CROSSING more."""
    source, target = int(grid[start[1], start[0]]), int(grid[goal[1], goal[0]])
    centre_start, centre_goal = (start[0] + 0.5, start[1] + 0.5), (goal[0] + 0.5, goal[1] + 0.5)
    if source == target:
        return _distance(centre_goal[0] - centre_start[0], centre_goal[1] - centre_start[1], m)
    leaving: dict[int, list[tuple[int, int]]] = {}
    for u, v in doors:
        leaving.setdefault(u, []).append((u, v))
    best: dict[tuple[int, int], float] = {}
    heap = []
    for state in leaving.get(source, []):
        p = doors[state]
        cost = _distance(p[0] - centre_start[0], p[1] - centre_start[1], m) + CROSSING
        heapq.heappush(heap, (cost, state))
    answer = math.inf
    while heap:
        cost, (u, v) = heapq.heappop(heap)
        if (u, v) in best:
            continue
        best[u, v] = cost
        p = doors[u, v]
        if v == target:
            answer = min(answer, cost + _distance(centre_goal[0] - p[0], centre_goal[1] - p[1], m))
        for state in leaving.get(v, []):
            if state[1] != u and state not in best:
                q = doors[state]
                heapq.heappush(
                    heap, (cost + _distance(q[0] - p[0], q[1] - p[1], m) + CROSSING, state)
                )
    return answer


@settings(max_examples=60, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.sampled_from([1, 2, 3]), st.data())
def test_the_route_is_the_cheapest_through_the_doors(
    blocked: np.ndarray, movement: int, level: int, data: st.DataObject
) -> None:
    c = Components.build(blocked, movement, top=level)
    doors = c.doors(level)
    assert doors.level == level
    grid = c.grids[level]
    reference = _doors(blocked, grid, movement)
    # Every state's door is the mean midpoint of the moves between its nodes.
    assert len(reference) == len(doors.tail)
    for j, (u, v) in enumerate(zip(doors.tail.tolist(), doors.head.tolist(), strict=True)):
        assert np.allclose(doors.point[j], reference[u, v])
        assert (doors.tail[doors.reverse[j]], doors.head[doors.reverse[j]]) == (v, u)
    pair = draw_free_pair(blocked, data)
    if pair is None or not c.connected(*pair):
        return
    (sx, sy), (gx, gy) = pair
    nodes, cost, expansions = doors.route((sx, sy), (gx, gy))
    assert math.isclose(
        cost, _reference_route(reference, (sx, sy), (gx, gy), grid, movement), rel_tol=1e-9
    )
    assert nodes[0] == grid[sy, sx] and nodes[-1] == grid[gy, gx]
    level_rows = c.levels[level]
    for u, v in zip(nodes, nodes[1:], strict=False):  # neighbours, each step
        assert v in level_rows.neighbour[level_rows.first[u] : level_rows.first[u + 1]]
    # The cost is the route's own through its doors.
    points = [(sx + 0.5, sy + 0.5)] + [
        reference[u, v] for u, v in zip(nodes, nodes[1:], strict=False)
    ]
    points.append((gx + 0.5, gy + 0.5))
    own = sum(
        _distance(b[0] - a[0], b[1] - a[1], movement)
        for a, b in zip(points, points[1:], strict=False)
    )
    assert math.isclose(cost, own + CROSSING * (len(nodes) - 1), rel_tol=1e-9)
    assert expansions >= len(nodes) - 2  # the route's doors but the last, popped to end it


def test_a_route_keeps_to_its_limit_and_counts_what_a_star_expands() -> None:
    blocked = np.zeros((64, 64), dtype=bool)
    blocked[8:56, 32] = True  # a wall between start and goal
    c = Components.build(blocked, 8, top=3)
    nodes, cost, expansions = c.doors(c.top).route((4, 32), (60, 32))
    assert len(nodes) - 2 <= expansions < len(c.doors(c.top).tail)
    with pytest.raises(SearchLimit):
        c.doors(c.top).route((4, 32), (60, 32), limit=expansions - 1)
    assert c.doors(c.top).route((4, 32), (60, 32), limit=expansions) == (nodes, cost, expansions)
    # Around the wall's end, not through it: the route's blocks pass row 56 or row 7.
    blocks = [c.block(node, 3) for node in nodes]
    assert any(y == 0 or y == 7 for _, y in blocks)


def test_a_route_within_one_node_is_that_node() -> None:
    c = Components.build(np.zeros((16, 16), dtype=bool), 4, top=2)
    assert c.doors(c.top).route((1, 1), (2, 3)) == ((c.node((1, 1), 2),), 3.0, 0)


def test_a_level_of_its_own_gets_its_doors_when_asked() -> None:
    c = Components.build(np.zeros((32, 32), dtype=bool), 8, top=3)
    found = c.route(2, (0, 0), (31, 31))
    assert found.level == 2 and found.nodes[0] == c.node((0, 0), 2)
    assert found.nodes[-1] == c.node((31, 31), 2)
    assert len(found.nodes) == 8  # the diagonal: fewest doors among the straightest routes


def test_the_doors_are_made_once_when_first_searched(monkeypatch: pytest.MonkeyPatch) -> None:
    """Not with the hierarchy: a planner that never searches through them never pays for them
    (`atp(doors=False)`, the navigation task's); asked for again, a level's are the same."""
    made: list[int] = []
    build = Doors.build

    def counted(level: int, *args: Any, **kwargs: Any) -> Doors:
        made.append(level)
        return build(level, *args, **kwargs)

    monkeypatch.setattr(Doors, "build", counted)
    blocked = np.zeros((32, 32), dtype=bool)
    blocked[8:24, 15] = True
    c = Components.build(blocked, 8, top=3)
    pyramid = Pyramid.build(blocked)
    list(atp(Context(), (2, 16), (29, 16), pyramid, movement=8, components=c, doors=False))
    assert made == []
    list(atp(Context(), (2, 16), (29, 16), pyramid, movement=8, components=c))
    assert made == [3]
    assert c.doors(3) is c.doors(3) and made == [3]
    # the top level's doors, read off level 0's grid, are a level's own grid's
    own = Components.build(blocked, 8, top=4).doors(3)
    for name in ("tail", "head", "point", "after", "length"):
        assert np.array_equal(getattr(c.doors(3), name), getattr(own, name)), name
    with pytest.raises(ValueError, match=r"^doors are of levels 1 to 3, not 0$"):
        c.doors(0)


@settings(max_examples=30, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.data())
def test_no_path_of_nodes_is_cheaper_through_its_doors_than_the_route(
    blocked: np.ndarray, movement: int, data: st.DataObject
) -> None:
    """The route is the cheapest through the doors: the path from centre to centre (the
    "centres" first plan) costs at least as much through its own doors."""
    c = Components.build(blocked, movement, top=2)
    pair = draw_free_pair(blocked, data)
    if pair is None or not c.connected(*pair):
        return
    start, goal = pair
    made = c.doors(c.top)
    _, cost, _ = made.route(start, goal)
    every = np.arange(len(c.levels[2]))
    centres = c.corridor(2, every, [c.node(start, 2)], [c.node(goal, 2)])
    assert centres is not None
    doors = _doors(blocked, c.grids[2], movement)
    nodes = centres.nodes
    points = [(start[0] + 0.5, start[1] + 0.5)]
    points += [doors[u, v] for u, v in zip(nodes, nodes[1:], strict=False)]
    points.append((goal[0] + 0.5, goal[1] + 0.5))
    own = sum(
        _distance(b[0] - a[0], b[1] - a[1], movement)
        for a, b in zip(points, points[1:], strict=False)
    )
    assert cost <= (own + CROSSING * (len(nodes) - 1)) * (1 + 1e-12)
    assert math.isclose(made.cost_of(nodes, start, goal), own + CROSSING * (len(nodes) - 1))
    # Bounded by the centres' path, or by the route itself (the cut at exactly its cost through
    # its doors, `corridor_search.door_route`), the search finds a route as cheap (of several,
    # the cut may leave another, its moves summed in another order: equal to rounding),
    # costing what `cost_of` says it does.
    for bound in (nodes, made.route(start, goal)[0]):
        bounded, bounded_cost, _ = made.route(start, goal, bound=bound)
        assert math.isclose(bounded_cost, cost, rel_tol=1e-12)
        assert math.isclose(made.cost_of(bounded, start, goal), cost, rel_tol=1e-12)


def test_the_doors_of_a_map_with_blocked_margins_are_where_its_moves_are() -> None:
    """A map padded with blocked cells (as a non-square one is): the doors are those of the
    free part, placed on the whole map."""
    inner = np.random.default_rng(5).random((20, 13)) < 0.3
    blocked = np.ones((32, 32), dtype=bool)
    blocked[7:27, 11:24] = inner
    c = Components.build(blocked, 8, top=2)
    reference = _doors(blocked, c.grids[2], 8)
    doors = c.doors(c.top)
    assert len(reference) == len(doors.tail)
    for j, (u, v) in enumerate(zip(doors.tail.tolist(), doors.head.tolist(), strict=True)):
        assert np.allclose(doors.point[j], reference[u, v])
