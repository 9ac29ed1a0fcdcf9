"""Landmarks of a level (the ALT heuristic of the first plan's search): their distances are the
level's shortest paths, their bound never overestimates, and a search with them finds a path as
cheap as without while counting no more expansions; on a maze, far fewer."""

from __future__ import annotations

import math

import numpy as np
from anytime_navigation.movingai import load_map
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp
from anytime_navigation.resources import data_file
from anytime_navigation.world import random_world
from grid_moves import draw_free_pair  # tests/navigation/grid_moves.py
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from anytime.modules import Context

maps = st.builds(
    lambda seed, density, side: np.random.default_rng(seed).random((side, side)) < density,
    st.integers(0, 2**31),
    st.floats(0.0, 0.6),
    st.sampled_from([8, 16, 32]),
)


def all_pairs(c: Components, level: int) -> np.ndarray:
    at = c.levels[level]
    n = len(at)
    graph = csr_matrix((at.cost, at.neighbour, at.first), shape=(n, n))
    distances: np.ndarray = shortest_path(graph, method="D")
    return distances


@settings(max_examples=40, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.sampled_from([1, 2, 3]), st.integers(1, 6))
def test_landmark_distances_are_shortest_paths_from_distinct_nodes_of_the_largest_region(
    blocked: np.ndarray, movement: int, level: int, count: int
) -> None:
    c = Components.build(blocked, movement, top=level)
    distances = c.landmarks(level, count).T  # a row per landmark
    n = len(c.levels[level])
    if n == 0:
        assert distances.shape == (0, 0)  # no nodes, no landmarks
        return
    exact = all_pairs(c, level)
    sources = [int(np.flatnonzero(row == 0)[0]) for row in distances]
    for source, row in zip(sources, distances, strict=True):
        np.testing.assert_allclose(row, exact[source], rtol=1e-12)
    region = np.isfinite(distances[0])
    assert len(set(sources)) == len(sources) == min(count, int(region.sum()))
    assert region.sum() == np.max(np.bincount(c.top_regions))  # the largest region's nodes
    assert c.landmarks(level, count) is c.landmarks(level, count)  # made once


@settings(max_examples=60, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.sampled_from([1, 2, 3]), st.data())
def test_a_path_with_landmarks_is_as_cheap_and_expands_no_more(
    blocked: np.ndarray, movement: int, level: int, data: st.DataObject
) -> None:
    c = Components.build(blocked, movement, top=level)
    pair = draw_free_pair(blocked, data)
    if pair is None or not c.connected(*pair):
        return
    source, target = (c.node(p, level) for p in pair)
    plain = c.path(level, source, target)
    count = data.draw(st.integers(1, 8))
    alt = c.path(level, source, target, landmarks=count)
    assert math.isclose(alt.cost, plain.cost, rel_tol=1e-9, abs_tol=1e-9)
    assert alt.nodes[0] == source and alt.nodes[-1] == target
    at = c.levels[level]
    edges = {
        (u, int(v)): float(w)
        for u in range(len(at))
        for v, w in zip(
            at.neighbour[at.first[u] : at.first[u + 1]],
            at.cost[at.first[u] : at.first[u + 1]],
            strict=True,
        )
    }
    steps = zip(alt.nodes, alt.nodes[1:], strict=False)
    assert math.isclose(sum(edges[step] for step in steps), alt.cost, rel_tol=1e-9, abs_tol=1e-9)
    assert alt.expansions <= plain.expansions
    # The bound never overestimates: no landmark says more than the true distance.
    exact = all_pairs(c, level)[:, target]
    distances = c.landmarks(level, count).T  # a row per landmark
    bound = np.abs(distances[:, [target]] - distances)
    finite = np.isfinite(bound)
    assert np.all(bound[finite] <= exact[np.nonzero(finite)[1]] + 1e-9)


def test_on_a_maze_the_first_plans_search_expands_a_fraction() -> None:
    blocked, _, _ = load_map(str(data_file("maps", "maze512-1-0.map")))
    c = Components.build(blocked, 8, top=4)
    rng = np.random.default_rng(0)
    free = np.argwhere(~blocked)
    plain = alt = 0
    for _ in range(8):
        (sy, sx), (gy, gx) = free[rng.choice(len(free), 2, replace=False)]
        source, target = c.node((int(sx), int(sy)), 4), c.node((int(gx), int(gy)), 4)
        one, other = c.path(4, source, target), c.path(4, source, target, landmarks=8)
        assert math.isclose(one.cost, other.cost, rel_tol=1e-9)
        plain, alt = plain + one.expansions, alt + other.expansions
    assert alt < 0.25 * plain


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([4, 8]), st.sampled_from([2, 3]))
def test_atp_with_landmarks_makes_its_first_plan_in_no_more_ticks(
    seed: int, movement: int, top: int
) -> None:
    world = random_world(64, seed=seed, movement=movement)
    pyramid = Pyramid.build(world.blocked)
    ticks = []
    for landmarks in (None, 8):
        ctx = Context()
        plans = atp(
            ctx, world.start, world.goal, pyramid, movement=movement, top=top, landmarks=landmarks
        )
        first = next(plans)
        ticks.append(ctx.elapsed)
        assert first.value.start == world.start and first.value.goal == world.goal
        assert list(plans)  # and it refines on to the end
    assert ticks[1] <= ticks[0]
