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
4. otherwise reached by obstacle avoidance, planning with the free-space assumption (Stentz's
   D*, Koenig & Likhachev's D* Lite setting): the robot sees the eight cells around it and
   remembers every blocked cell it has seen (`memory`); it plans with A* on that memory (every
   cell not seen blocked counts as free) into the block, walks the path, and plans again from
   where it stands when a cell seen blocked is in the way. Each re-plan follows the discovery
   of a blocked cell, so there are finitely many, and since the memory only holds truly blocked
   cells a path exists in it whenever the block is reachable: the robot always arrives.

   A plan made on the connectivity-aware abstraction says more than its blocks: each of its
   nodes is a connected free region of its block on the map planned on, and consecutive nodes
   are joined by a legal move. A robot told to trust it (`keep_to_plan`, for a plan made on the
   map it follows) keeps to the plan's *corridor* (`MultiPath.corridor`, the cells of its
   nodes) while a path into the block exists in it: on the map planned on, that is always, and
   a coarse plan through a maze or a room's door is followed without trying the other cells of
   its blocks. Where the true map cuts the corridor, the robot leaves it for that waypoint and
   feels its way as above. Not by default: on a sensed map, noise splits blocks, and a corridor
   of the sensed components leaves out free cells (measured on find-path's 128 x 128 sensed
   worlds, 2,000 per cell: at 100 ticks 0.974 against 0.993 at map quality 0.85, equal from
   400 ticks on).

   A robot told to give a waypoint up when the way to it turns long (`give_up`, the task's
   frames) stops feeling its way into a block once what it walked toward it and the path it
   plans on from there are longer than `give_up` times the block's distance from where it set
   out and than that distance plus `SLACK`, and aims for the next waypoint (never the goal):
   a plan made before the robot saw the walls around it may put a waypoint in a pocket that
   only the long way round reaches, a detour the plan never meant.

   A robot given its map (`believed`, with a `penalty`) plans its detours around the obstacles
   the map shows, each of their cells costing `penalty` cells more to cross than a free one,
   rather than through them: the frames give it the robot's map when the plan runs through
   cells blocked on the map it was made on (where that map walls the goal off, the planner
   opens the walls in the way and plans across them, `planner.atp`), where with the free-space
   assumption alone the robot felt its way along the wrong side of an obstacle it had read.
   Not impassable: vision's false obstacles are crossed at their cost.

The robot never enters a blocked cell, every step is a legal move, and the route ends at the
goal whenever the goal is reachable from the start (the goal is the last waypoint and every
waypoint reachable is reached). An unreachable goal (or a blocked one) is not an error: the
result has `reached=False` and the route followed until then.

Why short-sighted. The plan is what the robot knows of the world beyond its sensors; execution
must not consult the true map at a distance, or a coarse plan would be as good as a refined
one (a search on the true map between far-apart waypoints is A*). So the quality of a coarse
plan is what it is in the papers: short where the plan's blocks are free, long where the robot
has to feel its way around obstacles the plan glossed over.

What it costs. The cells reachable from the start are labelled once per call (connected
components, vectorised, O(N^2), not counted: it only lets the robot skip waypoints it could
never reach). Steps 1 to 3 cost O(1) per waypoint. Step 4 counts A* expansions
(`Execution.expansions`, reported with `ctx.tick`): one search per re-plan, each within the
bounding box of the robot and the block plus a margin of 8 cells (widened fourfold while it
finds nothing, up to the whole map), so a detour costs a few searches of its own size. A fully
refined plan computed on the true map costs 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from attrs import frozen

from anytime.plugin import Context

from ..planning.abstraction import cell_bounds
from ..planning.planner import MultiPath
from ..planning.search import find_path, find_path_to_box
from ..world import SQRT2, BoolGrid, Position, reachable

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

#: `execute(give_up=)`: a way to a waypoint is long only when it is longer than its distance
#: plus this many cells too (a small obstacle in the way of a near waypoint is no reason to give
#: it up).
SLACK = 8

