"""The general path finder: A* on one level of the grid pyramid (issue 6, part 3).

Zilberstein & Russell's PATH-FINDER plans between two positions of the same abstraction level,
minimising path length plus a weighted obstacleness term; at the base level it is the "standard
A*" baseline the anytime planner is compared with, so it is built to be a good A*:

- a binary heap (`heapq`) with lazy deletion (a cell's stale entries are skipped once the cell
  is closed); the g-values, parents and closed set are flat numpy arrays over the cells of a grid
  padded with one impassable cell on every side, so no move needs a bounds check;
- a consistent heuristic: Manhattan distance (4-connected) or octile distance (8-connected)
  times the cheapest cost per unit of length of any enterable cell;
- ties in f broken toward larger g (heap key `(f, -g, counter)`): on an open grid A* then runs
  straight to the goal instead of expanding every cell with the same f.

Cost model. A step of geometric length L (1 straight, sqrt 2 diagonal) into cell c costs
`L * (1 + weight * obstacleness[c])`: the obstacleness term is charged per unit of length
travelled inside the cell entered, so a diagonal through a half-blocked cell costs sqrt 2 times
a straight one, and with `weight=0` the cost is the geometric length. Grids are indexed
`[y, x]`, positions are `(x, y)` with (0, 0) upper left, as in MovingAI files. Diagonal moves
(movement 8) need both orthogonal neighbours passable: no corner cutting, the MovingAI rule.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from types import ModuleType
from typing import Any

import numpy as np
import numpy.typing as npt
from attrs import frozen

from ..world import SQRT2

__all__ = ["GridAstar", "PathResult", "SearchLimit", "find_path", "find_path_to_box"]

Position = tuple[int, int]

_BLOCKED = -1.0  # the step multiplier of an impassable cell in the padded grid


_compiled: ModuleType | None = None


def compiled() -> ModuleType:
    """The planner's compiled searches (`corridor_search`), imported on the first call: numba
    is not loaded with the plugin, and a search pays no import statement after the first."""
    global _compiled
    if _compiled is None:
        from . import corridor_search

        _compiled = corridor_search
    return _compiled


#: What the planner's compiled refinement step (`corridor_search.refine_step`) did: refined a
#: segment; found none left to refine; went over its limit (the plan unchanged); found no path
#: (a broken abstraction). Here, not there: the planner reads them without loading numba.
STEP_REFINED, STEP_NONE_LEFT, STEP_OVER, STEP_NO_PATH = 0, 1, 2, 3


class SearchLimit(Exception):
    """The search used up its `limit` of expansions before it could answer."""

    def __init__(self, expansions: int) -> None:
        super().__init__(f"stopped after {expansions} expansions")
        self.expansions = expansions


@frozen
class PathResult:
    """A path found by `find_path`.

    Attributes:
        path: the cells visited, `(x, y)`, start to goal inclusive.
        length: the path's geometric length (straight steps 1, diagonal steps sqrt 2).
        cost: the minimised cost, length plus the weighted obstacleness term.
        expansions: the cells A* expanded (the goal, popped last, is not counted).
    """

    path: tuple[Position, ...]
    length: float
    cost: float
    expansions: int


def find_path(
    cost: npt.ArrayLike,
    start: Position,
    goal: Position,
    *,
    movement: int = 4,
    weight: float = 1.0,
    impassable: npt.ArrayLike | None = None,
    ctx: Any = None,
) -> PathResult | None:
    """A cheapest path from `start` to `goal`, or None when the goal cannot be reached.

    Args:
        cost: obstacleness per cell in [0, 1], indexed `[y, x]`; a boolean blocked grid is read
            as 0/1.
        start: the start cell `(x, y)`.
        goal: the goal cell `(x, y)`.
        movement: 4 (straight moves) or 8 (octile, no corner cutting).
        weight: how much obstacleness costs per unit of length (>= 0).
        impassable: cells that cannot be entered, same shape as `cost`; by default those with
            obstacleness >= 1 (at the base level: the blocked cells).
        ctx: a `Context`; when given, each expansion is reported with `ctx.tick(1)`, so the work
            is measured in expansions.

    Returns:
        The path, or None when no path exists, including when the start or the goal is itself
        impassable. The work done before unreachability was proved is still reported to `ctx`.

    Raises:
        ValueError: a grid that is not 2-D, negative obstacleness, a start or goal outside the
            grid, an unknown movement or a negative weight.
    """
    gx, gy = _pair(goal, "goal")
    return find_path_to_box(
        cost,
        [start],
        (gx, gy, gx, gy),
        movement=movement,
        weight=weight,
        impassable=impassable,
        ctx=ctx,
    )


def find_path_to_box(
    cost: npt.ArrayLike,
    sources: Sequence[Position],
    box: tuple[int, int, int, int],
    *,
    movement: int = 4,
    weight: float = 1.0,
    impassable: npt.ArrayLike | None = None,
    ctx: Any = None,
    source_costs: Sequence[float] | None = None,
    box_costs: npt.ArrayLike | None = None,
    limit: float = math.inf,
) -> PathResult | None:
    """A cheapest path from any of `sources` to any cell of the rectangle `box`
    = (x0, y0, x1, y1), inclusive; `find_path` is the case of one source and a one-cell box.

    `source_costs` (one per source) and `box_costs` (shape of the box, `[y, x]`) are extra
    costs, >= 0, of starting at a source and of ending at a box cell: the path minimises their
    sum with the path's own cost (`PathResult.cost` includes them); a negative box cost says the
    path may not end at that cell (it may still cross it). `limit` bounds the
    expansions: reaching it raises `SearchLimit` (an anytime caller's deadline). The heuristic
    is the Manhattan or octile distance to the nearest cell of the box (still consistent).
    Impassable sources are ignored and impassable box cells cannot be reached; otherwise as
    `find_path`.
    """
    obstacleness, blocked, weight = _grids(cost, weight, impassable, movement)
    height, width = obstacleness.shape
    starts = [_cell(source, width, height, "start") for source in sources]
    initial = [0.0] * len(starts) if source_costs is None else [float(c) for c in source_costs]
    if len(initial) != len(starts):
        raise ValueError(f"{len(initial)} source costs for {len(starts)} sources")
    bx0, by0 = _cell(box[:2], width, height, "goal")
    bx1, by1 = _cell(box[2:], width, height, "goal")
    if bx1 < bx0 or by1 < by0:
        raise ValueError(f"the goal box {box} is empty")
    usable = [(xy, c) for xy, c in zip(starts, initial, strict=True) if not blocked[xy[1], xy[0]]]
    if not usable or blocked[by0 : by1 + 1, bx0 : bx1 + 1].all():
        return None

    padded, unit = _multipliers(obstacleness, blocked, weight)
    stride = width + 2
    size = padded.size
    g_values = np.full(size, math.inf)
    parents = np.empty(size, dtype=np.int64)  # read only along the path found, all written
    closed = np.zeros(size, dtype=np.uint8)
    # Memoryviews index the numpy buffers several times faster than numpy scalar indexing (and,
    # measured, beat converting them to lists: 0.15 vs 0.19 s on a 512x512 problem).
    mult = padded.ravel().data.cast("B").cast("d")
    g = g_values.data.cast("B").cast("d")
    parent = parents.data.cast("B").cast("q")
    done = closed.data
    # The cost of ending at each cell, -1 where the search may not end.
    ending = np.full((height + 2, stride), -1.0)
    ending[by0 + 1 : by1 + 2, bx0 + 1 : bx1 + 2] = 0.0 if box_costs is None else box_costs
    target = ending.ravel().data.cast("B").cast("d")
    # Padded coordinates of the box: the heuristic is the distance to its nearest cell.
    tx0, ty0, tx1, ty1 = bx0 + 1, by0 + 1, bx1 + 1, by1 + 1

    straight = ((1, 1, 0), (-1, -1, 0), (stride, 0, 1), (-stride, 0, -1))
    diagonal = (
        ((stride + 1, 1, 1), 1, stride),
        ((stride - 1, -1, 1), -1, stride),
        ((1 - stride, 1, -1), 1, -stride),
        ((-1 - stride, -1, -1), -1, -stride),
    )
    octile = movement == 8
    diagonal_unit = unit * (SQRT2 - 1.0)
    tick = ctx.tick if ctx is not None else None
    push, pop = heapq.heappush, heapq.heappop

    heap: list[tuple[float, float, int, int]] = []
    counter = 0
    for (sx, sy), g0 in usable:
        source = (sy + 1) * stride + sx + 1
        if g0 >= g[source]:
            continue
        g[source] = g0
        parent[source] = -1
        dx = tx0 - sx - 1 if sx + 1 < tx0 else sx + 1 - tx1 if sx + 1 > tx1 else 0
        dy = ty0 - sy - 1 if sy + 1 < ty0 else sy + 1 - ty1 if sy + 1 > ty1 else 0
        h0 = unit * (dx + dy) if not octile else unit * max(dx, dy) + diagonal_unit * min(dx, dy)
        counter += 1
        heap.append((g0 + h0, -g0, counter, source))
    heapq.heapify(heap)
    expansions = 0
    while heap:
        node = pop(heap)[3]
        if node < 0:  # ending at a box cell, the cheapest way to end
            node = -1 - node
            break
        if done[node]:
            continue  # a stale entry: the cell was closed with a smaller g
        end = target[node]
        if end == 0.0:
            break  # ending here costs nothing more: nothing left on the heap is cheaper
        if end > 0.0:  # ending here costs `end` more: a virtual entry competes with the rest
            counter += 1
            push(heap, (g[node] + end, -(g[node] + end), counter, -1 - node))
        if expansions + 1 > limit:
            raise SearchLimit(expansions)
        done[node] = 1
        expansions += 1
        if tick is not None:
            tick(1)
        g_node = g[node]
        y, x = divmod(node, stride)
        for offset, ddx, ddy in straight:
            neighbour = node + offset
            m = mult[neighbour]
            if m < 0.0 or done[neighbour]:
                continue
            g_new = g_node + m
            if g_new < g[neighbour]:
                g[neighbour] = g_new
                parent[neighbour] = node
                nx, ny = x + ddx, y + ddy
                dx = tx0 - nx if nx < tx0 else nx - tx1 if nx > tx1 else 0
                dy = ty0 - ny if ny < ty0 else ny - ty1 if ny > ty1 else 0
                if octile:
                    h = (
                        unit * dx + diagonal_unit * dy
                        if dx > dy
                        else unit * dy + diagonal_unit * dx
                    )
                else:
                    h = unit * (dx + dy)
                counter += 1
                push(heap, (g_new + h, -g_new, counter, neighbour))
        if not octile:
            continue
        for (offset, ddx, ddy), across, along in diagonal:
            neighbour = node + offset
            m = mult[neighbour]
            if m < 0.0 or done[neighbour] or mult[node + across] < 0.0 or mult[node + along] < 0.0:
                continue
            g_new = g_node + SQRT2 * m
            if g_new < g[neighbour]:
                g[neighbour] = g_new
                parent[neighbour] = node
                nx, ny = x + ddx, y + ddy
                dx = tx0 - nx if nx < tx0 else nx - tx1 if nx > tx1 else 0
                dy = ty0 - ny if ny < ty0 else ny - ty1 if ny > ty1 else 0
                h = unit * dx + diagonal_unit * dy if dx > dy else unit * dy + diagonal_unit * dx
                counter += 1
                push(heap, (g_new + h, -g_new, counter, neighbour))
    else:
        return None

    cells = [node]
    while parent[cells[-1]] >= 0:
        cells.append(parent[cells[-1]])
    cells.reverse()
    path = tuple((c % stride - 1, c // stride - 1) for c in cells)
    diagonals = sum(
        1 for a, b in zip(cells, cells[1:], strict=False) if abs(b - a) not in (1, stride)
    )
    length = (len(cells) - 1 - diagonals) + SQRT2 * diagonals
    return PathResult(
        path=path, length=length, cost=g[node] + max(target[node], 0.0), expansions=expansions
    )


def _grids(
    cost: npt.ArrayLike, weight: float, impassable: npt.ArrayLike | None, movement: int
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_], float]:
    """The obstacleness and impassable grids `find_path_to_box` reads, checked, and the weight
    as a float."""
    obstacleness = np.asarray(cost, dtype=np.float64)
    if obstacleness.ndim != 2:
        raise ValueError(f"cost must be a 2-D grid indexed [y, x], got shape {obstacleness.shape}")
    if movement not in (4, 8):
        raise ValueError(f"movement must be 4 or 8, got {movement!r}")
    weight = float(weight)
    if not weight >= 0.0 or math.isinf(weight):
        raise ValueError(f"weight must be finite and >= 0, got {weight!r}")
    if obstacleness.size and not obstacleness.min() >= 0.0:
        raise ValueError("obstacleness must be >= 0 (and not NaN)")
    if impassable is None:
        blocked = obstacleness >= 1.0
    else:
        blocked = np.asarray(impassable, dtype=bool)
        if blocked.shape != obstacleness.shape:
            raise ValueError(
                f"impassable has shape {blocked.shape}, cost has shape {obstacleness.shape}"
            )
    return obstacleness, blocked, weight


def _multipliers(
    obstacleness: npt.NDArray[np.float64], blocked: npt.NDArray[np.bool_], weight: float
) -> tuple[npt.NDArray[np.float64], float]:
    """The step multiplier 1 + weight * obstacleness per cell of the grid padded with one
    impassable cell on every side (_BLOCKED where impassable), and the heuristic's unit."""
    height, width = obstacleness.shape
    padded = np.empty((height + 2, width + 2))
    padded[[0, -1], :] = _BLOCKED
    padded[:, [0, -1]] = _BLOCKED
    inner = padded[1:-1, 1:-1]
    np.multiply(obstacleness, weight, out=inner)
    inner += 1.0
    np.copyto(inner, _BLOCKED, where=blocked)
    # The cheapest cost per unit of length anywhere scales the heuristic: every step costs at
    # least this much per unit of length it covers, so the heuristic stays consistent.
    unit = 1.0 if weight == 0.0 else float(np.min(inner, where=~blocked, initial=math.inf))
    return padded, unit


class GridAstar:
    """`find_path` compiled (numba: `corridor_search.grid_astar`), for many queries on one map:
    the same moves, costs, heuristic and tie-breaking (heap key `(f, -g, counter)`), so the same
    path and expansions as `find_path`, several times faster. It is the baseline the anytime
    planner is measured against (benchmarks/bench_navigation.py) and `anytime plan --planner
    astar`.

    Building one checks and pads the map once and allocates its scratch arrays (one entry per
    cell, stamped with a query number instead of cleared), so a query costs its search alone.
    The first query of a process loads the compiled search from numba's cache (`compiled()`).
    The work is reported to `ctx` in one `ctx.tick(expansions)` at the end: a compiled search
    cannot be interrupted (`find_path` with a `ctx` can).
    """

    def __init__(
        self,
        cost: npt.ArrayLike,
        *,
        movement: int = 4,
        weight: float = 1.0,
        impassable: npt.ArrayLike | None = None,
    ) -> None:
        obstacleness, blocked, weight = _grids(cost, weight, impassable, movement)
        self.shape = obstacleness.shape
        self.movement = movement
        padded, self.unit = _multipliers(obstacleness, blocked, weight)
        self.stride = padded.shape[1]
        self.mult = padded.ravel()
        size = self.mult.size
        self.g = np.empty(size)
        self.parent = np.empty(size, dtype=np.int64)
        self.seen = np.zeros(size, dtype=np.int64)
        self.done = np.zeros(size, dtype=np.int64)
        self.generation = 0

    def find_path(self, start: Position, goal: Position, *, ctx: Any = None) -> PathResult | None:
        """A cheapest path from `start` to `goal`, as `find_path` finds it, or None."""
        height, width = self.shape
        sx, sy = _cell(start, width, height, "start")
        gx, gy = _cell(goal, width, height, "goal")
        stride = self.stride
        source, target = (sy + 1) * stride + sx + 1, (gy + 1) * stride + gx + 1
        if self.mult[source] < 0.0 or self.mult[target] < 0.0:
            return None
        self.generation += 1
        cells, cost, expansions = compiled().grid_astar(
            self.mult,
            stride,
            source,
            target,
            gx + 1,
            gy + 1,
            self.movement == 8,
            self.unit,
            self.g,
            self.parent,
            self.seen,
            self.done,
            self.generation,
        )
        if ctx is not None:
            ctx.tick(expansions)
        if not len(cells):
            return None
        steps = np.abs(np.diff(cells))
        diagonals = int(np.count_nonzero((steps != 1) & (steps != stride)))
        length = (len(cells) - 1 - diagonals) + SQRT2 * diagonals
        xs, ys = (cells % stride - 1).tolist(), (cells // stride - 1).tolist()
        return PathResult(
            path=tuple(zip(xs, ys, strict=True)),
            length=length,
            cost=float(cost),
            expansions=int(expansions),
        )


def _pair(position: Position, what: str) -> Position:
    try:
        x, y = (int(v) for v in position)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be an (x, y) pair of integers, got {position!r}") from None
    return x, y


def _cell(position: Position, width: int, height: int, what: str) -> Position:
    x, y = _pair(position, what)
    if not (0 <= x < width and 0 <= y < height):
        raise ValueError(f"{what} {(x, y)} is outside the {width}x{height} grid")
    return x, y
