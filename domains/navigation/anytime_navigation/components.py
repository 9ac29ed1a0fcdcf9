"""The connectivity-aware abstraction: one abstract node per connected free component of each
block (issue 17).

Level k cuts the base grid into the 2^k x 2^k blocks of the pyramid (`abstraction`); a level-k
*node* is a connected component of one block's free cells, connected by the legal moves that
stay inside the block (4-connected, or octile without corner cutting, as the robot moves).
Level 0's nodes are the free cells. Two nodes of a level are *neighbours* when a legal move
joins a cell of one to a cell of the other, and a node's *parent* is the node one level up that
contains it.

Why. Obstacleness, the blocked fraction of a block, cannot see connectivity: a block split by a
one-cell wall looks passable, so coarse routes run through walls (rooms), every maze block is
split (mazes), and building clusters look free (streets). A node is a region the robot can
cross, so a path of neighbouring nodes is a route the robot can follow at that grain.

What the planner relies on. A node's children are connected among themselves (it is one
component), and a legal move joining two neighbours joins a child of each: so the children of a
path of neighbouring nodes are connected, and a search one level lower restricted to them always
finds a path. Refinement never needs a widened corridor.

Costs. A level's edges join the centres (mean positions) of the nodes' cells, each costing the
distance between them as the robot moves (Manhattan for 4-connected moves, octile for
8-connected ones; at level 0 that is the move's length, 1 or sqrt 2). The whole
hierarchy is built with vectorised label propagation (scipy's connected components per level),
once per map: O(N^2 log N) for an N x N map.

Arrays are indexed [y, x]; positions are (x, y).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from attrs import frozen
from numpy.typing import NDArray
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from .search import SearchLimit
from .world import BoolGrid, Position, is_power_of_two

__all__ = ["Components", "Level", "NodePath"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@frozen(eq=False)
class Level:
    """The nodes of one level: `block[i]` (x, y) is node i's block, `centre[i]` the mean base
    position (x + 0.5, y + 0.5) of its cells, `size[i]` how many cells it has, `parent[i]` its
    node one level up (-1 at the top). Above level 0 its neighbours are
    `neighbour[first[i]:first[i + 1]]`, each edge costing `cost[...]` likewise; level 0's are
    the legal moves from the cell (`grid`, the level-0 node of each base cell, -1 where
    blocked). Its children (nodes one level down) are `child[first_child[i]:first_child[i +
    1]]` (none at level 0)."""

    k: int
    block: IntArray
    centre: FloatArray
    size: IntArray
    parent: IntArray
    first: IntArray
    neighbour: IntArray
    cost: FloatArray
    first_child: IntArray
    child: IntArray
    movement: int
    grid: IntArray | None = None

    def __len__(self) -> int:
        return len(self.size)

    def children(self, node: int) -> list[int]:
        found: list[int] = self.child[self.first_child[node] : self.first_child[node + 1]].tolist()
        return found

    def children_of(self, nodes: Sequence[int]) -> IntArray:
        """The children of all of `nodes`, as one array."""
        parts = [self.child[self.first_child[n] : self.first_child[n + 1]] for n in nodes]
        return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)

    def edges_of(self, nodes: IntArray) -> tuple[IntArray, IntArray, FloatArray]:
        """Every edge leaving `nodes`: (tail, head, cost) arrays, tails among `nodes`."""
        if self.grid is None:
            counts = self.first[nodes + 1] - self.first[nodes]
            starts = np.repeat(self.first[nodes] - np.cumsum(counts) + counts, counts)
            index = starts + np.arange(int(counts.sum()))
            return np.repeat(nodes, counts), self.neighbour[index], self.cost[index]
        grid, side = self.grid, self.grid.shape[0]
        x, y = self.block[nodes, 0], self.block[nodes, 1]
        tails, heads, costs = [], [], []
        moves = _STRAIGHT_MOVES + (_DIAGONAL_MOVES if self.movement == 8 else ())
        for dx, dy, step in moves:
            nx, ny = x + dx, y + dy
            inside = (nx >= 0) & (nx < side) & (ny >= 0) & (ny < side)
            cx, cy = np.clip(nx, 0, side - 1), np.clip(ny, 0, side - 1)
            head = np.where(inside, grid[cy, cx], -1)
            ok = head >= 0
            if dx and dy:  # no corner cutting: both orthogonal neighbours free
                ok &= (grid[y, cx] >= 0) & (grid[cy, x] >= 0)
            tails.append(nodes[ok])
            heads.append(head[ok])
            costs.append(np.full(int(ok.sum()), step))
        return np.concatenate(tails), np.concatenate(heads), np.concatenate(costs)


_SQRT2 = math.sqrt(2.0)
_STRAIGHT_MOVES = ((1, 0, 1.0), (-1, 0, 1.0), (0, 1, 1.0), (0, -1, 1.0))
_DIAGONAL_MOVES = ((1, 1, _SQRT2), (-1, 1, _SQRT2), (1, -1, _SQRT2), (-1, -1, _SQRT2))


@frozen
class NodePath:
    """A path found by `Components.corridor`: `nodes` at `level`, start to end; its `cost` (the
    sum of its edges' costs, and the costs of its ends) and the nodes an A* search for it
    expands."""

    level: int
    nodes: tuple[int, ...]
    cost: float
    expansions: int


@frozen(eq=False)
class Components:
    """The hierarchy of a square power-of-two map: `levels[k]` for k = 0 .. top, and
    `grids[k]`, the level-k node of each base cell (-1 where blocked). Build it with
    `Components.build`."""

    levels: tuple[Level, ...]
    grids: tuple[IntArray, ...]
    movement: int
    regions: IntArray  # the connected free region of each base cell (-1 where blocked)

    @property
    def cell(self) -> IntArray:
        """The level-0 node of each base cell (-1 where blocked)."""
        return self.grids[0]

    @classmethod
    def build(cls, blocked: BoolGrid, movement: int = 4, top: int | None = None) -> Components:
        """The hierarchy of `blocked` (square, power-of-two side) up to level `top` (default
        log2(N): one block).

        A block's components are its 4-connected free regions (octile moves without corner
        cutting connect the same cells), labelled for every block of a level at once
        (`scipy.ndimage.label` on the blocks stacked, never connected across). A node's
        neighbours are found where a legal move crosses a block boundary."""
        grid = np.asarray(blocked, dtype=bool)
        if grid.ndim != 2 or grid.shape[0] != grid.shape[1] or not is_power_of_two(grid.shape[0]):
            raise ValueError(f"the grid must be square with a power-of-two side, got {grid.shape}")
        if movement not in (4, 8):
            raise ValueError(f"movement must be 4 or 8, got {movement!r}")
        highest = grid.shape[0].bit_length() - 1
        top = highest if top is None else top
        if not 0 <= top <= highest:
            raise ValueError(f"top must be in [0, {highest}], got {top}")
        free = ~grid
        ys, xs = np.nonzero(free)
        grids = [_block_labels(free, 1 << k) for k in range(top + 1)]
        levels: list[Level] = []
        for k, labels in enumerate(grids):
            count = int(labels.max()) + 1 if len(xs) else 0
            ids = labels[ys, xs]
            size = np.bincount(ids, minlength=count)
            centre = np.stack(
                [
                    np.bincount(ids, weights=xs + 0.5, minlength=count) / np.maximum(size, 1),
                    np.bincount(ids, weights=ys + 0.5, minlength=count) / np.maximum(size, 1),
                ],
                axis=1,
            )
            block = np.zeros((count, 2), dtype=np.int64)
            block[ids, 0], block[ids, 1] = xs >> k, ys >> k
            parent = np.full(count, -1, dtype=np.int64)
            if k < top:
                parent[ids] = grids[k + 1][ys, xs]
            first_child = np.zeros(count + 1, dtype=np.int64)
            child = np.zeros(0, dtype=np.int64)
            if k > 0:
                below = levels[-1].parent
                child = np.argsort(below, kind="stable").astype(np.int64)
                first_child = np.searchsorted(below[child], np.arange(count + 1)).astype(np.int64)
            if k == 0:
                first, neighbour = np.zeros(count + 1, dtype=np.int64), np.zeros(0, dtype=np.int64)
                cost = np.zeros(0, dtype=np.float64)
            else:
                first, neighbour, cost = _adjacency(labels, 1 << k, movement, centre, count)
            levels.append(
                Level(
                    k,
                    block,
                    centre,
                    size.astype(np.int64),
                    parent,
                    first,
                    neighbour,
                    cost,
                    first_child,
                    child,
                    movement,
                    labels if k == 0 else None,
                )
            )
        regions, _ = ndimage.label(free)  # 4-connected: octile moves join the same cells
        return cls(tuple(levels), tuple(grids), movement, regions.astype(np.int64) - 1)

    @property
    def top(self) -> int:
        return len(self.levels) - 1

    def node(self, position: Position, level: int) -> int:
        """The level-`level` node of a base cell (-1 when the cell is blocked)."""
        x, y = position
        return int(self.grids[level][y, x])

    def ancestor(self, node: int, level: int, to_level: int) -> int:
        """The node at `to_level` >= `level` that contains `node` of `level`."""
        for k in range(level, to_level):
            node = int(self.levels[k].parent[node])
        return node

    def block(self, node: int, level: int) -> Position:
        x, y = self.levels[level].block[node]
        return (int(x), int(y))

    def connected(self, one: Position, other: Position) -> bool:
        """Whether a route joins two free base cells."""
        (ax, ay), (bx, by) = one, other
        return bool(self.regions[ay, ax] >= 0 and self.regions[ay, ax] == self.regions[by, bx])

    def region(self, node: int, level: int) -> BoolGrid:
        """Which cells of the node's block belong to it, a (2^level, 2^level) mask [y, x]."""
        side = 1 << level
        bx, by = self.block(node, level)
        window = self.grids[level][by * side : (by + 1) * side, bx * side : (bx + 1) * side]
        return np.asarray(window == node)

    def corridor(
        self,
        level: int,
        allowed: IntArray,
        sources: Sequence[int],
        targets: Sequence[int],
        *,
        source_costs: Sequence[float] | None = None,
        target_costs: Sequence[float] | None = None,
        limit: float = math.inf,
    ) -> NodePath | None:
        """A cheapest path of neighbouring nodes at `level` from any of `sources` to any of
        `targets` through the `allowed` nodes (sources and targets among them), with the extra
        costs of starting and ending at each; None when no target can be reached.

        Dijkstra's algorithm over the corridor, in C (`scipy.sparse.csgraph`). Its work is
        counted as the nodes an A* search for the same path expands, those whose cost from a
        source plus the heuristic (the distance to the nearest target, consistent with the
        edges' costs) is below the path's cost: a measure of the search, not of how it is
        computed.

        Raises:
            SearchLimit: that work is more than `limit`.
        """
        nodes = np.unique(np.asarray(allowed, dtype=np.int64))
        n = len(nodes)
        tails, heads, costs = self.levels[level].edges_of(nodes)
        local = np.searchsorted(nodes, heads)
        ok = (local < n) & (nodes[np.minimum(local, n - 1)] == heads)
        tails, local, costs = np.searchsorted(nodes, tails[ok]), local[ok], costs[ok]
        start, finish = n, n + 1  # a source before every source, a target after every target
        s_local = np.searchsorted(nodes, np.asarray(sources, dtype=np.int64))
        t_local = np.searchsorted(nodes, np.asarray(targets, dtype=np.int64))
        s_costs = np.zeros(len(s_local)) if source_costs is None else np.asarray(source_costs)
        t_costs = np.zeros(len(t_local)) if target_costs is None else np.asarray(target_costs)
        rows = np.concatenate([tails, np.full(len(s_local), start), t_local])
        cols = np.concatenate([local, s_local, np.full(len(t_local), finish)])
        # Explicit zeros are no edges to csgraph: the free ends cost a hair.
        weights = np.concatenate([costs, s_costs + 1e-12, t_costs + 1e-12])
        graph = csr_matrix((weights, (rows, cols)), shape=(n + 2, n + 2))
        distance, previous = dijkstra(graph, indices=start, return_predecessors=True)
        best = float(distance[finish])
        estimate = distance[:n] + self._heuristic(level, nodes, nodes[t_local])
        expanded = (
            estimate < best - 1e-9 * max(1.0, best) if np.isfinite(best) else estimate < np.inf
        )
        path = []
        if np.isfinite(best):
            at = int(previous[finish])
            while at != start:
                path.append(at)
                at = int(previous[at])
            expanded[path[1:]] = True  # A* pops the path's nodes too; the target ends it
        expansions = int(np.count_nonzero(expanded))
        if expansions > limit:
            raise SearchLimit(int(limit))
        if not path:
            return None
        nodes_path = tuple(int(nodes[i]) for i in reversed(path))
        return NodePath(level, nodes_path, best, expansions)

    def _heuristic(self, level: int, nodes: IntArray, targets: IntArray) -> FloatArray:
        """The distance from each of `nodes` to the nearest of `targets` (centre to centre):
        Manhattan or octile at level 0, as the moves go, Euclidean above."""
        centre = self.levels[level].centre
        offsets = centre[nodes][:, None, :] - centre[targets][None, :, :]
        return np.asarray(_distance(offsets, self.movement).min(axis=1))


