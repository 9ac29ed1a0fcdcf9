"""The ATP's refinement step in compiled code (issue 36 item 2, `corridor_search.refine_step`):
the means it keeps are numpy's to the last bit, the estimate it keeps is `quality_estimate`'s,
and the arrays it reads (the abstraction's and the pyramid's levels, stacked) are the levels'
own, also for a pyramid whose levels are apart (unpickled)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp, quality_estimate
from anytime_navigation.planning.search import compiled
from anytime_navigation.world import random_world

from anytime.modules import Context


@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_sum_is_numpys_to_the_last_bit(seed: int) -> None:
    """The halves' mean obstacleness is made in compiled code as `np.add.reduce` makes it in
    Python (pairwise, by blocks of 128 in eight lanes): the same plans and estimates."""
    rng = np.random.default_rng(seed)
    lengths = [*range(1, 300), 1000, 1023, 4097, 20000]
    for n in lengths:
        values = rng.random(n + 10) * rng.choice([1e-3, 1.0, 1e3])
        lo = int(rng.integers(0, 10))
        expected = float(np.add.reduce(values[lo : lo + n]))
        assert compiled().pairwise_sum(values, lo, n) == expected, n


@pytest.mark.parametrize("movement", [4, 8])
@pytest.mark.parametrize("options", [{}, {"segment_moves": 8}, {"top": 4}])
def test_the_estimate_registered_is_the_plans_quality_estimate(
    movement: int, options: dict[str, int]
) -> None:
    """The step keeps the estimate's sums up to date instead of recomputing them: each plan's
    estimate is `quality_estimate` of it, up to rounding."""
    world = random_world(128, seed=5, movement=movement)
    pyramid = Pyramid.build(world.blocked)
    results = list(atp(Context(), world.start, world.goal, pyramid, movement=movement, **options))
    assert len(results) > 5
    for result in results:
        assert result.quality == pytest.approx(quality_estimate(result.value, pyramid), abs=1e-9)


def test_the_stacked_arrays_are_the_levels() -> None:
    """Levels 2 and up of the abstraction, and every level of the pyramid, read as slices of
    their concatenations are the levels' own arrays."""
    world = random_world(128, seed=1, movement=8)
    components = Components.build(world.blocked, 8, top=5)
    stacked = components.stacked()
    assert components.stacked() is stacked  # made once
    for k in range(2, components.top + 1):
        level = components.levels[k]
        nodes = slice(stacked.node_at[k], stacked.node_at[k + 1])
        rows = slice(stacked.first_at[k], stacked.first_at[k + 1])
        edges = slice(stacked.edge_at[k], stacked.edge_at[k + 1])
        children = slice(stacked.child_at[k], stacked.child_at[k + 1])
        assert np.array_equal(stacked.parent[nodes], level.parent)
        assert np.array_equal(stacked.block[nodes], level.block)
        assert np.array_equal(stacked.centre[nodes], level.centre)
        assert np.all(stacked.scratch[nodes] == -1)
        assert np.array_equal(stacked.first[rows], level.first)
        assert np.array_equal(stacked.first_child[rows], level.first_child)
        assert np.array_equal(stacked.neighbour[edges], level.neighbour)
        assert np.array_equal(stacked.cost[edges], level.cost)
        assert np.array_equal(stacked.child[children], level.child)
    pyramid = Pyramid.build(world.blocked)
    made = pyramid.stacked()
    assert made is not None
    values, at, side = made
    for n, level in enumerate(pyramid.levels):
        assert side[n] == level.shape[1]
        assert np.array_equal(values[at[n] : at[n + 1]].reshape(level.shape), level)


def test_a_pyramid_with_its_levels_apart_plans_the_same() -> None:
    """An unpickled pyramid's levels are arrays apart (no stack to read): the planner stacks
    them itself, and registers the same plans with the same estimates and ticks."""
    world = random_world(128, seed=2, movement=8)
    pyramid = Pyramid.build(world.blocked)
    unpickled = pickle.loads(pickle.dumps(pyramid))
    assert unpickled == pyramid and unpickled.stacked() is None
    runs = []
    for planned_on in (pyramid, unpickled):
        ctx = Context()
        results = list(atp(ctx, world.start, world.goal, planned_on, movement=8))
        runs.append(([(r.quality, r.value.parts) for r in results], ctx.ticks))
    assert runs[0] == runs[1]


def test_the_arrays_kept_for_the_last_map_go_with_it() -> None:
    """The step's arrays are kept for the last map planned on (`planner._map_reads`), and let
    go when its abstraction or pyramid is."""
    import gc

    from anytime_navigation.planning import planner

    world = random_world(64, seed=0, movement=8)
    pyramid = Pyramid.build(world.blocked)
    components = Components.build(world.blocked, 8, top=3)
    for _ in range(2):  # the second plan on the map reads what the first made
        list(atp(Context(), world.start, world.goal, pyramid, movement=8, components=components))
        assert planner._last_map is not None
        assert planner._last_map[0]() is components and planner._last_map[1]() is pyramid
    del pyramid
    gc.collect()
    assert planner._last_map is None
