"""The connectivity-aware abstraction: every level's nodes are the 4-connected free regions of
its blocks, found one block at a time by brute force; neighbours are exactly the nodes a legal
move joins; a node's children are its cells' nodes one level down and are connected among
themselves; a corridor search at level 0 finds A*'s optimal length."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import load_map
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.search import SearchLimit, find_path
from anytime_navigation.resources import data_file
from grid_moves import draw_free_pair, legal_moves  # tests/navigation/grid_moves.py
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

maps = st.builds(
    lambda seed, density, side: np.random.default_rng(seed).random((side, side)) < density,
    st.integers(0, 2**31),
    st.floats(0.0, 0.6),
    st.sampled_from([8, 16, 32]),
)

#: Maps of any density, 1 x 1 to 32 x 32, for comparing the build with the reference.
any_maps = st.builds(
    lambda seed, density, side: np.random.default_rng(seed).random((side, side)) < density,
    st.integers(0, 2**31),
    st.floats(0.0, 1.0),
    st.sampled_from([1, 2, 4, 8, 16, 32]),
)


@settings(max_examples=40, deadline=None)
@given(maps, st.sampled_from([4, 8]))
def test_nodes_are_the_free_regions_of_each_block_and_neighbours_the_moves_between(
    blocked: np.ndarray, movement: int
) -> None:
    c = Components.build(blocked, movement)
    side = blocked.shape[0]
    moves = legal_moves(blocked, movement)
    for k, level in enumerate(c.levels):
        grid, size = c.grids[k], 1 << k
        # The same partition of each block as labelling the block alone.
        for by in range(side // size):
            for bx in range(side // size):
                window = (slice(by * size, (by + 1) * size), slice(bx * size, (bx + 1) * size))
                alone, count = ndimage.label(~blocked[window])
                ours = grid[window]
                pairs = {(int(a), int(b)) for a, b in zip(alone.ravel(), ours.ravel(), strict=True)}
                assert (
                    len({a for a, _ in pairs if a}) == count == len({b for _, b in pairs if b >= 0})
                )
                assert len(pairs) == count + (1 if (alone == 0).any() else 0)
                assert all(level.block[b].tolist() == [bx, by] for a, b in pairs if a)
        assert np.array_equal(level.size, np.bincount(grid[grid >= 0], minlength=len(level)))
        if k < c.top:  # the parent of a node holds all its cells
            parents = c.levels[k].parent[grid[grid >= 0]]
            assert np.array_equal(parents, c.grids[k + 1][grid >= 0])
        if k == 0:
            continue
        expected = {
            frozenset((int(grid[ay, ax]), int(grid[by_, bx_])))
            for (ax, ay), (bx_, by_) in moves
            if grid[ay, ax] != grid[by_, bx_]
        }
        edges = set()
        for node in range(len(level)):
            tails, heads, costs = level.edges_of(np.array([node]))
            edges |= {frozenset((node, int(h))) for h in heads}
            centre = level.centre
            dx, dy = np.abs(centre[heads] - centre[node]).T
            octile = np.maximum(dx, dy) + (math.sqrt(2) - 1) * np.minimum(dx, dy)
            assert np.allclose(costs, dx + dy if movement == 4 else octile)
        assert edges == expected
        for node in range(len(level)):  # its children, connected among themselves
            children = level.children(node)
            assert sorted(children) == sorted(set(c.grids[k - 1][grid == node].tolist()))
            region = np.isin(c.grids[k - 1], children)
            _, count = ndimage.label(region)
            assert count == 1


@settings(max_examples=40, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.data())
def test_a_corridor_over_every_cell_finds_the_optimal_length(
    blocked: np.ndarray, movement: int, data: st.DataObject
) -> None:
    free = np.argwhere(~blocked)
    if len(free) < 2:
        return
    i, j = data.draw(st.integers(0, len(free) - 1)), data.draw(st.integers(0, len(free) - 1))
    (sy, sx), (gy, gx) = free[i], free[j]
    c = Components.build(blocked, movement, top=0)
    every = np.arange(len(c.levels[0]))
    found = c.corridor(0, every, [c.node((sx, sy), 0)], [c.node((gx, gy), 0)])
    best = find_path(blocked, (sx, sy), (gx, gy), movement=movement, weight=0.0)
    assert (found is None) == (best is None) == (not c.connected((sx, sy), (gx, gy)))
    if found is not None and best is not None:
        assert math.isclose(found.cost, best.length, rel_tol=1e-9, abs_tol=1e-9)
        cells = [c.block(node, 0) for node in found.nodes]
        assert cells[0] == (sx, sy) and cells[-1] == (gx, gy)


def test_a_corridor_search_counts_what_a_star_expands_and_keeps_to_its_limit() -> None:
    blocked = np.zeros((16, 16), dtype=bool)
    blocked[2:14, 8] = True  # a wall between start and goal
    c = Components.build(blocked, 8)
    every = np.arange(len(c.levels[0]))
    start, goal = c.node((2, 8), 0), c.node((14, 8), 0)
    found = c.corridor(0, every, [start], [goal])
    ours = find_path(blocked, (2, 8), (14, 8), movement=8, weight=0.0)
    assert found is not None and ours is not None
    assert math.isclose(found.cost, ours.length)
    # The nodes whose cost plus heuristic is below the path's, and the path's own: about
    # what our A* expands (its tie-breaking differs), far fewer than the corridor holds.
    assert len(found.nodes) - 1 <= found.expansions <= len(every) // 2
    assert abs(found.expansions - ours.expansions) <= 0.25 * ours.expansions
    with pytest.raises(SearchLimit):
        c.corridor(0, every, [start], [goal], limit=found.expansions - 1)
    assert c.corridor(0, every, [start], [goal], limit=found.expansions) == found


@settings(max_examples=40, deadline=None)
@given(any_maps, st.sampled_from([4, 8]), st.data())
def test_the_grids_between_made_when_read_are_the_same_and_so_is_a_pickle(
    blocked: np.ndarray, movement: int, data: st.DataObject
) -> None:
    """The grids between level 0 and the top are made when first read (`components._Grids`):
    a node read before them (through its ancestors) is the one they hold, whether a cell is
    connected to another is what the regions say, and a pickle is the same before and after
    they are read (it holds what they are made from)."""
    import pickle

    top = data.draw(st.integers(0, blocked.shape[0].bit_length() - 1))
    c = Components.build(blocked, movement, top=top)
    before = pickle.dumps(c)
    free = np.argwhere(~blocked)
    cells = [(int(x), int(y)) for y, x in free[:: max(1, len(free) // 8)]]
    nodes = {(cell, k): c.node(cell, k) for cell in cells for k in range(top + 1)}
    assert pickle.dumps(c) == before
    for (cell, k), node in nodes.items():
        assert node == c.grids[k][cell[1], cell[0]]
    for one in cells:
        for other in cells:
            assert c.connected(one, other) == (
                c.regions[one[1], one[0]] == c.regions[other[1], other[0]]
            )
            for k in range(top + 1):  # a problem's reads at once: its nodes when joined
                joined = c.joined(one, other, k)
                assert joined == (
                    (nodes[one, k], nodes[other, k]) if c.connected(one, other) else None
                )
    assert pickle.dumps(c) == before
    copy = pickle.loads(before)
    assert all(np.array_equal(a, b) for a, b in zip(copy.grids, c.grids, strict=True))
    assert np.array_equal(copy.regions, c.regions)


def test_a_block_split_by_a_wall_is_two_nodes() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[:, 3] = True
    c = Components.build(blocked, 4)
    assert len(c.levels[3]) == 2  # the whole map: left of the wall, right of it
    assert not c.connected((0, 0), (7, 7))
    assert c.joined((0, 0), (7, 7), 3) is None


@pytest.mark.parametrize(
    ("start", "goal", "message"),
    [
        ((8, 0), (0, 0), "start (8, 0) is outside the 8x8 map"),
        ((0, 0), (0, -1), "goal (0, -1) is outside the 8x8 map"),
        ((3, 2), (0, 0), "start (3, 2) is a blocked cell"),
        ((0, 0), (3, 7), "goal (3, 7) is a blocked cell"),
    ],
)
def test_a_problem_off_the_map_or_on_a_wall_is_refused(
    start: tuple[int, int], goal: tuple[int, int], message: str
) -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[:, 3] = True
    c = Components.build(blocked, 4)
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        c.joined(start, goal, 2)
    left = c.node((0, 0), 3)
    assert c.region(left, 3)[:, :3].all() and not c.region(left, 3)[:, 3:].any()


def test_it_refuses_a_map_it_cannot_cut_into_blocks() -> None:
    with pytest.raises(ValueError, match=r"square with a power-of-two side, got \(6, 6\)"):
        Components.build(np.zeros((6, 6), dtype=bool))
    with pytest.raises(ValueError, match="movement must be 4 or 8, got 6"):
        Components.build(np.zeros((8, 8), dtype=bool), 6)


def _reference(blocked: np.ndarray, movement: int, top: int) -> dict[str, list[np.ndarray]]:
    """The hierarchy the straightforward way: each level's grid labelled block by block
    (`ndimage.label` on the blocks stacked), nodes numbered as the labelling meets them; the
    edges the pairs of labels a move across a block boundary joins. What `Components.build`
    must equal, to the last bit."""
    free, side = ~blocked, blocked.shape[0]
    ys, xs = np.nonzero(free)
    grids = []
    for k in range(top + 1):
        size, m = 1 << k, side >> k
        stacked = free.reshape(m, size, m, size).transpose(0, 2, 1, 3).reshape(m * m, size, size)
        within = np.zeros((3, 3, 3), dtype=bool)
        within[1] = ndimage.generate_binary_structure(2, 1)
        labels, _ = ndimage.label(stacked, structure=within)
        labels = labels.reshape(m, m, size, size).transpose(0, 2, 1, 3).reshape(side, side)
        grids.append(labels.astype(np.int64) - 1)
    out: dict[str, list[np.ndarray]] = {"grid": grids, "block": [], "centre": [], "size": []}
    for name in ("parent", "first", "neighbour", "cost", "first_child", "child"):
        out[name] = []
    for k, labels in enumerate(grids):
        count = int(labels.max()) + 1 if len(xs) else 0
        ids = labels[ys, xs]
        size = np.bincount(ids, minlength=count)
        out["size"].append(size)
        out["centre"].append(
            np.stack(
                [
                    np.bincount(ids, weights=xs + 0.5, minlength=count) / np.maximum(size, 1),
                    np.bincount(ids, weights=ys + 0.5, minlength=count) / np.maximum(size, 1),
                ],
                axis=1,
            )
        )
        block = np.zeros((count, 2), dtype=np.int64)
        block[ids, 0], block[ids, 1] = xs >> k, ys >> k
        out["block"].append(block)
        parent = np.full(count, -1)
        if k < top:
            parent[ids] = grids[k + 1][ys, xs]
        out["parent"].append(parent)
        child, first_child = np.zeros(0, dtype=np.int64), np.zeros(count + 1, dtype=np.int64)
        if k > 0:
            below = out["parent"][k - 1]
            child = np.argsort(below, kind="stable")
            first_child = np.searchsorted(below[child], np.arange(count + 1))
        out["child"].append(child)
        out["first_child"].append(first_child)
        first, neighbour, cost = _reference_edges(labels, 1 << k, movement, out["centre"][k])
        out["first"].append(first)
        out["neighbour"].append(neighbour)
        out["cost"].append(cost)
    out["regions"] = [ndimage.label(free)[0].astype(np.int64) - 1]
    return out


def _reference_edges(
    labels: np.ndarray, side: int, movement: int, centre: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The level's edges, every pair of labels a legal move across a block boundary joins, as
    compressed rows: a node's higher neighbours, then its lower ones, each ascending."""
    count = len(centre)
    if side == 1:
        return np.zeros(count + 1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    pairs = []
    cut = np.arange(side - 1, labels.shape[0] - 1, side)  # the last row/column of each block
    pairs.append((labels[:, cut], labels[:, cut + 1]))
    pairs.append((labels[cut, :], labels[cut + 1, :]))
    if movement == 8:  # diagonal moves across a boundary, both orthogonal neighbours free
        for rows, cols in ((slice(None), cut), (cut, slice(None))):
            upper = labels[:-1, :-1][rows, cols], labels[:-1, 1:][rows, cols]
            lower = labels[1:, :-1][rows, cols], labels[1:, 1:][rows, cols]
            square = (upper[0] >= 0) & (upper[1] >= 0) & (lower[0] >= 0) & (lower[1] >= 0)
            pairs.append((np.where(square, upper[0], -1), lower[1]))
            pairs.append((np.where(square, upper[1], -1), lower[0]))
    a = np.concatenate([one.ravel() for one, _ in pairs])
    b = np.concatenate([two.ravel() for _, two in pairs])
    keep = (a >= 0) & (b >= 0) & (a != b)
    keys = np.unique(np.minimum(a[keep], b[keep]) * count + np.maximum(a[keep], b[keep]))
    low, high = keys // max(count, 1), keys % max(count, 1)
    dx, dy = np.abs(centre[low] - centre[high]).T
    step = (
        dx + dy if movement == 4 else np.maximum(dx, dy) + (math.sqrt(2) - 1) * np.minimum(dx, dy)
    )
    tails, heads = np.concatenate([low, high]), np.concatenate([high, low])
    order = np.argsort(tails, kind="stable")
    first = np.searchsorted(tails[order], np.arange(count + 1))
    return first, heads[order], np.concatenate([step, step])[order]


def _assert_same_as_reference(blocked: np.ndarray, movement: int, top: int) -> None:
    c = Components.build(blocked, movement, top=top)
    expected = _reference(blocked, movement, top)
    assert len(c.levels) == top + 1
    for name, arrays in expected.items():
        for k, array in enumerate(arrays):
            if name == "grid":
                ours = c.grids[k]
            elif name == "regions":
                ours = c.regions
            else:
                ours = getattr(c.levels[k], name)
            assert ours.shape == np.shape(array), (name, k)
            assert ours.dtype == (np.float64 if name in ("centre", "cost") else np.int64), name
            assert np.array_equal(ours, array), (name, k)  # to the last bit: no tolerance
    assert c.levels[0].grid is c.grids[0]


@settings(max_examples=60, deadline=None)
@given(any_maps, st.sampled_from([4, 8]), st.data())
def test_the_build_equals_the_straightforward_one(
    blocked: np.ndarray, movement: int, data: st.DataObject
) -> None:
    top = data.draw(st.integers(0, blocked.shape[0].bit_length() - 1))
    _assert_same_as_reference(blocked, movement, top)


@pytest.mark.parametrize("name", ["random512-10-0", "8room_000", "maze512-1-0", "arena"])
def test_the_build_equals_the_straightforward_one_on_the_shipped_maps(name: str) -> None:
    blocked = load_map(Path(str(data_file("maps"))) / f"{name}.map")[0]
    for movement in (4, 8):
        _assert_same_as_reference(blocked, movement, 3)


def _edges_cost(c: Components, level: int, nodes: tuple[int, ...]) -> float:
    """The sum of the costs of the level's edges joining consecutive `nodes` (each must be one)."""
    at, total = c.levels[level], 0.0
    for u, v in itertools.pairwise(nodes):
        edges = range(at.first[u], at.first[u + 1])
        (edge,) = [e for e in edges if at.neighbour[e] == v]
        total += float(at.cost[edge])
    return total


@settings(max_examples=40, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.sampled_from([1, 2, 3]), st.data())
def test_a_path_over_a_level_is_the_corridor_over_every_node(
    blocked: np.ndarray, movement: int, top: int, data: st.DataObject
) -> None:
    c = Components.build(blocked, movement, top=top)
    rows = [a.copy() for a in (c.levels[top].first, c.levels[top].neighbour, c.levels[top].cost)]
    pair = draw_free_pair(blocked, data)
    if pair is None or not c.connected(*pair):
        return
    (sx, sy), (gx, gy) = pair
    landmarks = data.draw(st.sampled_from([0, 2]))
    for level in range(1, top + 1):  # the top's graph made with the hierarchy, the others now
        source, target = c.node((sx, sy), level), c.node((gx, gy), level)
        every = np.arange(len(c.levels[level]))
        reference = c.corridor(level, every, [source], [target], landmarks=landmarks)
        assert reference is not None
        for _ in range(2):  # its scratch, kept between searches, holds nothing of the last one
            found = c.path(level, source, target, landmarks=landmarks)
            if landmarks:  # ties go to the deeper node: a path as cheap, as much work but its own
                assert found.cost == pytest.approx(reference.cost, rel=1e-9, abs=1e-12)
                assert found.nodes[0] == source and found.nodes[-1] == target
                assert _edges_cost(c, level, found.nodes) == pytest.approx(found.cost, abs=1e-9)
                tied = len(found.nodes) + len(reference.nodes)  # the paths' own nodes
                assert abs(found.expansions - reference.expansions) <= tied
            else:  # the same search (`corridor_search.level_search`): path, cost and work
                assert (found.nodes, found.cost) == (reference.nodes, reference.cost)
                assert found.expansions == reference.expansions
            c.path(level, target, source, landmarks=landmarks)
        if found.expansions:
            with pytest.raises(SearchLimit):
                c.path(level, source, target, limit=found.expansions - 1, landmarks=landmarks)
    # The level's rows are as they were (its graph is a sorted copy).
    after = (c.levels[top].first, c.levels[top].neighbour, c.levels[top].cost)
    assert all(np.array_equal(a, b) for a, b in zip(rows, after, strict=True))


@pytest.mark.parametrize(
    ("count", "width", "line"), [(0, 8, 64), (2, 16, 128), (8, 16, 128), (9, 24, 128)]
)
def test_a_level_search_table_holds_each_node_in_whole_aligned_cache_lines(
    count: int, width: int, line: int
) -> None:
    """`corridor_search.level_table`: a row per node and one for the search's number, each
    row whole cache lines of 8 floats aligned on them (two adjacent ones with landmarks), the
    node's centre and landmark distances in their columns, nothing reached."""
    from anytime_navigation.planning import corridor_search as cs

    rng = np.random.default_rng(count)
    centre, distances = rng.random((5, 2)), rng.random((5, count))
    table = cs.level_table(centre, distances)
    assert table.shape == (6, width)
    assert table.ctypes.data % line == 0 and table.strides == (8 * width, 8)
    assert np.array_equal(table[:5, cs.ROW_X : cs.ROW_Y + 1], centre)
    assert np.array_equal(table[:5, cs.ROW_LANDMARKS : cs.ROW_LANDMARKS + count], distances)
    searched = [cs.ROW_REACHED, cs.ROW_SETTLED, cs.ROW_DISTANCE, cs.ROW_ESTIMATE, cs.ROW_PREVIOUS]
    assert not table[:, searched].any() and not table[5].any()


@settings(max_examples=40, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.sampled_from([1, 2, 3]), st.integers(0, 3), st.data())
def test_a_widened_corridor_is_the_children_of_the_nodes_a_few_edges_from_the_route(
    blocked: np.ndarray, movement: int, level: int, rings: int, data: st.DataObject
) -> None:
    c = Components.build(blocked, movement, top=level)
    count = len(c.levels[level])
    if count == 0:
        return
    route = data.draw(st.lists(st.integers(0, count - 1), min_size=1, max_size=6))
    # The reference: rings of neighbours by the level's edges, then each node's children.
    reached = set(route)
    for _ in range(rings):
        tails = np.array(sorted(reached), dtype=np.int64)
        reached |= set(c.levels[level].edges_of(tails)[1].tolist())
    expected = [int(x) for node in sorted(reached) for x in c.levels[level].children(node)]
    assert c.widened(level, route, rings).tolist() == expected
    assert (c._scratch[level] == -1).all()  # left as found, for the next search


@settings(max_examples=40, deadline=None)
@given(maps, st.sampled_from([4, 8]), st.sampled_from([1, 2, 3]), st.integers(0, 3), st.data())
def test_a_refinement_in_one_call_is_its_steps_one_by_one(
    blocked: np.ndarray, movement: int, level: int, rings: int, data: st.DataObject
) -> None:
    """`Components.refinement` (one compiled call) finds what `widened` then `corridor` find,
    with ends fixed or flexible (any child, each at its extra distance from a point)."""
    c = Components.build(blocked, movement, top=level)
    pair = draw_free_pair(blocked, data)
    if pair is None or not c.connected(*pair):
        return
    start, goal = pair
    route = c.path(level, c.node(start, level), c.node(goal, level)).nodes
    lower = level - 1
    ends = []
    for position, node in ((start, route[0]), (goal, route[-1])):
        if data.draw(st.booleans()):
            ends.append(((c.node(position, lower), -1, 0.0, 0.0), [c.node(position, lower)], None))
        else:
            x, y = data.draw(st.floats(0, 64)), data.draw(st.floats(0, 64))
            children = c.levels[level].children(node)
            centres = c.levels[lower].centre[children]
            d = np.hypot(centres[:, 0] - x, centres[:, 1] - y)
            ends.append(((-1, node, x, y), children, (d - d.min()).tolist()))
    (source, sources, source_costs), (target, targets, target_costs) = ends
    allowed = c.widened(level, route, rings)
    reference = c.corridor(
        lower, allowed, sources, targets, source_costs=source_costs, target_costs=target_costs
    )
    assert reference is not None  # the children of a path hold a path
    path, cost, expansions = c.refinement(level, route, rings, source, target)
    assert (tuple(path.tolist()), cost, expansions) == (
        reference.nodes,
        reference.cost,
        reference.expansions,
    )
    if expansions:
        with pytest.raises(SearchLimit):
            c.refinement(level, route, rings, source, target, limit=expansions - 1)
    assert all((scratch == -1).all() for scratch in c._scratch)  # left as found


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 50), st.integers(1, 60), st.integers(0, 300))
def test_the_counting_sorts_are_numpys_sorts(seed: int, count: int, below: int, n: int) -> None:
    """The build's edges ordered in counting passes (`corridor_search.counting_order`,
    `lifted_pairs`) as numpy's sorts ordered them: the lifted edges are the pairs of different
    parents, lesser first, once each, ascending."""
    from anytime_navigation.planning.search import compiled

    rng = np.random.default_rng(seed)
    low, high = rng.integers(0, count, n), rng.integers(0, count, n)
    order = compiled().counting_order(high, count)
    assert np.array_equal(order, np.argsort(high, kind="stable"))
    # edges of `below` nodes, each node's parent one of `count`; some buckets long (> 32)
    low, high = rng.integers(0, below, n), rng.integers(0, below, n)
    parent = rng.integers(0, count, below)
    a, b = parent[low], parent[high]
    between = a != b
    bits = count.bit_length()
    keys = np.unique(np.minimum(a, b)[between] << bits | np.maximum(a, b)[between])
    lifted_low, lifted_high = compiled().lifted_pairs(low, high, parent, count)
    assert np.array_equal(lifted_low, keys >> bits)
    assert np.array_equal(lifted_high, keys & ((1 << bits) - 1))