def _distance(offset: FloatArray, movement: int) -> FloatArray:
    """The length of the shortest move sequence across `offset` (..., 2) on an open grid:
    Manhattan for 4-connected moves, octile for 8-connected ones (a metric: the heuristic it
    gives is consistent with edges that cost it)."""
    dx, dy = np.abs(offset[..., 0]), np.abs(offset[..., 1])
    if movement == 4:
        return np.asarray(dx + dy)
    return np.asarray(np.maximum(dx, dy) + (math.sqrt(2.0) - 1.0) * np.minimum(dx, dy))


def _block_labels(free: BoolGrid, side: int) -> IntArray:
    """The 4-connected component of each free cell within its `side` x `side` block, numbered
    from 0 block by block (-1 where blocked)."""
    n = free.shape[0]
    m = n // side
    stacked = free.reshape(m, side, m, side).transpose(0, 2, 1, 3).reshape(m * m, side, side)
    within = np.zeros((3, 3, 3), dtype=bool)  # 4-connected inside one block, never across
    within[1] = ndimage.generate_binary_structure(2, 1)
    labels, _ = ndimage.label(stacked, structure=within)
    labels = labels.reshape(m, m, side, side).transpose(0, 2, 1, 3).reshape(n, n)
    return np.asarray(labels, dtype=np.int64) - 1


