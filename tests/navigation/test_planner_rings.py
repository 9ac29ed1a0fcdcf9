"""The ATP's ring options (issue 36): `no_ring_when_open`, an open level-1 segment refined
without a ring, `one_ring_when_open`, an open level-2 segment refined with one ring of
neighbouring nodes, not three, and `no_ring_when_clear`, a level-2 segment mostly of clear
blocks refined without rings."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from anytime_navigation.planning import planner
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp
from anytime_navigation.planning.search import STEP_REFINED
from anytime_navigation.task.execution import execute
from anytime_navigation.world import random_world

from anytime.modules import Context

OPEN_MAP = np.zeros((64, 64), dtype=bool)
_SHARES: list[float] = []
START, GOAL = (2, 3), (60, 55)


def _run(
    monkeypatch: pytest.MonkeyPatch,
    level: int,
    blocked: np.ndarray,
    start: Any,
    goal: Any,
    **options: Any,
) -> tuple[list[tuple[int, float]], Any, int]:
    """(rings, mean obstacleness of the segment) of every refinement at `level`, the last plan
    and the ticks of a run; `_SHARES` gets the share of each one's nodes whose blocks are
    clear."""
    pyramid = Pyramid.build(blocked)
    components = Components.build(blocked, 8, top=3)
    used: list[tuple[int, float]] = []
    refine = planner._Steps.refine

    def recorded(self: Any, limit: float) -> Any:
        # the segment refined is the heap's first (`corridor_search.refine_step`)
        worst = int(self.heap_items[0]) if self.counts[3] else -1
        done, index, lower, rings, *rest = refine(self, limit)
        if done == STEP_REFINED and lower + 1 == level:
            route = self.pool[self.begin_at[worst] : self.end_at[worst]]
            blocks = components.levels[level].block[route]
            values = pyramid.levels[level][blocks[:, 1], blocks[:, 0]]
            used.append((rings, float(values.mean())))
            _SHARES.append(float(np.mean(values == 0.0)))
        return (done, index, lower, rings, *rest)

    monkeypatch.setattr(planner._Steps, "refine", recorded)
    _SHARES.clear()
    ctx = Context()
    plans = list(atp(ctx, start, goal, pyramid, movement=8, components=components, **options))
    monkeypatch.setattr(planner._Steps, "refine", refine)
    return used, plans[-1].value, int(ctx.ticks)


def _near_optimal_on_the_open_map(plan: Any, within: float = 0.01) -> bool:
    """The route followed within `within` of the optimum (its quality at least 1 - within)."""
    dx, dy = abs(GOAL[0] - START[0]), abs(GOAL[1] - START[1])
    optimal = max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)
    return execute(plan, OPEN_MAP, movement=8).length <= optimal / (1 - within)


def test_an_open_map_is_refined_without_rings_at_level_1(monkeypatch: pytest.MonkeyPatch) -> None:
    """On an open map every level-1 segment is free: with the option each is refined through
    its own nodes' cells only, in fewer ticks, the route within 1% of the optimum."""
    used, _, ticks = _run(monkeypatch, 1, OPEN_MAP, START, GOAL)
    bare, plan, bare_ticks = _run(monkeypatch, 1, OPEN_MAP, START, GOAL, no_ring_when_open=0.0)
    assert used and {rings for rings, _ in used} == {1}
    assert bare and {rings for rings, _ in bare} == {0}
    assert bare_ticks < ticks
    assert _near_optimal_on_the_open_map(plan)


def test_an_open_map_is_refined_with_one_ring_at_level_2(monkeypatch: pytest.MonkeyPatch) -> None:
    """On an open map every level-2 segment is free: with the option each is refined with one
    ring of neighbours, in fewer ticks, the route within 1% of the optimum."""
    used, _, ticks = _run(monkeypatch, 2, OPEN_MAP, START, GOAL)
    one, plan, one_ticks = _run(monkeypatch, 2, OPEN_MAP, START, GOAL, one_ring_when_open=0.0)
    assert used and {rings for rings, _ in used} == {3}
    assert one and {rings for rings, _ in one} == {1}
    assert one_ticks <= ticks  # open space: A* keeps to the straight way either way
    assert _near_optimal_on_the_open_map(plan)


