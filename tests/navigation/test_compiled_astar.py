"""The compiled A* (`search.GridAstar`), the baseline the planner is measured against: the same
paths, costs and expansions as the pure-Python `find_path` (same moves, heuristic and
tie-breaking), the `.scen` optimal lengths, and queries that do not disturb one another."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import load_map, load_scenarios
from anytime_navigation.planning.search import GridAstar, find_path
from anytime_navigation.resources import data_file
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.modules import Context

MOVINGAI = Path(str(data_file("maps")))


def test_arena_every_problem_is_the_scen_optimum_and_find_paths_search() -> None:
    blocked, _, _ = load_map(MOVINGAI / "arena.map")
    problems = load_scenarios(MOVINGAI / "arena.map.scen")
    assert len(problems) == 160
    astar = GridAstar(blocked, movement=8, weight=0.0)
    for problem in problems:
        found = astar.find_path(problem.start, problem.goal)
        assert found is not None
        # The old-style file prints 6 significant digits (11.8284 for 8 + 4 sqrt 2).
        assert math.isclose(found.length, problem.optimal, rel_tol=1e-5), problem
        assert found == find_path(blocked, problem.start, problem.goal, movement=8, weight=0.0)


@pytest.mark.parametrize("name", ["random512-10-0.map", "8room_000.map", "maze512-1-0.map"])
def test_512_maps_longest_problems_are_the_scen_optima(name: str) -> None:
    blocked, _, _ = load_map(MOVINGAI / name)
    problems = load_scenarios(MOVINGAI / f"{name}.scen")
    astar = GridAstar(blocked, movement=8, weight=0.0)
    for problem in sorted(problems, key=lambda p: -p.optimal)[:10]:
        found = astar.find_path(problem.start, problem.goal)
        assert found is not None
        assert math.isclose(found.length, problem.optimal, rel_tol=1e-6), problem


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    side=st.integers(1, 24),
    density=st.sampled_from([0.0, 0.15, 0.3, 0.45]),
    movement=st.sampled_from([4, 8]),
    weight=st.sampled_from([0.0, 1.0, 3.0]),
)
def test_same_path_cost_and_expansions_as_find_path(
    seed: int, side: int, density: float, movement: int, weight: float
) -> None:
    """Step for step the pure-Python search: the heap pops in the same order, so the path, its
    cost and the expansions are equal exactly, on every query of one map in a row."""
    rng = np.random.default_rng(seed)
    cost = rng.random((side, side + 3))
    cost[rng.random(cost.shape) < density] = 1.0
    astar = GridAstar(cost, movement=movement, weight=weight)
    for _ in range(4):
        start = (int(rng.integers(side + 3)), int(rng.integers(side)))
        goal = (int(rng.integers(side + 3)), int(rng.integers(side)))
        ctx = Context()
        found = astar.find_path(start, goal, ctx=ctx)
        assert found == find_path(cost, start, goal, movement=movement, weight=weight)
        if found is not None:
            assert ctx.ticks == found.expansions


@pytest.mark.parametrize("movement", [4, 8])
def test_unreachable_and_blocked_ends_are_none(movement: int) -> None:
    blocked = np.zeros((9, 9), dtype=bool)
    blocked[3:6, 3:6] = True
    blocked[4, 4] = False  # a free cell walled in
    astar = GridAstar(blocked, movement=movement)
    assert astar.find_path((0, 0), (4, 4)) is None
    assert astar.find_path((4, 4), (0, 0)) is None
    assert astar.find_path((0, 0), (3, 3)) is None  # goal blocked
    assert astar.find_path((3, 3), (0, 0)) is None  # start blocked
    found = astar.find_path((0, 0), (8, 8))  # a query after the failed ones is unaffected
    assert found == find_path(blocked, (0, 0), (8, 8), movement=movement)


def test_no_corner_cutting_and_start_equals_goal() -> None:
    squeeze = GridAstar(np.array([[False, True], [True, False]]), movement=8)
    assert squeeze.find_path((0, 0), (1, 1)) is None
    found = GridAstar(np.zeros((4, 4))).find_path((2, 1), (2, 1))
    assert found is not None and found.path == ((2, 1),) and found.expansions == 0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cost": np.zeros(4)}, "2-D grid"),
        ({"movement": 6}, "movement must be 4 or 8, got 6"),
        ({"weight": -1.0}, "weight must be finite and >= 0"),
        ({"impassable": np.zeros((3, 3), bool)}, "impassable has shape"),
    ],
    ids=["1-D", "movement", "weight", "shape"],
)
def test_bad_maps_are_named(kwargs: dict, message: str) -> None:
    arguments = {"cost": np.zeros((4, 4))} | kwargs
    with pytest.raises(ValueError, match=message):
        GridAstar(arguments.pop("cost"), **arguments)


def test_positions_outside_the_map_are_named() -> None:
    astar = GridAstar(np.zeros((4, 4)))
    with pytest.raises(ValueError, match=r"goal \(4, 0\) is outside the 4x4 grid"):
        astar.find_path((0, 0), (4, 0))
