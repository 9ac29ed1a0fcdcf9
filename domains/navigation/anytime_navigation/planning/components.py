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
8-connected ones; at level 0 that is the move's length, 1 or sqrt 2). The whole hierarchy is
built once per map, bottom-up, vectorised and compiled (`Components.build`): level 1 read off
the 2 x 2 blocks' patterns, each level above from the graph of the one below (a union-find);
linear in the free cells, each level's edges sorted by counting. A level's *doors* (`doors`:
where a route crosses from node to node, for searching the first plan's level again by the way
through the nodes rather than their centres) are made when a route is first searched through
them, not with the hierarchy: a planner that never does so never pays for them.

Landmarks. On request (`landmarks`), a level gets the distances from a few of its nodes to every
other, over its edges, for the ALT heuristic of the searches over the whole level (the first
plan): by the triangle inequality, |d(L, goal) - d(L, node)| is at most the distance from node
to goal, a bound that sees the walls the straight line cannot. The landmarks are chosen
farthest first in the level's largest connected region (the first one farthest from node 0).
On a maze, where the straight line says little, the first plan's search over the level
expands a fifth to a sixth of the nodes it did with the distance as the robot moves alone
(MovingAI's mazes of widths 1 and 2, level 4, the 16 longest problems, 8 landmarks: 17,646 of
91,478 and 13,815 of 79,045), on the other maps a quarter.

Arrays are indexed [y, x]; positions are (x, y).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from typing import Any, NamedTuple, overload

import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from ..world import BoolGrid, Position, is_power_of_two
from .doors import Doors
from .search import SearchLimit, compiled

__all__ = ["Components", "Level", "NodePath"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]
Edges = tuple[IntArray, IntArray]  # a level's edges (low, high): low < high, sorted, once each


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
    # Level 0's `grid` ravelled with a border of -1 (blocked): a move's head is one look-up.
    padded: IntArray | None = None

    def __len__(self) -> int:
        return len(self.size)

    def children(self, node: int) -> list[int]:
        found: list[int] = self.child[self.first_child[node] : self.first_child[node + 1]].tolist()
        return found

    def edges_of(self, nodes: IntArray) -> tuple[IntArray, IntArray, FloatArray]:
        """Every edge leaving `nodes`: (tail, head, cost) arrays, tails among `nodes`."""
        if self.grid is None:
            index = _rows(self.first, nodes)
            counts = self.first[nodes + 1] - self.first[nodes]
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
    # `nodes` as the search's array (None when not made by one): read by the planner instead of
    # converting the tuple back (on mazes a base route of thousands of cells, 0.1 ms)
    array: IntArray | None = field(default=None, eq=False, repr=False)


class _Grids(Sequence[IntArray]):
    """The level-k node of each base cell, k = 0 .. top (-1 where blocked): level 0's made with
    the hierarchy, the others when first read (`grids[k + 1]` is level k's parents of
    `grids[k]`, the top's level 0's nodes' ancestors `up`: the planner reads none of them, an
    executor reading a plan's regions does; on a 1024 x 1024 map each is 8 MB written). A
    pickle holds what they are made from, not what was read: the same before and after."""

    def __init__(self, base: IntArray, parents: tuple[IntArray, ...]) -> None:
        self._parents = parents
        self.base = base  # level 0's, read per problem (`Components.cell`)
        self._made: dict[int, IntArray] = {0: base}
        # each level-0 node's ancestor at the top (itself at top 0)
        self.up = np.arange(len(parents[0]) if parents else 0, dtype=np.int64)
        for parent in parents:
            compiled().lift(self.up, parent)
        self._regions: IntArray | None = None

    def __reduce__(self) -> tuple[object, ...]:
        return (_Grids, (self.base, self._parents))

    def __len__(self) -> int:
        return len(self._parents) + 1

    @overload
    def __getitem__(self, index: int) -> IntArray: ...

    @overload
    def __getitem__(self, index: slice) -> tuple[IntArray, ...]: ...

    def __getitem__(self, index: int | slice) -> IntArray | tuple[IntArray, ...]:
        if isinstance(index, slice):
            return tuple(self[k] for k in range(len(self))[index])
        k = index + len(self) if index < 0 else index
        if not 0 <= k < len(self):
            raise IndexError(f"level {index} of {len(self)}")
        if k not in self._made:
            grid: IntArray
            if k == len(self._parents):  # one map-sized pass
                grid = np.append(self.up, -1)[self._made[0]]  # blocked, -1: the -1 appended
            else:
                grid = np.append(self._parents[k - 1], -1)[self[k - 1]]
            self._made[k] = grid
        return self._made[k]

    def top_node(self, position: Position) -> int:
        """The top-level node of a base cell (-1 where blocked), its grid unread."""
        x, y = position
        node = int(self.base[y, x])
        return node if node < 0 or not self._parents else int(self.up[node])

    def made(self, k: int) -> bool:
        """Whether level k's grid is made."""
        return k in self._made

    def regions(self, top_regions: IntArray) -> IntArray:
        """Each base cell's region, its top-level node's (`top_regions`), made once (one
        map-sized pass)."""
        if self._regions is None:
            below = top_regions[self.up] if self._parents else top_regions  # level 0's nodes'
            self._regions = np.append(below, -1)[self._made[0]]
        return self._regions


