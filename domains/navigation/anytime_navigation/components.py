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
distance between them (Euclidean; at level 0 that is the move's length, 1 or sqrt 2). The whole
hierarchy is built with vectorised label propagation (scipy's connected components per level),
once per map: O(N^2 log N) for an N x N map.

Arrays are indexed [y, x]; positions are (x, y).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable, Sequence

import numpy as np
from attrs import frozen
from numpy.typing import NDArray
from scipy import ndimage

from .world import BoolGrid, Position, is_power_of_two

__all__ = ["Components", "Level", "NodePath"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@frozen(eq=False, slots=False)
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

    def __attrs_post_init__(self) -> None:
        # The search reads these one node at a time: Python lists are several times faster
        # to index than numpy arrays.
        object.__setattr__(self, "_bx", self.block[:, 0].tolist())
        object.__setattr__(self, "_by", self.block[:, 1].tolist())
        object.__setattr__(self, "_x", self.centre[:, 0].tolist())
        object.__setattr__(self, "_y", self.centre[:, 1].tolist())
        if self.grid is None:
            object.__setattr__(self, "_first", self.first.tolist())
            object.__setattr__(self, "_neighbour", self.neighbour.tolist())
            object.__setattr__(self, "_cost", self.cost.tolist())
        else:
            object.__setattr__(self, "_ids", self.grid.ravel().tolist())
            object.__setattr__(self, "_side", int(self.grid.shape[0]))

    def __len__(self) -> int:
        return len(self.size)

    def neighbours(self, node: int) -> tuple[list[int], list[float]]:
        """The node's neighbours and the cost of the edge to each."""
        if self.grid is not None:
            return self._moves(node)
        first: list[int] = self._first  # type: ignore[attr-defined]
        a, b = first[node], first[node + 1]
        return self._neighbour[a:b], self._cost[a:b]  # type: ignore[attr-defined]

    def _moves(self, node: int) -> tuple[list[int], list[float]]:
        """Level 0: the legal moves from a cell (no corner cutting)."""
        ids: list[int] = self._ids  # type: ignore[attr-defined]
        side: int = self._side  # type: ignore[attr-defined]
        x, y = int(self._x[node]), int(self._y[node])  # type: ignore[attr-defined]
        row = y * side
        left = ids[row + x - 1] if x > 0 else -1
        right = ids[row + x + 1] if x + 1 < side else -1
        up = ids[row - side + x] if y > 0 else -1
        down = ids[row + side + x] if y + 1 < side else -1
        found = [n for n in (left, right, up, down) if n >= 0]
        costs = [1.0] * len(found)
        if self.movement == 8:
            for dx, dy, a, b in ((-1, -1, left, up), (1, -1, right, up),
                                 (-1, 1, left, down), (1, 1, right, down)):  # fmt: skip
                corner = ids[row + dy * side + x + dx] if a >= 0 and b >= 0 else -1
                if corner >= 0:  # free, and both orthogonal neighbours too
                    found.append(corner)
                    costs.append(_SQRT2)
        return found, costs

    def children(self, node: int) -> list[int]:
        return self.child[self.first_child[node] : self.first_child[node + 1]].tolist()


_SQRT2 = math.sqrt(2.0)


@frozen(eq=False)
class NodePath:
    """A path found by `Components.search`: `nodes` at `level`, start to end; its `cost` (the
    sum of its edges' costs) and the nodes the search expanded."""

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
                empty = np.zeros(0, dtype=np.int64)
                first, neighbour, cost = np.zeros(count + 1, dtype=np.int64), empty, empty + 0.0
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
        return cls(tuple(levels), tuple(grids), movement)

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
        nodes = self.levels[level]
        return (nodes._bx[node], nodes._by[node])  # type: ignore[attr-defined]

    def region(self, node: int, level: int) -> BoolGrid:
        """Which cells of the node's block belong to it, a (2^level, 2^level) mask [y, x]."""
        side = 1 << level
        bx, by = self.block(node, level)
        return self.grids[level][by * side : (by + 1) * side, bx * side : (bx + 1) * side] == node

    def search(
        self,
        level: int,
        sources: Sequence[int],
        targets: Iterable[int],
        *,
        allowed: set[int] | None = None,
        source_costs: Sequence[float] | None = None,
        target_costs: dict[int, float] | None = None,
        limit: float = math.inf,
    ) -> NodePath | None:
        """A cheapest path of neighbouring nodes at `level` from any of `sources` to any of
        `targets`, through `allowed` nodes only (all by default): A* with the distance to the
        nearest target's centre as its heuristic (consistent: edge costs are distances between
        centres). `source_costs` and `target_costs` are extra costs of starting or ending at
        a node. None when no target can be reached.

        Raises:
            SearchLimit: more than `limit` expansions were needed.
        """
        from .search import SearchLimit

        nodes = self.levels[level]
        goal = list(targets)
        end = target_costs or {}
        goal_set = set(goal)
        if not goal_set:
            return None
        xs: list[float] = nodes._x  # type: ignore[attr-defined]
        ys: list[float] = nodes._y  # type: ignore[attr-defined]
        goals = [(xs[t], ys[t]) for t in goal]
        diagonal = math.sqrt(2) - 1
        octile = level == 0 and self.movement == 8
        manhattan = level == 0 and self.movement == 4

        def h(node: int) -> float:
            cx, cy = xs[node], ys[node]
            best = math.inf
            for gx, gy in goals:
                dx, dy = abs(gx - cx), abs(gy - cy)
                if manhattan:
                    d = dx + dy
                elif octile:
                    d = max(dx, dy) + diagonal * min(dx, dy)
                else:
                    d = math.hypot(dx, dy)
                best = min(best, d)
            return best

        g: dict[int, float] = {}
        parent: dict[int, int] = {}
        heap: list[tuple[float, float, int]] = []
        for i, source in enumerate(sources):
            if allowed is not None and source not in allowed:
                continue
            cost = 0.0 if source_costs is None else float(source_costs[i])
            if cost < g.get(source, math.inf):
                g[source] = cost
                parent[source] = -1
                heapq.heappush(heap, (cost + h(source), -cost, source))
        closed: set[int] = set()
        expansions = 0
        while heap:
            _, negative, node = heapq.heappop(heap)
            if node < 0:  # the finish of a path ending at target -node - 1
                target = -node - 1
                return NodePath(level, _unwind(parent, target), g[target], expansions)
            if node in closed:
                continue
            closed.add(node)
            cost = -negative
            if node in goal_set:  # finishing here costs its ending cost more (h is 0 here)
                total = cost + end.get(node, 0.0)
                heapq.heappush(heap, (total, -total, -node - 1))
            if expansions + 1 > limit:  # this expansion would take it past its limit
                raise SearchLimit(expansions)
            expansions += 1
            neighbours, steps = nodes.neighbours(node)
            for neighbour, step in zip(neighbours, steps, strict=True):
                if neighbour in closed or (allowed is not None and neighbour not in allowed):
                    continue
                reach = cost + step
                if reach < g.get(neighbour, math.inf):
                    g[neighbour] = reach
                    parent[neighbour] = node
                    heapq.heappush(heap, (reach + h(neighbour), -reach, neighbour))
        return None


def _unwind(parent: dict[int, int], node: int) -> tuple[int, ...]:
    path = [node]
    while parent[path[-1]] >= 0:
        path.append(parent[path[-1]])
    return tuple(reversed(path))


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
    return labels.astype(np.int64) - 1


def _adjacency(
    labels: IntArray, side: int, movement: int, centre: FloatArray, count: int
) -> tuple[IntArray, IntArray, FloatArray]:
    """The level's edges as compressed rows (first, neighbour, cost): the pairs of nodes a legal
    move across a block boundary joins, once each, costing the distance between centres."""
    pairs = []
    cut = np.arange(side - 1, labels.shape[0] - 1, side)  # the last row/column of each block
    pairs.append((labels[:, cut], labels[:, cut + 1]))  # across a vertical boundary
    pairs.append((labels[cut, :], labels[cut + 1, :]))  # across a horizontal boundary
    if movement == 8:  # diagonal moves with both orthogonal neighbours free
        free = labels >= 0
        square = free[:-1, :-1] & free[:-1, 1:] & free[1:, :-1] & free[1:, 1:]
        pairs.append((np.where(square, labels[:-1, :-1], -1), labels[1:, 1:]))
        pairs.append((np.where(square, labels[:-1, 1:], -1), labels[1:, :-1]))
    a = np.concatenate([one.ravel() for one, _ in pairs])
    b = np.concatenate([two.ravel() for _, two in pairs])
    keep = (a >= 0) & (b >= 0) & (a != b)
    low, high = np.minimum(a[keep], b[keep]), np.maximum(a[keep], b[keep])
    keys = np.sort(low * max(count, 1) + high)
    keys = keys[np.concatenate(([True], keys[1:] != keys[:-1]))] if len(keys) else keys
    a, b = keys // max(count, 1), keys % max(count, 1)
    step = np.hypot(*(centre[a] - centre[b]).T) if len(a) else np.zeros(0)
    tails, heads = np.concatenate([a, b]), np.concatenate([b, a])
    order = np.argsort(tails, kind="stable")
    first = np.searchsorted(tails[order], np.arange(count + 1)).astype(np.int64)
    return first, heads[order].astype(np.int64), np.concatenate([step, step])[order]
