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
4. otherwise reached by obstacle avoidance, a myopic real-time search: LRTA* (Korf 1990) with
   a look-ahead of one move. The robot sees only its neighbouring cells; it moves to the
   neighbour with the least move cost + h, where h is the Manhattan (4) or octile (8) distance
   to the block, and first raises h of the cell it leaves to that least value (what it learned
   about that cell). On open ground this walks a shortest path; at an obstacle the plan did not
   know of it slides along it and, in a dead end, learns its way out, re-walking cells. LRTA*
   reaches the block whenever it is reachable (Korf's completeness result on finite graphs).

The robot never enters a blocked cell, every step is a legal move, and the route ends at the
goal whenever the goal is reachable from the start (the goal is the last waypoint and every
waypoint reachable is reached). An unreachable goal (or a blocked one) is not an error: the
result has `reached=False` and the route followed until then.

Why myopic. The plan is what the robot knows of the world beyond its sensors; execution must
not consult the true map at a distance, or a coarse plan would be as good as a refined one (a
search on the true map between far-apart waypoints is A*). So the quality of a coarse plan is
what it is in the papers: short where the plan's blocks are free, long where the robot has to
feel its way around obstacles the plan glossed over.

What it costs. The cells reachable from the start are labelled once per call (connected
components, vectorised, O(N^2), not counted: it only lets the robot skip waypoints it could
never reach). Steps 1 to 3 cost O(1) per waypoint. Step 4 counts one unit of work per
neighbour looked at (`Execution.expansions`, reported with `ctx.tick`): at most 8 per step
walked. LRTA*'s steps are bounded by O(F^2) for F reachable cells (each step raises some h or
moves closer); in practice a detour costs a few times its length. As a guard against that
quadratic worst case, after `patience * F` steps toward one waypoint the robot is guided the
rest of the way by A*. A fully refined plan computed on the true map costs 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from attrs import frozen
from scipy import ndimage

from anytime.modules import Context

from .abstraction import cell_bounds
from .planner import MultiPath
from .search import SQRT2, find_path, find_path_to_box
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
    patience: float = 4.0,
) -> Execution:
    """Follow `plan` on the true map `blocked` (see the module docstring).

    Args:
        plan: a `MultiPath` at any mix of levels, or a plain sequence of base cells (x, y) from
            the start to the goal (consecutive cells need not be neighbours, nor free).
        blocked: the true map, `blocked[y, x]`.
        movement: 4 or 8 (octile, no corner cutting).
        ctx: a `Context`; each obstacle-avoidance expansion is reported with `ctx.tick(1)`.
        patience: how long LRTA* may wander, in steps per cell of the robot's component,
            before A* guides it (see `_real_time_into`).

    Raises:
        ValueError: an empty plan, a start or a waypoint outside the grid, a blocked start, an
            unknown movement or a patience <= 0.
    """
    grid = np.asarray(blocked, dtype=bool)
    if grid.ndim != 2:
        raise ValueError(f"the map must be a 2-D grid blocked[y, x], got shape {grid.shape}")
    if movement not in (4, 8):
        raise ValueError(f"movement must be 4 or 8, got {movement!r}")
    if not patience > 0:
        raise ValueError(f"patience must be > 0, got {patience}")
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
        path, work = _real_time_into(grid, ok, route[-1], (x0, y0, x1, y1), movement, patience)
        expansions += work
        if tick is not None:
            tick(work)
        route.extend(path[1:])
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


def _real_time_into(
    grid: BoolGrid, ok: BoolGrid, position: Position, box: Box, movement: int, patience: float
) -> tuple[list[Position], int]:
    """Obstacle avoidance toward `box`: LRTA* with a look-ahead of one move (see the module
    docstring). Returns the cells walked (`position` first) and the moves looked at.

    After `patience` times as many steps as the robot's component has cells (never reached in
    the tests, but LRTA*'s worst case is quadratic), the robot is guided the rest of the way by
    A* (`search.find_path_to_box`) on the true map, so that execution always ends."""
    height, width = grid.shape
    x0, y0, x1, y1 = box
    octile = movement == 8
    moves = _STRAIGHT if not octile else _STRAIGHT + _DIAGONAL
    learned: dict[Position, float] = {}

    def distance(x: int, y: int) -> float:
        dx = x0 - x if x < x0 else (x - x1 + 1 if x >= x1 else 0)
        dy = y0 - y if y < y0 else (y - y1 + 1 if y >= y1 else 0)
        if octile:
            return max(dx, dy) + (SQRT2 - 1.0) * min(dx, dy)
        return float(dx + dy)

    path = [position]
    limit = patience * float(np.count_nonzero(ok))
    work = 0
    x, y = position
    while not (x0 <= x < x1 and y0 <= y < y1):
        if len(path) > limit:
            rest = find_path_to_box(
                grid.astype(np.float64),
                [(x, y)],
                (x0, y0, x1 - 1, y1 - 1),
                movement=movement,
                weight=0.0,
                impassable=~ok,
            )
            assert rest is not None  # the caller checked that the box has a reachable cell
            return path + list(rest.path[1:]), work + rest.expansions
        best, best_f = (x, y), math.inf
        for dx, dy in moves:
            nx, ny = x + dx, y + dy
            if not (0 <= nx < width and 0 <= ny < height) or grid[ny, nx]:
                continue
            if dx and dy and (grid[y, nx] or grid[ny, x]):
                continue  # no corner cutting
            work += 1
            f = (SQRT2 if dx and dy else 1.0) + learned.get((nx, ny), distance(nx, ny))
            if f < best_f:
                best, best_f = (nx, ny), f
        learned[(x, y)] = max(learned.get((x, y), distance(x, y)), best_f)
        x, y = best
        path.append(best)
    return path, work