class Stacked(NamedTuple):
    """Levels 2 .. top's arrays, each kind concatenated (values unchanged) so that compiled code
    reads any level's as a slice (`corridor_search.refine_step`): level k's nodes' rows are
    `[node_at[k]:node_at[k + 1]]` of `parent`, `block`, `centre` and `scratch` (-1 everywhere,
    a search's), its compressed rows `[first_at[k]:first_at[k + 1]]` of `first` and
    `first_child`, its edges `[edge_at[k]:edge_at[k + 1]]` of `neighbour` and `cost`, its
    children `[child_at[k]:child_at[k + 1]]` of `child`. Levels 0 and 1 are read apart (their
    arrays, and `base_scratch`, `one_scratch` and `cells`, the abstraction's own scratch): copying
    level 1's, a third of the cells, cost 4-7 ms per 512 x 512 map, levels 2 and up's 0.2."""

    base_scratch: IntArray
    one_scratch: IntArray
    cells: NDArray[np.uint8]
    node_at: IntArray
    parent: IntArray
    block: IntArray
    centre: FloatArray
    scratch: IntArray
    first_at: IntArray
    first: IntArray
    edge_at: IntArray
    neighbour: IntArray
    cost: FloatArray
    child_at: IntArray
    first_child: IntArray
    child: IntArray


def _stack(
    levels: Sequence[Level], scratch: Sequence[IntArray], cells: NDArray[np.uint8]
) -> Stacked:
    above = levels[2:]

    def offsets(sizes: list[int]) -> IntArray:
        return np.cumsum([0, 0, 0, *sizes], dtype=np.int64)  # levels 0 and 1: apart

    def joined(arrays: list[NDArray[Any]], empty: NDArray[Any]) -> NDArray[Any]:
        return np.concatenate(arrays) if arrays else empty

    no_ints, no_floats = np.zeros(0, dtype=np.int64), np.zeros(0)
    node_at = offsets([len(level) for level in above])
    return Stacked(
        scratch[0],
        scratch[1] if len(scratch) > 1 else no_ints,
        cells,
        node_at,
        joined([level.parent for level in above], no_ints),
        joined([level.block for level in above], np.zeros((0, 2), dtype=np.int64)),
        joined([level.centre for level in above], np.zeros((0, 2))),
        np.full(int(node_at[-1]), -1, dtype=np.int64),
        offsets([len(level.first) for level in above]),
        joined([level.first for level in above], no_ints),
        offsets([len(level.neighbour) for level in above]),
        joined([level.neighbour for level in above], no_ints),
        joined([level.cost for level in above], no_floats),
        offsets([len(level.child) for level in above]),
        joined([level.first_child for level in above], no_ints),
        joined([level.child for level in above], no_ints),
    )


# Each abstraction's `Stacked`, made when a plan is first refined: kept apart from its fields, so
# that a plan's pickle, which holds its abstraction, is the same before and after.
_STACKED: weakref.WeakKeyDictionary[Components, Stacked] = weakref.WeakKeyDictionary()
# Each level's arguments of `Components.path`'s searches over the whole level (its table,
# edges, heap's room and blocks: `corridor_search.level_search`) by the landmarks' count, made
# when first searched or with the build (`Components.search_room`, `planner.made_ahead`); at
# (0, 0) the room of level 0's search by jump points (`Components.whole_room`).
_LEVEL_SEARCHES: weakref.WeakKeyDictionary[Components, dict[tuple[int, int], tuple[Any, ...]]] = (
    weakref.WeakKeyDictionary()
)
# The most jump points a search over every cell is asked to settle without a limit: one search
# settles each free cell once at most, and a limit of inf is no int
_MOST = 2**62


# Each abstraction's doors by level, made when a route is first searched through them (as above):
# a planner that never searches the doors (`atp(doors=False)`, the navigation task's, or a
# direct route through a maze) does not pay for them (two thirds of the build of a 128 x 128
# world).
_DOORS: weakref.WeakKeyDictionary[Components, dict[int, Doors]] = weakref.WeakKeyDictionary()
# Each abstraction's landmark distances by (level, count), made when first asked for (as above).
_LANDMARKS: weakref.WeakKeyDictionary[Components, dict[tuple[int, int], FloatArray]] = (
    weakref.WeakKeyDictionary()
)


