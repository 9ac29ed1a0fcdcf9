"""The anytime abstract planner (ATP): the first plan is at the top level, every refinement
lowers exactly one segment one level, segment lengths stay about invariant, the final plan is
a free base route from start to goal, quality estimates are in [0, 1], interruption works."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import Scenario, load_map, load_problems
from anytime_navigation.planning.abstraction import Pyramid, project
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import (
    DEFAULT_TOP,
    MultiPath,
    Segment,
    atp,
    quality_estimate,
    segmentize,
)
from anytime_navigation.resources import data_file
from anytime_navigation.task.execution import execute, optimal_length, plan_quality
from anytime_navigation.world import random_world
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.modules import Context, Result

MOVEMENTS = [pytest.param(4, id="4-connected"), pytest.param(8, id="8-connected")]


def _run(size: int, seed: int, movement: int, top: int | None = None) -> list[Result]:
    world = random_world(size, seed=seed, movement=movement)
    pyramid = Pyramid.build(world.blocked)
    return list(atp(Context(), world.start, world.goal, pyramid, movement=movement, top=top))


def _refinements(results: list[Result]) -> list[tuple[Result, Result]]:
    """The consecutive results, each a refinement of the one before: the first plan's
    re-routing through the doors is not registered, and the second result refines it; the
    first plan is one segment, which that refinement replaces whole, as one of the first
    plan's would."""
    return list(zip(results, results[1:], strict=False))


def _changed(before: MultiPath, after: MultiPath) -> tuple[int, Segment, tuple[Segment, ...]]:
    """The index of the route segment replaced, the old segment and what replaced it."""
    old, new = before.segments, after.segments
    i = next(i for i, (a, b) in enumerate(zip(old, new, strict=False)) if a != b)
    tail = len(old) - i - 1
    assert old[i + 1 :] == new[len(new) - tail :]
    return i, old[i], new[i : len(new) - tail]


def _neighbours(a: tuple[int, int], b: tuple[int, int], movement: int) -> bool:
    dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
    return dx + dy == 1 if movement == 4 else max(dx, dy) == 1


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("top", [None, 4, 3], ids=["top=pyramid", "top=4", "top=3"])
def test_first_plan_is_at_the_top_level_in_equal_segments(movement: int, top: int | None) -> None:
    world = random_world(64, seed=1, movement=movement)
    pyramid = Pyramid.build(world.blocked)
    first = next(
        atp(
            Context(), world.start, world.goal, pyramid, movement=movement, top=top, segment_moves=8
        )
    )
    level = min(DEFAULT_TOP, pyramid.top) if top is None else top
    plan = first.value
    assert {s.level for s in plan.segments} == {level}
    assert plan.segments[0].source == project(world.start, 0, level)
    assert plan.segments[-1].target == project(world.goal, 0, level)
    moves = [s.moves for s in plan.segments]
    assert max(moves) <= 8 and max(moves) - min(moves) <= 1
    for a, b in zip(plan.segments, plan.segments[1:], strict=False):
        assert a.target == b.source
    assert plan.head == segmentize(world.start, level)
    assert [s.level for s in plan.tail] == list(range(level - 1, -1, -1))
    assert plan.tail[-1].cells == (world.goal,)


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_refinement_lowers_one_segment_one_level(movement: int, seed: int) -> None:
    results = _run(64, seed, movement)
    assert len(results) > 1
    for before, after in _refinements(results):
        _, old, new = _changed(before.value, after.value)
        assert old.level >= 1
        assert 1 <= len(new) <= 2
        assert all(s.level == old.level - 1 for s in new)
        # The halves meet at one junction cell.
        if len(new) == 2:
            assert new[0].target == new[1].source


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("seed", range(6))
def test_segment_length_stays_within_one_move_on_an_open_map(movement: int, seed: int) -> None:
    """Refining a segment of m moves gives halves of at most m + 1 moves at the lower level, one
    at most a move longer than the other (on an open map, where no detour lengthens a half;
    shorter where the first plan steps through the middles of its blocks' sides, as long as
    a diagonal through their corners between the doors)."""
    rng = np.random.default_rng(seed)
    pyramid = Pyramid.build(np.zeros((64, 64), dtype=bool))
    start, goal = (tuple(int(v) for v in rng.integers(0, 64, 2)) for _ in range(2))
    for top in (2, 3, 4):
        results = list(atp(Context(), start, goal, pyramid, movement=movement, top=top))
        for before, after in _refinements(results):
            _, old, new = _changed(before.value, after.value)
            if old.moves == 0:
                continue  # a one-cell segment is re-planned whole, not halved
            moves = [s.moves for s in new]
            assert max(moves) <= old.moves + 1 and max(moves) - min(moves) <= 1, (old.moves, moves)