#: `execute(believed=)`: the margin around the robot and the block of obstacle avoidance's first
#: search; the free-space assumption's 8 cells leave no room to go round an obstacle read wider.
MARGIN_BELIEVED = 24

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
    return [(level, cell) for level, cell, _ in _targets(plan)]


def _targets(plan: MultiPath) -> list[tuple[int, Position, int | None]]:
    """`waypoints` with the abstraction's node of each (None where the plan has none)."""
    kept: list[tuple[int, Position, int | None, Box]] = [
        (0, plan.start, None, cell_bounds(plan.start, 0))
    ]
    sequence = [
        (s.level, c, s.nodes[i] if s.nodes else None)
        for s in plan.parts
        for i, c in enumerate(s.cells)
    ] + [(0, plan.goal, None)]
    for level, cell, node in sequence:
        box = cell_bounds(cell, level)
        if _contains(box, kept[-1][3]):
            continue
        while len(kept) > 1 and _contains(kept[-1][3], box):
            kept.pop()
        if _contains(box, kept[-1][3]):
            continue
        kept.append((level, cell, node, box))
    return [(level, cell, node) for level, cell, node, _ in kept]


def execute(
    plan: MultiPath | Sequence[Position],
    blocked: BoolGrid,
    *,
    movement: int = 4,
    ctx: Context | None = None,
    memory: BoolGrid | None = None,
    keep_to_plan: bool = False,
    give_up: float | None = None,
    believed: npt.ArrayLike | None = None,
    penalty: float = 0.0,
) -> Execution:
    """Follow `plan` on the true map `blocked` (see the module docstring).

    Args:
        plan: a `MultiPath` at any mix of levels, or a plain sequence of base cells (x, y) from
            the start to the goal (consecutive cells need not be neighbours, nor free).
        blocked: the true map, `blocked[y, x]`.
        movement: 4 or 8 (octile, no corner cutting).
        ctx: a `Context`; each obstacle-avoidance expansion is reported with `ctx.tick(1)`.
        memory: the blocked cells the robot has seen so far, a writable boolean grid shaped like
            `blocked`, updated in place (a robot that executes plan after plan keeps it);
            default: nothing seen yet.
        keep_to_plan: keep to the plan's corridor (`MultiPath.corridor`) while it holds a way:
            for a plan made on the map it is followed on (a known map, as `anytime plan`'s).
            Off by default: on a sensed map the corridor may leave out free cells the noise
            hid, and a robot that feels its way does better early on (find-path's profile,
            measured on sensed maps, is of that robot).
        give_up: let the robot give a waypoint up when the way to it turns long: when what it
            walked toward a waypoint's block and the path it plans on from there on its memory
            (free-space assumption) are longer than `give_up` times the distance to the block
            from where it set out for it (Manhattan, or octile with 8
            moves) and longer than that distance plus `SLACK` cells, it aims for the next
            waypoint instead (never the goal's: the goal is always sought). For a plan made
            ahead of time on a map that did not yet hold what the robot saw since (the task's
            frames, whose plan is made while the segment before is walked): its waypoints may
            lie behind walls it has found, and reaching one the long way round only to come
            back is a detour the plan never meant. None (the default): every reachable
            waypoint is reached, as find-path's profile was measured.
        believed: the cells the robot's map says are blocked (a sensed map, with its errors),
            shaped like `blocked`: obstacle avoidance plans around them, each costing `penalty`
            cells more to cross than a free one, rather than through them as if free; they are
            not impassable (a false reading of one cell costs its `penalty`, a wide obstacle
            read as such costs its width times it). Only the memory's cells are impassable.
            Default: none (the free-space assumption alone, as find-path's profile was
            measured).
        penalty: the extra cost of crossing a `believed` cell, in cells (>= 0).

    Raises:
        ValueError: an empty plan, a start or a waypoint outside the grid, a blocked start, an
            unknown movement or a memory of the wrong shape.
    """
    grid = np.asarray(blocked, dtype=bool)
    if grid.ndim != 2:
        raise ValueError(f"the map must be a 2-D grid blocked[y, x], got shape {grid.shape}")
    if movement not in (4, 8):
        raise ValueError(f"movement must be 4 or 8, got {movement!r}")
    if give_up is not None and not give_up >= 1.0:
        raise ValueError(f"give_up must be >= 1 or None, got {give_up!r}")
    if not penalty >= 0.0 or math.isinf(penalty):
        raise ValueError(f"penalty must be finite and >= 0, got {penalty!r}")
    costs: np.ndarray | None = None
    if believed is not None and penalty > 0:
        costs = np.asarray(believed, dtype=np.float64)
        if costs.shape != grid.shape:
            raise ValueError(f"believed has shape {costs.shape}, the map {grid.shape}")
    regions: list[BoolGrid | None]
    corridor: BoolGrid | None = None
    if isinstance(plan, MultiPath):
        start, goal = plan.start, plan.goal
        targets = _targets(plan)
        points = [(level, cell) for level, cell, _ in targets]
        regions = [plan.region(level, node) for level, _, node in targets]
        corridor = plan.corridor() if keep_to_plan else None
    else:
        cells = [(int(x), int(y)) for x, y in plan]
        if not cells:
            raise ValueError("a plan needs at least one cell")
        start, goal = cells[0], cells[-1]
        points = [(0, c) for c in cells]
        regions = [None] * len(points)
    height, width = grid.shape
    boxes = [_clip(cell_bounds(c, level), width, height, (level, c)) for level, c in points]
    sx, sy = start
    if grid[sy, sx]:
        raise ValueError(f"the start {start} is a blocked cell")

    # The cells reachable from the start (the same for 4- and 8-connected moves, `world`).
    # Every cell the robot stands on is one of them.
    ok = reachable(grid, start)
    tick = ctx.tick if ctx is not None else None
    if memory is None:
        memory = np.zeros_like(grid)
    elif memory.shape != grid.shape:
        raise ValueError(f"the memory has shape {memory.shape}, the map {grid.shape}")

    route: list[Position] = [start]
    expansions = 0
    last = len(boxes) - 1
    for i, ((x0, y0, x1, y1), region) in enumerate(zip(boxes, regions, strict=True)):
        target = ok[y0:y1, x0:x1]
        if region is not None:  # the node's cells (as the plan's map says) that can be reached
            aimed = target & region[: y1 - y0, : x1 - x0]
            target = aimed if aimed.any() else target
        x, y = route[-1]
        if x0 <= x < x1 and y0 <= y < y1 and target[y - y0, x - x0]:
            continue
        if not target.any():
            continue  # nothing of this block can be reached: skip the waypoint
        step = _step_into(grid, target, route[-1], (x0, y0, x1, y1), movement)
        if step is not None:
            route.append(step)
            continue
        path, work = _feel_into(
            grid,
            memory,
            route[-1],
            (x0, y0, x1, y1),
            target,
            movement,
            corridor,
            give_up if i < last else None,
            costs,
            penalty,
        )
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
    grid: BoolGrid, target: BoolGrid, position: Position, box: Box, movement: int
) -> Position | None:
    """A cell of `box` that is a target (`target`, the box's mask) one legal move from
    `position`, straight moves first; None when there is none."""
    x, y = position
    x0, y0, x1, y1 = box
    for dx, dy in _STRAIGHT if movement == 4 else _STRAIGHT + _DIAGONAL:
        nx, ny = x + dx, y + dy
        if not (x0 <= nx < x1 and y0 <= ny < y1) or not target[ny - y0, nx - x0]:
            continue
        if dx and dy and (grid[y, nx] or grid[ny, x]):
            continue  # no corner cutting
        return (nx, ny)
    return None