@frozen(eq=False)
class Components:
    """The hierarchy of a square power-of-two map: `levels[k]` for k = 0 .. top, and
    `grids[k]`, the level-k node of each base cell (-1 where blocked). Build it with
    `Components.build`."""

    levels: tuple[Level, ...]
    # Made when first read but for levels 0 and top (`_Grids`): the planner reads no other.
    grids: _Grids
    movement: int
    # The connected free region of each top-level node: `regions` (each base cell's) is made
    # from it when first read; `connected` reads the two cells' nodes.
    top_regions: IntArray
    # Each level's scratch for its searches: -1 for every node between them (made here, so that
    # a plan's pickle, which holds its abstraction, is the same before and after a search).
    _scratch: tuple[IntArray, ...] = field(init=False, repr=False)
    # Level 0's padded cells as jump point searches read them (`corridor_search.CELL_*`):
    # blocked or free between searches, a search's corridor marked in it while it runs.
    _cells: NDArray[np.uint8] = field(init=False, repr=False)

    @_scratch.default
    def _no_nodes(self) -> tuple[IntArray, ...]:
        return tuple(np.full(len(level), -1, dtype=np.int64) for level in self.levels)

    @_cells.default
    def _free_cells(self) -> NDArray[np.uint8]:
        padded = self.levels[0].padded
        if padded is None:
            return np.zeros(0, dtype=np.uint8)
        return (padded >= 0).astype(np.uint8)  # CELL_FREE where free, else CELL_BLOCKED

    def stacked(self) -> Stacked:
        """Levels 2 .. top's arrays concatenated (`Stacked`), made once."""
        stacked = _STACKED.get(self)
        if stacked is None:
            stacked = _STACKED[self] = _stack(self.levels, self._scratch, self._cells)
        return stacked

    def doors(self, level: int) -> Doors:
        """The doors of `level` > 0 (`doors.Doors`), made when first asked for: the top level's
        read each cell's node off level 0's grid, so its grid is not made."""
        made = _DOORS.setdefault(self, {})
        if level not in made:
            if not 0 < level <= self.top:
                raise ValueError(f"doors are of levels 1 to {self.top}, not {level}")
            at = self.levels[level]
            if level == self.top:
                grid, up = self.grids[0], self.grids.up
            else:
                grid, up = self.grids[level], None
            made[level] = Doors.build(
                level, grid, at.block, at.first, at.neighbour, self.movement, up=up
            )
        return made[level]

    def landmarks(self, level: int, count: int) -> FloatArray:
        """The distances over `level`'s edges from `count` landmark nodes to every node of the
        level, shape (nodes, count) (a node's distances side by side, as a search reads them;
        inf where unreachable), made once: the landmarks chosen farthest first in the level's
        largest connected region (see the module's doc)."""
        made = _LANDMARKS.get(self)  # not `setdefault`: no dict made per search
        if made is None:
            made = _LANDMARKS[self] = {}
        key = (level, count)
        if key not in made:
            made[key] = _landmark_distances(self.levels[level], count)
        return made[key]

    @property
    def cell(self) -> IntArray:
        """The level-0 node of each base cell (-1 where blocked)."""
        return self.grids.base

    @property
    def regions(self) -> IntArray:
        """The connected free region of each base cell (-1 where blocked), made when first
        read (`grids` keeps it)."""
        return self.grids.regions(self.top_regions)

    @classmethod
    def build(cls, blocked: BoolGrid, movement: int = 4, top: int | None = None) -> Components:
        """The hierarchy of `blocked` (square, power-of-two side) up to level `top` (default
        log2(N): one block).

        Bottom-up, the grid never labelled again: level 0's nodes are the free cells, level 1's
        are read off each 2 x 2 block's pattern of free cells, and a node higher up is a
        component of the graph of the nodes one level down in its block, joined by their edges
        (the legal moves between them stay inside the block). A level's edges are the edges
        one level down between blocks, taken up to the parents. Nodes are numbered by block
        (row by row), then by first cell (row by row): the order a raster scan of each block
        meets its components in."""
        grid = np.asarray(blocked, dtype=bool)
        if grid.ndim != 2 or grid.shape[0] != grid.shape[1] or not is_power_of_two(grid.shape[0]):
            raise ValueError(f"the grid must be square with a power-of-two side, got {grid.shape}")
        if movement not in (4, 8):
            raise ValueError(f"movement must be 4 or 8, got {movement!r}")
        side = grid.shape[0]
        highest = side.bit_length() - 1
        top = highest if top is None else top
        if not 0 <= top <= highest:
            raise ValueError(f"top must be in [0, {highest}], got {top}")
        free = ~grid
        cells, nodes = compiled().cell_nodes(free)  # level 0's nodes, in raster order
        grids = [nodes.reshape(side, side)]
        # A level in the making: each node's first cell in raster order (y * side + x), its
        # number of cells, the sums of their x and of their y (exact, in any order), and the
        # level's edges (low < high, sorted).
        made: list[tuple[IntArray, IntArray, tuple[FloatArray, FloatArray], Edges]] = []
        first_cell, size = cells, np.ones(len(cells), dtype=np.int64)
        no_sums = np.zeros(0)
        sums = (no_sums, no_sums)  # level 0's centres are its cells' (level 1's: `_quads`)
        edges: Edges = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
        parents: list[IntArray] = []
        quad_children: IntArray | None = None  # level 1's children, read off its blocks
        for k in range(top):  # level k + 1 from level k
            if k == 0:
                parent, count, edges_up, quad_children, first_up, size_up, sums_up = _quads(
                    free, nodes, movement
                )
            else:
                k_up, across = k + 1, side >> (k + 1)  # blocks per row one level up
                x, y = first_cell & (side - 1), first_cell >> highest
                block_up = (y >> k_up) * across + (x >> k_up)
                parent, count, first_up = _components(edges, block_up, first_cell, side)
                edges_up = _lifted(edges, parent, count)
            made.append((first_cell, size, sums, edges))
            parents.append(parent)
            if k == 0:  # counted and summed block by block
                size, sums = size_up, sums_up
            else:
                size = np.bincount(parent, weights=size, minlength=count).astype(np.int64)
                sums = (  # float64 already: not copied
                    np.bincount(parent, weights=sums[0], minlength=count).astype(float, copy=False),
                    np.bincount(parent, weights=sums[1], minlength=count).astype(float, copy=False),
                )
            first_cell, edges = first_up, edges_up
        made.append((first_cell, size, sums, edges))
        parents.append(np.full(len(size), -1, dtype=np.int64))
        levels = tuple(
            _level(  # level 1's children known, the others' sorted out
                k,
                *made[k],
                parents[k],
                parents[k - 1] if k else None,
                quad_children if k == 1 else None,
                grids[0],
                movement,
            )
            for k in range(top + 1)
        )
        made_grids = _Grids(grids[0], tuple(parents[:top]))
        if top > 0:  # the free regions: the components of the top level's graph
            region, _, _ = _components(edges, np.zeros(len(size), np.int64), first_cell, side)
        else:
            from scipy import ndimage  # imported here, as in `world.reachable`

            labels, _ = ndimage.label(free)  # 4-connected: octile moves join the same cells
            region = labels.ravel()[cells].astype(np.int64) - 1
        return cls(levels, made_grids, movement, region)

    @property
    def top(self) -> int:
        return len(self.levels) - 1

    def node(self, position: Position, level: int) -> int:
        """The level-`level` node of a base cell (-1 when the cell is blocked)."""
        x, y = position
        if self.grids.made(level):
            return int(self.grids[level][y, x])
        if level == self.top:
            return self.grids.top_node(position)
        node = int(self.grids[0][y, x])
        return node if node < 0 else self.ancestor(node, 0, level)

    def ancestor(self, node: int, level: int, to_level: int) -> int:
        """The node at `to_level` >= `level` that contains `node` of `level`."""
        for k in range(level, to_level):
            node = int(self.levels[k].parent[node])
        return node

    def block(self, node: int, level: int) -> Position:
        x, y = self.levels[level].block[node]
        return (int(x), int(y))

    def joined(self, start: Position, goal: Position, level: int) -> tuple[int, int] | None:
        """The level-`level` nodes of the start's and the goal's base cells when a route joins
        them, else None: a planner's reads of a problem, at once.

        Raises:
            ValueError: the start or the goal is outside the map or a blocked cell.
        """
        grids, ends = self.grids, []
        height, width = grids.base.shape
        for name, position in (("start", start), ("goal", goal)):
            x, y = position
            if not (0 <= x < width and 0 <= y < height):
                raise ValueError(f"{name} {position} is outside the {width}x{height} map")
            node = grids.top_node(position)
            if node < 0:
                raise ValueError(f"{name} {position} is a blocked cell")
            ends.append(node)
        if self.top_regions[ends[0]] != self.top_regions[ends[1]]:
            return None
        if level == len(self.levels) - 1:  # the top's, read above
            return ends[0], ends[1]
        return self.node(start, level), self.node(goal, level)

    def connected(self, one: Position, other: Position) -> bool:
        """Whether a route joins two free base cells."""
        a, b = self.grids.top_node(one), self.grids.top_node(other)
        return bool(a >= 0 and b >= 0 and self.top_regions[a] == self.top_regions[b])

    def region(self, node: int, level: int) -> BoolGrid:
        """Which cells of the node's block belong to it, a (2^level, 2^level) mask [y, x]."""
        side = 1 << level
        bx, by = self.block(node, level)
        window = self.grids[level][by * side : (by + 1) * side, bx * side : (bx + 1) * side]
        return np.asarray(window == node)

    def route(
        self,
        level: int,
        start: Position,
        goal: Position,
        *,
        bound: Sequence[int] | None = None,
        rings: int | None = None,
        limit: float = math.inf,
    ) -> NodePath:
        """The cheapest path of nodes at `level` > 0 from the start's node to the goal's (they
        must be connected) through the level's doors (`doors`: built with the hierarchy for
        its top level, here for another); `bound`, a path of nodes between them, bounds the
        search by its cost through its doors. With `rings` (and `bound`), the route keeps to
        `bound`'s nodes and those up to `rings` edges from them (`neighbourhood`).

        Raises:
            SearchLimit: its work is more than `limit`.
        """
        doors = self.doors(level)
        within = None
        if rings is not None and bound is not None:
            within = self.neighbourhood(level, bound, rings)
        nodes, cost, expansions = doors.route(start, goal, bound=bound, within=within, limit=limit)
        return NodePath(level, nodes, cost, expansions)

    def neighbourhood(self, level: int, nodes: Sequence[int], rings: int) -> NDArray[np.bool_]:
        """Which nodes of `level` are among `nodes` or up to `rings` edges from one of them,
        one entry per node."""
        at = self.levels[level]
        near: NDArray[np.bool_] = compiled().neighbourhood(
            at.first, at.neighbour, np.asarray(nodes, dtype=np.int64), rings, len(at)
        )
        return near

    def path(
        self,
        level: int,
        source: int,
        target: int,
        *,
        limit: float = math.inf,
        landmarks: int = 0,
        jump_points: bool = False,
    ) -> NodePath:
        """A cheapest path of neighbouring nodes at `level` between two nodes over the whole
        level, from centre to centre: `corridor` over every node (with `landmarks`, its
        heuristic bounded by theirs; with `jump_points` at level 0 and octile moves, by jump
        points), the same cost and work; above level 0 without the cost of the level's size
        (`corridor_search.level_search`: the first plan's search), and so at level 0 by jump
        points (`corridor_search.whole_jump_search`, its room kept: `whole_room`).

        Raises:
            SearchLimit: its work, counted as `corridor` counts it, is more than `limit` (by
                jump points: it would settle more of them than `limit`, and stops there).
        """
        if level > 0:  # the same search, its scratch kept per level (`read_path`)
            return self.read_path(
                level, source, target, np.zeros((0, 0)), limit=limit, landmarks=landmarks
            )[0]
        at = self.levels[0]
        if jump_points and self.movement == 8 and at.padded is not None and at.grid is not None:
            cells, *kept = self.whole_room()
            most = int(min(limit, _MOST))
            path, best, expansions = compiled().whole_jump_search(
                at.padded, cells, at.grid.shape[1] + 2, at.block, at.centre, source, target,
                *kept, most,
            )  # fmt: skip
            if best < 0.0:  # it stopped: more jump points to settle than `limit`
                raise SearchLimit(most)
            if not len(path):
                raise AssertionError(f"no path between cells {source} and {target}")
            return NodePath(0, tuple(path.tolist()), best, expansions, path)
        every = np.arange(len(at))
        found = self.corridor(0, every, [source], [target], limit=limit)
        if found is None:
            raise AssertionError(f"no path at level {level} between nodes {source} and {target}")
        return found

    def read_path(
        self,
        level: int,
        source: int,
        target: int,
        values: FloatArray,
        *,
        limit: float = math.inf,
        landmarks: int = 0,
    ) -> tuple[NodePath, IntArray, IntArray, float]:
        """`path` at `level` > 0, and what a plan reads of it in the same compiled call
        (`corridor_search.level_search`, the first plan's): its nodes' blocks (x and y) and the
        mean of `values` (one per block of the level, indexed [y, x]) over them (none and NaN
        with `values` empty). Its table and room are kept per level (`search_room`).

        Raises:
            SearchLimit: as `path`.
        """
        table, first, neighbour, cost, heap_keys, heap_items, block = self.search_room(
            level, landmarks
        )
        path, best, expansions, xs, ys, mean = compiled().level_search(
            table, first, neighbour, cost, self.movement, source, target, landmarks,
            heap_keys, heap_items, block, values,
        )  # fmt: skip
        if expansions > limit:
            raise SearchLimit(int(limit))
        if not len(path):
            raise AssertionError(f"no path at level {level} between nodes {source} and {target}")
        return NodePath(level, tuple(path.tolist()), best, expansions, path), xs, ys, mean

    def whole_room(self) -> tuple[Any, ...]:
        """What `path`'s jump point search over every cell reads besides the problem, made when
        first asked for and kept: the padded cells, every free one in its corridor; each cell's
        distance, estimate, previous cell and settled flag, in their state before a search; the
        list of cells a search touched; the heap's room; the map's jumps (`corridor_search.
        jump_distances`, made here: a pass over the free cells per straight move)."""
        made = _LEVEL_SEARCHES.get(self)
        if made is None:
            made = _LEVEL_SEARCHES[self] = {}
        room = made.get((0, 0))
        if room is None:
            at = self.levels[0]
            assert at.grid is not None and at.padded is not None  # level 0's cells
            n = len(at)
            searches = compiled()
            cells = self._cells.copy()
            cells[cells == searches.CELL_FREE] = searches.CELL_CORRIDOR
            room = made[0, 0] = (
                cells, np.full(n, np.inf), np.full(n, -1.0), np.full(n, -1, dtype=np.int64),
                np.zeros(n, dtype=np.bool_), np.empty(n, dtype=np.int64),
                np.empty(8 * n + 2), np.empty(8 * n + 2, dtype=np.int64),
                searches.jump_distances(cells, at.grid.shape[1] + 2),
            )  # fmt: skip
        return room

    def search_room(self, level: int, landmarks: int = 0) -> tuple[Any, ...]:
        """What `path`'s searches over `level` (> 0) with `landmarks` landmarks read besides
        the problem, made when first asked for and kept: the table (`corridor_search.
        level_table`, each node's row), the level's edges, the heap's room (one more than the
        edges) and the nodes' blocks."""
        made = _LEVEL_SEARCHES.get(self)  # not `setdefault`: no dict made per search
        if made is None:
            made = _LEVEL_SEARCHES[self] = {}
        room = made.get((level, landmarks))
        if room is None:
            at = self.levels[level]
            distances = self.landmarks(level, landmarks) if landmarks else np.zeros((len(at), 0))
            edges = len(at.neighbour) + 1
            room = made[level, landmarks] = (
                compiled().level_table(at.centre, distances), at.first, at.neighbour, at.cost,
                np.empty(edges), np.empty(edges, dtype=np.int64), at.block,
            )  # fmt: skip
        return room

    def widened(self, level: int, nodes: Sequence[int] | IntArray, rings: int) -> IntArray:
        """The children (at `level` - 1) of `nodes` (at `level`) and of every node up to
        `rings` edges from them, each once, in node order: the corridor a refinement searches."""
        at = self.levels[level]
        children: IntArray = compiled().widened_children(
            at.first, at.neighbour, at.first_child, at.child,
            np.asarray(nodes, dtype=np.int64), rings, self._scratch[level],
        )  # fmt: skip
        return children

    def refinement(
        self,
        level: int,
        route: Sequence[int],
        rings: int,
        source: tuple[int, int, float, float],
        target: tuple[int, int, float, float],
        *,
        limit: float = math.inf,
    ) -> tuple[IntArray, float, int]:
        """A refinement's search in one compiled call: `corridor` at `level` - 1 through
        `widened(level, route, rings)`, from `source` to `target`, each (node, -1, 0, 0) for a
        fixed end one level down, or (-1, node, x, y) for any child of a node of `route`'s
        level, each costing how much farther its centre is from (x, y) than the nearest
        child's. Returns the path's nodes (empty when none), its cost and its expansions.

        Raises:
            SearchLimit: its expansions are more than `limit`.
        """
        up, at = self.levels[level], self.levels[level - 1]
        none = np.zeros(0, dtype=np.int64)
        path, best, expansions = compiled().refinement(
            up.first, up.neighbour, up.first_child, up.child, self._scratch[level],
            np.asarray(route, dtype=np.int64), rings, none, none,
            at.first if at.k else none,
            at.neighbour if at.k else none,
            at.cost if at.k else np.zeros(0),
            at.padded if at.padded is not None else none,
            self._cells if level == 1 else np.zeros(0, dtype=np.uint8),
            at.grid.shape[1] + 2 if at.grid is not None else 0,
            at.block, at.centre, self.movement, False, self._scratch[level - 1],
            *source, *target,
        )  # fmt: skip
        if expansions > limit:
            raise SearchLimit(int(limit))
        return path, best, expansions

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
        landmarks: int = 0,
        jump_points: bool = False,
    ) -> NodePath | None:
        """A cheapest path of neighbouring nodes at `level` from any of `sources` to any of
        `targets` through the `allowed` nodes (sources and targets among them), with the extra
        costs of starting and ending at each; None when no target can be reached. With
        `landmarks` (a level above 0), the heuristic is also bounded by that many landmarks'
        distances (`landmarks`): a path as cheap, fewer nodes expanded.

        A* over the corridor, compiled (`corridor_search`), stopped once the cheapest way to a
        target is known. Its work is counted as the nodes an A* search for the
        same path expands, those whose cost from a source plus the heuristic (the distance to the
        nearest target, consistent with the edges' costs) is below the path's cost: a measure
        of the search, not of how it is computed. With `jump_points` at level 0 and octile
        moves, a jump point search (`corridor_search.jump_search`): a path as cheap, its work
        the jump points expanded.

        Raises:
            SearchLimit: that work is more than `limit`.
        """
        at = self.levels[level]
        local = self._scratch[level]
        none = np.zeros(0, dtype=np.int64)
        padded = at.padded if at.padded is not None else none
        wide = at.grid.shape[1] + 2 if at.grid is not None else 0
        sources_ = np.asarray(sources, dtype=np.int64)
        targets_ = np.asarray(targets, dtype=np.int64)
        source_costs_ = np.zeros(len(sources_)) if source_costs is None else source_costs
        target_costs_ = np.zeros(len(targets_)) if target_costs is None else target_costs
        ends = (
            sources_,
            np.asarray(source_costs_, float),
            targets_,
            np.asarray(target_costs_, float),
        )
        nodes = np.asarray(allowed, dtype=np.int64)
        if jump_points and level == 0 and self.movement == 8:
            path, best, expansions = compiled().jump_search(
                nodes, local, padded, self._cells, wide, at.block, at.centre, *ends
            )
        else:
            path, best, expansions = compiled().search(
                nodes,
                local,
                at.first if at.k else none,
                at.neighbour if at.k else none,
                at.cost if at.k else np.zeros(0),
                padded,
                wide,
                at.block,
                at.centre,
                self.movement,
                *ends,
                self.landmarks(level, landmarks) if landmarks and level else np.zeros((0, 0)),
            )
        if expansions > limit:
            raise SearchLimit(int(limit))
        if not len(path):
            return None
        return NodePath(level, tuple(path.tolist()), best, expansions, path)