@pytest.mark.parametrize("movement", MOVEMENTS)
@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("size", [32, 64])
def test_final_plan_is_a_free_base_route(movement: int, seed: int, size: int) -> None:
    world = random_world(size, seed=seed, density=0.25, movement=movement)
    pyramid = Pyramid.build(world.blocked)
    results = list(atp(Context(), world.start, world.goal, pyramid, movement=movement))
    plan = results[-1].value
    assert not plan.refinable
    assert all(s.level == 0 for s in plan.parts)
    assert plan.head == () and plan.tail == ()
    for a, b in zip(plan.segments, plan.segments[1:], strict=False):
        assert a.target == b.source
    route = plan.base_route()
    assert route is not None
    assert route[0] == world.start and route[-1] == world.goal
    assert all(_neighbours(a, b, movement) for a, b in zip(route, route[1:], strict=False))
    assert not any(world.blocked[y, x] for x, y in route)
    if movement == 8:  # no corner cutting
        for (ax, ay), (bx, by) in zip(route, route[1:], strict=False):
            assert not world.blocked[ay, bx] and not world.blocked[by, ax]


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_quality_estimates_are_in_unit_interval_and_end_at_one(movement: int) -> None:
    results = _run(64, 3, movement)
    qualities = [r.quality for r in results]
    assert all(0.0 <= q <= 1.0 for q in qualities)
    assert qualities[0] < 0.8  # a 16 x 16 abstract plan of a 64 x 64 map
    assert qualities[-1] == 1.0  # fully refined: a base route through free cells
    assert qualities[-1] == max(qualities)


def test_quality_estimate_discounts_level_and_obstacleness() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[0:2, 2:4] = True  # level-1 cell (1, 0) fully blocked, level-2 cell (0, 0) 1/4
    pyramid = Pyramid.build(blocked)
    clear = MultiPath((0, 0), (7, 7), (Segment(1, [(0, 2), (1, 2), (2, 2)]),))
    # Mean obstacleness 0, level 1 of top 3: (1 - 1/4).
    assert quality_estimate(clear, pyramid) == pytest.approx(0.75)
    cluttered = MultiPath((0, 0), (7, 7), (Segment(2, [(0, 0), (1, 0)]),))
    # Mean obstacleness (1/4 + 0) / 2, level 2: (1 - 1/8) * (1 - 2/4).
    assert quality_estimate(cluttered, pyramid) == pytest.approx(0.875 * 0.5)
    base = MultiPath((0, 0), (1, 0), (Segment(0, [(0, 0), (1, 0)]),))
    assert quality_estimate(base, pyramid) == 1.0


def test_segmentize_is_the_chain_of_cells_containing_the_position() -> None:
    assert segmentize((13, 6), 3) == (
        Segment(0, [(13, 6)]),
        Segment(1, [(6, 3)]),
        Segment(2, [(3, 1)]),
    )


