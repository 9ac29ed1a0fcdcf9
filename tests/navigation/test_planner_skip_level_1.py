"""The ATP's `skip_level_1` option (issue 36): a level-2 segment is refined straight to the base
cells, through its own nodes' cells, so no segment is ever of level 1."""

from __future__ import annotations

from typing import Any

import pytest
from anytime_navigation.planning import planner
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp
from anytime_navigation.planning.search import STEP_REFINED
from anytime_navigation.task.execution import execute
from anytime_navigation.world import random_world

from anytime.modules import Context


def _run(
    monkeypatch: pytest.MonkeyPatch, seed: int, top: int, **options: Any
) -> tuple[list[tuple[int, int]], list[Any], Any]:
    """(level refined, level made) of every refinement, the plans registered and the world."""
    world = random_world(64, seed=seed, movement=8)
    pyramid = Pyramid.build(world.blocked)
    components = Components.build(world.blocked, 8, top=top)
    steps: list[tuple[int, int]] = []
    refine = planner._Steps.refine

    def recorded(self: Any, limit: float) -> Any:
        worst = int(self.heap_items[0]) if self.counts[3] else -1
        done, index, lower, *rest = refine(self, limit)
        if done == STEP_REFINED:
            steps.append((int(self.level[worst]), lower))
        return (done, index, lower, *rest)

    monkeypatch.setattr(planner._Steps, "refine", recorded)
    plans = list(
        atp(Context(), world.start, world.goal, pyramid, movement=8, components=components,
            top=top, **options)
    )  # fmt: skip
    monkeypatch.setattr(planner._Steps, "refine", refine)
    return steps, [r.value for r in plans], world


@pytest.mark.parametrize("seed", [1, 5, 9])
@pytest.mark.parametrize("top", [2, 3])
def test_level_2_segments_are_refined_straight_to_the_cells(
    monkeypatch: pytest.MonkeyPatch, seed: int, top: int
) -> None:
    """Every segment above level 2 is refined one level down, every one at it straight to level
    0; no segment is ever of level 1; fewer refinements than without; the last plan is all base
    cells (the start's and goal's one-cell segments gone with the levels above) and followed to
    the goal."""
    usual, _, _ = _run(monkeypatch, seed, top)
    steps, plans, world = _run(monkeypatch, seed, top, skip_level_1=True)
    assert {lower for _, lower in usual} == set(range(top))
    assert steps and all(lower == (0 if k == 2 else k - 1) for k, lower in steps)
    assert {k for k, _ in steps} == set(range(2, top + 1))
    assert len(steps) < len(usual)
    for plan in plans:
        assert all(segment.level != 1 for segment in plan.segments)
        assert len(plan.head) == plan.segments[0].level
        assert len(plan.tail) == plan.segments[-1].level
    last = plans[-1]
    assert not last.head and not last.tail and {s.level for s in last.segments} == {0}
    assert execute(last, world.blocked, movement=8, keep_to_plan=True).reached