def _landmark_distances(at: Level, count: int) -> FloatArray:
    """`Components.landmarks` of one level above level 0: Dijkstra's (scipy's, in C) from each
    landmark in turn, the next the node of the largest region farthest from those chosen."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components, dijkstra

    n = len(at)
    if at.k == 0 or n == 0 or count <= 0:
        return np.zeros((n, 0))
    graph = csr_matrix((at.cost, at.neighbour, at.first), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    largest = label == np.argmax(np.bincount(label))
    nearest = np.where(largest, np.inf, -np.inf)  # distance to the nearest landmark chosen
    rows = []
    # The first landmark: the node farthest from the largest region's first node.
    seed = dijkstra(graph, indices=int(np.argmax(largest)))
    candidate = int(np.argmax(np.where(largest, seed, -np.inf)))
    for _ in range(min(count, int(largest.sum()))):
        row = dijkstra(graph, indices=candidate)
        rows.append(row)
        nearest = np.minimum(nearest, row)
        candidate = int(np.argmax(np.where(largest, nearest, -np.inf)))
    distances: FloatArray = np.ascontiguousarray(np.vstack(rows).T)
    return distances


def _rows(first: IntArray, nodes: IntArray) -> IntArray:
    """The indices of the entries of `nodes`' rows in compressed rows `first`, row by row."""
    counts = first[nodes + 1] - first[nodes]
    return np.repeat(first[nodes] - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())