@pytest.mark.parametrize("threshold", [0.0, 0.03])
def test_only_segments_as_open_as_the_threshold_lose_their_ring(
    monkeypatch: pytest.MonkeyPatch, threshold: float
) -> None:
    world = random_world(64, seed=3, movement=8)
    used, _, _ = _run(
        monkeypatch, 1, world.blocked, world.start, world.goal, no_ring_when_open=threshold
    )
    assert {rings for rings, _ in used} == {0, 1}  # both kinds on this world
    assert all(rings == (0 if o <= threshold else 1) for rings, o in used)


@pytest.mark.parametrize("threshold", [0.05, 0.1])
def test_only_segments_as_open_as_the_threshold_get_one_ring(
    monkeypatch: pytest.MonkeyPatch, threshold: float
) -> None:
    world = random_world(64, seed=10, movement=8)
    used, _, _ = _run(
        monkeypatch, 2, world.blocked, world.start, world.goal, one_ring_when_open=threshold
    )
    assert {rings for rings, _ in used} == {1, 3}  # both kinds on this world
    assert all(rings == (1 if o <= threshold else 3) for rings, o in used)


def test_with_no_ring_when_open_level_2_is_unchanged(monkeypatch: pytest.MonkeyPatch) -> None:
    """The two options act on different levels: a run with both refines level 2 as with
    one_ring_when_open alone (every level-2 segment is refined before any level-1 one: it
    scores higher)."""
    world = random_world(64, seed=10, movement=8)
    alone, _, _ = _run(
        monkeypatch, 2, world.blocked, world.start, world.goal, one_ring_when_open=0.1
    )
    both, _, _ = _run(
        monkeypatch,
        2,
        world.blocked,
        world.start,
        world.goal,
        one_ring_when_open=0.1,
        no_ring_when_open=0.05,
    )
    assert alone == both


def test_an_open_map_is_refined_without_rings_at_level_2(monkeypatch: pytest.MonkeyPatch) -> None:
    """On an open map every level-2 segment's blocks are clear: with the option each is
    refined through its own nodes' children only, in fewer ticks than with three rings. The
    price: the level-1 route keeps to the 4 x 4 blocks of the level-2 one, a staircase of
    blocks across the diagonal, and is followed within 2% of the optimum (0.9855 here), not
    1%."""
    used, _, ticks = _run(monkeypatch, 2, OPEN_MAP, START, GOAL)
    bare, plan, bare_ticks = _run(monkeypatch, 2, OPEN_MAP, START, GOAL, no_ring_when_clear=0.7)
    assert used and {rings for rings, _ in used} == {3}
    assert bare and {rings for rings, _ in bare} == {0}
    assert bare_ticks < ticks
    assert _near_optimal_on_the_open_map(plan, within=0.02)
    assert not _near_optimal_on_the_open_map(plan)


@pytest.mark.parametrize("threshold", [0.5, 0.7])
def test_only_segments_as_clear_as_the_threshold_lose_their_rings(
    monkeypatch: pytest.MonkeyPatch, threshold: float
) -> None:
    """A level-2 segment loses its rings when at least `threshold` of its nodes' blocks are
    clear, and keeps what the other options give it otherwise (here one_ring_when_open's one
    ring, or three)."""
    world = random_world(64, seed=2, movement=8, density=0.3)
    used, _, _ = _run(
        monkeypatch,
        2,
        world.blocked,
        world.start,
        world.goal,
        segment_moves=1,  # many segments: each kind of refinement on this world
        one_ring_when_open=0.1,
        no_ring_when_clear=threshold,
    )
    shares = list(_SHARES)
    assert {rings for rings, _ in used} == {0, 1, 3}
    for (rings, o), share in zip(used, shares, strict=True):
        assert rings == (0 if share >= threshold else 1 if o <= 0.1 else 3)


@pytest.mark.parametrize(
    "option", ["no_ring_when_open", "one_ring_when_open", "no_ring_when_clear"]
)
def test_a_negative_threshold_is_refused(option: str) -> None:
    world = random_world(16, seed=0, movement=8)
    plans = atp(Context(), world.start, world.goal, Pyramid.build(world.blocked), **{option: -1.0})
    with pytest.raises(ValueError, match=option):
        next(plans)
