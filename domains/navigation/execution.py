"""Plan execution (Zilberstein & Russell, "Plan execution"): follow a plan of any mix of
abstraction levels on the *true* map, filling in what the plan leaves out with an
obstacle-avoidance procedure, and measure the plan's quality as the papers define it,
optimal length / executed length.

What it does. The plan is reduced to a list of waypoints (`waypoints`): the cells of its parts
in order, each a (level, cell) pair; a level-k cell means "get into that 2^k x 2^k block of base
cells" (`abstraction.cell_bounds`). Junction cells repeated by consecutive segments, and a
waypoint whose block contains the one before it (already reached) or the one after it (reached
on the way to that one), are dropped; the last waypoint is the goal's own base cell. From the
robot's base cell, each waypoint in turn is

1. already reached when the robot is inside its block (no move);
2. skipped when its block has no free cell reachable from the start on the true map (a cell the
   noisy map planned through is in fact blocked, or walled off);
3. reached in one step when a legal move (4- or 8-connected, no corner cutting) enters a free
   cell of the block, a straight move in preference to a diagonal: this is how a fully refined
   plan of free cells is followed, verbatim and with no search;
4. otherwise reached by obstacle avoidance: A* with step costs the geometric length (1 straight,
   sqrt 2 diagonal) on the true grid, from the robot's cell to the nearest free cell of the
   block (a multi-target search: its heuristic is the Manhattan or octile distance to the
   block's rectangle, consistent, so the first block cell popped is a nearest one), restricted
   to a local window: the bounding box of the robot's cell and the block plus `margin` cells on
   every side. When the window cuts every way in off, the margin doubles and the search is
   repeated, up to the whole map, where it cannot fail (step 2 kept only reachable cells).

The robot never enters a blocked cell, every step is a legal move, and the route ends at the
goal whenever the goal is reachable from the start (the goal is the last waypoint and every
waypoint reachable is reached). An unreachable goal (or a blocked one) is not an error: the
result has `reached=False` and the route followed until then.

What it costs. The cells reachable from the start are labelled once per call (connected
components, vectorised numpy/scipy over the whole map, O(N^2) and not counted as work). Steps 1
to 3 cost O(1) per waypoint (and a numpy test on the block's cells). Only step 4 counts, in A*
expansions (`Execution.expansions`, and one `ctx.tick` each). A search expands each free cell of
its window at most once; its window is the bounding box of the robot and the block grown by the
margin m, and each failure doubles m, so one waypoint costs at most 1 + ceil(log2(N / m))
windows (m >= 1; an N x N map), hence at most (1 + ceil(log2(N / m))) * F expansions, F the
free cells of the map, and the whole execution at most that times the number of waypoints. In
practice the first window succeeds and a waypoint costs the A* expansions of one local detour
(the cells of its window at most); a fully refined plan computed on the true map costs 0.

A waypoint far from the robot gives a large window: the one-cell top-level plan reduces to the
waypoints start and goal, and its "obstacle avoidance" is then A* over the whole map, with the
optimal length (quality 1) for the cost of A*. Refined plans make the robot pass through the
blocks they name, so their quality can be below that of the first plan.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Sequence

import numpy as np
from attrs import frozen
from scipy import ndimage

from anytime.modules import Context

from .abstraction import cell_bounds
from .planner import MultiPath
from .search import SQRT2, find_path
from .world import BoolGrid, Position

__all__ = [
    "Execution",
    "execute",
    "optimal_length",
    "plan_quality",
    "route_length",
    "waypoints",
]

Waypoint = tuple[int, Position]
Box = tuple[int, int, int, int]  # (x0, y0, x1, y1), half-open: blocked[y0:y1, x0:x1]

#: 4-connectivity, which is also reachability under octile moves without corner cutting (see
#: `world`).
_FOUR = ndimage.generate_binary_structure(2, 1)
_STRAIGHT = ((1, 0), (-1, 0), (0, 1), (0, -1))
_DIAGONAL = ((1, 1), (-1, 1), (1, -1), (-1, -1))


@frozen
class Execution:
    """An executed route.

    Attributes:
        route: the base cells visited, start to goal inclusive (to the last cell reached when
            the goal is unreachable); consecutive cells are one legal move apart.
        length: the route's geometric length (straight steps 1, diagonal steps sqrt 2).
        expansions: the A* expansions of obstacle avoidance; 0 when the plan was followed
            verbatim.
        reached: whether the route ends at the goal (False only when the goal is unreachable
            from the start on the true map).
    """

    route: tuple[Position, ...]
    length: float
    expansions: int
    reached: bool


def waypoints(plan: MultiPath) -> list[Waypoint]:
    """The plan's waypoints, (level, cell) in order, from the cells of `plan.parts`.

    A waypoint is dropped when its block contains the previous one kept (the robot is already
    inside it: a junction cell repeated, or a coarser segment starting where a finer one ended,
    or SEGMENTIZE(start) going up) or when it contains the next one (getting into the next one
    gets into it: a coarse segment ending where a finer one starts, or SEGMENTIZE(goal) going
    down). The first waypoint is the start's base cell, the last the goal's.
    """
    kept: list[tuple[int, Position, Box]] = [(0, plan.start, cell_bounds(plan.start, 0))]
    sequence = [(s.level, c) for s in plan.parts for c in s.cells] + [(0, plan.goal)]
    for level, cell in sequence:
        box = cell_bounds(cell, level)
        if _contains(box, kept[-1][2]):
            continue
        while len(kept) > 1 and _contains(kept[-1][2], box):
            kept.pop()
        if _contains(box, kept[-1][2]):
            continue
        kept.append((level, cell, box))
    return [(level, cell) for level, cell, _ in kept]


def execute(
    plan: MultiPath | Sequence[Position],
    blocked: BoolGrid,
    *,
    movement: int = 4,
    ctx: Context | None = None,
    margin: int = 4,
) -> Execution:
    """Follow `plan` on the true map `blocked` (see the module docstring).

    Args:
        plan: a `MultiPath` at any mix of levels, or a plain sequence of base cells (x, y) from
            the start to the goal (consecutive cells need not be neighbours, nor free).
        blocked: the true map, `blocked[y, x]`.
        movement: 4 or 8 (octile, no corner cutting).
        ctx: a `Context`; each obstacle-avoidance expansion is reported with `ctx.tick(1)`.
        margin: the cells added on every side of the first local window of obstacle avoidance.

    Raises:
        ValueError: an empty plan, a start or a waypoint outside the grid, a blocked start, an
            unknown movement or a negative margin.
    """
    grid = np.asarray(blocked, dtype=bool)
    if grid.ndim != 2:
        raise ValueError(f"the map must be a 2-D grid blocked[y, x], got shape {grid.shape}")
    if movement not in (4, 8):
        raise ValueError(f"movement must be 4 or 8, got {movement!r}")
    if margin < 0:
        raise ValueError(f"margin must be >= 0, got {margin}")
    if isinstance(plan, MultiPath):
        start, goal = plan.start, plan.goal
        points = waypoints(plan)
    else:
        cells = [(int(x), int(y)) for x, y in plan]
        if not cells:
            raise ValueError("a plan needs at least one cell")
        start, goal = cells[0], cells[-1]
        points = [(0, c) for c in cells]
    height, width = grid.shape
    boxes = [_clip(cell_bounds(c, level), width, height, (level, c)) for level, c in points]
    sx, sy = start
    if grid[sy, sx]:
        raise ValueError(f"the start {start} is a blocked cell")

    # The cells reachable from the start: 4-connected components (also octile reachability
    # without corner cutting). Every cell the robot stands on is one of them.
    labels, _ = ndimage.label(~grid, structure=_FOUR)
    ok = np.asarray(labels == labels[sy, sx])
    tick = ctx.tick if ctx is not None else None

    route: list[Position] = [start]
    expansions = 0
    for x0, y0, x1, y1 in boxes:
        x, y = route[-1]
        if x0 <= x < x1 and y0 <= y < y1:
            continue
        if not ok[y0:y1, x0:x1].any():
            continue  # nothing of this block can be reached: skip the waypoint
        step = _step_into(grid, ok, route[-1], (x0, y0, x1, y1), movement)
        if step is not None:
            route.append(step)
            continue
        m = margin
        while True:
            window = (
                max(0, min(x, x0) - m),
                max(0, min(y, y0) - m),
                min(width, max(x + 1, x1) + m),
                min(height, max(y + 1, y1) + m),
            )
            path, work = _search_into(grid, ok, route[-1], (x0, y0, x1, y1), window, movement, tick)
            expansions += work
            if path is not None:
                route.extend(path[1:])
                break
            if window == (0, 0, width, height):  # pragma: no cover - ok says it is reachable
                raise AssertionError(f"no way into {(x0, y0, x1, y1)} from {route[-1]}")
            m = max(1, 2 * m)
    return Execution(
        route=tuple(route),
        length=route_length(route),
        expansions=expansions,
        reached=route[-1] == goal,
    )


def route_length(route: Sequence[Position]) -> float:
    """The geometric length of a route of unit moves: 1 per straight, sqrt 2 per diagonal
    step."""
    if len(route) < 2:
        return 0.0
    steps = np.abs(np.diff(np.asarray(route, dtype=np.int64), axis=0))
    diagonals = int(np.count_nonzero(steps.min(axis=1)))
    return (len(route) - 1 - diagonals) + SQRT2 * diagonals


def optimal_length(
    blocked: BoolGrid, start: Position, goal: Position, *, movement: int = 4
) -> float | None:
    """The length of a shortest route on the true map (A* with weight 0), None when the goal is
    unreachable from the start."""
    found = find_path(blocked, start, goal, movement=movement, weight=0.0)
    return None if found is None else found.length


def plan_quality(executed_length: float, optimal: float) -> float:
    """The papers' plan quality: optimal length / executed length, clipped to [0, 1] (rounding
    can make a route of optimal length a hair shorter). 1.0 when both are 0 (start = goal), 0.0
    for an infinite executed length (a goal never reached).

    Raises:
        ValueError: a negative or NaN length, or an executed length of 0 with a positive
            optimal one (no route is shorter than the optimum).
    """
    executed, best = float(executed_length), float(optimal)
    if not (executed >= 0.0 and best >= 0.0):
        raise ValueError(f"lengths must be >= 0, got {executed_length!r} and {optimal!r}")
    if executed == 0.0:
        if best > 0.0:
            raise ValueError(f"an executed length of 0 cannot beat an optimal one of {best}")
        return 1.0
    return min(1.0, max(0.0, best / executed))


def _contains(outer: Box, inner: Box) -> bool:
    ox0, oy0, ox1, oy1 = outer
    ix0, iy0, ix1, iy1 = inner
    return ox0 <= ix0 and oy0 <= iy0 and ix1 <= ox1 and iy1 <= oy1


def _clip(box: Box, width: int, height: int, what: Waypoint) -> Box:
    x0, y0, x1, y1 = max(0, box[0]), max(0, box[1]), min(width, box[2]), min(height, box[3])
    if x0 >= x1 or y0 >= y1:
        level, cell = what
        raise ValueError(f"waypoint {cell} at level {level} is outside the {width}x{height} grid")
    return (x0, y0, x1, y1)


def _step_into(
    grid: BoolGrid, ok: BoolGrid, position: Position, box: Box, movement: int
) -> Position | None:
    """A cell of `box` reachable (per `ok`) one legal move from `position`, straight moves
    first; None when there is none."""
    x, y = position
    x0, y0, x1, y1 = box
    for dx, dy in _STRAIGHT if movement == 4 else _STRAIGHT + _DIAGONAL:
        nx, ny = x + dx, y + dy
        if not (x0 <= nx < x1 and y0 <= ny < y1) or not ok[ny, nx]:
            continue
        if dx and dy and (grid[y, nx] or grid[ny, x]):
            continue  # no corner cutting
        return (nx, ny)
    return None


def _search_into(
    grid: BoolGrid,
    ok: BoolGrid,
    position: Position,
    box: Box,
    window: Box,
    movement: int,
    tick: Callable[[float], None] | None,
) -> tuple[list[Position] | None, int]:
    """A* inside `window` from `position` to the nearest cell of `box` that `ok` marks: the
    path (global cells, `position` first) or None, and the expansions.

    Flat arrays over the window padded with one impassable cell on every side, as in
    `search.find_path`; the heuristic is the Manhattan (4) or octile (8) distance to the box's
    rectangle, which is consistent; ties in f go to the larger g.
    """
    wx0, wy0, wx1, wy1 = window
    stride = wx1 - wx0 + 2
    padded = np.zeros((wy1 - wy0 + 2, stride), dtype=np.uint8)
    padded[1:-1, 1:-1] = ~grid[wy0:wy1, wx0:wx1]
    targets = np.zeros_like(padded)
    bx0, by0, bx1, by1 = box
    targets[by0 - wy0 + 1 : by1 - wy0 + 1, bx0 - wx0 + 1 : bx1 - wx0 + 1] = ok[by0:by1, bx0:bx1]
    free = padded.ravel().tobytes()
    goal = targets.ravel().tobytes()
    # The box's rectangle in padded window coordinates, inclusive.
    rx0, ry0, rx1, ry1 = bx0 - wx0 + 1, by0 - wy0 + 1, bx1 - wx0, by1 - wy0
    octile = movement == 8
    diagonal_extra = SQRT2 - 1.0

    def heuristic(node: int) -> float:
        ny, nx = divmod(node, stride)
        dx = rx0 - nx if nx < rx0 else (nx - rx1 if nx > rx1 else 0)
        dy = ry0 - ny if ny < ry0 else (ny - ry1 if ny > ry1 else 0)
        if octile:
            return max(dx, dy) + diagonal_extra * min(dx, dy)
        return float(dx + dy)

    straight = (1, -1, stride, -stride)
    diagonal = (
        (stride + 1, 1, stride),
        (stride - 1, -1, stride),
        (1 - stride, 1, -stride),
        (-1 - stride, -1, -stride),
    )
    size = padded.size
    g = [math.inf] * size
    parent = [0] * size
    closed = bytearray(size)
    source = (position[1] - wy0 + 1) * stride + position[0] - wx0 + 1
    g[source] = 0.0
    heap: list[tuple[float, float, int, int]] = [(heuristic(source), -0.0, 0, source)]
    counter = expansions = 0
    push, pop = heapq.heappush, heapq.heappop
    found = -1
    while heap:
        node = pop(heap)[3]
        if closed[node]:
            continue
        if goal[node]:
            found = node
            break
        closed[node] = 1
        expansions += 1
        if tick is not None:
            tick(1)
        g_node = g[node]
        moves = [(n, 1.0) for n in (node + o for o in straight)]
        if octile:
            moves += [
                (node + o, SQRT2)
                for o, across, along in diagonal
                if free[node + across] and free[node + along]
            ]
        for neighbour, step in moves:
            if not free[neighbour] or closed[neighbour]:
                continue
            g_new = g_node + step
            if g_new < g[neighbour]:
                g[neighbour] = g_new
                parent[neighbour] = node
                counter += 1
                push(heap, (g_new + heuristic(neighbour), -g_new, counter, neighbour))
    if found < 0:
        return None, expansions
    cells = [found]
    while cells[-1] != source:
        cells.append(parent[cells[-1]])
    cells.reverse()
    return [(c % stride - 1 + wx0, c // stride - 1 + wy0) for c in cells], expansions