def _quad_labels() -> IntArray:
    """The components of a 2 x 2 block for each of the 16 patterns of free cells (bit p of the
    pattern: position p = 2y + x free): each position's label, numbered in raster order (-1
    where blocked)."""
    labels = np.full((16, 4), -1, dtype=np.int64)
    for pattern in range(16):
        count = 0
        for p in range(4):
            if pattern >> p & 1 and labels[pattern, p] < 0:
                labels[pattern, p] = count
                for q in (p ^ 1, p ^ 2, p ^ 3):  # p ^ 3, diagonal, joins through p ^ 1 or p ^ 2
                    if pattern >> q & 1 and (q != p ^ 3 or pattern & (1 << (p ^ 1) | 1 << (p ^ 2))):
                        labels[pattern, q] = count
                count += 1
    return labels


_QUAD_LABELS = _quad_labels().astype(np.int8)
#: The neighbouring blocks (dx, dy) that come after a block in raster order, in their order.
_FORWARD = ((1, 0), (-1, 1), (0, 1), (1, 1))


def _quad_moves(movement: int) -> IntArray:
    """The legal moves from a 2 x 2 block into one of the `_FORWARD` blocks, every move between
    two blocks once, ordered by direction: rows (direction, the tail's position, the head's,
    dx, dy)."""
    moves = _STRAIGHT_MOVES + (_DIAGONAL_MOVES if movement == 8 else ())
    found = []
    for tail in range(4):
        tx, ty = tail & 1, tail >> 1
        for dx, dy, _ in moves:
            hx, hy = tx + dx, ty + dy
            if (hx >> 1, hy >> 1) in _FORWARD:
                head = 2 * (hy & 1) + (hx & 1)
                found.append((_FORWARD.index((hx >> 1, hy >> 1)), tail, head, dx, dy))
    return np.array(sorted(found, key=lambda move: move[0]), dtype=np.int64)


