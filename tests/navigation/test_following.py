"""The compiled follower (`following.Follower`): the length `execution.execute` walks following a
plan with keep_to_plan, to the bit, for every plan ATP yields (on the true map, on a noisy one:
the corridor cut, waypoints out of reach); and with it as atp's `follow`, the registered plans'
executed lengths never increase."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from anytime_navigation.movingai import load_problems
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.following import Follower
from anytime_navigation.planning.planner import MultiPath, atp
from anytime_navigation.resources import data_file
from anytime_navigation.task.execution import execute
from anytime_navigation.world import BoolGrid, random_world, reachable
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.modules import Context


def _plans(
    blocked: BoolGrid,
    start: tuple[int, int],
    goal: tuple[int, int],
    movement: int,
    **options: Any,
) -> list[MultiPath]:
    pyramid = Pyramid.build(blocked)
    return [r.value for r in atp(Context(), start, goal, pyramid, movement=movement, **options)]


def _noisy(
    blocked: BoolGrid, start: tuple[int, int], goal: tuple[int, int], movement: int, seed: int
) -> BoolGrid:
    """The map with 5% of its cells flipped, start and goal free, the goal reachable on it."""
    rng = np.random.default_rng(seed)
    while True:
        seen = blocked ^ (rng.random(blocked.shape) < 0.05)
        for x, y in (start, goal):
            seen[y, x] = False
        if reachable(seen, start, movement)[goal[1], goal[0]]:
            return seen


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    size=st.sampled_from([16, 32, 64]),
    movement=st.sampled_from([4, 8]),
    density=st.sampled_from([0.1, 0.2, 0.3]),
    noisy=st.booleans(),
    options=st.sampled_from(
        [
            {},
            {"top": 2},
            {"segment_moves": 3},
            {"direct_width": 12.0},
            {"no_ring_when_open": 0.05, "one_ring_when_open": 0.1},
        ]
    ),
)
def test_follower_is_execute(
    seed: int, size: int, movement: int, density: float, noisy: bool, options: dict[str, float]
) -> None:
    world = random_world(size, seed=seed, density=density, movement=movement)
    planned = world.blocked
    if noisy:  # plans on a map that is not the one followed: the corridor may be cut
        planned = _noisy(world.blocked, world.start, world.goal, movement, seed)
    follower = Follower(world.blocked, movement)
    for plan in _plans(planned, world.start, world.goal, movement, **options):
        expected = execute(plan, world.blocked, movement=movement, keep_to_plan=True).length
        assert follower(plan) == expected


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), movement=st.sampled_from([4, 8]), data=st.data())
def test_follower_in_any_order(seed: int, movement: int, data: st.DataObject) -> None:
    """Called on plans in any order, of two problems interleaved: what it resumes from is only
    ever what the plans share, so each is still followed as `execute` follows it."""
    world = random_world(32, seed=seed, density=0.2, movement=movement)
    plans = _plans(world.blocked, world.start, world.goal, movement, top=3)
    back = _plans(world.blocked, world.goal, world.start, movement, top=3)
    mixed = data.draw(st.permutations(plans + back))
    follower = Follower(world.blocked, movement)
    for plan in mixed:
        expected = execute(plan, world.blocked, movement=movement, keep_to_plan=True).length
        assert follower(plan) == expected
    assert (
        follower.route(mixed[0])
        == execute(mixed[0], world.blocked, movement=movement, keep_to_plan=True).route
    )


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    size=st.sampled_from([32, 64]),
    movement=st.sampled_from([4, 8]),
    noisy=st.booleans(),
    log=st.sampled_from([None, 0, 7, 60]),
    data=st.data(),
)
def test_taken_over_end_is_the_walked_one(
    seed: int, size: int, movement: int, noisy: bool, log: int | None, data: st.DataObject
) -> None:
    """A plan's route taken over from the last plan's run (the robot where that run's stood,
    the same waypoints to the goal, nothing it touched from there different) is the route a
    follower walking it from the start walks, and so is every later plan's: called on the
    plans in order, some left out (a longer change from plan to plan), on a map the plans
    were made on or not (the corridor cut: the memory decides), and with a touched log too
    short for some runs (`log` entries: those runs' ends are not taken over)."""
    world = random_world(size, seed=seed, density=0.2, movement=movement)
    planned = world.blocked
    if noisy:
        planned = _noisy(world.blocked, world.start, world.goal, movement, seed)
    plans = _plans(planned, world.start, world.goal, movement, segment_moves=3)
    chosen = [p for p in plans if data.draw(st.integers(0, 3)) > 0]
    follower = Follower(world.blocked, movement)
    walked = Follower(world.blocked, movement)
    if log is not None:
        follower._touched = np.zeros(log, dtype=np.int64)
    for plan in chosen:
        walked.reset()  # nothing to take over: every plan followed from the start
        length = walked(plan)
        assert follower(plan) == length
        assert length == execute(plan, world.blocked, movement=movement, keep_to_plan=True).length
    if log == 0:
        assert follower.taken_over == 0
    assert walked.taken_over == 0


def test_follower_takes_over_on_a_movingai_map() -> None:
    """The longest problem of random512-10-0, every plan of the large-map options in order: most
    of each plan's route is taken over from the last plan's, and each length is a walk's."""
    blocked, _, _, scenarios = load_problems(Path(str(data_file("maps"))) / "random512-10-0.map")
    scenario = max(scenarios, key=lambda s: s.optimal)
    options = {"top": 4, "direct": 4, "direct_width": 12, "no_ring_when_open": 0.05}
    plans = _plans(blocked, scenario.start, scenario.goal, 8, **options)
    follower, walked = Follower(blocked, 8), Follower(blocked, 8)
    for plan in plans:
        walked.reset()
        assert follower(plan) == walked(plan)
    assert follower.taken_over > 0


def test_follower_is_execute_on_a_movingai_map() -> None:
    """A 512 x 512 map (random, 10% blocked), two long problems, every plan of the best
    options of issue 36's per-kind table."""
    blocked, _, _, scenarios = load_problems(Path(str(data_file("maps"))) / "random512-10-0.map")
    follower = Follower(blocked, 8)
    options = {"top": 4, "direct": 4, "direct_width": 12, "no_ring_when_open": 0.05}
    for scenario in sorted(scenarios, key=lambda s: -s.optimal)[:2]:
        for plan in _plans(blocked, scenario.start, scenario.goal, 8, **options):
            expected = execute(plan, blocked, movement=8, keep_to_plan=True).length
            assert follower(plan) == expected


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    size=st.sampled_from([32, 64]),
    movement=st.sampled_from([4, 8]),
    segment_moves=st.sampled_from([None, 2]),
)
def test_registered_plans_are_followed_no_worse(
    seed: int, size: int, movement: int, segment_moves: int | None
) -> None:
    world = random_world(size, seed=seed, density=0.25, movement=movement)
    follower = Follower(world.blocked, movement)
    pyramid = Pyramid.build(world.blocked)
    plans = [
        r.value
        for r in atp(
            Context(),
            world.start,
            world.goal,
            pyramid,
            movement=movement,
            segment_moves=segment_moves,
            follow=follower,
        )
    ]
    lengths = [
        execute(p, world.blocked, movement=movement, keep_to_plan=True).length for p in plans
    ]
    assert lengths == sorted(lengths, reverse=True)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    size=st.sampled_from([32, 64]),
    movement=st.sampled_from([4, 8]),
    density=st.sampled_from([0.1, 0.2, 0.3]),
    top=st.sampled_from([1, 2, 3]),
)
def test_direct_route_is_followed_no_longer_than_the_first_plan(
    seed: int, size: int, movement: int, density: float, top: int
) -> None:
    """`Follower.planned_on_its_map`: a robot keeping to the first plan's corridor on the map
    it was made on walks inside the cells the direct route is the shortest through (the first
    plan's nodes and their neighbours'), so the direct route is never followed longer: the
    planner may register it without following either plan."""
    world = random_world(size, seed=seed, density=density, movement=movement)
    first, direct = _plans(
        world.blocked, world.start, world.goal, movement, top=top, direct_width=1e9
    )
    follower = Follower(world.blocked, movement)
    assert follower.planned_on_its_map
    assert not direct.refinable
    assert follower(direct) <= follower(first)


def test_plan_without_abstraction() -> None:
    world = random_world(16, seed=1)
    plan = _plans(world.blocked, world.start, world.goal, 4)[0]
    bare = MultiPath(plan.start, plan.goal, plan.segments)
    with pytest.raises(ValueError, match="abstraction"):
        Follower(world.blocked, 4)(bare)
