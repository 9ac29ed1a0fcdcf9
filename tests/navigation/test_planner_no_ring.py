"""The ATP's `no_ring_when_open` (issue 36): an open level-1 segment refined without a ring."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp
from anytime_navigation.task.execution import execute
from anytime_navigation.world import random_world

from anytime.modules import Context


def _run(
    monkeypatch: pytest.MonkeyPatch, blocked: np.ndarray, start: Any, goal: Any, **options: Any
) -> tuple[list[tuple[int, float]], Any, int]:
    """(rings, mean obstacleness of the segment) of every level-1 refinement, the last plan and
    the ticks of a run."""
    pyramid = Pyramid.build(blocked)
    components = Components.build(blocked, 8, top=3)
    used: list[tuple[int, float]] = []
    refinement = Components.refinement

    def recorded(
        self: Components, level: int, route: Any, rings: int, *rest: Any, **kw: Any
    ) -> Any:
        if level == 1:
            blocks = self.levels[1].block[np.asarray(route)]
            used.append((rings, float(pyramid.levels[1][blocks[:, 1], blocks[:, 0]].mean())))
        return refinement(self, level, route, rings, *rest, **kw)

    monkeypatch.setattr(Components, "refinement", recorded)
    ctx = Context()
    plans = list(atp(ctx, start, goal, pyramid, movement=8, components=components, **options))
    monkeypatch.setattr(Components, "refinement", refinement)
    return used, plans[-1].value, int(ctx.ticks)


def test_an_open_map_is_refined_without_rings_at_level_1(monkeypatch: pytest.MonkeyPatch) -> None:
    """On an open map every level-1 segment is free: with the option each is refined through
    its own nodes' cells only, in fewer ticks, the route within 1% of the optimum."""
    open_map = np.zeros((64, 64), dtype=bool)
    start, goal = (2, 3), (60, 55)
    used, _, ticks = _run(monkeypatch, open_map, start, goal)
    bare, plan, bare_ticks = _run(monkeypatch, open_map, start, goal, no_ring_when_open=0.0)
    assert used and {rings for rings, _ in used} == {1}
    assert bare and {rings for rings, _ in bare} == {0}
    assert bare_ticks < ticks
    dx, dy = abs(goal[0] - start[0]), abs(goal[1] - start[1])
    optimal = max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)
    assert execute(plan, open_map, movement=8).length <= optimal / 0.99


@pytest.mark.parametrize("threshold", [0.0, 0.03])
def test_only_segments_as_open_as_the_threshold_lose_their_ring(
    monkeypatch: pytest.MonkeyPatch, threshold: float
) -> None:
    world = random_world(64, seed=3, movement=8)
    used, _, _ = _run(
        monkeypatch, world.blocked, world.start, world.goal, no_ring_when_open=threshold
    )
    assert {rings for rings, _ in used} == {0, 1}  # both kinds on this world
    assert all(rings == (0 if o <= threshold else 1) for rings, o in used)


def test_a_negative_threshold_is_refused() -> None:
    world = random_world(16, seed=0, movement=8)
    plans = atp(
        Context(), world.start, world.goal, Pyramid.build(world.blocked), no_ring_when_open=-1.0
    )
    with pytest.raises(ValueError, match="no_ring_when_open"):
        next(plans)
