"""The planner's searches compiled (issue 17, part 3: where the anytime planner's time goes).

A refinement searches a corridor of a few thousand nodes. Done with scipy's Dijkstra, making its
sparse graph cost three times the search, the search settled the whole corridor, and the fixed
cost of the numpy calls around it dominated short problems. Compiled with numba, `search` is A*
over the corridor reading the level's own rows (at level 0, the moves off the grid), and
`door_search` is A* over a level's directed doors (`doors`): the ATP runs 2x faster on the
MovingAI maps (random512-10-0: 355 -> 165 ms for the 16 longest problems; ost003d, a cave:
175 -> 86 ms). Both are compiled on their first call and cached on disk (numba's cache, beside
this file or in the user's cache directory), so a later process loads them in a fraction of a
second.

What they return is what their callers promise: a cheapest path (ties may go either way) and
its work counted as the states an A* search for it expands, those whose cost plus heuristic is
below the path's, and the path's own but the last. (A* with a consistent heuristic expands
exactly those before it stops, so the count is also the search's own.)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numpy.typing import NDArray

from .search import STEP_NO_PATH, STEP_NONE_LEFT, STEP_OVER, STEP_REFINED

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]
CellArray = NDArray[np.uint8]

_SQRT2 = math.sqrt(2.0)
_F = TypeVar("_F", bound=Callable[..., Any])


def _compiled(function: _F) -> _F:
    """Compiled to machine code on the first call and cached on disk for the next process."""
    return cast(_F, numba.njit(cache=True, nogil=True)(function))


# The moves: straight ones first (all a 4-connected search takes), then the diagonals.
_DX = np.array([1, -1, 0, 0, 1, -1, 1, -1])
_DY = np.array([0, 0, 1, -1, 1, 1, -1, -1])
_STEP = np.array([1.0, 1.0, 1.0, 1.0, _SQRT2, _SQRT2, _SQRT2, _SQRT2])


@_compiled
def _move_distance(dx: float, dy: float, movement: int) -> float:
    """`world.move_distance` of one offset (dx, dy >= 0), by the same operations."""
    if movement == 4:
        return dx + dy
    return max(dx, dy) + (_SQRT2 - 1.0) * min(dx, dy)


@_compiled
def _push(keys: FloatArray, items: IntArray, size: int, key: float, item: int) -> int:
    """Push (key, item) on the binary heap of the first `size` entries; the new size."""
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if keys[parent] <= key:
            break
        keys[i], items[i] = keys[parent], items[parent]
        i = parent
    keys[i], items[i] = key, item
    return size + 1


@_compiled
def _pop(keys: FloatArray, items: IntArray, size: int) -> int:
    """Remove the heap's least entry (read it from keys[0], items[0] first); the new size."""
    size -= 1
    key, item = keys[size], items[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and keys[child + 1] < keys[child]:
            child += 1
        if keys[child] >= key:
            break
        keys[i], items[i] = keys[child], items[child]
        i = child
    if size > 0:
        keys[i], items[i] = key, item
    return size


@_compiled
def _numbered(nodes: IntArray, local: IntArray) -> IntArray:
    """A search's members: `nodes` once each, in first-seen order, each numbered in `local`
    (scratch, -1 everywhere before) by its place."""
    n = 0
    for node in nodes:
        if local[node] < 0:
            local[node] = n
            n += 1
    members = np.empty(n, dtype=np.int64)
    for node in nodes:
        members[local[node]] = node
    return members


@_compiled
def _finishes(targets: IntArray, target_costs: FloatArray, local: IntArray, n: int) -> FloatArray:
    """Each member's cost to end there: its least target cost (inf: not a target)."""
    finish = np.full(n, np.inf)
    for j in range(len(targets)):
        t = local[targets[j]]
        finish[t] = min(finish[t], target_costs[j])
    return finish


@_compiled
def _counted(
    settled: NDArray[np.bool_],
    distance: FloatArray,
    estimate: FloatArray,
    previous: IntArray,
    end: int,
    best: float,
) -> tuple[IntArray, int]:
    """The path found (members, first to last) and the expansions an A* search for it counts:
    the members settled below its cost, and its own but the last."""
    expanded = np.zeros(len(settled), dtype=np.bool_)
    tolerance = 1e-9 * max(1.0, best) if best < np.inf else 0.0
    for u in range(len(settled)):
        expanded[u] = settled[u] and distance[u] + estimate[u] < best - tolerance
    path = _traced(previous, end, expanded)
    return path, int(np.count_nonzero(expanded))


@_compiled
def search(
    nodes: IntArray,
    local: IntArray,
    first: IntArray,
    neighbour: IntArray,
    cost: FloatArray,
    padded: IntArray,
    wide: int,
    block: IntArray,
    centre: FloatArray,
    movement: int,
    sources: IntArray,
    source_costs: FloatArray,
    targets: IntArray,
    target_costs: FloatArray,
    landmarks: FloatArray,
) -> tuple[IntArray, float, int]:
    """A* from `sources` (each starting at its cost) to any of `targets` (each adding its cost at
    the end) through `nodes` (level node numbers; duplicates are fine), with `_nearest` as the
    heuristic (admissible: a target's cost is never negative), bounded by the `landmarks`'
    distances (one row per node of the level, one column per landmark; none: no rows).

    The level's edges are its compressed rows (`first`, `neighbour`, `cost`) above level 0; at
    level 0 (`padded` not empty: the level-0 node of each cell, ravelled with a border of -1,
    `wide` cells a row) they are the legal moves from each cell (`block`), diagonals without
    corner cutting when `movement` is 8. `local` is scratch, one entry per node of the level
    and -1 everywhere; it is left so.

    Returns (the path's nodes, source first; empty when no target is reached), its cost (inf
    when none), and the expansions as `Components.corridor` counts them."""
    members = _numbered(nodes, local)
    n = len(members)
    # Each member's centre and, at level 0, its padded cell, read once here: the expansions
    # read these (small, hot) rather than the level's arrays (megabytes at level 0, cold after
    # another search has run: 7-11% of the planner's time on the MovingAI maps' 16 longest)
    x = np.empty(n)
    y = np.empty(n)
    at_of = np.empty(n if len(padded) else 0, dtype=np.int64)
    for i in range(n):
        node = members[i]
        x[i], y[i] = centre[node, 0], centre[node, 1]
        if len(padded):
            at_of[i] = (block[node, 1] + 1) * wide + block[node, 0] + 1
    target_x, target_y = centre[targets, 0], centre[targets, 1]
    # The targets' distances from the landmarks, read for every node reached
    to_targets = np.empty((len(targets), landmarks.shape[1]))
    if landmarks.shape[1]:
        for j in range(len(targets)):
            to_targets[j] = landmarks[targets[j]]
    distance = np.full(n, np.inf)
    estimate = np.full(n, -1.0)  # the heuristic, made when the node is first reached
    previous = np.full(n, -1, dtype=np.int64)
    settled = np.zeros(n, dtype=np.bool_)
    finish = _finishes(targets, target_costs, local, n)  # a target's cost to end there
    capacity = 8 * n + len(sources) + 1
    keys = np.empty(capacity, dtype=np.float64)
    items = np.empty(capacity, dtype=np.int64)
    size = 0
    for j in range(len(sources)):
        s = local[sources[j]]
        if source_costs[j] < distance[s]:
            if estimate[s] < 0.0:
                estimate[s] = _nearest(x[s], y[s], target_x, target_y, movement)
                estimate[s] = _landmark_bound(estimate[s], sources[j], to_targets, landmarks)
            distance[s] = source_costs[j]
            size = _push(keys, items, size, source_costs[j] + estimate[s], s)
    best, end = np.inf, -1
    moves = 8 if movement == 8 else 4
    while size > 0:
        f, u = keys[0], items[0]
        size = _pop(keys, items, size)
        if settled[u] or f > distance[u] + estimate[u]:
            continue
        if f >= best:  # no way through a node left is cheaper than the path found
            break
        settled[u] = True
        d = distance[u]
        if finish[u] < np.inf and d + finish[u] < best:
            best, end = d + finish[u], u
        if len(padded):  # level 0: the moves off the grid
            at = at_of[u]
            for m in range(moves):
                dx, dy, step = _DX[m], _DY[m], _STEP[m]
                head = padded[at + dy * wide + dx]
                if head < 0:
                    continue
                if dx != 0 and dy != 0 and (padded[at + dx] < 0 or padded[at + dy * wide] < 0):
                    continue  # no corner cutting: both orthogonal neighbours free
                v = local[head]
                if v >= 0 and d + step < distance[v]:
                    if estimate[v] < 0.0:
                        estimate[v] = _nearest(x[v], y[v], target_x, target_y, movement)
                    distance[v], previous[v] = d + step, u
                    if size == len(keys):
                        keys, items = _grown(keys, items)
                    size = _push(keys, items, size, d + step + estimate[v], v)
        else:
            node = members[u]
            for e in range(first[node], first[node + 1]):
                v = local[neighbour[e]]
                if v >= 0 and d + cost[e] < distance[v]:
                    if estimate[v] < 0.0:
                        estimate[v] = _nearest(x[v], y[v], target_x, target_y, movement)
                        if landmarks.shape[1]:
                            estimate[v] = _landmark_bound(
                                estimate[v], neighbour[e], to_targets, landmarks
                            )
                    distance[v], previous[v] = d + cost[e], u
                    if size == len(keys):
                        keys, items = _grown(keys, items)
                    size = _push(keys, items, size, d + cost[e] + estimate[v], v)
    path, expansions = _counted(settled, distance, estimate, previous, end, best)
    path = members[path]
    for node in nodes:
        local[node] = -1
    return path, best, expansions


# What `jump_search` reads of a padded cell (`Components` keeps the grid, `cells`): blocked,
# free, in the corridor, or a target in it. A scan reads one byte a cell, not a cell's node and
# then its corridor number (two int64 arrays of megabytes): 2.6-2.8x faster on MovingAI's caves.
CELL_BLOCKED, CELL_FREE, CELL_CORRIDOR, CELL_TARGET = 0, 1, 2, 3


@_compiled
def _straight_forced(cells: CellArray, at: int, step: int, side: int) -> bool:
    """Whether the cell `at`, entered by the straight move `step`, has a neighbour toward
    `side` that no shortest path reaches but through it: the side cell when the cell behind it
    is blocked (no diagonal past it: no corner cutting), or the diagonal ahead toward the side
    when that cell behind is blocked or the side cell is outside the corridor."""
    beside, behind = at + side, at + side - step
    if cells[behind] == CELL_BLOCKED and cells[beside] >= CELL_CORRIDOR:
        return True
    return bool(
        cells[at + side + step] >= CELL_CORRIDOR
        and cells[at + step] != CELL_BLOCKED
        and cells[beside] != CELL_BLOCKED
        and (cells[behind] == CELL_BLOCKED or cells[beside] < CELL_CORRIDOR)
    )


@_compiled
def _diagonal_forced(cells: CellArray, at: int, dx: int, dy: int) -> bool:
    """Whether the cell `at`, entered by the diagonal move (dx, dy) (`dy` a padded row's
    step), has a neighbour no shortest path reaches but through it: the diagonal back across
    one component, (-dx, dy) or (dx, -dy), when the cell between is free but outside the
    corridor (the corner may be passed, the cell not entered)."""
    for ax, ay in ((-dx, dy), (dx, -dy)):
        across = ax if ax == -dx else ay  # the component turned back: the cell between
        if (
            cells[at + ax + ay] >= CELL_CORRIDOR
            and cells[at + ax] != CELL_BLOCKED
            and cells[at + ay] != CELL_BLOCKED
            and cells[at + across] < CELL_CORRIDOR
        ):
            return True
    return False


@_compiled
def _straight_jump(cells: CellArray, at: int, step: int, side: int) -> int:
    """The first jump point moving straight by `step` from the padded cell `at` (not `at`
    itself): a target or a cell with a forced neighbour (`_straight_forced`, toward either
    side), or -1 when the corridor ends first."""
    cur = at
    while True:
        cur += step
        state = cells[cur]
        if state < CELL_CORRIDOR:
            return -1
        if state == CELL_TARGET:
            return cur
        if _straight_forced(cells, cur, step, side) or _straight_forced(cells, cur, step, -side):
            return cur


@_compiled
def _jump(cells: CellArray, wide: int, at: int, dx: int, dy: int) -> int:
    """The jump point from the padded cell `at` in direction (dx, dy), or -1. Diagonally: the
    first cell reached by legal diagonal moves (both straight cells free: no corner cutting)
    that is a target, has a forced neighbour (`_diagonal_forced`), or from which a straight
    scan along either component finds a jump point."""
    if dy == 0:
        return _straight_jump(cells, at, dx, wide)
    if dx == 0:
        return _straight_jump(cells, at, dy * wide, 1)
    row = dy * wide
    cur = at
    while True:
        if cells[cur + dx] == CELL_BLOCKED or cells[cur + row] == CELL_BLOCKED:
            return -1
        cur += row + dx
        state = cells[cur]
        if state < CELL_CORRIDOR:
            return -1
        if state == CELL_TARGET or _diagonal_forced(cells, cur, dx, row):
            return cur
        if _straight_jump(cells, cur, dx, wide) >= 0 or _straight_jump(cells, cur, row, 1) >= 0:
            return cur


@_compiled
def _kept(cells: CellArray, wide: int, at: int, px: int, py: int, dx: int, dy: int) -> bool:
    """Whether a jump point entered moving (px, py) ((0, 0): a source) goes on in direction
    (dx, dy): the natural directions (ahead, and a diagonal's components) and those toward a
    forced neighbour (`_straight_forced`, `_diagonal_forced`); every other neighbour has a
    shortest path that does not pass through the cell."""
    if px == 0 and py == 0:
        return True
    if px != 0 and py != 0:
        if (dx == px and dy in (0, py)) or (dx == 0 and dy == py):
            return True
        if dx == -px and dy == py:  # back across x: the cell between outside the corridor
            return bool(cells[at - px] < CELL_CORRIDOR)
        if dx == px and dy == -py:
            return bool(cells[at - py * wide] < CELL_CORRIDOR)
        return False
    step = px + py * wide
    if dx == px and dy == py:
        return True
    if px != 0:  # along x: a side (0, s) or the diagonal (px, s) toward it
        if dx == -px or dy == 0:
            return False
        side = dy * wide
    else:
        if dy == -py or dx == 0:
            return False
        side = dx
    behind_blocked = bool(cells[at + side - step] == CELL_BLOCKED)
    if dx == 0 or dy == 0:  # the side cell
        return behind_blocked
    return behind_blocked or bool(cells[at + side] < CELL_CORRIDOR)


@_compiled
def _marked(cells: CellArray, wide: int, block: IntArray, nodes: IntArray, state: int) -> None:
    """Each of `nodes`' padded cells set to `state` in `cells`."""
    for node in nodes:
        cells[(block[node, 1] + 1) * wide + block[node, 0] + 1] = state


@_compiled
def _between(jumps: IntArray, block: IntArray, padded: IntArray, wide: int) -> IntArray:
    """Every cell of a path of jump points (level-0 nodes, in order), each pair joined by one
    straight or diagonal line."""
    count = 1 if len(jumps) else 0
    for i in range(1, len(jumps)):
        a, b = jumps[i - 1], jumps[i]
        count += max(abs(block[b, 0] - block[a, 0]), abs(block[b, 1] - block[a, 1]))
    path = np.empty(count, dtype=np.int64)
    if len(jumps):
        path[0] = jumps[0]
    k = 1
    for i in range(1, len(jumps)):
        a, b = jumps[i - 1], jumps[i]
        ax, ay = block[a, 0], block[a, 1]
        sx, sy = np.sign(block[b, 0] - ax), np.sign(block[b, 1] - ay)
        for j in range(1, max(abs(block[b, 0] - ax), abs(block[b, 1] - ay)) + 1):
            path[k] = padded[(ay + j * sy + 1) * wide + ax + j * sx + 1]
            k += 1
    return path


@_compiled
def jump_search(
    nodes: IntArray,
    local: IntArray,
    padded: IntArray,
    cells: CellArray,
    wide: int,
    block: IntArray,
    centre: FloatArray,
    sources: IntArray,
    source_costs: FloatArray,
    targets: IntArray,
    target_costs: FloatArray,
) -> tuple[IntArray, float, int]:
    """`search` at level 0 with octile moves and no corner cutting, by jump points (Harabor and
    Grastien's JPS, its rules without corner cutting, on the same graph: a move enters only
    cells of the corridor `nodes`, and a diagonal needs its two straight cells free on the map,
    in the corridor or not). Each source starts in all eight directions; a cell reached moving
    one way goes on only where no other shortest path leads (`_kept`): ahead and, after a
    diagonal, along its components, and toward a forced neighbour, one only a path through
    this cell reaches cheapest (`_straight_forced`, `_diagonal_forced`: where a cell outside
    the corridor stands beside the move, more than where walls alone do). Between jump points a
    scan moves straight or diagonally over cells without pushing them, and it stops at every
    target. Its scans read one byte a cell (`cells`). On the direct route's corridors (the
    walled-map options, the 16 longest problems) it takes 22% of the time of A* over the same
    corridor on ht_chantry (a cave), 12% on den520d, 9% on Boston, 14% on the maze of width 4,
    85% on the maze of width 1 (every cell a turn or a junction) and 67-81% on the random maps
    (most cells beside an obstacle).

    `cells` is scratch, the padded grid's `CELL_BLOCKED` and `CELL_FREE` (`Components`'): the
    search marks its corridor and targets in it and leaves it as it was.

    Returns what `search` returns: a cheapest path (its cells, every one, source first), its
    cost, and the expansions: the jump points expanded below the path's cost and the path's
    own but the last (each scanned cell is not counted)."""
    members = _numbered(nodes, local)
    n = len(members)
    distance = np.full(n, np.inf)
    estimate = np.full(n, -1.0)
    previous = np.full(n, -1, dtype=np.int64)
    settled = np.zeros(n, dtype=np.bool_)
    finish = _finishes(targets, target_costs, local, n)
    target_x, target_y = centre[targets, 0], centre[targets, 1]
    capacity = 8 * n + len(sources) + 1
    keys = np.empty(capacity, dtype=np.float64)
    items = np.empty(capacity, dtype=np.int64)
    size = 0
    _marked(cells, wide, block, members, CELL_CORRIDOR)
    _marked(cells, wide, block, targets, CELL_TARGET)
    for j in range(len(sources)):
        s = local[sources[j]]
        if source_costs[j] < distance[s]:
            if estimate[s] < 0.0:
                node = sources[j]
                estimate[s] = _nearest(centre[node, 0], centre[node, 1], target_x, target_y, 8)
            distance[s] = source_costs[j]
            size = _push(keys, items, size, source_costs[j] + estimate[s], s)
    best, end = np.inf, -1
    while size > 0:
        f, u = keys[0], items[0]
        size = _pop(keys, items, size)
        if settled[u] or f > distance[u] + estimate[u]:
            continue
        if f >= best:
            break
        settled[u] = True
        d = distance[u]
        if finish[u] < np.inf and d + finish[u] < best:
            best, end = d + finish[u], u
        node = members[u]
        ux, uy = block[node, 0], block[node, 1]
        at = (uy + 1) * wide + ux + 1
        p = previous[u]
        px, py = 0, 0  # the direction u was reached in (none at a source)
        if p >= 0:
            pn = members[p]
            px, py = np.sign(ux - block[pn, 0]), np.sign(uy - block[pn, 1])
        for m in range(8):
            dx, dy = _DX[m], _DY[m]
            if not _kept(cells, wide, at, px, py, dx, dy):
                continue
            found = _jump(cells, wide, at, dx, dy)
            if found < 0:
                continue
            v = local[padded[found]]
            vx, vy = found % wide - 1, found // wide - 1
            steps = max(abs(vx - ux), abs(vy - uy))
            g = d + steps * (_SQRT2 if dx != 0 and dy != 0 else 1.0)
            if g < distance[v]:
                if estimate[v] < 0.0:
                    head = padded[found]
                    estimate[v] = _nearest(centre[head, 0], centre[head, 1], target_x, target_y, 8)
                distance[v], previous[v] = g, u
                if size == len(keys):
                    keys, items = _grown(keys, items)
                size = _push(keys, items, size, g + estimate[v], v)
    jumps, expansions = _counted(settled, distance, estimate, previous, end, best)
    path = _between(members[jumps], block, padded, wide)
    _marked(cells, wide, block, members, CELL_FREE)
    for node in nodes:
        local[node] = -1
    return path, best, expansions


@_compiled
def jump_distances(cells: CellArray, wide: int) -> NDArray[np.int32]:
    """Each padded cell's jump in each straight move (`_DX`, `_DY`'s first four: east, west,
    south, north) over the whole map (`cells`, every free cell `CELL_CORRIDOR`), a row a cell:
    k > 0 when the k-th cell that way is the first jump point (`_straight_jump`'s, no target
    marked), else -k, k the moves that way before a wall (a blocked cell's: unset). Harabor and
    Grastien's straight jump points read from a table made once per map (Rabin's JPS+), not
    scanned per search: a scan across open ground runs to the far wall from every jump point
    (and a diagonal one scans straight from every cell it crosses), and on MovingAI's small
    maps took more than A*'s whole search of a short problem. The diagonal moves are scanned
    (`_diagonal_jump`), a cell at a time, each read off this table. One pass a move over the
    free cells, each read from the one ahead of it; over the whole map (every free cell in the
    corridor) a straight move's forced neighbour (`_straight_forced`) is a free side cell
    whose cell behind is blocked. By padded cell, not by node: a search reads it without
    looking a cell's node up (a fifth of a search's time on MovingAI's small maps)."""
    # A blocked cell's row is never read (a search reads a free cell's, and so does this), so
    # it is left unwritten: on a map of a few free cells the table's pages are not all touched
    table = np.empty((len(cells), 4), dtype=np.int32)
    free = np.flatnonzero(cells != CELL_BLOCKED)  # ascending
    count = len(free)
    for m in range(4):
        step = _DX[m] + _DY[m] * wide
        side = wide if _DY[m] == 0 else 1
        for i in range(count):
            at = free[count - 1 - i] if step > 0 else free[i]  # the cell ahead done first
            ahead = at + step
            if cells[ahead] == CELL_BLOCKED:
                table[at, m] = 0
            elif (
                cells[ahead + side - step] == CELL_BLOCKED and cells[ahead + side] != CELL_BLOCKED
            ) or (
                cells[ahead - side - step] == CELL_BLOCKED and cells[ahead - side] != CELL_BLOCKED
            ):
                table[at, m] = 1
            else:
                jump = table[ahead, m]
                table[at, m] = jump + 1 if jump > 0 else jump - 1
    return table


@_compiled
def _diagonal_jump(
    cells: CellArray, jumps: NDArray[np.int32], wide: int, at: int, dx: int, dy: int, most: int
) -> int:
    """The moves from the padded cell `at` diagonally (dx, dy) to its jump point over the whole
    map (`_jump`'s, no target marked: the first cell reached by legal moves from which a
    straight move along either component has one, read off `jumps`), or to the `most`-th cell
    when that comes first (0 < `most`: the target's row or column, Rabin's target jump point);
    0 when neither comes before a wall."""
    row = dy * wide
    along_x = 0 if dx > 0 else 1
    along_y = 2 if dy > 0 else 3
    cur, k = at, 0
    while True:
        if cells[cur + dx] == CELL_BLOCKED or cells[cur + row] == CELL_BLOCKED:
            return 0
        cur += row + dx
        k += 1
        if cells[cur] == CELL_BLOCKED:
            return 0
        if k == most or jumps[cur, along_x] > 0 or jumps[cur, along_y] > 0:
            return k


@_compiled
def whole_jump_search(
    padded: IntArray,
    cells: CellArray,
    wide: int,
    block: IntArray,
    centre: FloatArray,
    source: int,
    target: int,
    distance: FloatArray,
    estimate: FloatArray,
    previous: IntArray,
    settled: NDArray[np.bool_],
    touched: IntArray,
    keys: FloatArray,
    items: IntArray,
    jumps: NDArray[np.int32],
    most: int,
) -> tuple[IntArray, float, int]:
    """`jump_search` over every free cell, from one source to one target, its work in
    proportion to the cells it touches, not to the map's: its corridor is the whole map
    (`cells`, every free cell `CELL_CORRIDOR`), its straight jumps read from the map's table
    (`jump_distances`, `jumps`) and its diagonal ones scanned off it (`_diagonal_jump`), and
    what it keeps per cell (`distance` inf, `estimate` -1, `previous` -1, `settled` False, by
    level-0 node, and the heap's room `keys` and `items`) is kept between searches, each left
    as it found it (the cells it touched, listed in `touched`, are reset: `_untouched`). A
    short problem on a map of thousands of cells cost tens of microseconds in `jump_search`'s
    setup alone.

    The target is found as the jumps pass it: a straight move whose line holds it within the
    move's reach goes to it, and a diagonal one toward it stops where it meets its row or
    column (a jump point of its own, Rabin's target jump point: the straight move on
    from there reaches it); such a stop is a cell of the diagonal, which its expansion goes on
    along, so no jump point past it is lost.

    Returns what `jump_search` returns; when it would settle more than `most` jump points, it
    stops and returns no path, a cost of -1 and `most` (the room reset all the same)."""
    target_x, target_y = centre[target, 0], centre[target, 1]
    gx, gy = block[target, 0], block[target, 1]
    count = 1
    touched[0] = source
    estimate[source] = _move_distance(
        abs(centre[source, 0] - target_x), abs(centre[source, 1] - target_y), 8
    )
    distance[source] = 0.0
    size = _push(keys, items, 0, estimate[source], source)
    best, end, settling = np.inf, -1, 0
    while size > 0:
        f, u = keys[0], items[0]
        size = _pop(keys, items, size)
        if settled[u] or f > distance[u] + estimate[u]:
            continue
        if f >= best:
            break
        settling += 1
        if settling > most:
            best = -1.0
            break
        settled[u] = True
        d = distance[u]
        if u == target:
            best, end = d, u
            continue
        ux, uy = block[u, 0], block[u, 1]
        ex, ey = gx - ux, gy - uy  # the target, from u
        at = (uy + 1) * wide + ux + 1
        p = previous[u]
        px, py = 0, 0  # the direction u was reached in (none at the source)
        if p >= 0:
            px, py = np.sign(ux - block[p, 0]), np.sign(uy - block[p, 1])
        for m in range(8):
            dx, dy = _DX[m], _DY[m]
            if not _kept(cells, wide, at, px, py, dx, dy):
                continue
            if dx != 0 and dy != 0:  # scanned, a cell at a time: to the target's row or column
                to_target = min(abs(ex), abs(ey)) if ex * dx > 0 and ey * dy > 0 else 0
                steps = _diagonal_jump(cells, jumps, wide, at, dx, dy, to_target)
                if steps == 0:
                    continue
            else:  # read: to the target on its line within reach, else to the jump point
                jump = jumps[at, m]
                to_target = 0
                if dy == 0 and ey == 0 and ex * dx > 0:
                    to_target = abs(ex)
                elif dx == 0 and ex == 0 and ey * dy > 0:
                    to_target = abs(ey)
                if 0 < to_target <= abs(jump):
                    steps = to_target
                elif jump > 0:
                    steps = jump
                else:
                    continue
            found = at + steps * (dx + dy * wide)
            v = padded[found]
            g = d + steps * (_SQRT2 if dx != 0 and dy != 0 else 1.0)
            if g < distance[v]:
                if estimate[v] < 0.0:
                    estimate[v] = _move_distance(
                        abs(centre[v, 0] - target_x), abs(centre[v, 1] - target_y), 8
                    )
                    touched[count] = v
                    count += 1
                distance[v], previous[v] = g, u
                if size == len(keys):
                    keys, items = _grown(keys, items)
                size = _push(keys, items, size, g + estimate[v], v)
    if best < 0.0:  # over `most`
        _untouched(touched, count, distance, estimate, previous, settled)
        return np.zeros(0, dtype=np.int64), -1.0, most
    # The expansions an A* search for the path counts (`_counted`), over the touched cells
    tolerance = 1e-9 * max(1.0, best) if best < np.inf else 0.0
    expansions = 0
    for i in range(count):
        u = touched[i]
        expansions += settled[u] and distance[u] + estimate[u] < best - tolerance
    path_jumps = _path_back(previous, end)
    for u in path_jumps[:-1]:  # A* pops the path's cells too, but the last
        if not (distance[u] + estimate[u] < best - tolerance):
            expansions += 1
    path = _between(path_jumps, block, padded, wide)
    _untouched(touched, count, distance, estimate, previous, settled)
    return path, best, expansions


@_compiled
def _untouched(
    touched: IntArray,
    count: int,
    distance: FloatArray,
    estimate: FloatArray,
    previous: IntArray,
    settled: NDArray[np.bool_],
) -> None:
    """The first `count` cells of `touched` as `whole_jump_search` finds them: unreached."""
    for i in range(count):
        u = touched[i]
        distance[u], estimate[u], previous[u], settled[u] = np.inf, -1.0, -1, False


@_compiled
def path_reads(
    block: IntArray, obstacleness: FloatArray, path: IntArray, bounds: IntArray
) -> tuple[IntArray, IntArray, FloatArray]:
    """What the planner reads of a path of nodes to make its segments (`planner._Planner.
    segments`), in one call: each node's block (x, y) at its level, and the mean obstacleness
    of those blocks (`obstacleness`, the level's, indexed [y, x]) over each run of nodes
    `bounds[i]`..`bounds[i + 1]` (inclusive: consecutive runs share their junction), summed as
    `np.add.reduce` sums them (`pairwise_sum`)."""
    n = len(path)
    xs = np.empty(n, dtype=np.int64)
    ys = np.empty(n, dtype=np.int64)
    values = np.empty(n)
    for i in range(n):
        xs[i], ys[i] = block[path[i], 0], block[path[i], 1]
        values[i] = obstacleness[ys[i], xs[i]]
    means = np.empty(len(bounds) - 1)
    for r in range(len(bounds) - 1):
        count = bounds[r + 1] + 1 - bounds[r]
        means[r] = pairwise_sum(values, bounds[r], count) / count
    return xs, ys, means


#: The columns of `level_search`'s table, one row per node of a level (and a last one for the
#: search's number): what a search reaches a node by, side by side, so that a node reached costs
#: one cache line, or two adjacent ones with landmarks, not one per array (cold, as a first plan
#: runs after another problem's whole run, the reads were most of the search's time).
ROW_REACHED, ROW_SETTLED, ROW_DISTANCE, ROW_ESTIMATE, ROW_PREVIOUS, ROW_X, ROW_Y = range(7)
ROW_LANDMARKS = 8  # the node's distances from the landmarks, from this column on


@_compiled
def level_search(
    table: FloatArray,
    first: IntArray,
    neighbour: IntArray,
    cost: FloatArray,
    movement: int,
    source: int,
    target: int,
    landmarks: int,
    heap_keys: FloatArray,
    heap_items: IntArray,
    block: IntArray,
    values: FloatArray,
) -> tuple[IntArray, float, int, IntArray, IntArray, float]:
    """`search` over every node of a level above level 0 from one node to another (the first
    plan), and with `values` not empty what the plan's segment reads of its path in the same
    call (`path_reads` of it as one run: one compiled call in every first plan's time, not
    two): the same path, cost and expansions (the same pushes in the same order: its local
    numbers are the level's own when every node is allowed), at the cost of the nodes it
    reaches rather than of the level's.

    `table` holds a row per node (`ROW_*`): its centre and its distances from `landmarks`
    landmarks (from `ROW_LANDMARKS` on) are the level's; its distance, estimate and previous
    node are the search's while its `ROW_REACHED` is the search's number (`table[-1, 0]`,
    which it advances), and it is settled while its `ROW_SETTLED` is: nothing the size of the
    level is made or cleared per search. `heap_keys`, `heap_items` are the heap's room, one
    more than the level's edges: each edge pushes at most once (when the node it leaves is
    settled), so it never runs out.

    Returns the path's nodes (source first; empty when the target is not reached), its cost
    (inf when none), the expansions, and the path's nodes' blocks (x, y; `block` the level's)
    and the mean of `values` (the level's, indexed [y, x]) over them (empty and NaN without
    `values` or a path)."""
    last = len(table) - 1
    table[last, 0] += 1.0
    now = table[last, 0]
    to = table[target]
    # With landmarks, the heuristic is exact along many routes, so many nodes tie (within
    # rounding) with the cheapest path's cost: keyed g * (1 - lean) + h, the deeper of two such
    # nodes comes first, and fewer are settled (MovingAI's caves of 200 x 200, the 16 longest
    # problems, blocks of 8 x 8: 86-90 -> 56-63); the path costs at most 1 / (1 - lean) times
    # the cheapest. Without, the key is g + h.
    lean = 1e-9 if landmarks else 0.0
    keys, items = heap_keys, heap_items
    closed = np.empty(64, dtype=np.int64)  # the settled nodes, in order
    settled = 0
    row = table[source]
    row[ROW_REACHED], row[ROW_DISTANCE], row[ROW_PREVIOUS] = now, 0.0, -1.0
    row[ROW_ESTIMATE] = _row_bound(row, to, movement, landmarks)
    size = _push(keys, items, 0, row[ROW_ESTIMATE], source)
    best, end = np.inf, -1
    while size > 0:
        f, u = keys[0], items[0]
        size = _pop(keys, items, size)
        row = table[u]
        d = row[ROW_DISTANCE]
        if row[ROW_SETTLED] == now or f > d * (1.0 - lean) + row[ROW_ESTIMATE]:
            continue
        if d + row[ROW_ESTIMATE] >= best:  # no way through a node left is cheaper
            break
        row[ROW_SETTLED] = now
        if settled == len(closed):
            closed = np.concatenate((closed, np.empty(len(closed), dtype=np.int64)))
        closed[settled] = u
        settled += 1
        if u == target and d < best:
            best, end = d, u
        for e in range(first[u], first[u + 1]):
            v = neighbour[e]
            reached = table[v]
            if reached[ROW_REACHED] != now:  # first reached: its heuristic made now
                reached[ROW_REACHED] = now
                reached[ROW_DISTANCE], reached[ROW_PREVIOUS] = np.inf, -1.0
                reached[ROW_ESTIMATE] = _row_bound(reached, to, movement, landmarks)
            g = d + cost[e]
            if g < reached[ROW_DISTANCE]:
                reached[ROW_DISTANCE], reached[ROW_PREVIOUS] = g, u
                if size == len(keys):
                    raise AssertionError("the heap's room is one more than the level's edges")
                size = _push(keys, items, size, g * (1.0 - lean) + reached[ROW_ESTIMATE], v)
    tolerance = 1e-9 * max(1.0, best) if best < np.inf else 0.0
    expansions = 0
    for i in range(settled):
        row = table[closed[i]]
        expansions += row[ROW_DISTANCE] + row[ROW_ESTIMATE] < best - tolerance
    # the path's nodes but the last count as expanded (A* pops them too) where the count above
    # left them out
    path = _path_back(table[:, ROW_PREVIOUS], end)
    for u in path[:-1]:
        row = table[u]
        expansions += not row[ROW_DISTANCE] + row[ROW_ESTIMATE] < best - tolerance
    if not len(path) or not len(values):
        nothing = np.zeros(0, dtype=np.int64)
        return path, best, expansions, nothing, nothing, np.nan
    bounds = np.zeros(2, dtype=np.int64)
    bounds[1] = len(path) - 1
    xs, ys, means = path_reads(block, values, path, bounds)
    return path, best, expansions, xs, ys, means[0]


@_compiled
def _row_bound(row: FloatArray, to: FloatArray, movement: int, landmarks: int) -> float:
    """`_landmark_bound` of `_nearest`'s distance between the centres of two rows of
    `level_search`'s table (a node's and the target's), without a branch per landmark: a
    landmark another region holds is inf from both, and inf - inf, NaN, raises no bound; one
    the node's region holds and the target's does not (never in a search between connected
    nodes) gives inf, the true distance."""
    bound = _move_distance(abs(row[ROW_X] - to[ROW_X]), abs(row[ROW_Y] - to[ROW_Y]), movement)
    for k in range(ROW_LANDMARKS, ROW_LANDMARKS + landmarks):
        d = abs(to[k] - row[k])
        bound = d if d > bound else bound
    return bound


def level_table(centre: FloatArray, landmarks: FloatArray) -> FloatArray:
    """`level_search`'s table for a level whose nodes' centres are `centre` and distances from
    the landmarks `landmarks` (shape (nodes, count)): each row a whole number of cache lines
    (8 floats), aligned on them, no node reached."""
    nodes, count = landmarks.shape
    width = ROW_LANDMARKS * (1 + -(-count // ROW_LANDMARKS))
    line = 64 if width == ROW_LANDMARKS else 128  # a row's own line, or its two adjacent ones
    room = np.zeros((nodes + 1) * width + line // 8)
    skip = (-room.ctypes.data % line) // 8
    table = room[skip : skip + (nodes + 1) * width].reshape(nodes + 1, width)
    table[:nodes, ROW_X : ROW_Y + 1] = centre
    table[:nodes, ROW_LANDMARKS : ROW_LANDMARKS + count] = landmarks
    return table


@_compiled
def _traced(previous: IntArray, end: int, expanded: NDArray[np.bool_]) -> IntArray:
    """The path back from `end` by `previous` (-1 before its first), first to last (empty when
    `end` is -1); its entries but the last marked `expanded` (A* pops them too; the last ends
    it)."""
    path = _path_back(previous, end)
    for u in path[:-1]:
        expanded[u] = True
    return path


@_compiled
def _path_back(previous: IntArray | FloatArray, end: int) -> IntArray:
    """The path back from `end` by `previous` (-1 before its first; whole numbers, integers or
    floats: `level_search`'s table column), first to last (empty when `end` is -1)."""
    count = 0
    u = end
    while u >= 0:
        count += 1
        u = int(previous[u])
    path = np.empty(count, dtype=np.int64)
    u = end
    for i in range(count - 1, -1, -1):
        path[i] = u
        u = int(previous[u])
    return path


@_compiled
def _landmark_bound(
    estimate: float, node: int, to_targets: FloatArray, landmarks: FloatArray
) -> float:
    """`estimate` (a distance to the nearest target) raised to the landmarks' bound where that
    is higher for every target: the distance from `node` to a target is at least
    |d(L, target) - d(L, node)| for each landmark L (the triangle inequality over the level's
    edges; consistent, as the landmarks' distances are exact). `to_targets[t]`: the targets'
    distances from the landmarks; `landmarks[node]`: the node's."""
    if landmarks.shape[1] == 0:
        return estimate
    nearest = np.inf
    for t in range(len(to_targets)):
        bound = 0.0
        for k in range(landmarks.shape[1]):
            a, b = to_targets[t, k], landmarks[node, k]
            if a < np.inf and b < np.inf:
                bound = max(bound, abs(a - b))
        nearest = min(nearest, bound)
    return max(estimate, nearest)


@_compiled
def _nearest(
    x: float, y: float, target_x: FloatArray, target_y: FloatArray, movement: int
) -> float:
    """The heuristic: the distance from a node's centre (x, y) to the nearest target's
    (`target_x`, `target_y`), as the robot moves (octile or Manhattan; consistent with every
    level's edges)."""
    nearest = np.inf
    for t in range(len(target_x)):
        h = _move_distance(abs(x - target_x[t]), abs(y - target_y[t]), movement)
        nearest = min(nearest, h)
    return float(nearest)


@_compiled
def _grown(keys: FloatArray, items: IntArray) -> tuple[FloatArray, IntArray]:
    more_keys = np.empty(2 * len(keys), dtype=np.float64)
    more_items = np.empty(2 * len(items), dtype=np.int64)
    more_keys[: len(keys)] = keys
    more_items[: len(items)] = items
    return more_keys, more_items


@_compiled
def door_route(
    grid: IntArray,
    up: IntArray,
    first: IntArray,
    keys: IntArray,
    order: IntArray,
    point: FloatArray,
    after_first: IntArray,
    after: IntArray,
    length: FloatArray,
    head_block: IntArray,
    head: IntArray,
    level: int,
    movement: int,
    crossing: float,
    start_x: int,
    start_y: int,
    goal_x: int,
    goal_y: int,
    bound: IntArray,
    within: NDArray[np.bool_],
) -> tuple[int, IntArray, float, int]:
    """`doors.Doors.route` in one call (the doors' arrays as `Doors` holds them): the start's
    and goal's nodes, the states leaving the start's node with their cost from the start, the
    cut at `bound`'s cost through its doors (`Doors.cost_of`, the same operations and the same
    sum, none when `bound` is empty), then `door_search`. Returns (the start's node; the route's
    nodes, start's first, empty when none is found and the start's node alone when the goal is
    in it; its cost, 0 then; its expansions)."""
    source = up[grid[start_y, start_x]]
    target = up[grid[goal_y, goal_x]]
    if source == target:
        alone = np.empty(1, dtype=np.int64)
        alone[0] = source
        return source, alone, 0.0, 0
    sx, sy, gx, gy = start_x + 0.5, start_y + 0.5, goal_x + 0.5, goal_y + 0.5
    leaving = np.arange(first[source], first[source + 1])
    to_first = np.empty(len(leaving))
    for i in range(len(leaving)):
        dx, dy = abs(point[leaving[i], 0] - sx), abs(point[leaving[i], 1] - sy)
        to_first[i] = _move_distance(dx, dy, movement) + crossing
    cut = np.inf
    if len(bound):  # what is dearer than the bound's route is not searched
        count = len(first) - 1
        doors = len(bound) - 1
        steps = np.empty(doors + 1)
        x, y = sx, sy
        for i in range(doors):
            state = order[np.searchsorted(keys, bound[i] * count + bound[i + 1])]
            steps[i] = _move_distance(abs(point[state, 0] - x), abs(point[state, 1] - y), movement)
            x, y = point[state, 0], point[state, 1]
        steps[doors] = _move_distance(abs(gx - x), abs(gy - y), movement)
        dearest = pairwise_sum(steps, 0, doors + 1) + crossing * doors
        cut = dearest + 1e-9 * max(1.0, dearest)
    states, cost, expansions = door_search(
        after_first, after, length, point, head_block, head, level, movement, crossing, leaving,
        to_first, target, gx, gy, cut, within,
    )  # fmt: skip
    nodes = np.empty(len(states) + 1 if len(states) else 0, dtype=np.int64)
    if len(states):
        nodes[0] = source
        for i in range(len(states)):
            nodes[i + 1] = head[states[i]]
    return source, nodes, cost, expansions


@_compiled
def door_search(
    after_first: IntArray,
    after: IntArray,
    length: FloatArray,
    point: FloatArray,
    head_block: IntArray,
    head: IntArray,
    level: int,
    movement: int,
    crossing: float,
    leaving: IntArray,
    to_first: FloatArray,
    target: int,
    goal_x: float,
    goal_y: float,
    cut: float,
    within: NDArray[np.bool_],
) -> tuple[IntArray, float, int]:
    """A* over the directed doors of a level (`doors.Doors`: state j is followed by
    `after[after_first[j]:after_first[j + 1]]`, each `length` + `crossing` away) from the states
    `leaving` the start's node (each `to_first` from the start) to a state whose head is node
    `target`, ending with the straight way from its door to the goal (`goal_x`, `goal_y`). The
    heuristic is `Doors`' (the distance to the goal plus a crossing per block still to cross:
    consistent), and no state whose cost plus heuristic is above `cut` is searched. `within`, when
    not empty, is the level's nodes a route may enter (one entry per node): a state into any other
    is never reached.

    Returns (the route's states, first to last; empty when none is found under `cut`), its cost,
    and the states an A* expands: those whose cost plus heuristic is below the route's, and the
    route's own but the last."""
    states = len(head)
    g = np.full(states, np.inf)
    previous = np.full(states, -1, dtype=np.int64)
    closed = np.zeros(states, dtype=np.bool_)
    popped = np.empty(states, dtype=np.int64)  # the closed states, in order
    f_of = np.empty(states, dtype=np.float64)
    gbx, gby = int(goal_x) >> level, int(goal_y) >> level
    capacity = 4 * len(leaving) + 64
    keys = np.empty(capacity, dtype=np.float64)
    items = np.empty(capacity, dtype=np.int64)
    size = 0
    bounded = len(within) > 0
    for i in range(len(leaving)):
        j = leaving[i]
        if bounded and not within[head[j]]:
            continue
        h = _door_heuristic(point, head_block, j, goal_x, goal_y, gbx, gby, movement, crossing)
        if to_first[i] < g[j] and to_first[i] + h <= cut:
            g[j], f_of[j] = to_first[i], to_first[i] + h
            size = _push(keys, items, size, to_first[i] + h, j)
    count, best, end = 0, np.inf, -1
    while size > 0:
        f, u = keys[0], items[0]
        size = _pop(keys, items, size)
        if closed[u] or f > f_of[u]:
            continue
        if head[u] == target:  # its heuristic is the last leg, exact: the route is found
            best, end = f, u
            break
        closed[u] = True
        popped[count] = u
        count += 1
        for e in range(after_first[u], after_first[u + 1]):
            v = after[e]
            if bounded and not within[head[v]]:
                continue
            cost = g[u] + length[e] + crossing
            if cost < g[v] and not closed[v]:
                h = _door_heuristic(
                    point, head_block, v, goal_x, goal_y, gbx, gby, movement, crossing
                )
                if cost + h <= cut:
                    g[v], f_of[v], previous[v] = cost, cost + h, u
                    if size == len(keys):
                        keys, items = _grown(keys, items)
                    size = _push(keys, items, size, cost + h, v)
    expanded = np.zeros(states, dtype=np.bool_)
    tolerance = 1e-9 * max(1.0, best) if best < np.inf else 0.0
    for i in range(count):
        expanded[popped[i]] = f_of[popped[i]] < best - tolerance
    route = _traced(previous, end, expanded)
    return route, best, int(np.count_nonzero(expanded))


@_compiled
def _door_heuristic(
    point: FloatArray,
    head_block: IntArray,
    j: int,
    goal_x: float,
    goal_y: float,
    gbx: int,
    gby: int,
    movement: int,
    crossing: float,
) -> float:
    h = _move_distance(abs(point[j, 0] - goal_x), abs(point[j, 1] - goal_y), movement)
    away = max(abs(head_block[0, j] - gbx), abs(head_block[1, j] - gby))
    return float(h + crossing * away)


@_compiled
def widened_children(
    first: IntArray,
    neighbour: IntArray,
    first_child: IntArray,
    child: IntArray,
    route: IntArray,
    rings: int,
    mark: IntArray,
) -> IntArray:
    """The children of the nodes of `route` and of those up to `rings` edges from them (a
    level's compressed rows `first`, `neighbour`; node i's children are
    `child[first_child[i]:first_child[i + 1]]`), each node's once, in node order. `mark` is
    scratch, one entry per node of the level and -1 everywhere; it is left so."""
    around = np.empty(len(mark), dtype=np.int64)
    n = 0
    for node in route:
        if mark[node] < 0:
            mark[node] = 0
            around[n] = node
            n += 1
    begin = 0
    for _ in range(rings):
        end = n
        for i in range(begin, end):
            u = around[i]
            for e in range(first[u], first[u + 1]):
                v = neighbour[e]
                if mark[v] < 0:
                    mark[v] = 0
                    around[n] = v
                    n += 1
        begin = end
    around = np.sort(around[:n])  # children in node order, as the level stores them
    for i in range(n):
        mark[around[i]] = -1
    return children_of(around, first_child, child)


@_compiled
def children_of(nodes: IntArray, first_child: IntArray, child: IntArray) -> IntArray:
    """The children of `nodes` (node i's are `child[first_child[i]:first_child[i + 1]]`), each
    node's in turn."""
    total = 0
    for u in nodes:
        total += first_child[u + 1] - first_child[u]
    children = np.empty(total, dtype=np.int64)
    k = 0
    for u in nodes:
        for c in range(first_child[u], first_child[u + 1]):
            children[k] = child[c]
            k += 1
    return children


@_compiled
def refinement(
    up_first: IntArray,
    up_neighbour: IntArray,
    first_child: IntArray,
    child: IntArray,
    mark: IntArray,
    route: IntArray,
    rings: int,
    grand_first_child: IntArray,
    grand_child: IntArray,
    first: IntArray,
    neighbour: IntArray,
    cost: FloatArray,
    padded: IntArray,
    cells: CellArray,
    wide: int,
    block: IntArray,
    centre: FloatArray,
    movement: int,
    jump: bool,
    local: IntArray,
    source: int,
    source_node: int,
    source_x: float,
    source_y: float,
    target: int,
    target_node: int,
    target_x: float,
    target_y: float,
) -> tuple[IntArray, float, int]:
    """One refinement's search in one call (the planner's `_Planner.refine`, its steps as they
    were made in Python): the corridor is the children of `route` (one level up: its compressed
    rows `up_first`, `up_neighbour`, its children `first_child`, `child`, scratch `mark`) and
    of the nodes up to `rings` edges from them (`widened_children`); an end is node `source`
    (`target`) when it is >= 0, else any child of `source_node` (`target_node`), each costing
    how much farther its centre is from (`source_x`, `source_y`) than the nearest child's;
    then `search` one level down (its rows, or at level 0 `padded` and `wide`; `local` its
    scratch; at level 0 with octile moves `jump_search` (its scratch `cells`) instead when
    `jump` and the search
    has one source: each source scans all eight ways, and a coarser neighbour's node gives up
    to 16 of them, where A* grows them as one frontier). With
    `grand_first_child` not empty, the search is two levels down: the corridor and the ends are
    the children's children (`grand_first_child`, `grand_child`: the rows of the level one
    down). Returns what `search` returns."""
    allowed = widened_children(up_first, up_neighbour, first_child, child, route, rings, mark)
    if len(grand_first_child):
        allowed = children_of(allowed, grand_first_child, grand_child)
    sources, source_costs = _ends(
        first_child, child, grand_first_child, grand_child, centre,
        source, source_node, source_x, source_y,
    )  # fmt: skip
    targets, target_costs = _ends(
        first_child, child, grand_first_child, grand_child, centre,
        target, target_node, target_x, target_y,
    )  # fmt: skip
    if jump and len(padded) and movement == 8 and len(sources) == 1:
        return jump_search(
            allowed, local, padded, cells, wide, block, centre,
            sources, source_costs, targets, target_costs,
        )  # fmt: skip
    return search(
        allowed, local, first, neighbour, cost, padded, wide, block, centre, movement,
        sources, source_costs, targets, target_costs, np.zeros((0, 0)),
    )  # fmt: skip


@_compiled
def _ends(
    first_child: IntArray,
    child: IntArray,
    grand_first_child: IntArray,
    grand_child: IntArray,
    centre: FloatArray,
    fixed: int,
    node: int,
    x: float,
    y: float,
) -> tuple[IntArray, FloatArray]:
    """A refined segment's end: the node `fixed` (>= 0) at no cost, or the children of `node`
    (their children when `grand_first_child` is not empty), each at its centre's distance from
    (x, y) less the nearest one's (the planner's `_approach`)."""
    if fixed >= 0:
        ends = np.empty(1, dtype=np.int64)
        ends[0] = fixed
        return ends, np.zeros(1)
    ends = child[first_child[node] : first_child[node + 1]].copy()
    if len(grand_first_child):
        ends = children_of(ends, grand_first_child, grand_child)
    d = np.empty(len(ends))
    for i in range(len(ends)):
        d[i] = math.hypot(centre[ends[i], 0] - x, centre[ends[i], 1] - y)
    return ends, d - d.min()


@_compiled
def neighbourhood(
    first: IntArray, neighbour: IntArray, route: IntArray, rings: int, count: int
) -> NDArray[np.bool_]:
    """Which of a level's `count` nodes are `route`'s or up to `rings` edges from one of them
    (the level's compressed rows `first`, `neighbour`)."""
    near = np.zeros(count, dtype=np.bool_)
    frontier = np.empty(count, dtype=np.int64)
    n = 0
    for node in route:
        if not near[node]:
            near[node] = True
            frontier[n] = node
            n += 1
    begin = 0
    for _ in range(rings):
        end = n
        for i in range(begin, end):
            u = frontier[i]
            for e in range(first[u], first[u + 1]):
                v = neighbour[e]
                if not near[v]:
                    near[v] = True
                    frontier[n] = v
                    n += 1
        begin = end
    return near


@_compiled
def counting_order(keys: IntArray, count: int) -> IntArray:
    """The indices of `keys` (each in [0, count)) ordered by key, equal keys by index: what a
    stable sort by key gives, in one counting pass (the abstraction's build sorts its edges so,
    `components`)."""
    start = np.zeros(count + 1, dtype=np.int64)
    for key in keys:
        start[key + 1] += 1
    for i in range(count):
        start[i + 1] += start[i]
    order = np.empty(len(keys), dtype=np.int64)
    for i in range(len(keys)):
        order[start[keys[i]]] = i
        start[keys[i]] += 1
    return order


@_compiled
def lifted_pairs(
    low: IntArray, high: IntArray, parent: IntArray, count: int
) -> tuple[IntArray, IntArray]:
    """The edges one level up (`components._lifted`): for each edge (low, high) whose ends have
    different parents, the pair (lesser parent, greater parent), each pair once, in ascending
    order (by low, then high). One counting pass buckets the pairs by their lesser end; each
    bucket (a node's few higher neighbours, with repeats) is then sorted where it lies: no sort
    of the whole level, no temporary the size of its edges but the buckets."""
    start = np.zeros(count + 1, dtype=np.int64)
    for e in range(len(low)):
        a, b = parent[low[e]], parent[high[e]]
        if a != b:
            start[min(a, b) + 1] += 1
    for u in range(count):
        start[u + 1] += start[u]
    slot = start[:-1].copy()
    other = np.empty(start[count], dtype=np.int64)
    for e in range(len(low)):
        a, b = parent[low[e]], parent[high[e]]
        if a != b:
            u = min(a, b)
            other[slot[u]] = max(a, b)
            slot[u] += 1
    lifted_low = np.empty(len(other), dtype=np.int64)
    lifted_high = np.empty(len(other), dtype=np.int64)
    m = 0
    for u in range(count):
        s, t = start[u], start[u + 1]
        if t - s > 32:  # a long bucket (a block of many regions): a library sort
            other[s:t] = np.sort(other[s:t])
        else:  # insertion sort: a bucket holds a few entries
            for i in range(s + 1, t):
                v = other[i]
                j = i - 1
                while j >= s and other[j] > v:
                    other[j + 1] = other[j]
                    j -= 1
                other[j + 1] = v
        for i in range(s, t):
            if i == s or other[i] != other[i - 1]:
                lifted_low[m], lifted_high[m] = u, other[i]
                m += 1
    return lifted_low[:m].copy(), lifted_high[:m].copy()


@_compiled
def level_geometry(
    first_cell: IntArray, size: IntArray, sum_x: FloatArray, sum_y: FloatArray, k: int, side: int
) -> tuple[IntArray, FloatArray]:
    """Each node's block (x, y) at level k, from its first cell (y * side + x), and its centre:
    the mean of its cells' (x + 0.5, y + 0.5), from their number and the sums of their x and y
    (level 0, no sums: the cell's own), by the operations the vectorised build used (the same
    bits)."""
    count = len(first_cell)
    shift = 0
    while 1 << shift < side:
        shift += 1
    block = np.empty((count, 2), dtype=np.int64)
    centre = np.empty((count, 2), dtype=np.float64)
    for i in range(count):
        x, y = first_cell[i] & (side - 1), first_cell[i] >> shift
        block[i, 0], block[i, 1] = x >> k, y >> k
        if len(sum_x) == 0:
            centre[i, 0], centre[i, 1] = block[i, 0] + 0.5, block[i, 1] + 0.5
        else:
            n = max(size[i], 1)
            centre[i, 0] = (sum_x[i] + 0.5 * size[i]) / n
            centre[i, 1] = (sum_y[i] + 0.5 * size[i]) / n
    return block, centre


@_compiled
def cell_nodes(free: NDArray[np.bool_]) -> tuple[IntArray, IntArray]:
    """Level 0 of the abstraction: the free cells' indices (y * side + x) in raster order, and
    each cell's node (its rank among them; -1 where blocked), ravelled."""
    flat = free.ravel()
    node = np.empty(len(flat), dtype=np.int64)
    count = 0
    for c in range(len(flat)):
        if flat[c]:
            node[c] = count
            count += 1
        else:
            node[c] = -1
    cells = np.empty(count, dtype=np.int64)
    for c in range(len(flat)):
        if node[c] >= 0:
            cells[node[c]] = c
    return cells, node


@_compiled
def lift(nodes: IntArray, parent: IntArray) -> None:
    """Each of `nodes` replaced by its `parent` (one level up), in place."""
    for i in range(len(nodes)):
        nodes[i] = parent[nodes[i]]


@_compiled
def compressed_rows(
    low: IntArray, high: IntArray, centre: FloatArray, movement: int
) -> tuple[IntArray, IntArray, FloatArray]:
    """A level's edges (low < high, sorted by low, then high) as compressed rows over its nodes
    (first, neighbour, cost), each edge costing the distance between its ends' centres (row i:
    node i's x, y) as the robot moves (`world.move_distance`, by the same operations): a node's
    row holds its higher neighbours, then its lower ones, each ascending."""
    n, count = len(low), len(centre)
    first = np.zeros(count + 1, dtype=np.int64)
    step = np.empty(n, dtype=np.float64)
    for i in range(n):
        u, v = low[i], high[i]
        first[u + 1] += 1
        first[v + 1] += 1
        dx, dy = abs(centre[u, 0] - centre[v, 0]), abs(centre[u, 1] - centre[v, 1])
        step[i] = _move_distance(dx, dy, movement)
    for u in range(count):
        first[u + 1] += first[u]
    slot = first[:-1].copy()
    neighbour = np.empty(2 * n, dtype=np.int64)
    cost = np.empty(2 * n, dtype=np.float64)
    for i in range(n):  # each node's higher neighbours, ascending: the edges' order
        u = low[i]
        neighbour[slot[u]], cost[slot[u]] = high[i], step[i]
        slot[u] += 1
    for i in range(n):  # then its lower ones, ascending likewise
        v = high[i]
        neighbour[slot[v]], cost[slot[v]] = low[i], step[i]
        slot[v] += 1
    return first, neighbour, cost


@_compiled
def quads(
    free: NDArray[np.bool_],
    cell_node: IntArray,
    movement: int,
    labels: NDArray[np.int8],
    moves: IntArray,
    side_joins: NDArray[np.uint8],
) -> tuple[IntArray, int, IntArray, IntArray, IntArray, IntArray, IntArray, FloatArray, FloatArray]:
    """Level 1 of the abstraction (`components._quads`) in three passes over the 2 x 2 blocks:
    each block's pattern of free cells (bit 2y + x) and its components (`labels`, one row per
    pattern), numbered block by block in raster order; the level-1 node of each level-0 node
    (`cell_node`: the level-0 node of each base cell, ravelled, -1 where blocked), the level-0
    nodes of each level-1 node, node by node, and each node's first cell (raster order); then
    the edges each block has to the blocks after it (`moves`: the rows (direction, tail
    position, head position, dx, dy) of the legal moves into the `_FORWARD` blocks, by
    direction, the diagonals needing their two corner cells free; for the blocks beside and
    below, whose moves' corner cells are all in the two blocks, `side_joins[d >> 1, pattern,
    pattern]` holds the pairs those rows join), made in ascending order (by
    low, then high) without a sort: a block's lower node first, the directions' blocks in raster
    order, and their lower node before their higher within each. (No map-sized array is made:
    the level-1 grid is the level-0 grid's nodes' parents, `components._Grids`.)

    Returns (parent of each level-0 node, count, low, high, children, first cell of each
    node, and each node's number of cells and the sums of their x and of their y: integers, so
    exact in any order)."""
    side = free.shape[0]
    m = side // 2
    pattern = np.zeros(m * m, dtype=np.int64)
    offset = np.full(m * m, -1, dtype=np.int64)
    count = 0
    occupied = 0
    for by in range(m):
        for bx in range(m):
            y, x = 2 * by, 2 * bx
            p = (
                np.int64(free[y, x])
                | np.int64(free[y, x + 1]) << 1
                | np.int64(free[y + 1, x]) << 2
                | np.int64(free[y + 1, x + 1]) << 3
            )
            if p:
                b = by * m + bx
                pattern[b] = p
                offset[b] = count
                most = -1
                for q in range(4):
                    if labels[p, q] > most:
                        most = labels[p, q]
                count += most + 1
                occupied += 1
    parent = np.empty(4 * occupied, dtype=np.int64)
    children = np.empty(4 * occupied, dtype=np.int64)
    first_cell = np.full(count, -1, dtype=np.int64)
    size = np.zeros(count, dtype=np.int64)
    sum_x = np.zeros(count, dtype=np.float64)
    sum_y = np.zeros(count, dtype=np.float64)
    k = 0
    for b in range(m * m):
        p = pattern[b]
        if p == 0:
            continue
        x, y = 2 * (b % m), 2 * (b // m)
        for q in range(4):
            label = labels[p, q]
            if label >= 0:
                cell = (y + (q >> 1)) * side + x + (q & 1)
                node = offset[b] + label
                below = cell_node[cell]
                parent[below] = node
                children[k] = below
                k += 1
                if first_cell[node] < 0:
                    first_cell[node] = cell
                size[node] += 1
                sum_x[node] += x + (q & 1)
                sum_y[node] += y + (q >> 1)
    # The pairs of components each block joins with each block after it: bit 2 * tail's label
    # + head's, per direction (`moves` ordered by direction: each one's rows read once).
    move_first = np.zeros(5, dtype=np.int64)
    for r in range(len(moves)):
        move_first[moves[r, 0] + 1] = r + 1
    for d in range(4):
        move_first[d + 1] = max(move_first[d + 1], move_first[d])
    fdx = (1, -1, 0, 1)
    fdy = (0, 1, 1, 1)
    joined = np.zeros(4 * m * m, dtype=np.uint8)
    total = 0
    for b in range(m * m):
        p = pattern[b]
        if p == 0:
            continue
        bx, by = b % m, b // m
        for d in range(4):
            nx, ny = bx + fdx[d], by + fdy[d]
            if nx < 0 or nx >= m or ny >= m or pattern[ny * m + nx] == 0:
                continue
            np_ = pattern[ny * m + nx]
            if d == 0 or d == 2:  # the blocks beside and below: read off the two patterns
                pairs = int(side_joins[d >> 1, p, np_])
                joined[4 * b + d] = pairs
                total += (pairs & 1) + (pairs >> 1 & 1) + (pairs >> 2 & 1) + (pairs >> 3)
                continue
            bits = 0
            for r in range(move_first[d], move_first[d + 1]):
                tail, head, dx, dy = moves[r, 1], moves[r, 2], moves[r, 3], moves[r, 4]
                tail_label, head_label = labels[p, tail], labels[np_, head]
                if tail_label < 0 or head_label < 0:
                    continue
                if dx != 0 and dy != 0:  # no corner cutting: both orthogonal neighbours free
                    tx, ty = 2 * bx + (tail & 1), 2 * by + (tail >> 1)
                    if not (free[ty, tx + dx] and free[ty + dy, tx]):
                        continue
                bits |= 1 << (2 * tail_label + head_label)
            joined[4 * b + d] = bits
            for bit in range(4):
                total += (bits >> bit) & 1
    low = np.empty(total, dtype=np.int64)
    high = np.empty(total, dtype=np.int64)
    e = 0
    for b in range(m * m):
        if pattern[b] == 0:
            continue
        bx, by = b % m, b // m
        for tail_label in range(2):
            for d in range(4):
                bits = joined[4 * b + d]
                if bits == 0:
                    continue
                nb = (by + fdy[d]) * m + bx + fdx[d]
                for head_label in range(2):
                    if bits >> (2 * tail_label + head_label) & 1:
                        low[e] = offset[b] + tail_label
                        high[e] = offset[nb] + head_label
                        e += 1
    return parent[:k], count, low, high, children[:k], first_cell, size, sum_x, sum_y


@_compiled
def _root(parent: IntArray, u: int) -> int:
    """Node u's representative in the union-find forest `parent`, halving the path to it."""
    while parent[u] != u:
        parent[u] = parent[parent[u]]
        u = parent[u]
    return u


@_compiled
def grouped_components(
    low: IntArray, high: IntArray, group: IntArray, first_cell: IntArray, side: int
) -> tuple[IntArray, int, IntArray]:
    """The components of the graph of the edges (low, high) that stay within a `group`
    (`components._components`), by union-find: each node's component, their number and first
    cells (the least of their nodes' `first_cell`), numbered by group, then by first cell."""
    n = len(group)
    forest = np.arange(n)
    for e in range(len(low)):
        a, b = low[e], high[e]
        if group[a] == group[b]:
            ra, rb = _root(forest, a), _root(forest, b)
            if ra != rb:
                forest[max(ra, rb)] = min(ra, rb)
    label = np.full(n, -1, dtype=np.int64)
    count = 0
    for u in range(n):
        r = _root(forest, u)
        if label[r] < 0:
            label[r] = count
            count += 1
        label[u] = label[r]
    first = np.full(count, side * side, dtype=np.int64)
    where = np.zeros(count, dtype=np.int64)
    for u in range(n):
        c = label[u]
        first[c] = min(first[c], first_cell[u])
        where[c] = group[u]
    order = np.argsort(where * side * side + first)  # unique keys: first cells differ
    rank = np.empty(count, dtype=np.int64)
    rank[order] = np.arange(count)
    component = np.empty(n, dtype=np.int64)
    for u in range(n):
        component[u] = rank[label[u]]
    return component, count, first[order]


@_compiled
def door_points(
    grid: IntArray,
    up: IntArray,
    level: int,
    movement: int,
    ordered: IntArray,
    order: IntArray,
    count: int,
    states: int,
) -> FloatArray:
    """The doors' points (`doors.Doors`), in one pass over the grid: for each legal base move
    between two nodes of a level (each cell's node `up[grid[y, x]]`, none where `grid` is -1,
    blocked), its midpoint added to the state from the lower node to the higher (`ordered`:
    tail * count + head of the states, ascending, `order` their states), then each such
    state's mean. (The midpoints are multiples of 1/2, so their sums are exact in any
    order.) Only the cells of the last row and of the first and last columns of each block of
    the `level` are read: a legal move within a block joins two cells of one node (its
    connected components are the nodes), and from any other cell every move stays in it."""
    sums = np.zeros((states, 2))
    moves = np.zeros(states)
    height, width = grid.shape
    side = 1 << level
    for y in range(height):
        if y & (side - 1) == side - 1 or side <= 2:  # its moves down leave the block
            for x in range(width):
                _door_moves(grid, up, movement, ordered, order, count, sums, moves, x, y)
        else:
            for x0 in range(0, width, side):
                _door_moves(grid, up, movement, ordered, order, count, sums, moves, x0, y)
                last = x0 + side - 1
                _door_moves(grid, up, movement, ordered, order, count, sums, moves, last, y)
    for j in range(states):
        if moves[j] > 0.0:
            sums[j, 0] /= moves[j]
            sums[j, 1] /= moves[j]
    return sums


@_compiled
def _door_moves(
    grid: IntArray,
    up: IntArray,
    movement: int,
    ordered: IntArray,
    order: IntArray,
    count: int,
    sums: FloatArray,
    moves: FloatArray,
    x: int,
    y: int,
) -> None:
    """`door_points`' forward moves from cell (x, y): each legal one between two nodes added
    to its state's sums."""
    height, width = grid.shape
    a = grid[y, x]
    if a < 0:
        return
    a = up[a]
    forward = 4 if movement == 8 else 2
    for m in range(forward):  # (1, 0), (0, 1), (1, 1), (-1, 1)
        dx = 1 if m == 0 or m == 2 else (-1 if m == 3 else 0)
        dy = 0 if m == 0 else 1
        tx, ty = x + dx, y + dy
        if tx < 0 or tx >= width or ty >= height:
            continue
        b = grid[ty, tx]
        if b < 0:
            continue
        b = up[b]
        if b == a:
            continue
        if dx != 0 and dy != 0 and (grid[y, tx] < 0 or grid[ty, x] < 0):
            continue  # no corner cutting: both orthogonal neighbours free
        key = min(a, b) * count + max(a, b)
        state = order[np.searchsorted(ordered, key)]
        sums[state, 0] += x + 0.5 + dx / 2
        sums[state, 1] += y + 0.5 + dy / 2
        moves[state] += 1.0


@_compiled
def _before(f: FloatArray, h: FloatArray, c: IntArray, i: int, j: int) -> bool:
    """Whether heap entry i comes before entry j: keys (f, -g, counter), as `heapq` orders the
    tuples of the pure-Python A* (`search.find_path_to_box`), so both pop in the same order."""
    if f[i] != f[j]:
        return bool(f[i] < f[j])
    if h[i] != h[j]:
        return bool(h[i] < h[j])
    return bool(c[i] < c[j])


@_compiled
def grid_astar(
    mult: FloatArray,
    stride: int,
    source: int,
    goal: int,
    goal_x: int,
    goal_y: int,
    octile: bool,
    unit: float,
    g: FloatArray,
    parent: IntArray,
    seen: IntArray,
    done: IntArray,
    generation: int,
) -> tuple[IntArray, float, int]:
    """A* on a whole grid from cell `source` to cell `goal` (padded, ravelled indices; `mult` the
    step multiplier of each padded cell, < 0 where impassable, a row `stride` cells; the goal's
    padded coordinates `goal_x`, `goal_y`): the pure-Python `search.find_path_to_box` for one
    source and a one-cell box, step for step (the same heuristic, arithmetic and heap order:
    the same path and expansions).

    `g`, `parent`, `seen` and `done` are the caller's, one entry per padded cell, kept between
    queries: an entry of `g` or `parent` counts only where `seen` is `generation`, a cell is
    closed only where `done` is, so no query clears a map-sized array.

    Returns (the path's padded cells, source first; empty when the goal is not reached), its
    cost, and the expansions (the goal, popped last, not counted)."""
    diagonal_unit = unit * (_SQRT2 - 1.0)
    capacity = 1024
    hf = np.empty(capacity, dtype=np.float64)
    hg = np.empty(capacity, dtype=np.float64)
    hc = np.empty(capacity, dtype=np.int64)
    hn = np.empty(capacity, dtype=np.int64)
    straight = (1, -1, stride, -stride)
    sdx = (1, -1, 0, 0)
    sdy = (0, 0, 1, -1)
    seen[source] = generation
    g[source] = 0.0
    parent[source] = -1
    sy, sx = source // stride, source % stride
    dx0, dy0 = abs(sx - goal_x), abs(sy - goal_y)
    if octile:
        h0 = unit * max(dx0, dy0) + diagonal_unit * min(dx0, dy0)
    else:
        h0 = unit * (dx0 + dy0)
    counter = 1
    hf[0], hg[0], hc[0], hn[0] = h0, -0.0, counter, source
    size = 1
    expansions = 0
    found = False
    while size > 0:
        node = hn[0]
        # pop the least entry: the last one sifted down from the root
        size -= 1
        if size > 0:
            hf[0], hg[0], hc[0], hn[0] = hf[size], hg[size], hc[size], hn[size]
            i = 0
            while True:
                child = 2 * i + 1
                if child >= size:
                    break
                if child + 1 < size and _before(hf, hg, hc, child + 1, child):
                    child += 1
                if not _before(hf, hg, hc, child, i):
                    break
                hf[i], hf[child] = hf[child], hf[i]
                hg[i], hg[child] = hg[child], hg[i]
                hc[i], hc[child] = hc[child], hc[i]
                hn[i], hn[child] = hn[child], hn[i]
                i = child
        if done[node] == generation:
            continue  # a stale entry: the cell was closed with a smaller g
        if node == goal:
            found = True
            break
        done[node] = generation
        expansions += 1
        g_node = g[node]
        y, x = node // stride, node % stride
        for k in range(8 if octile else 4):
            if k < 4:
                offset = straight[k]
                nx, ny = x + sdx[k], y + sdy[k]
                m = mult[node + offset]
                if m < 0.0:
                    continue
                step = m
            else:
                ddx = 1 if k == 4 or k == 6 else -1
                ddy = 1 if k < 6 else -1
                offset = ddy * stride + ddx
                nx, ny = x + ddx, y + ddy
                m = mult[node + offset]
                if m < 0.0 or mult[node + ddx] < 0.0 or mult[node + ddy * stride] < 0.0:
                    continue  # no corner cutting: both orthogonal neighbours free
                step = _SQRT2 * m
            neighbour = node + offset
            if done[neighbour] == generation:
                continue
            g_new = g_node + step
            if seen[neighbour] != generation or g_new < g[neighbour]:
                seen[neighbour] = generation
                g[neighbour] = g_new
                parent[neighbour] = node
                dx, dy = abs(nx - goal_x), abs(ny - goal_y)
                if octile:
                    if dx > dy:
                        h = unit * dx + diagonal_unit * dy
                    else:
                        h = unit * dy + diagonal_unit * dx
                else:
                    h = unit * (dx + dy)
                counter += 1
                if size == capacity:
                    capacity *= 2
                    hf2 = np.empty(capacity, dtype=np.float64)
                    hg2 = np.empty(capacity, dtype=np.float64)
                    hc2 = np.empty(capacity, dtype=np.int64)
                    hn2 = np.empty(capacity, dtype=np.int64)
                    hf2[:size], hg2[:size], hc2[:size], hn2[:size] = hf, hg, hc, hn
                    hf, hg, hc, hn = hf2, hg2, hc2, hn2
                # push: sift the new entry up from the end
                i = size
                hf[i], hg[i], hc[i], hn[i] = g_new + h, -g_new, counter, neighbour
                size += 1
                while i > 0:
                    up = (i - 1) >> 1
                    if not _before(hf, hg, hc, i, up):
                        break
                    hf[i], hf[up] = hf[up], hf[i]
                    hg[i], hg[up] = hg[up], hg[i]
                    hc[i], hc[up] = hc[up], hc[i]
                    hn[i], hn[up] = hn[up], hn[i]
                    i = up
    if not found:
        return np.empty(0, dtype=np.int64), np.inf, expansions
    count = 0
    u = goal
    while u >= 0:
        count += 1
        u = parent[u]
    path = np.empty(count, dtype=np.int64)
    u = goal
    for i in range(count - 1, -1, -1):
        path[i] = u
        u = parent[u]
    return path, g[goal], expansions


# The anytime planner's refinement step (`planner.atp`) in one compiled call: WORST-SEGMENT, the
# refinement's search, the two halves and the quality estimate kept up to date, over a plan held
# in arrays (issue 36: the step's Python objects and numpy calls were 25-40% of the planner's
# time). A plan's segments are numbered in the order they are made; segment s is at level
# `level[s]`, its nodes `pool[begin[s]:end[s]]`, its mean obstacleness `obstacleness[s]`;
# `order[:counts[0]]` the plan's segments in route order; `counts` also holds how many segments
# were made, how many entries of `pool` are used and the heap's size; `sums` the estimate's
# extent and credit. A level k >= 2's arrays are slices of the concatenations of those of
# levels 2 .. top (`Components.stacked`), levels 0 and 1's are passed apart (`_of_level`).


@_compiled
def pairwise_sum(values: FloatArray, lo: int, n: int) -> float:
    """The sum of `values[lo:lo + n]` exactly as numpy's `np.add.reduce` makes it (pairwise, by
    blocks of 128 in eight lanes): the means the planner keeps match those made in Python to
    the last bit. numpy halves a longer run (the first half a multiple of 8) and adds the two
    sums; here that tree is walked with a stack of its pending halves rather than by recursion
    (a recursive function compiled into a caller that numba caches is left unresolved when the
    caller is loaded from the cache: the process crashed)."""
    if n <= 128:
        return _block_sum(values, lo, n)
    starts = np.empty(64, dtype=np.int64)  # the runs being summed, outermost first
    sizes = np.empty(64, dtype=np.int64)
    left = np.empty(64)  # each run's first half's sum, once it is made
    done_left = np.zeros(64, dtype=np.bool_)
    top = 0
    starts[0], sizes[0] = lo, n
    made = 0.0  # the sum of the run just finished
    returning = False
    while top >= 0:
        if returning:  # `made` is a half of the run on top of the stack
            if not done_left[top]:
                left[top], done_left[top] = made, True
                half = sizes[top] // 2
                half -= half % 8
                top += 1
                starts[top], sizes[top], done_left[top] = (
                    starts[top - 1] + half,
                    sizes[top - 1] - half,
                    False,
                )
                returning = False
            else:
                made = left[top] + made
                top -= 1
            continue
        if sizes[top] <= 128:
            made = _block_sum(values, starts[top], sizes[top])
            top -= 1
            returning = True
            continue
        half = sizes[top] // 2
        half -= half % 8
        top += 1
        starts[top], sizes[top], done_left[top] = starts[top - 1], half, False
    return float(made)


@_compiled
def _block_sum(values: FloatArray, lo: int, n: int) -> float:
    """numpy's sum of a run of at most 128: in order below 8, else in eight lanes."""
    if n < 8:
        total = 0.0
        for i in range(lo, lo + n):
            total += values[i]
        return total
    r = values[lo : lo + 8].copy()
    i = 8
    while i < n - (n % 8):
        for j in range(8):
            r[j] += values[lo + i + j]
        i += 8
    total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        total += values[lo + i]
        i += 1
    return float(total)


@_compiled
def _before_in_heap(keys: FloatArray, items: IntArray, i: int, key: float, item: int) -> bool:
    """Whether heap entry i comes before (key, item): by key, then by item (the order made)."""
    return bool(keys[i] < key or (keys[i] == key and items[i] < item))


@_compiled
def _push_ordered(keys: FloatArray, items: IntArray, size: int, key: float, item: int) -> int:
    """`_push` with ties broken by the smaller item (Python's heap of (key, order) tuples)."""
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if _before_in_heap(keys, items, parent, key, item):
            break
        keys[i], items[i] = keys[parent], items[parent]
        i = parent
    keys[i], items[i] = key, item
    return size + 1


@_compiled
def _pop_ordered(keys: FloatArray, items: IntArray, size: int) -> int:
    """`_pop` with ties broken by the smaller item; the new size."""
    size -= 1
    key, item = keys[size], items[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        if child + 1 < size and _before_in_heap(keys, items, child + 1, keys[child], items[child]):
            child += 1
        if not _before_in_heap(keys, items, child, key, item):
            break
        keys[i], items[i] = keys[child], items[child]
        i = child
    if size > 0:
        keys[i], items[i] = key, item
    return size


@_compiled
def _credit(moves: int, level: int, obstacleness: float, top: int) -> tuple[float, float]:
    """A segment's (extent, credit) in the quality estimate (`planner._credit`, the same
    arithmetic)."""
    extent = max(moves, 1) * float(1 << level)
    if level == 0:
        return extent, extent
    coarseness = 1.0 - level / (top + 1)
    return extent, extent * (1.0 - obstacleness) * coarseness


@_compiled
def _entered(
    s: int,
    level: IntArray,
    begin: IntArray,
    end: IntArray,
    obstacleness: FloatArray,
    heap_keys: FloatArray,
    heap_items: IntArray,
    counts: IntArray,
    sums: FloatArray,
    top: int,
) -> None:
    """Segment s enters the estimate and, above level 0, WORST-SEGMENT's heap (`_Worst.add`),
    its score `2^k * (1 + o)`."""
    extent, credit = _credit(end[s] - begin[s] - 1, level[s], obstacleness[s], top)
    sums[0] += extent
    sums[1] += credit
    if level[s] > 0:
        score = (1 << level[s]) * (1.0 + obstacleness[s])
        counts[3] = _push_ordered(heap_keys, heap_items, counts[3], -score, s)


@_compiled
def begin_plan(
    level: IntArray,
    begin: IntArray,
    end: IntArray,
    obstacleness: FloatArray,
    heap_keys: FloatArray,
    heap_items: IntArray,
    counts: IntArray,
    sums: FloatArray,
    top: int,
) -> float:
    """The first `counts[1]` segments, in route order, enter the estimate and the heap; the
    estimate."""
    sums[0] = sums[1] = 0.0
    counts[3] = 0
    for s in range(counts[1]):
        _entered(s, level, begin, end, obstacleness, heap_keys, heap_items, counts, sums, top)
    return float(min(1.0, max(0.0, sums[1] / sums[0])))


@_compiled
def _ancestor(node: int, level: int, to_level: int, parent0: IntArray, parent1: IntArray,
              parents: IntArray, node_at: IntArray) -> int:  # fmt: skip
    """The node at `to_level` that contains `node` of `level` (`Components.ancestor`)."""
    for k in range(level, to_level):
        if k == 0:
            node = parent0[node]
        elif k == 1:
            node = parent1[node]
        else:
            node = parents[node_at[k] + node]
    return node


@_compiled
def _of_level(k: int, one: Any, stacked: Any, at: IntArray) -> Any:
    """Level k's (>= 1) rows of an array: level 1's apart, those of levels 2 and up a slice of
    their concatenation (`Components.stacked`)."""
    if k == 1:
        return one
    return stacked[at[k] : at[k + 1]]


@_compiled
def _clear_share(
    route: IntArray,
    k: int,
    block1: IntArray,
    blocks: IntArray,
    node_at: IntArray,
    pyramid: FloatArray,
    pyramid_at: IntArray,
    pyramid_side: IntArray,
) -> float:
    """The share of a level-k route's nodes whose blocks are clear (no blocked cell: the node is
    its whole block)."""
    block = _of_level(k, block1, blocks, node_at)
    side = pyramid_side[k]
    clear = 0
    for node in route:
        clear += pyramid[pyramid_at[k] + block[node, 1] * side + block[node, 0]] == 0.0
    return clear / len(route)


@_compiled
def refine_step(
    level: IntArray,
    begin: IntArray,
    end: IntArray,
    obstacleness: FloatArray,
    pool: IntArray,
    order: IntArray,
    heap_keys: FloatArray,
    heap_items: IntArray,
    counts: IntArray,
    sums: FloatArray,
    parent0: IntArray,
    block0: IntArray,
    centre0: FloatArray,
    scratch0: IntArray,
    padded: IntArray,
    cells: CellArray,
    wide: int,
    parent1: IntArray,
    block1: IntArray,
    centre1: FloatArray,
    scratch1: IntArray,
    first1: IntArray,
    neighbour1: IntArray,
    cost1: FloatArray,
    first_child1: IntArray,
    child1: IntArray,
    node_at: IntArray,
    parents: IntArray,
    blocks: IntArray,
    centres: FloatArray,
    scratches: IntArray,
    first_at: IntArray,
    firsts: IntArray,
    edge_at: IntArray,
    neighbours: IntArray,
    costs: FloatArray,
    child_at: IntArray,
    first_children: IntArray,
    children: IntArray,
    pyramid: FloatArray,
    pyramid_at: IntArray,
    pyramid_side: IntArray,
    movement: int,
    top: int,
    rings_by_level: IntArray,
    start: int,
    goal: int,
    no_ring_when_open: float,
    one_ring_when_open: float,
    no_ring_when_clear: float,
    skip_level_1: bool,
    jump_points: bool,
    limit: float,
) -> tuple[int, int, int, int, int, float, IntArray, IntArray, IntArray]:
    """REFINE(WORST-SEGMENT(plan)) (`planner._Planner.refine`, the same choices): the worst
    segment's nodes searched one level lower through the children of its nodes and of
    `rings_by_level[k]` rings of neighbours (none or one when its mean obstacleness is at most
    `no_ring_when_open` at level 1 or `one_ring_when_open` at level 2, and none at level 2
    when at least the share `no_ring_when_clear` of its nodes are clear blocks; NaN: never); a
    level-2 segment is searched at level 0 instead with `skip_level_1`, through its own nodes'
    cells (no rings: `refinement`'s two levels down); its
    ends
    the start's and goal's nodes (`start`, `goal`: level 0's) or a finer neighbour's end, else
    any child of its end node, costed toward the coarser neighbour's next node; the path found
    cut at its middle into two segments (one when it has fewer than two moves) in its place.

    Returns (what it did, `search.STEP_*`; the plan's index of the segment refined; the new
    segments' level; the rings searched; the search's expansions; the quality estimate after
    it; the path's nodes; their blocks (x, y) at that level; `pool`, grown when it ran out).
    Over `limit` or without a path, the plan is left as it was."""
    nothing = np.zeros(0, dtype=np.int64)
    no_blocks = np.zeros((0, 2), dtype=np.int64)
    if counts[3] == 0:
        return STEP_NONE_LEFT, -1, -1, -1, 0, 1.0, nothing, no_blocks, pool
    s = heap_items[0]
    counts[3] = _pop_ordered(heap_keys, heap_items, counts[3])
    count = counts[0]
    index = 0
    while order[index] != s:
        index += 1
    k = level[s]
    # Straight to the base level (then no segment is ever of level 1: the plan's segments are
    # of level 2 or above until refined, and then of level 0)
    to_base = skip_level_1 and k == 2
    lower = 0 if to_base else k - 1
    if index == 0:
        source = _ancestor(start, 0, lower, parent0, parent1, parents, node_at)
        source_node, source_x, source_y = -1, 0.0, 0.0
    else:
        p = order[index - 1]
        if level[p] <= lower:
            source = _ancestor(
                pool[end[p] - 1], level[p], lower, parent0, parent1, parents, node_at
            )
            source_node, source_x, source_y = -1, 0.0, 0.0
        else:
            toward = pool[begin[p] + max(end[p] - begin[p] - 2, 0)]
            source, source_node = -1, pool[begin[s]]
            centre = _of_level(level[p], centre1, centres, node_at)
            source_x, source_y = centre[toward, 0], centre[toward, 1]
    if index == count - 1:
        target = _ancestor(goal, 0, lower, parent0, parent1, parents, node_at)
        target_node, target_x, target_y = -1, 0.0, 0.0
    else:
        n = order[index + 1]
        if level[n] <= lower:
            target = _ancestor(pool[begin[n]], level[n], lower, parent0, parent1, parents, node_at)
            target_node, target_x, target_y = -1, 0.0, 0.0
        else:
            toward = pool[begin[n] + min(1, end[n] - begin[n] - 1)]
            target, target_node = -1, pool[end[s] - 1]
            centre = _of_level(level[n], centre1, centres, node_at)
            target_x, target_y = centre[toward, 0], centre[toward, 1]
    o = obstacleness[s]
    rings = rings_by_level[k] if k < len(rings_by_level) else 1
    if k == 1 and o <= no_ring_when_open:
        rings = 0
    if k == 2 and o <= one_ring_when_open:
        rings = 1
    route = pool[begin[s] : end[s]]
    if to_base:  # through the route's own nodes' cells
        rings = 0
    elif k == 2 and no_ring_when_clear <= 1.0:  # NaN: never
        clear = _clear_share(route, k, block1, blocks, node_at, pyramid, pyramid_at, pyramid_side)
        if clear >= no_ring_when_clear:
            rings = 0
    up_nodes = _of_level(k, scratch1, scratches, node_at)
    up_first = _of_level(k, first1, firsts, first_at)
    up_neighbour = _of_level(k, neighbour1, neighbours, edge_at)
    first_child = _of_level(k, first_child1, first_children, first_at)
    child = _of_level(k, child1, children, child_at)
    if lower == 0:
        grand_first_child, grand_child = (first_child1, child1) if to_base else (nothing, nothing)
        path, _, expansions = refinement(
            up_first, up_neighbour, first_child, child, up_nodes, route, rings,
            grand_first_child, grand_child,
            nothing, nothing, np.zeros(0), padded, cells, wide, block0, centre0, movement,
            jump_points, scratch0,
            source, source_node, source_x, source_y, target, target_node, target_x, target_y,
        )  # fmt: skip
        blocks_lower = block0
    else:
        blocks_lower = _of_level(lower, block1, blocks, node_at)
        path, _, expansions = refinement(
            up_first, up_neighbour, first_child, child, up_nodes, route, rings, nothing, nothing,
            _of_level(lower, first1, firsts, first_at),
            _of_level(lower, neighbour1, neighbours, edge_at),
            _of_level(lower, cost1, costs, edge_at),
            nothing, np.zeros(0, dtype=np.uint8), 0, blocks_lower,
            _of_level(lower, centre1, centres, node_at), movement,
            False, _of_level(lower, scratch1, scratches, node_at),
            source, source_node, source_x, source_y, target, target_node, target_x, target_y,
        )  # fmt: skip
    if expansions > limit:  # checked first, as `Components.refinement` does
        return STEP_OVER, index, lower, rings, expansions, 0.0, path, no_blocks, pool
    if not len(path):
        return STEP_NO_PATH, index, lower, rings, expansions, 0.0, path, no_blocks, pool
    # The path's blocks and their obstacleness, then its halves made segments in its place.
    moves = len(path) - 1
    found = np.empty((moves + 1, 2), dtype=np.int64)
    values = np.empty(moves + 1)
    side = pyramid_side[lower]
    for i in range(moves + 1):
        x, y = blocks_lower[path[i], 0], blocks_lower[path[i], 1]
        found[i, 0], found[i, 1] = x, y
        values[i] = pyramid[pyramid_at[lower] + y * side + x]
    if counts[2] + 2 * (moves + 1) > len(pool):
        pool = _grown_pool(pool, counts[2] + 2 * (moves + 1))
    halves = 1 if moves < 2 else 2
    middle = moves // 2
    # `_Worst.remove`, then `add` for each half, in that order (the sums' rounding).
    extent, credit = _credit(end[s] - begin[s] - 1, k, o, top)
    sums[0] -= extent
    sums[1] -= credit
    if halves == 2:
        for i in range(count - 1, index, -1):
            order[i + 1] = order[i]
        counts[0] = count + 1
    for h in range(halves):
        first, last = (0, moves) if halves == 1 else ((0, middle) if h == 0 else (middle, moves))
        new = counts[1]
        counts[1] = new + 1
        level[new] = lower
        begin[new] = counts[2]
        pool[counts[2] : counts[2] + last + 1 - first] = path[first : last + 1]
        counts[2] += last + 1 - first
        end[new] = counts[2]
        obstacleness[new] = pairwise_sum(values, first, last + 1 - first) / (last + 1 - first)
        order[index + h] = new
        _entered(new, level, begin, end, obstacleness, heap_keys, heap_items, counts, sums, top)
    quality = 1.0 if counts[3] == 0 else min(1.0, max(0.0, sums[1] / sums[0]))
    return STEP_REFINED, index, lower, rings, expansions, quality, path, found, pool


@_compiled
def _grown_pool(pool: IntArray, least: int) -> IntArray:
    grown = np.empty(max(2 * len(pool), least), dtype=np.int64)
    grown[: len(pool)] = pool
    return grown