def _adjacency(
    labels: IntArray, side: int, movement: int, centre: FloatArray, count: int
) -> tuple[IntArray, IntArray, FloatArray]:
    """The level's edges as compressed rows (first, neighbour, cost): the pairs of nodes a legal
    move across a block boundary joins, once each, costing the distance between centres."""
    pairs = []
    cut = np.arange(side - 1, labels.shape[0] - 1, side)  # the last row/column of each block
    pairs.append((labels[:, cut], labels[:, cut + 1]))  # across a vertical boundary
    pairs.append((labels[cut, :], labels[cut + 1, :]))  # across a horizontal boundary
    if movement == 8:  # diagonal moves across a boundary, both orthogonal neighbours free
        for rows, cols in ((slice(None), cut), (cut, slice(None))):
            top = labels[:-1, :-1][rows, cols], labels[:-1, 1:][rows, cols]
            bottom = labels[1:, :-1][rows, cols], labels[1:, 1:][rows, cols]
            square = (top[0] >= 0) & (top[1] >= 0) & (bottom[0] >= 0) & (bottom[1] >= 0)
            pairs.append((np.where(square, top[0], -1), bottom[1]))
            pairs.append((np.where(square, top[1], -1), bottom[0]))
    a = np.concatenate([one.ravel() for one, _ in pairs])
    b = np.concatenate([two.ravel() for _, two in pairs])
    keep = (a >= 0) & (b >= 0) & (a != b)
    low, high = np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])
    keys = np.sort(low * max(count, 1) + high)
    keys = keys[np.concatenate(([True], keys[1:] != keys[:-1]))] if len(keys) else keys
    a, b = keys // max(count, 1), keys % max(count, 1)
    step = _distance(centre[a] - centre[b], movement)
    tails, heads = np.concatenate([a, b]), np.concatenate([b, a])
    order = np.argsort(tails, kind="stable")
    first = np.searchsorted(tails[order], np.arange(count + 1)).astype(np.int64)
    return first, heads[order].astype(np.int64), np.concatenate([step, step])[order]