def _feel_into(
    grid: BoolGrid,
    memory: BoolGrid,
    position: Position,
    box: Box,
    target: BoolGrid,
    movement: int,
    corridor: BoolGrid | None = None,
    give_up: float | None = None,
    believed: np.ndarray | None = None,
    penalty: float = 0.0,
) -> tuple[list[Position], int]:
    """Obstacle avoidance toward the `target` cells of `box` (a mask of the box) with the
    free-space assumption (see the module docstring): plan with A* on `memory` (the blocked
    cells the robot has seen; updated in place), walk the path, re-plan when a cell seen
    blocked is in the way. With `give_up`, stop (short of the box) when the cells walked and
    the path planned on from there are longer than `give_up` times the distance to the box from
    `position` and than that distance plus `SLACK`. With `believed`, its cells cost `penalty`
    more to cross (see `execute`), and the first search looks further around (`MARGIN_BELIEVED`):
    a detour around an obstacle the robot read is wider than one around a cell it bumped into.
    Returns the cells walked (`position` first) and the A* expansions."""
    height, width = grid.shape
    x0, y0, x1, y1 = box
    walked = [position]
    work = 0
    x, y = position
    _see(grid, memory, x, y)
    ending = np.where(target, 0.0, -1.0)
    if give_up is not None:
        near = _distance_to_box(x, y, box, movement)
        longest = max(give_up * near, near + SLACK)
    while not (x0 <= x < x1 and y0 <= y < y1 and target[y - y0, x - x0]):
        path = None
        margin = 8 if believed is None else MARGIN_BELIEVED
        while path is None:
            wx0, wy0 = max(0, min(x, x0) - margin), max(0, min(y, y0) - margin)
            wx1, wy1 = min(width, max(x + 1, x1) + margin), min(height, max(y + 1, y1) + margin)
            seen = memory[wy0:wy1, wx0:wx1]
            closed = seen
            if corridor is not None:  # the robot may stand outside it (having left it before)
                closed = seen | ~corridor[wy0:wy1, wx0:wx1]
                closed[y - wy0, x - wx0] = False
            found = find_path_to_box(
                seen if believed is None else believed[wy0:wy1, wx0:wx1],
                [(x - wx0, y - wy0)],
                (x0 - wx0, y0 - wy0, x1 - 1 - wx0, y1 - 1 - wy0),
                movement=movement,
                weight=penalty if believed is not None else 0.0,
                impassable=closed,
                box_costs=ending,  # only at a target: the box's other cells may be crossed
            )
            if found is not None:
                work += found.expansions
                path = [(cx + wx0, cy + wy0) for cx, cy in found.path]
            elif (wx0, wy0, wx1, wy1) != (0, 0, width, height):
                work += seen.size
                margin *= 4
            elif corridor is not None:  # the plan's corridor is cut on the true map: leave it
                work += seen.size
                corridor, margin = None, 8
            else:  # pragma: no cover
                raise AssertionError(f"no way into {box} on the robot's map")  # ok said there is
        if give_up is not None and route_length(walked) + route_length(path) > longest:
            break  # the way has turned long: the caller aims for the next waypoint
        for nx, ny in path[1:]:
            if memory[ny, nx] or (nx != x and ny != y and (memory[y, nx] or memory[ny, x])):
                break  # seen blocked since the path was planned: plan again from here
            x, y = nx, ny
            walked.append((x, y))
            _see(grid, memory, x, y)
    return walked, work


def _distance_to_box(x: int, y: int, box: Box, movement: int) -> float:
    """The distance from (x, y) to the nearest cell of `box` on an empty map."""
    x0, y0, x1, y1 = box
    dx = max(x0 - x, 0, x - (x1 - 1))
    dy = max(y0 - y, 0, y - (y1 - 1))
    if movement == 4:
        return float(dx + dy)
    return float(max(dx, dy) + (SQRT2 - 1) * min(dx, dy))


def _see(grid: BoolGrid, memory: BoolGrid, x: int, y: int) -> None:
    """The robot sees the cells around it: their true state enters its memory."""
    ys, xs = slice(max(0, y - 1), y + 2), slice(max(0, x - 1), x + 2)
    memory[ys, xs] |= grid[ys, xs]