def test_a_segment_of_an_array_of_cells_is_the_segment_of_its_int_tuples() -> None:
    cells = np.array([[3, 4], [4, 4], [5, 5]], dtype=np.int64)
    segment = Segment(1, cells, np.array([7, 8, 9]))
    assert segment == Segment(1, [(3, 4), (4, 4), (5, 5)], (7, 8, 9))
    assert all(type(v) is int for cell in segment.cells for v in cell)
    assert all(type(node) is int for node in segment.nodes)
    assert Segment(0, np.array([[1.7, 2.2]])).cells == ((1, 2),)  # floats: int() as before
    with pytest.raises(ValueError, match="at least one cell"):
        Segment(0, np.zeros((0, 2), dtype=np.int64))


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_interruption_keeps_a_result_and_never_works_past_the_deadline(movement: int) -> None:
    world = random_world(128, seed=4, movement=movement)
    pyramid = Pyramid.build(world.blocked)
    full = Context()
    ticks = [full.elapsed for _ in atp(full, world.start, world.goal, pyramid, movement=movement)]
    assert len(ticks) > 3
    # Enough for the second plan and part of the third refinement.
    allocation = (ticks[1] + ticks[2]) / 2
    ctx = Context(allocation=allocation)
    results = list(atp(ctx, world.start, world.goal, pyramid, movement=movement))
    assert len(results) == 2
    assert results[-1].value.refinable
    assert ctx.elapsed <= allocation
    # Less than the first plan needs: no result, and no work past the deadline either.
    short = Context(allocation=ticks[0] / 2)
    assert list(atp(short, world.start, world.goal, pyramid, movement=movement)) == []
    assert short.elapsed <= ticks[0] / 2


