"""Plan execution: any plan (ATP's first, middle and final plans, on the true map or on a noisy
one, or a plain list of cells) is followed to the goal on the true map whenever the goal is
reachable, through free cells and legal moves only; a fully refined plan is followed verbatim
with no search; an unreachable goal gives reached=False; plan quality is optimal / executed."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import load_problems
from anytime_navigation.planning.abstraction import Pyramid, cell_bounds, project
from anytime_navigation.planning.planner import MultiPath, Segment, atp
from anytime_navigation.planning.search import find_path
from anytime_navigation.resources import data_file
from anytime_navigation.task.execution import (
    Execution,
    execute,
    optimal_length,
    plan_quality,
    route_length,
    waypoints,
)
from anytime_navigation.task.vision import prior_map, sense
from anytime_navigation.world import BoolGrid, Position, World, random_world, reachable
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from anytime.modules import Context

MOVEMENTS = [pytest.param(4, id="4-connected"), pytest.param(8, id="8-connected")]


def _plans(world: World, seen: BoolGrid | None = None, top: int | None = None) -> list[MultiPath]:
    """Every plan ATP yields for `world`, planned on `seen` (the true map by default), from
    `top` (ATP's default level by default)."""
    pyramid = Pyramid.build(world.blocked if seen is None else seen)
    results = atp(Context(), world.start, world.goal, pyramid, movement=world.movement, top=top)
    return [r.value for r in results]


def _stages(plans: list[MultiPath]) -> list[MultiPath]:
    """The first, a middle and the final plan."""
    return [plans[0], plans[len(plans) // 2], plans[-1]]


def _noisy(world: World, error: float, seed: int) -> BoolGrid | None:
    """The true map with each cell flipped with probability `error`, start and goal kept free,
    redrawn until the goal is reachable on it (ATP needs a solvable map); None if 100 draws
    fail."""
    rng = np.random.default_rng(seed)
    for _ in range(100):
        seen = world.blocked ^ (rng.random(world.blocked.shape) < error)
        for x, y in (world.start, world.goal):
            seen[y, x] = False
        if reachable(seen, world.start, world.movement)[world.goal[1], world.goal[0]]:
            return seen
    return None


def _legal(a: Position, b: Position, blocked: BoolGrid, movement: int) -> bool:
    dx, dy = b[0] - a[0], b[1] - a[1]
    if movement == 4:
        return abs(dx) + abs(dy) == 1
    if max(abs(dx), abs(dy)) != 1:
        return False
    return not (dx and dy and (blocked[a[1], b[0]] or blocked[b[1], a[0]]))


def _check_route(execution: Execution, blocked: BoolGrid, start: Position, movement: int) -> None:
    """The invariants of every execution: starts at the start, free cells, legal moves, and the
    length is the sum of the steps."""
    route = execution.route
    assert route[0] == start
    xs, ys = np.array(route).T
    assert not blocked[ys, xs].any(), "the route enters a blocked cell"
    assert all(_legal(a, b, blocked, movement) for a, b in zip(route, route[1:], strict=False))
    steps = sum(math.dist(a, b) for a, b in zip(route, route[1:], strict=False))
    assert execution.length == pytest.approx(steps)
    assert execution.expansions >= 0


def _check_reaches(execution: Execution, world: World) -> None:
    _check_route(execution, world.blocked, world.start, world.movement)
    assert execution.reached
    assert execution.route[-1] == world.goal
    optimal = optimal_length(world.blocked, world.start, world.goal, movement=world.movement)
    assert optimal is not None
    assert execution.length >= optimal - 1e-9
    assert 0.0 <= plan_quality(execution.length, optimal) <= 1.0


def _enters_in_order(route: tuple[Position, ...], boxes: list[tuple[int, int, int, int]]) -> bool:
    """Whether the route enters each box in turn (greedy subsequence matching)."""
    i = 0
    for x0, y0, x1, y1 in boxes:
        while i < len(route) and not (x0 <= route[i][0] < x1 and y0 <= route[i][1] < y1):
            i += 1
        if i == len(route):
            return False
    return True


# --- waypoints ---------------------------------------------------------------------------------


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_the_one_cell_top_level_plan_reduces_to_start_and_goal(movement: int) -> None:
    world = random_world(32, seed=0, movement=movement)
    first = _plans(world, top=5)[0]
    assert [s.level for s in first.segments] == [5]
    assert waypoints(first) == [(0, world.start), (0, world.goal)]


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_the_waypoints_of_a_fully_refined_plan_are_its_base_route(movement: int) -> None:
    world = random_world(32, seed=1, movement=movement)
    final = _plans(world)[-1]
    route = final.base_route()
    assert route is not None
    assert waypoints(final) == [(0, cell) for cell in route]


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("seed", [0, 1])
def test_no_waypoint_block_contains_its_neighbour(movement: int, seed: int) -> None:
    world = random_world(32, seed=seed, movement=movement)
    for plan in _plans(world):
        points = waypoints(plan)
        assert points[0] == (0, world.start) and points[-1] == (0, world.goal)
        for (la, a), (lb, b) in zip(points, points[1:], strict=False):
            # Projected to the coarser level, two nested blocks would be the same cell.
            level = max(la, lb)
            assert project(a, la, level) != project(b, lb, level)


def test_waypoints_of_a_mixed_plan() -> None:
    """Junctions repeated, a coarse cell ending where a finer segment starts, and a coarse cell
    starting where a finer one ended, are all dropped."""
    plan = MultiPath(
        start=(0, 0),
        goal=(7, 0),
        segments=(
            Segment(1, [(0, 0), (1, 0)]),  # (1, 0)@1 contains (2, 0)@0: dropped
            Segment(0, [(2, 0), (3, 0), (4, 0)]),  # (2, 0)@1 contains (4, 0)@0: dropped
            Segment(1, [(2, 0), (3, 0)]),  # (3, 0)@1 contains the goal: dropped
        ),
    )
    assert waypoints(plan) == [(0, (0, 0)), (0, (2, 0)), (0, (3, 0)), (0, (4, 0)), (0, (7, 0))]


# --- following plans ---------------------------------------------------------------------------


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_fully_refined_plan_is_followed_verbatim_without_search(movement: int, seed: int) -> None:
    world = random_world(64, seed=seed, movement=movement)
    final = _plans(world)[-1]
    ctx = Context()
    execution = execute(final, world.blocked, movement=movement, ctx=ctx)
    assert execution.route == final.base_route()
    assert execution.expansions == 0 and ctx.ticks == 0
    _check_reaches(execution, world)


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("seed", range(4))
def test_every_plan_of_atp_reaches_the_goal(movement: int, seed: int) -> None:
    world = random_world(32, seed=seed, movement=movement)
    for plan in _plans(world):
        execution = execute(plan, world.blocked, movement=movement)
        _check_reaches(execution, world)
        # Every waypoint block with a reachable free cell is entered, in order.
        ok = reachable(world.blocked, world.start)
        boxes = [cell_bounds(cell, level) for level, cell in waypoints(plan)]
        boxes = [(x0, y0, x1, y1) for x0, y0, x1, y1 in boxes if ok[y0:y1, x0:x1].any()]
        assert _enters_in_order(execution.route, boxes)


@settings(max_examples=30, deadline=None)
@given(
    size=st.sampled_from([16, 32, 64]),
    seed=st.integers(0, 10_000),
    movement=st.sampled_from([4, 8]),
    density=st.floats(0.05, 0.3),
    error=st.sampled_from([0.0, 0.02, 0.1, 0.2]),
)
def test_execution_reaches_the_goal_from_plans_on_a_noisy_map(
    size: int, seed: int, movement: int, density: float, error: float
) -> None:
    """The property of the issue: on connected worlds, plans from ATP at every stage, computed
    on a map with wrong cells, are executed to the goal on the true map."""
    world = random_world(size, seed=seed, density=density, movement=movement)
    seen = _noisy(world, error, seed) if error else world.blocked
    assume(seen is not None)
    for plan in _stages(_plans(world, seen)):
        ctx = Context()
        execution = execute(plan, world.blocked, movement=movement, ctx=ctx)
        _check_reaches(execution, world)
        assert ctx.ticks == execution.expansions


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_plans_on_a_sensed_map_reach_the_goal(movement: int) -> None:
    """The noisy map from anytime vision (q = 0.8 at t_a), and the prior (all free)."""
    world = random_world(64, seed=5, movement=movement)
    seen = sense(Context(10), world, t_a=10, q_a=0.8, t_b=100, seed=_vision_seed(world, movement))
    for grid in (seen.value, prior_map(world)):
        for plan in _stages(_plans(world, grid)):
            _check_reaches(execute(plan, world.blocked, movement=movement), world)


def _vision_seed(world: World, movement: int) -> int:
    """A vision seed whose map leaves the goal reachable with start and goal free."""
    for seed in range(200):
        grid = sense(Context(10), world, t_a=10, q_a=0.8, t_b=100, seed=seed).value
        x, y = world.goal
        if not grid[world.start[1], world.start[0]] and not grid[y, x]:
            if reachable(grid, world.start, movement)[y, x]:
                return seed
    raise AssertionError("no usable vision seed")  # pragma: no cover


# --- the plan's corridor -----------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    size=st.sampled_from([16, 32, 64]),
    seed=st.integers(0, 10_000),
    movement=st.sampled_from([4, 8]),
    density=st.floats(0.05, 0.35),
)
def test_a_plan_on_the_true_map_is_followed_inside_its_corridor(
    size: int, seed: int, movement: int, density: float
) -> None:
    """The cells of a plan's nodes (and the corners its diagonal moves between nodes need) join
    the start to the goal, and the robot keeping to the plan on the map it was made on never
    leaves them: it goes where the plan means."""
    world = random_world(size, seed=seed, density=density, movement=movement)
    for plan in _stages(_plans(world)):
        corridor = plan.corridor()
        assert corridor is not None and corridor.shape == world.blocked.shape
        assert not (corridor & world.blocked).any()
        inside = find_path(
            world.blocked | ~corridor, world.start, world.goal, movement=movement, weight=0.0
        )
        assert inside is not None, "the corridor joins the start to the goal"
        execution = execute(plan, world.blocked, movement=movement, keep_to_plan=True)
        _check_reaches(execution, world)
        xs, ys = np.array(execution.route).T
        assert corridor[ys, xs].all()


def test_a_first_plan_through_a_maze_is_followed_without_a_dead_end() -> None:
    """On a maze of one-cell corridors, the first plan's nodes hold the maze's only route, and
    the robot told to keep to them follows it optimally; one that takes the unseen cells of the
    plan's blocks as free goes into dead ends (0.43-0.84 on the four longest problems)."""
    blocked, _, _, scenarios = load_problems(Path(str(data_file("maps"))) / "maze512-1-0.map")
    problem = max(scenarios, key=lambda s: s.optimal)
    pyramid = Pyramid.build(blocked)
    first = next(atp(Context(), problem.start, problem.goal, pyramid, movement=8)).value
    assert first.refinable and {s.level for s in first.segments} == {3}
    execution = execute(first, blocked, movement=8, keep_to_plan=True)
    optimal = optimal_length(blocked, problem.start, problem.goal, movement=8)
    assert optimal is not None
    assert execution.reached and execution.length == pytest.approx(optimal)
    feeling = execute(first, blocked, movement=8)  # not told to: the unseen cells count as free
    assert feeling.reached and feeling.length > 1.1 * optimal


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_a_corridor_a_wall_cuts_on_the_true_map_is_left(movement: int) -> None:
    """Planned on an empty map, the first plan runs straight along one row of blocks; the
    true map has a wall across that row with its gap outside the corridor: the robot meets
    the wall, leaves the corridor and arrives through the gap."""
    seen = np.zeros((32, 32), dtype=bool)
    blocked = seen.copy()
    blocked[:31, 16] = True  # the gap at (16, 31), in the blocks' bottom row
    world = World(blocked, (2, 17), (29, 17), movement)
    first = _plans(world, seen)[0]
    corridor = first.corridor()
    assert corridor is not None and not corridor[31, 16]
    execution = execute(first, blocked, movement=movement, keep_to_plan=True)
    _check_reaches(execution, world)
    assert (16, 31) in execution.route


def test_a_plan_without_an_abstraction_has_no_corridor() -> None:
    plan = MultiPath((0, 0), (1, 0), (Segment(0, [(0, 0), (1, 0)]),))
    assert plan.corridor() is None


# --- plain lists of cells ----------------------------------------------------------------------


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_an_optimal_route_as_a_list_is_followed_verbatim_with_quality_1(movement: int) -> None:
    world = random_world(64, seed=2, movement=movement)
    found = find_path(world.blocked, world.start, world.goal, movement=movement, weight=0)
    assert found is not None
    execution = execute(list(found.path), world.blocked, movement=movement)
    assert execution.route == found.path and execution.expansions == 0
    optimal = optimal_length(world.blocked, world.start, world.goal, movement=movement)
    assert optimal is not None and optimal == pytest.approx(found.length)
    assert plan_quality(execution.length, optimal) == 1.0


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("seed", [0, 3])
def test_start_and_goal_alone_is_walked_by_obstacle_avoidance(movement: int, seed: int) -> None:
    """With no plan between start and goal the robot feels its way: it arrives, never by a
    route shorter than the optimum, and on an open map by an optimal one."""
    world = random_world(32, seed=seed, movement=movement)
    optimal = optimal_length(world.blocked, world.start, world.goal, movement=movement)
    assert optimal is not None
    walked = execute([world.start, world.goal], world.blocked, movement=movement)
    _check_reaches(walked, world)
    assert walked.length >= optimal - 1e-9
    assert walked.expansions > 0
    open_map = np.zeros((32, 32), dtype=bool)
    walked = execute([world.start, world.goal], open_map, movement=movement)
    assert walked.length == pytest.approx(
        optimal_length(open_map, world.start, world.goal, movement=movement)
    )


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_a_sparse_list_through_blocked_cells_reaches_the_goal(movement: int) -> None:
    world = random_world(32, seed=4, density=0.3, movement=movement)
    ys, xs = np.nonzero(world.blocked)
    plan = [world.start, (int(xs[0]), int(ys[0])), (16, 3), (int(xs[-1]), int(ys[-1])), world.goal]
    execution = execute(plan, world.blocked, movement=movement)
    _check_reaches(execution, world)
    assert execution.expansions > 0


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_a_wall_with_its_gap_at_the_far_end_is_felt_around(movement: int) -> None:
    """The robot, seeing only its neighbours, heads straight for the goal, meets the wall, and
    follows what it has seen of it down to the gap and back up: it arrives, and a second trip
    with the memory of the first is no longer."""
    blocked = np.zeros((32, 32), dtype=bool)
    blocked[:31, 16] = True  # gap at (16, 31)
    world = World(blocked, (15, 0), (17, 0), movement)
    ctx = Context()
    memory = np.zeros_like(blocked)
    first = execute([world.start, world.goal], blocked, movement=movement, ctx=ctx, memory=memory)
    _check_reaches(first, world)
    assert (16, 31) in first.route
    assert ctx.ticks == first.expansions > 0
    optimal = optimal_length(blocked, (15, 0), (17, 0), movement=movement)
    assert optimal is not None
    assert optimal - 1e-9 <= first.length < 1.5 * optimal
    assert memory.sum() > 0 and not (memory & ~blocked).any()  # it remembers only the truth
    second = execute([world.start, world.goal], blocked, movement=movement, memory=memory)
    _check_reaches(second, world)
    assert second.length <= first.length + 1e-9


def test_start_equal_to_goal() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    execution = execute([(3, 3)], blocked)
    assert execution == Execution(route=((3, 3),), length=0.0, expansions=0, reached=True)
    assert plan_quality(execution.length, optimal_length(blocked, (3, 3), (3, 3)) or 0.0) == 1.0


# --- unreachable goals -------------------------------------------------------------------------


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_an_unreachable_goal_gives_reached_false(movement: int) -> None:
    """A wall the planner does not know of (it plans on the prior, all free): no exception, a
    route through the start's side only, reached=False."""
    blocked = np.zeros((32, 32), dtype=bool)
    blocked[:, 20] = True
    start, goal = (0, 0), (31, 31)
    assert optimal_length(blocked, start, goal, movement=movement) is None
    pyramid = Pyramid.build(prior_map(blocked))
    plans = [r.value for r in atp(Context(), start, goal, pyramid, movement=movement)]
    ok = reachable(blocked, start)
    candidates: list[MultiPath | list[Position]] = [*_stages(plans)]
    candidates.append([start, (10, 10), (25, 10), goal])
    for plan in candidates:
        execution = execute(plan, blocked, movement=movement)
        assert not execution.reached
        _check_route(execution, blocked, start, movement)
        xs, ys = np.array(execution.route).T
        assert ok[ys, xs].all()
    # The waypoints beyond the wall are skipped: the route ends at the last one reachable.
    assert execution.route[-1] == (10, 10)
    assert plan_quality(math.inf, 42.0) == 0.0


def test_a_blocked_goal_gives_reached_false() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[7, 7] = True
    execution = execute([(0, 0), (7, 7)], blocked, movement=8)
    assert not execution.reached and execution.route[0] == (0, 0)


# --- quality, length and errors ----------------------------------------------------------------


def test_plan_quality() -> None:
    assert plan_quality(10.0, 8.0) == pytest.approx(0.8)
    assert plan_quality(8.0, 8.0) == 1.0
    assert plan_quality(8.0 - 1e-12, 8.0) == 1.0  # rounding is clipped
    assert plan_quality(0.0, 0.0) == 1.0
    assert plan_quality(math.inf, 5.0) == 0.0
    for bad in [(-1.0, 1.0), (1.0, -1.0), (math.nan, 1.0), (0.0, 3.0)]:
        with pytest.raises(ValueError):
            plan_quality(*bad)


def test_route_length() -> None:
    assert route_length([]) == 0.0
    assert route_length([(0, 0)]) == 0.0
    assert route_length([(0, 0), (1, 0), (2, 1), (2, 2), (1, 3)]) == pytest.approx(
        2 + 2 * math.sqrt(2)
    )


def test_errors() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[0, 0] = True
    with pytest.raises(ValueError, match="blocked"):
        execute([(0, 0), (5, 5)], blocked)
    with pytest.raises(ValueError, match="outside"):
        execute([(1, 1), (8, 5)], blocked)
    with pytest.raises(ValueError, match="outside"):
        execute([(1, 1), (-1, 5)], blocked)
    with pytest.raises(ValueError, match="at least one"):
        execute([], blocked)
    with pytest.raises(ValueError, match="movement"):
        execute([(1, 1)], blocked, movement=6)
    with pytest.raises(ValueError, match=r"the memory has shape \(2, 2\), the map \(8, 8\)"):
        execute([(1, 1)], blocked, memory=np.zeros((2, 2), dtype=bool))