_QUAD_MOVES = {movement: _quad_moves(movement) for movement in (4, 8)}


def _side_joins(movement: int) -> NDArray[np.uint8]:
    """For the blocks beside (direction 0 of `_FORWARD`) and below (direction 2) a 2 x 2
    block, by the two blocks' patterns: the pairs of their components the legal moves between
    them join, bit 2 * the first's label + the second's (what `corridor_search.quads` made row
    by row of `_QUAD_MOVES`: the corner cells of these moves are all in the two blocks)."""
    joins = np.zeros((2, 16, 16), dtype=np.uint8)
    moves = _QUAD_MOVES[movement]
    for d in (0, 2):
        dx_, dy_ = _FORWARD[d]
        for p in range(16):
            for q in range(16):
                free = np.zeros((4, 4), dtype=bool)  # the two blocks, the first at (0, 0)
                for position in range(4):
                    x, y = position & 1, position >> 1
                    free[y, x] = bool(p >> position & 1)
                    free[2 * dy_ + y, 2 * dx_ + x] = bool(q >> position & 1)
                bits = 0
                for _, tail, head, dx, dy in moves[moves[:, 0] == d].tolist():
                    tail_label, head_label = _QUAD_LABELS[p, tail], _QUAD_LABELS[q, head]
                    if tail_label < 0 or head_label < 0:
                        continue
                    if dx and dy:  # no corner cutting: both orthogonal neighbours free
                        tx, ty = tail & 1, tail >> 1
                        if not (free[ty, tx + dx] and free[ty + dy, tx]):
                            continue
                    bits |= 1 << (2 * int(tail_label) + int(head_label))
                joins[d >> 1, p, q] = bits
    return joins