def test_rejects_a_blocked_start_and_a_bad_top() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[0, 0] = True
    pyramid = Pyramid.build(blocked)
    with pytest.raises(ValueError, match=r"^start \(0, 0\) is a blocked cell$"):
        next(atp(Context(), (0, 0), (7, 7), pyramid))
    with pytest.raises(ValueError, match=r"^goal \(7, 8\) is outside the 8x8 map$"):
        next(atp(Context(), (1, 0), (7, 8), pyramid))
    with pytest.raises(ValueError, match=r"top must be in \[0, 3\], got 5"):
        next(atp(Context(), (1, 0), (7, 7), pyramid, top=5))


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_true_quality_is_non_decreasing_in_expectation(movement: int) -> None:
    """The papers' quality (optimal / executed length, the plan followed on the true map) of
    the first, middle and final plans, averaged over worlds, does not fall as ATP refines."""
    stages = []
    for seed in range(12):
        world = random_world(64, seed=seed, density=0.25, movement=movement)
        results = list(
            atp(Context(), world.start, world.goal, Pyramid.build(world.blocked), movement=movement)
        )
        optimal = optimal_length(world.blocked, world.start, world.goal, movement=movement)
        assert optimal is not None
        plans = [results[0], results[len(results) // 2], results[-1]]
        stages.append(
            [
                plan_quality(execute(r.value, world.blocked, movement=movement).length, optimal)
                for r in plans
            ]
        )
    first, middle, final = np.mean(stages, axis=0)
    assert first <= middle + 1e-9 <= final + 2e-9
    assert final > 0.9


def test_by_default_the_first_plan_is_one_segment_of_blocks_of_8_by_8_cells() -> None:
    world = random_world(128, seed=2)
    pyramid = Pyramid.build(world.blocked)
    first = next(atp(Context(), world.start, world.goal, pyramid)).value
    assert [s.level for s in first.segments] == [DEFAULT_TOP] == [3]


def test_a_coarse_plan_never_runs_through_a_wall_that_splits_a_block() -> None:
    """A wall with one door splits the map; with obstacleness the 8 x 8 blocks the wall
    crosses look passable (one column in eight blocked), with components they are two regions
    each, and the first plan goes through the door's block."""
    blocked = np.zeros((64, 64), dtype=bool)
    blocked[:, 35] = True  # a wall inside the blocks of columns 32..39
    blocked[60, 35] = False  # its one door, in the bottom block
    pyramid = Pyramid.build(blocked)
    first = next(atp(Context(), (2, 2), (62, 2), pyramid, movement=8)).value
    (segment,) = first.segments
    crossing = [cell for cell in segment.cells if cell[0] == 35 // 8]
    assert (35 // 8, 60 // 8) in crossing  # the door's block
    final = list(atp(Context(), (2, 2), (62, 2), pyramid, movement=8))[-1].value
    route = final.base_route()
    assert route is not None and (35, 60) in route
    assert execute(first, blocked, movement=8).reached


@pytest.mark.parametrize("doors", [True, False])
def test_either_way_the_plan_is_refined_to_a_free_base_route(doors: bool) -> None:
    world = random_world(64, seed=3, density=0.25, movement=8)
    pyramid = Pyramid.build(world.blocked)
    results = list(atp(Context(), world.start, world.goal, pyramid, movement=8, doors=doors))
    route = results[-1].value.base_route()
    assert route is not None and route[0] == world.start and route[-1] == world.goal
    assert all(not world.blocked[y, x] for x, y in route)


def test_the_first_plan_is_routed_again_through_the_doors_where_that_is_cheaper() -> None:
    """On rooms of 8 cells the first plan by centres takes dearer doors: the planner goes on
    from the cheapest route through the doors without registering it (by centres, what the
    first plan minimises, it is not shorter), and what follows refines it."""
    blocked = load_map(Path(str(data_file("maps"))) / "8room_000.map")[0]
    pyramid = Pyramid.build(blocked)
    components = Components.build(blocked, 8, top=3)
    doors = components.doors(3)
    start, goal = (4, 4), (500, 500)
    assert not blocked[4, 4] and not blocked[500, 500]
    without = list(atp(Context(), start, goal, pyramid, movement=8, doors=False))
    results = list(atp(Context(), start, goal, pyramid, movement=8, components=components))
    first = results[0].value.segments[0].nodes
    assert first == without[0].value.segments[0].nodes
    cheapest, cost, _ = doors.route(start, goal)
    assert cost < doors.cost_of(first, start, goal)
    # The second result is the door route's first refinement: its two halves, one level lower,
    # run through the children of the door route's nodes and of their neighbours.
    second = results[1].value.segments
    assert [s.level for s in second] == [2, 2]
    lower = [n for s in second for n in s.nodes]
    assert set(lower) <= set(components.widened(3, cheapest, 1).tolist())
    assert not set(lower) <= set(components.widened(3, first, 1).tolist())


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    size=st.sampled_from([32, 64]),
    density=st.sampled_from([0.1, 0.2, 0.3]),
    movement=st.sampled_from([4, 8]),
    segment_moves=st.sampled_from([None, 2]),
)
def test_with_follow_the_executed_quality_never_falls_from_one_plan_to_the_next(
    seed: int, size: int, density: float, movement: int, segment_moves: int | None
) -> None:
    """Issue 36: given how the robot will follow a plan (here: executed on the map planned on,
    keeping to the plan's corridor), the planner registers a plan only when it is followed no
    longer than the last one registered, so the quality executed never falls; the first plan is
    always registered, and what is dropped is only ever worse."""
    world = random_world(size, seed=seed, density=density, movement=movement)
    pyramid = Pyramid.build(world.blocked)
    followed: list[float] = []

    def follow(plan: MultiPath) -> float:
        length = execute(plan, world.blocked, movement=movement, keep_to_plan=True).length
        followed.append(length)
        return length

    results = list(
        atp(
            Context(),
            world.start,
            world.goal,
            pyramid,
            movement=movement,
            follow=follow,
            segment_moves=segment_moves,
        )
    )
    lengths = [
        execute(r.value, world.blocked, movement=movement, keep_to_plan=True).length
        for r in results
    ]
    assert lengths and lengths[0] == followed[0]
    assert all(b <= a for a, b in zip(lengths, lengths[1:], strict=False))
    assert lengths[-1] == min(followed)  # the best plan made is the last registered
    optimal = optimal_length(world.blocked, world.start, world.goal, movement=movement)
    assert optimal is not None
    qualities = [plan_quality(length, optimal) for length in lengths]
    assert all(b >= a for a, b in zip(qualities, qualities[1:], strict=False))


def _shipped(name: str) -> tuple[np.ndarray, list[Scenario]]:
    """A shipped MovingAI map and its problems."""
    blocked, _, _, scenarios = load_problems(Path(str(data_file("maps"))) / f"{name}.map")
    return blocked, scenarios


def _record(results: list[Result], ctx: Context) -> tuple[object, ...]:
    """What a run registers: each plan's segments (level, cells, nodes) and quality, and the
    work it reported."""
    plans = tuple(
        (r.quality, tuple((s.level, s.cells, s.nodes) for s in r.value.parts)) for r in results
    )
    return plans, ctx.ticks


def _fingerprint() -> str:
    """A digest of what the planner registers, and the ticks it reports, on fixed problems:
    random worlds of both movements with the options of the navigation task and of the
    benchmark, and the longest problems of a shipped MovingAI map."""
    import hashlib

    records = []
    for seed in range(3):
        for movement in (4, 8):
            world = random_world(128, seed=seed, movement=movement)
            pyramid = Pyramid.build(world.blocked)
            for options in ({}, {"doors": False}, {"segment_moves": 8}, {"top": 4}):
                ctx = Context()
                results = list(
                    atp(ctx, world.start, world.goal, pyramid, movement=movement, **options)
                )
                records.append(_record(results, ctx))
    blocked, scenarios = _shipped("8room_000")
    pyramid = Pyramid.build(blocked)
    components = Components.build(blocked, 8, top=DEFAULT_TOP)
    for scenario in sorted(scenarios, key=lambda s: -s.optimal)[:3]:
        ctx = Context()
        results = list(
            atp(ctx, scenario.start, scenario.goal, pyramid, movement=8, components=components)
        )
        records.append(_record(results, ctx))
    return hashlib.sha256(repr(records).encode()).hexdigest()


def test_speedups_leave_the_plans_and_ticks_unchanged() -> None:
    """Issue 36: the planner made faster without changing what it registers or reports (the
    navigation task's profiles and monitor were measured on these): the digest of its plans,
    qualities and ticks on fixed problems, as the planner of commit 5437123 made them."""
    assert _fingerprint() == FINGERPRINT


FINGERPRINT = "24af41e18998ff36b78aa29d39633ec567784c614aa334d6ef31a9509d2c6f29"


@pytest.mark.parametrize("movement", MOVEMENTS)
def test_door_rings_keep_the_door_route_near_the_first_plan(movement: int) -> None:
    """With `door_rings`, the door search keeps to the first plan's nodes and their neighbours
    up to that many edges away; with rings reaching every node it is the default search."""
    blocked = load_map(Path(str(data_file("maps"))) / "8room_000.map")[0]
    pyramid = Pyramid.build(blocked)
    components = Components.build(blocked, movement, top=3)
    start, goal = (4, 4), (500, 500)
    runs = {}
    for rings in (None, 0, 1, 10**6):
        ctx = Context()
        results = list(
            atp(
                ctx,
                start,
                goal,
                pyramid,
                movement=movement,
                components=components,
                door_rings=rings,
            )
        )
        runs[rings] = (results, ctx)
        route = results[-1].value.base_route()
        assert route is not None and route[0] == start and route[-1] == goal
        assert not any(blocked[y, x] for x, y in route)
    default, every = runs[None], runs[10**6]
    assert _record(*default) == _record(*every)
    first = default[0][0].value.segments[0].nodes
    near = components.neighbourhood(3, first, 1)
    bounded = components.route(3, start, goal, bound=first, rings=1)
    assert all(near[n] for n in bounded.nodes)
    assert not all(near[n] for n in components.route(3, start, goal, bound=first).nodes)
    # The door route's first refinement: through its nodes' children and their neighbours'.
    second = runs[1][0][1].value.segments
    around = components.neighbourhood(3, first, 2)
    assert all(around[components.levels[2].parent[n]] for s in second for n in s.nodes)
    assert runs[1][1].ticks < default[1].ticks  # less work


def test_direct_answers_a_short_problem_with_one_base_route() -> None:
    """With `direct`, a first plan of few nodes is followed by one search through its cells
    and its neighbours': one result, a free base route from start to goal, in fewer ticks
    than the refinements; a longer problem is planned as without it."""
    blocked, scenarios = _shipped("random512-10-0")
    pyramid = Pyramid.build(blocked)
    components = Components.build(blocked, 8, top=3)
    short = next(s for s in scenarios if 20 <= s.optimal <= 30)
    default, ctx = list(atp(Context(), short.start, short.goal, pyramid, movement=8)), Context()
    results = list(
        atp(ctx, short.start, short.goal, pyramid, movement=8, components=components, direct=6)
    )
    assert len(results) == 1 < len(default)
    plan = results[0].value
    assert results[0].quality == 1.0 and not plan.refinable and plan.head == plan.tail == ()
    route = plan.base_route()
    assert route is not None and route[0] == short.start and route[-1] == short.goal
    assert not any(blocked[y, x] for x, y in route)
    assert all(_neighbours(a, b, 8) for a, b in zip(route, route[1:], strict=False))
    length = execute(plan, blocked, movement=8).length
    assert short.optimal - 1e-4 <= length <= short.optimal / 0.95
    full = Context()
    list(atp(full, short.start, short.goal, pyramid, movement=8, components=components))
    assert ctx.ticks < full.ticks
    long = max(scenarios, key=lambda s: s.optimal)
    ctx, other = Context(), Context()
    with_direct = list(
        atp(ctx, long.start, long.goal, pyramid, movement=8, components=components, direct=6)
    )
    without = list(atp(other, long.start, long.goal, pyramid, movement=8, components=components))
    assert _record(with_direct, ctx) == _record(without, other)


def test_direct_never_works_past_the_deadline() -> None:
    blocked, scenarios = _shipped("random512-10-0")
    pyramid = Pyramid.build(blocked)
    short = next(s for s in scenarios if 20 <= s.optimal <= 30)
    full = Context()
    list(atp(full, short.start, short.goal, pyramid, movement=8, direct=6))
    first = Context()
    next(atp(first, short.start, short.goal, pyramid, movement=8))
    # Enough for the first plan, not for the direct search: the first plan is registered.
    allocation = (first.ticks + full.ticks) / 2
    ctx = Context(allocation=allocation)
    results = list(atp(ctx, short.start, short.goal, pyramid, movement=8, direct=6))
    assert len(results) == 1 and results[0].value.segments[0].level == DEFAULT_TOP
    assert ctx.elapsed <= allocation


def test_bad_options_are_named() -> None:
    world = random_world(64, seed=1)
    pyramid = Pyramid.build(world.blocked)
    for name in ("door_rings", "direct", "direct_width"):
        for _ in range(2):  # checked once per set of options, refused every time
            with pytest.raises(ValueError, match=f"{name} must be >= 0 or None, got -1"):
                next(atp(Context(), world.start, world.goal, pyramid, **{name: -1}))


@pytest.mark.parametrize("movement", [4, 8])
def test_a_plan_across_opened_walls_is_worth_less_than_its_estimate(movement: int) -> None:
    """A wall one cell thick walls the goal off: the planner opens the cheapest route that
    counts a blocked cell as two free ones (along the top row: 15 cells, one blocked, cost 16)
    and plans on that map; its plans keep 15 / 16 of their estimate, the last, fully refined
    (1.0 on the opened map), is reported at 15 / 16 exactly, not 1.0."""
    blocked = np.zeros((16, 16), dtype=bool)
    blocked[:, 8] = True
    pyramid = Pyramid.build(blocked)
    results = list(atp(Context(), (0, 0), (15, 0), pyramid, movement=movement))
    route = results[-1].value.base_route()
    assert route is not None and (8, 0) in route  # across the wall, where it was opened
    assert results[-1].quality == 15 / 16
    assert all(r.quality <= 15 / 16 for r in results)
    blocked[0, 8] = False  # a door there: the same route, nothing opened, quality 1.0
    free = list(atp(Context(), (0, 0), (15, 0), Pyramid.build(blocked), movement=movement))
    assert free[-1].value.base_route() == route
    assert free[-1].quality == 1.0
