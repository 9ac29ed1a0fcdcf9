"""The ATP's `direct_width` (issue 36): a narrow corridor searched at once after the first plan."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import Scenario, load_problems
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp
from anytime_navigation.resources import data_file
from anytime_navigation.task.execution import execute

from anytime.modules import Context, Result


def _longest(name: str) -> tuple[np.ndarray, Scenario, Pyramid, Components]:
    """A shipped map's longest problem, its pyramid and its abstraction up to level 4."""
    blocked, _, _, scenarios = load_problems(Path(str(data_file("maps"))) / f"{name}.map")
    problem = max(scenarios, key=lambda s: s.optimal)
    return blocked, problem, Pyramid.build(blocked), Components.build(blocked, 8, top=4)


def _plans(
    ctx: Context, problem: Scenario, pyramid: Pyramid, components: Components, width: float | None
) -> Iterator[Result]:
    return atp(
        ctx,
        problem.start,
        problem.goal,
        pyramid,
        movement=8,
        components=components,
        top=4,
        direct_width=width,
    )


def test_a_maze_is_searched_at_once_after_the_first_plan() -> None:
    """On a maze of corridors one cell wide (about 4 cells of corridor per unit of length),
    `direct_width=12` registers the first plan, then one base route through the first plan's
    nodes and their neighbours: optimal here, in fewer ticks than refining level by level."""
    blocked, problem, pyramid, components = _longest("maze512-1-0")
    default, ctx = Context(), Context()
    refined = list(_plans(default, problem, pyramid, components, None))
    results = list(_plans(ctx, problem, pyramid, components, 12))
    assert len(results) == 2 < len(refined)
    assert results[0].value == refined[0].value  # the same first plan
    final = results[1]
    assert final.quality == 1.0 and not final.value.refinable
    route = final.value.base_route()
    assert route is not None and (route[0], route[-1]) == (problem.start, problem.goal)
    length = execute(final.value, blocked, movement=8).length
    assert length == pytest.approx(problem.optimal, rel=1e-5)
    assert ctx.ticks < default.ticks


def test_a_wide_corridor_is_refined_as_without_it() -> None:
    """Rooms (about 30 cells of corridor per unit of length): planned as without the option."""
    _, problem, pyramid, components = _longest("8room_000")
    default, ctx = Context(), Context()
    without = [r.value for r in _plans(default, problem, pyramid, components, None)]
    with_it = [r.value for r in _plans(ctx, problem, pyramid, components, 12)]
    assert with_it == without and ctx.ticks == default.ticks


def test_direct_width_never_works_past_the_deadline() -> None:
    _, problem, pyramid, components = _longest("maze512-1-0")
    full, first = Context(), Context()
    list(_plans(full, problem, pyramid, components, 12))
    next(_plans(first, problem, pyramid, components, 12))
    allocation = (first.ticks + full.ticks) / 2  # the first plan, not the direct search
    ctx = Context(allocation=allocation)
    results = list(_plans(ctx, problem, pyramid, components, 12))
    assert len(results) == 1 and results[0].value.refinable
    assert ctx.elapsed <= allocation