_SIDE_JOINS = {movement: _side_joins(movement) for movement in (4, 8)}


def _level(
    k: int,
    first_cell: IntArray,
    size: IntArray,
    sums: tuple[FloatArray, FloatArray],
    edges: Edges,
    parent: IntArray,
    below: IntArray | None,
    children: IntArray | None,
    base: IntArray,
    movement: int,
) -> Level:
    """Level k from its making (`Components.build`), the parents of the level below and its
    nodes' children, ascending, when known (level 1's); `base` is level 0's grid."""
    side, count = base.shape[0], len(size)
    block, centre = compiled().level_geometry(first_cell, size, *sums, k, side)
    first_child, child = np.zeros(count + 1, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if below is not None:
        first_child, child = _grouped(below, count, children)
    first, neighbour, cost = _compressed(edges, centre, movement)
    return Level(
        k,
        block,
        centre,
        size,
        parent,
        first,
        neighbour,
        cost,
        first_child,
        child,
        movement,
        base if k == 0 else None,
        np.pad(base, 1, constant_values=-1).ravel() if k == 0 else None,
    )


def _quads(
    free: BoolGrid, cell_node: IntArray, movement: int
) -> tuple[IntArray, int, Edges, IntArray, IntArray, IntArray, tuple[FloatArray, FloatArray]]:
    """Level 1 from the 2 x 2 blocks' patterns of free cells (`_QUAD_LABELS`; the blocks with a
    free cell only: a sparse map costs little), `cell_node` the level-0 node of each base cell
    (ravelled, -1 where blocked): the level-1 node of each level-0 node (its parent), the
    number of level-1 nodes, their edges, their children (level-0 nodes) node by node,
    ascending (a block's two components, when it has two, are one cell each, in raster order),
    each node's first cell, its number of cells and the sums of their x and of their y. One
    compiled call (`corridor_search.quads`: a third of the time of the vectorised passes it
    replaced on 512 x 512 maps, about 5 against 16 ms), making no map-sized array (on a
    1024 x 1024 map the level-1 grid it made was 8 MB written)."""
    parent, count, low, high, children, first, size, sum_x, sum_y = compiled().quads(
        np.ascontiguousarray(free, dtype=np.bool_),
        cell_node,
        movement,
        _QUAD_LABELS,
        _QUAD_MOVES[movement],
        _SIDE_JOINS[movement],
    )
    return parent, int(count), (low, high), children, first, size, (sum_x, sum_y)


def _components(
    edges: Edges, group: IntArray, first_cell: IntArray, side: int
) -> tuple[IntArray, int, IntArray]:
    """The components of the graph of the edges that stay within a `group` (a block one level
    up): each node's component, their number and first cells, numbered by group, then by first
    cell."""
    if len(group) == 0:
        return np.zeros(0, dtype=np.int64), 0, np.zeros(0, dtype=np.int64)
    # compiled union-find (`corridor_search.grouped_components`): scipy's connected components
    # on a sparse matrix made for it cost 3-4x as much
    component, count, first = compiled().grouped_components(*edges, group, first_cell, side)
    return component, int(count), first


def _lifted(edges: Edges, parent: IntArray, count: int) -> Edges:
    """The edges one level up: the parents of the ends of the edges between blocks, once
    each (compiled: `corridor_search.lifted_pairs`)."""
    lifted: Edges = compiled().lifted_pairs(*edges, parent, count)
    return lifted


def _grouped(
    parent: IntArray, count: int, children: IntArray | None = None
) -> tuple[IntArray, IntArray]:
    """The children of each of `count` nodes, ascending, as compressed rows (first, child);
    `children` the child column when known."""
    first = np.zeros(count + 1, dtype=np.int64)
    np.cumsum(np.bincount(parent, minlength=count), out=first[1:])
    if children is not None:
        return first, children
    by_parent: IntArray = compiled().counting_order(parent, count)
    return first, by_parent


def _compressed(
    edges: Edges, centre: FloatArray, movement: int
) -> tuple[IntArray, IntArray, FloatArray]:
    """The edges as compressed rows (first, neighbour, cost), each costing the distance between
    the centres (row i: node i's x, y) of its ends: a node's row holds its higher neighbours,
    then its lower ones, each ascending."""
    low, high = edges
    if len(low) == 0:  # none (at level 0 a node's neighbours are the moves from its cell)
        return np.zeros(len(centre) + 1, dtype=np.int64), low, np.zeros(0, dtype=np.float64)
    rows: tuple[IntArray, IntArray, FloatArray] = compiled().compressed_rows(
        low, high, centre, movement
    )
    return rows
