"""The general path finder: optimal against scipy's Dijkstra and the MovingAI optimal lengths,
valid paths, good tie-breaking, work reported to the context."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import Scenario, load_map, load_scenarios
from anytime_navigation.planning.search import PathResult, find_path
from anytime_navigation.resources import data_file
from anytime_navigation.world import SQRT2
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from anytime.modules import Context

MOVINGAI = Path(str(data_file("maps")))
MAPS_512 = ["random512-10-0.map", "8room_000.map", "maze512-1-0.map"]


def _graph(obstacleness: np.ndarray, blocked: np.ndarray, movement: int, weight: float):
    """The same directed graph as find_path's, as a sparse matrix over cells y * width + x."""
    height, width = blocked.shape
    moves = [(1, 0), (-1, 0), (0, 1), (0, -1)]
    if movement == 8:
        moves += [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    ys, xs = np.nonzero(~blocked)
    rows, cols, data = [], [], []
    for dx, dy in moves:
        nx, ny = xs + dx, ys + dy
        ok = (nx >= 0) & (nx < width) & (ny >= 0) & (ny < height)
        x, y, nx, ny = xs[ok], ys[ok], nx[ok], ny[ok]
        ok = ~blocked[ny, nx]
        if dx and dy:
            ok &= ~blocked[y, nx] & ~blocked[ny, x]
        x, y, nx, ny = x[ok], y[ok], nx[ok], ny[ok]
        step = SQRT2 if dx and dy else 1.0
        rows.append(y * width + x)
        cols.append(ny * width + nx)
        data.append(step * (1.0 + weight * obstacleness[ny, nx]))
    n = height * width
    return coo_matrix(
        (np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    ).tocsr()


def _check_path(result: PathResult, blocked: np.ndarray, start, goal, movement: int) -> None:
    """Consecutive cells are legal moves between passable cells, without corner cutting; the
    reported length is the path's geometric length."""
    path = result.path
    assert path[0] == tuple(start) and path[-1] == tuple(goal)
    assert all(not blocked[y, x] for x, y in path)
    length = 0.0
    for (x0, y0), (x1, y1) in zip(path, path[1:], strict=False):
        dx, dy = x1 - x0, y1 - y0
        assert max(abs(dx), abs(dy)) == 1
        if dx and dy:
            assert movement == 8
            assert not blocked[y0, x1] and not blocked[y1, x0], "corner cut"
            length += SQRT2
        else:
            length += 1.0
    assert result.length == pytest.approx(length, rel=1e-12)


def _path_cost(path, obstacleness: np.ndarray, weight: float) -> float:
    total = 0.0
    for (x0, y0), (x1, y1) in zip(path, path[1:], strict=False):
        step = SQRT2 if x0 != x1 and y0 != y1 else 1.0
        total += step * (1.0 + weight * obstacleness[y1, x1])
    return total


@pytest.mark.parametrize("movement", [4, 8])
@pytest.mark.parametrize("weight", [0.0, 3.0], ids=["length", "weighted"])
@pytest.mark.parametrize("seed", range(6))
def test_costs_equal_dijkstra_on_random_grids(seed: int, weight: float, movement: int) -> None:
    rng = np.random.default_rng(seed)
    height, width = 23, 31
    blocked = rng.random((height, width)) < 0.3
    # Obstacleness in [0, 1), 1 where blocked: the shape of an abstraction level's grid.
    obstacleness = np.where(blocked, 1.0, rng.random((height, width)) * (rng.random() < 0.5))
    distances = dijkstra(_graph(obstacleness, blocked, movement, weight), directed=True)
    free = np.flatnonzero(~blocked.ravel())
    pairs = rng.choice(free, size=(25, 2))
    reached = 0
    for a, b in pairs:
        start, goal = (a % width, a // width), (b % width, b // width)
        result = find_path(obstacleness, start, goal, movement=movement, weight=weight)
        if math.isinf(distances[a, b]):
            assert result is None
            continue
        reached += 1
        assert result is not None
        assert result.cost == pytest.approx(distances[a, b], rel=1e-9)
        assert result.cost == pytest.approx(_path_cost(result.path, obstacleness, weight))
        if weight == 0.0:
            assert result.length == pytest.approx(distances[a, b], rel=1e-9)
        _check_path(result, blocked, start, goal, movement)
    assert reached >= 5  # the grids are connected enough for the check to mean something


def test_bool_grid_is_obstacleness_zero_one() -> None:
    rng = np.random.default_rng(7)
    blocked = rng.random((20, 20)) < 0.25
    blocked[0, 0] = blocked[19, 19] = False
    as_bool = find_path(blocked, (0, 0), (19, 19), movement=8)
    as_float = find_path(blocked.astype(float), (0, 0), (19, 19), movement=8)
    assert as_bool == as_float


def test_obstacleness_weight_detours_around_costly_cells() -> None:
    cost = np.zeros((3, 5))
    cost[1, 1:4] = 0.9  # a costly strip on the straight line from (0, 1) to (4, 1)
    direct = find_path(cost, (0, 1), (4, 1), weight=0.0)
    detour = find_path(cost, (0, 1), (4, 1), weight=1.0)
    assert direct is not None and detour is not None
    assert direct.length == 4 and direct.cost == 4
    assert detour.length == 6 and detour.cost == 6
    assert all(y != 1 for x, y in detour.path[1:-1])


def test_impassable_overrides_the_default() -> None:
    cost = np.full((1, 5), 0.5)
    wall = np.zeros((1, 5), dtype=bool)
    wall[0, 2] = True
    assert find_path(cost, (0, 0), (4, 0), impassable=wall) is None
    result = find_path(np.ones((1, 5)), (0, 0), (4, 0), impassable=np.zeros((1, 5), bool))
    assert result is not None and result.cost == 8.0  # 4 steps, each 1 + 1 * 1


def test_arena_every_problem_matches_the_optimal_length() -> None:
    blocked, _, _ = load_map(MOVINGAI / "arena.map")  # padded to 64x64 with blocked cells
    problems = load_scenarios(MOVINGAI / "arena.map.scen")
    assert len(problems) == 160
    for problem in problems:
        start, goal, optimal = problem.start, problem.goal, problem.optimal
        result = find_path(blocked, start, goal, movement=8, weight=0.0)
        assert result is not None
        # The old-style file prints 6 significant digits (11.8284 for 8 + 4 sqrt 2).
        assert math.isclose(result.length, optimal, rel_tol=1e-5), (start, goal)
        _check_path(result, blocked, start, goal, 8)


def _check_scenarios(name: str, problems: list[Scenario]) -> None:
    blocked, _, _ = load_map(MOVINGAI / name)
    for problem in problems:
        start, goal = problem.start, problem.goal
        result = find_path(blocked, start, goal, movement=8, weight=0.0)
        assert result is not None
        assert math.isclose(result.length, problem.optimal, rel_tol=1e-6), (name, start, goal)
        _check_path(result, blocked, start, goal, 8)


@pytest.mark.parametrize("name", MAPS_512)
def test_512_maps_hardest_buckets_match_the_optimal_lengths(name: str) -> None:
    problems = load_scenarios(MOVINGAI / f"{name}.scen")
    # 40 problems spread evenly over the longer half of the buckets (a sample, to stay fast).
    top = max(p.bucket for p in problems)
    longest = [p for p in problems if p.bucket >= top // 2]
    sample = longest[:: max(1, len(longest) // 40)][:40]
    assert len(sample) == 40
    _check_scenarios(name, sample)


@pytest.mark.slow
@pytest.mark.parametrize("name", MAPS_512)
def test_512_maps_problems_of_every_bucket_match_the_optimal_length(name: str) -> None:
    """Up to 1000 problems per map, evenly spread over the file (so over every bucket): all
    12,000 of the maze's would take about an hour."""
    problems = load_scenarios(MOVINGAI / f"{name}.scen")
    _check_scenarios(name, problems[:: max(1, len(problems) // 1000)])


@pytest.mark.parametrize("movement", [4, 8])
def test_open_grid_corner_to_corner_expands_about_the_path(movement: int) -> None:
    """Ties broken toward larger g: without that, A* expands most of the 128x128 grid."""
    grid = np.zeros((128, 128))
    result = find_path(grid, (0, 0), (127, 127), movement=movement, weight=0.0)
    assert result is not None
    assert result.length == pytest.approx(254 if movement == 4 else 127 * SQRT2)
    assert result.expansions <= 2 * len(result.path)


@pytest.mark.parametrize("movement", [4, 8])
def test_unreachable_goal_returns_none(movement: int) -> None:
    blocked = np.zeros((9, 9), dtype=bool)
    blocked[3:6, 3:6] = True
    blocked[4, 4] = False  # a free cell walled in
    assert find_path(blocked, (0, 0), (4, 4), movement=movement) is None
    assert find_path(blocked, (4, 4), (0, 0), movement=movement) is None
    assert find_path(blocked, (0, 0), (3, 3), movement=movement) is None  # goal blocked
    assert find_path(blocked, (3, 3), (0, 0), movement=movement) is None  # start blocked


def test_diagonal_squeeze_between_two_blocked_cells_is_not_allowed() -> None:
    blocked = np.array([[False, True], [True, False]])
    assert find_path(blocked, (0, 0), (1, 1), movement=8) is None


def test_start_equals_goal() -> None:
    result = find_path(np.zeros((4, 4)), (2, 1), (2, 1))
    assert result == PathResult(path=((2, 1),), length=0.0, cost=0.0, expansions=0)


@pytest.mark.parametrize("reachable", [True, False])
def test_context_ticks_equal_expansions(reachable: bool) -> None:
    rng = np.random.default_rng(3)
    blocked = rng.random((40, 40)) < 0.2
    blocked[0, 0] = blocked[39, 39] = False
    if not reachable:
        blocked[38:, 38:] = True
        blocked[39, 39] = False
    ctx = Context()
    result = find_path(blocked, (0, 0), (39, 39), movement=8, ctx=ctx)
    if reachable:
        assert result is not None and result.expansions > 0
        assert ctx.ticks == result.expansions
    else:
        assert result is None
        assert ctx.ticks > 0  # the work that proved it is still reported


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cost": np.zeros(4)}, "2-D grid"),
        ({"movement": 6}, "movement must be 4 or 8, got 6"),
        ({"weight": -1.0}, "weight must be finite and >= 0"),
        ({"cost": -np.ones((4, 4))}, "obstacleness must be >= 0"),
        ({"goal": (4, 0)}, r"goal \(4, 0\) is outside the 4x4 grid"),
        ({"start": "ab"}, "start must be an \\(x, y\\) pair"),
        ({"impassable": np.zeros((3, 3), bool)}, "impassable has shape"),
    ],
    ids=["1-D", "movement", "weight", "negative", "outside", "not-a-pair", "shape"],
)
def test_bad_arguments_are_named(kwargs: dict, message: str) -> None:
    arguments = {"cost": np.zeros((4, 4)), "start": (0, 0), "goal": (3, 3)} | kwargs
    cost, start, goal = arguments.pop("cost"), arguments.pop("start"), arguments.pop("goal")
    with pytest.raises(ValueError, match=message):
        find_path(cost, start, goal, **arguments)
