"""How long a route the robot walks following a plan on the map it was made on, compiled: the
`follow` that makes `planner.atp`'s anytime curve monotone (issue 36, item 3).

`Follower(blocked, movement)(plan)` is `execution.execute(plan, blocked, movement=movement,
keep_to_plan=True).length`, to the bit: the same waypoints (`execution.waypoints`), the same
steps into their blocks, the same obstacle avoidance (A* on the robot's memory inside the
plan's corridor, `MultiPath.corridor`, the same windows, the same heap order, so the same
path whenever several are equally short) and the same re-plans. What differs is the cost:
`execute` runs in Python and materialises the corridor and the reachable cells once per call
(10-20 ms per plan on a 512 x 512 MovingAI map, five to nine times the compiled A*'s time for
the ATP's 15 or 16 plans of a long problem); here the map's connected cells are labelled once
per map, each plan's nodes are marked in a table per level (a cell's node at each level is its
level-0 node's ancestor), the corridor is judged cell by cell as obstacle avoidance's searches
reach it, and a plan is followed from where the last one's route stops being its own (a
refinement changes one segment: the route before it, up to a corridor cell the change touched,
is the same) up to where it is the last one's again: once the robot stands where the last
plan's run stood before a waypoint from which the two plans' waypoints are the same to the
goal, and no cell that run touched from there on (read by its searches, or seen) differs in
the robot's memory or in the corridor, the rest of the route is that run's, taken over. All of
it compiled, the search's inner loop written out (numba counts a reference for each array an
inlined call is passed, which cost more than the search itself): on random512-10-0's 16
longest problems, every plan of the large-map options followed in order, about 0.25 ms per
plan and 4 ms per problem, a fifth of the compiled A*'s time (a quarter of it the first plan's
walk from the start; after it, three fifths of the waypoints a plan would walk again are taken
over).

With it, `atp(..., follow=follower)` registers a plan only when the robot would walk no farther
following it than following the last plan registered: the executed quality never falls from
one registered plan to the next.
"""

from __future__ import annotations

import math
import mmap
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numpy.typing import NDArray

from ..world import BoolGrid, Position
from .components import Components
from .planner import MultiPath, Segment

__all__ = ["Follower"]

IntArray = NDArray[np.int64]

_SQRT2 = math.sqrt(2.0)
_F = TypeVar("_F")


def _compiled(function: _F) -> _F:
    """Compiled to machine code on the first call and cached on disk for the next process."""
    return cast(_F, numba.njit(cache=True, nogil=True)(function))


def _inlined(function: _F) -> _F:
    """Compiled into its callers: a call passing arrays counts references to each, which cost
    more than these small functions' own work (they run for every cell a search reaches)."""
    return cast(_F, numba.njit(cache=True, nogil=True, inline="always")(function))


# execute's move order: straight moves first, then the diagonals (`execution._step_into`), and
# find_path_to_box's (`search`): its neighbour order decides which of equal keys is pushed first.
_STEP_DX = np.array([1, -1, 0, 0, 1, -1, 1, -1], dtype=np.int64)
_STEP_DY = np.array([0, 0, 1, -1, 1, 1, -1, -1], dtype=np.int64)
_ASTAR_DX = np.array([1, -1, 0, 0, 1, -1, 1, -1], dtype=np.int64)
_ASTAR_DY = np.array([0, 0, 1, -1, 1, 1, -1, -1], dtype=np.int64)


@_inlined
def _less(f1: float, n1: float, c1: int, f2: float, n2: float, c2: int) -> bool:
    """find_path_to_box's heap order: its keys (f, -g, counter) as tuples compare (the heap
    holds -g, `n`)."""
    if f1 != f2:
        return f1 < f2
    if n1 != n2:
        return n1 < n2
    return c1 < c2


@_inlined
def _push(
    hf: NDArray[np.float64],
    hg: NDArray[np.float64],
    hc: IntArray,
    hn: IntArray,
    size: int,
    f: float,
    g: float,
    c: int,
    n: int,
) -> int:
    i = size
    while i > 0:
        parent = (i - 1) >> 1
        if not _less(f, g, c, hf[parent], hg[parent], hc[parent]):
            break
        hf[i], hg[i], hc[i], hn[i] = hf[parent], hg[parent], hc[parent], hn[parent]
        i = parent
    hf[i], hg[i], hc[i], hn[i] = f, g, c, n
    return size + 1


# The follower's state, map-sized columns of `stamps` (rows x + y * width: a cell's stamps side
# by side, in one cache line): a cell's entry in a
# column holds while it carries the current epoch's number (a new problem starts a new epoch), or
# the search's for the last two, so nothing map-sized is cleared between plans or searches.
# _MEMORY: the robot has seen the cell blocked; _MEANT, _CORRIDOR: `meant` and `corridor` hold
# the cell's (dropped when a node of its or of a neighbour's flips in or out of the plan);
# _TOUCHED: the cell is in the touched log for the current waypoint (its visit's number);
# _LAST: `marks[0]` holds the last waypoint of the last run that touched the cell (the run's
# number); _PREVIOUS: `marks[1]` holds its place among the last run's cells seen after the
# point this run resumes from (this run's number).
_MEMORY, _MEANT, _CORRIDOR, _REACHED, _CLOSED, _TOUCHED, _LAST, _PREVIOUS = range(8)
# `counters`: the epoch, the last search's number, the route's steps, the lengths of the two
# logs (the cells seen blocked, the cells whose corridor was read, in order: what a resumed run
# takes back), how many waypoints the last plan had; statistics; the touched log's length (the
# cells each waypoint's searches read or its robot saw, once per waypoint), the run's number,
# the waypoint visit's, whether the last run's touched log is whole (its end reusable), and
# how many waypoints were taken over from the last run (statistics).
_EPOCH, _SEARCH, _STEPS, _SEEN, _READ, _COUNT, _EXPANDED, _JUDGED = range(8)
_LOGGED, _RUN, _VISIT, _WHOLE, _REUSED = range(8, 13)
# `checkpoints[i]`: the state before waypoint i of the last plan followed (its last row: at the
# end): position, moves straight and diagonal, steps, the three logs' lengths.
_CHECKPOINT = 8
_NEVER = np.iinfo(np.int64).max  # `read_at` of a cell not read
_HEAP = 8 * 8192 + 8


def _untouched(shape: tuple[int, ...], dtype: type[np.generic]) -> NDArray[Any]:
    """Zeros the kernel makes a page of 4 KiB at a time, as they are first written (an anonymous
    mapping, huge pages declined): the follower reads and writes the cells near the routes it
    follows, a small part of its map-sized arrays. numpy's own zeros ask for huge pages above
    4 MiB, and the first cell written in each 2 MiB then costs a huge page the kernel may first
    have to make room for: on brc202d (a 1,024 x 1,024 square) the first plan followed took
    5-7 ms or, when memory was fragmented, 85-97 ms."""
    count = math.prod(shape)
    size = count * np.dtype(dtype).itemsize
    pages = mmap.mmap(-1, max(size, 1))
    if hasattr(mmap, "MADV_NOHUGEPAGE"):  # Linux
        pages.madvise(mmap.MADV_NOHUGEPAGE)
    return np.frombuffer(pages, dtype=dtype, count=count).reshape(shape)


@_inlined
def _free(grids: IntArray, x: int, y: int) -> bool:
    return bool(0 <= y < grids.shape[0] and 0 <= x < grids.shape[1] and grids[y, x] >= 0)


@_compiled
def _in_corridor(
    grids: IntArray,
    ancestors: IntArray,
    held: NDArray[np.bool_],
    offsets: IntArray,
    ends: IntArray,
    stamps: IntArray,
    meant: NDArray[np.bool_],
    corridor: NDArray[np.bool_],
    epoch: int,
    corners: bool,
    x: int,
    y: int,
) -> bool:
    """`MultiPath.corridor()[y, x]`: a cell of the plan's nodes, or with 8 moves a free corner
    cell of a diagonal move between two of them. Worked out once, until a node of the cell's
    or of a neighbour's flips (`_flip`)."""
    height, width = grids.shape
    levels = ancestors.shape[1]
    c = x + y * width
    if stamps[c, _CORRIDOR] == epoch:
        return bool(corridor[c])
    # whether the cell is of the plan's nodes, or the start or the goal (`MultiPath.corridor`
    # before its corner cells), and for a free cell with 8 moves whether its four neighbours
    # (left, right, up, down) are: each worked out once into `meant`, until a node of the
    # cell's flips; written out, not a function called five times (an inlined call binds each
    # array it is passed, counting a reference to it, which cost more than the lookups)
    free = 0 <= y < height and 0 <= x < width and grids[y, x] >= 0
    bits = 0
    for k in range(5 if corners and free else 1):
        xx = x + (0, -1, 1, 0, 0)[k]
        yy = y + (0, 0, 0, -1, 1)[k]
        if not (0 <= yy < height and 0 <= xx < width):
            continue
        cc = xx + yy * width
        if stamps[cc, _MEANT] == epoch:
            held_here = bool(meant[cc])
        else:
            held_here = (xx == ends[0] and yy == ends[1]) or (xx == ends[2] and yy == ends[3])
            base = grids[yy, xx]
            if not held_here and base >= 0:
                for level in range(levels):
                    node = ancestors[base, level]
                    if offsets[level] >= 0 and node >= 0 and held[offsets[level] + node]:
                        held_here = True
                        break
            stamps[cc, _MEANT] = epoch
            meant[cc] = held_here
        if held_here:
            bits |= 1 << k
        if k == 0 and held_here:
            break
    value = bits & 1 == 1
    if not value and bits:
        # the four diagonal moves that have (x, y) as a corner cell (`MultiPath.corridor`)
        left, right, up, down = bits & 2 > 0, bits & 4 > 0, bits & 8 > 0, bits & 16 > 0
        value = (
            (left and down and _free(grids, x - 1, y + 1))
            or (up and right and _free(grids, x + 1, y - 1))
            or (left and up and _free(grids, x - 1, y - 1))
            or (down and right and _free(grids, x + 1, y + 1))
        )
    stamps[c, _CORRIDOR] = epoch
    corridor[c] = value
    return value


@_inlined
def _touch(stamps: IntArray, touched: IntArray, counters: IntArray, visit: int, c: int) -> None:
    """Log cell `c` as touched by the current waypoint (once): its memory or corridor read, or
    seen. A log longer than its array is counted, not kept (the run's end is then not reused)."""
    if stamps[c, _TOUCHED] != visit:
        stamps[c, _TOUCHED] = visit
        if counters[_LOGGED] < touched.shape[0]:
            touched[counters[_LOGGED]] = c
        counters[_LOGGED] += 1


@_inlined
def _see(
    blocked: NDArray[np.bool_],
    stamps: IntArray,
    logs: IntArray,
    touched: IntArray,
    counters: IntArray,
    epoch: int,
    visit: int,
    x: int,
    y: int,
) -> None:
    """The robot sees the cells around it: the blocked ones enter its memory (and the log), and
    the touched log (whether its memory held them or not)."""
    height, width = blocked.shape
    for yy in range(max(0, y - 1), min(height, y + 2)):
        for xx in range(max(0, x - 1), min(width, x + 2)):
            c = xx + yy * width
            if blocked[yy, xx]:
                _touch(stamps, touched, counters, visit, c)
                if stamps[c, _MEMORY] != epoch:
                    stamps[c, _MEMORY] = epoch
                    logs[0, counters[_SEEN]] = c
                    counters[_SEEN] += 1


@_inlined
def _passable(
    grids: IntArray,
    ancestors: IntArray,
    held: NDArray[np.bool_],
    offsets: IntArray,
    ends: IntArray,
    stamps: IntArray,
    meant: NDArray[np.bool_],
    corridor: NDArray[np.bool_],
    read_at: IntArray,
    logs: IntArray,
    touched: IntArray,
    counters: IntArray,
    epoch: int,
    visit: int,
    corners: bool,
    keep: bool,
    robot: int,
    waypoint: int,
    x: int,
    y: int,
) -> bool:
    """Whether obstacle avoidance's search may enter (x, y): not in the memory, and with `keep`
    in the plan's corridor (or the robot's own cell). A corridor cell read for the first time
    is logged with its waypoint: a later plan whose corridor differs there resumes before it;
    every cell read is touched (`_touch`)."""
    c = x + y * grids.shape[1]
    _touch(stamps, touched, counters, visit, c)
    if stamps[c, _MEMORY] == epoch:
        return False
    if not keep or c == robot:
        return True
    if read_at[c] > waypoint:
        read_at[c] = waypoint
        logs[1, counters[_READ]] = c
        counters[_READ] += 1
    if stamps[c, _CORRIDOR] == epoch:
        return bool(corridor[c])
    counters[_JUDGED] += 1  # once per cell, until its nodes flip: called, not inlined
    return _in_corridor(
        grids, ancestors, held, offsets, ends, stamps, meant, corridor, epoch, corners, x, y
    )


@_compiled
def _astar(
    window: tuple[int, int, int, int],
    robot: tuple[int, int],
    box: tuple[int, int, int, int],
    target: NDArray[np.bool_],
    keep: bool,
    waypoint: int,
    visit: int,
    grids: IntArray,
    ancestors: IntArray,
    held: NDArray[np.bool_],
    offsets: IntArray,
    ends: IntArray,
    stamps: IntArray,
    meant: NDArray[np.bool_],
    corridor: NDArray[np.bool_],
    read_at: IntArray,
    logs: IntArray,
    touched: IntArray,
    counters: IntArray,
    g: NDArray[np.float64],
    parent: IntArray,
    keys: NDArray[np.float64],
    items: IntArray,
    octile: bool,
    corners: bool,
) -> IntArray:
    """find_path_to_box as obstacle avoidance calls it (`execution._feel_into`, weight 0): from
    the robot to a `target` cell of `box` (half-open) inside `window`, the memory's cells
    impassable and, with `keep`, the cells off the plan's corridor but the robot's; the same
    keys (f, -g, order pushed) and neighbour order, so the same path. Its cells as flat indices
    (x + y * width), the robot's first; empty when there is none. Cells are judged passable
    when the search first reaches them, not the whole window beforehand."""
    wx0, wy0, wx1, wy1 = window
    x0, y0, x1, y1 = box
    rx, ry = robot
    width = grids.shape[1]
    me = rx + ry * width
    epoch = counters[_EPOCH]
    counters[_SEARCH] += 1
    search = counters[_SEARCH]
    empty = np.empty(0, dtype=np.int64)
    if not _passable(
        grids, ancestors, held, offsets, ends, stamps, meant, corridor, read_at, logs,
        touched, counters, epoch, visit, corners, keep, me, waypoint, rx, ry,
    ):  # fmt: skip
        return empty
    any_box = False
    for yy in range(y0, y1):
        for xx in range(x0, x1):
            if _passable(
                grids, ancestors, held, offsets, ends, stamps, meant, corridor, read_at, logs,
                touched, counters, epoch, visit, corners, keep, me, waypoint, xx, yy,
            ):  # fmt: skip
                any_box = True
                break
        if any_box:
            break
    if not any_box:
        return empty
    # the heap: every push lowers a cell's g, at most once per neighbour expanded
    capacity = 8 * (wx1 - wx0) * (wy1 - wy0) + 8
    if capacity <= keys.shape[1]:
        hf, hg, hc, hn = keys[0], keys[1], items[0], items[1]
    else:  # a window wider than the follower's heap (a search widened far): its own
        hf, hg = np.empty(capacity), np.empty(capacity)
        hc, hn = np.empty(capacity, dtype=np.int64), np.empty(capacity, dtype=np.int64)
    tx1, ty1 = x1 - 1, y1 - 1
    unit = 1.0
    diagonal_unit = unit * (_SQRT2 - 1.0)
    g[me] = 0.0
    stamps[me, _REACHED] = search
    parent[me] = -1
    dx = x0 - rx if rx < x0 else rx - tx1 if rx > tx1 else 0
    dy = y0 - ry if ry < y0 else ry - ty1 if ry > ty1 else 0
    if octile:
        h0 = unit * max(dx, dy) + diagonal_unit * min(dx, dy)
    else:
        h0 = unit * (dx + dy)
    counter = 1
    heap = _push(hf, hg, hc, hn, 0, 0.0 + h0, -0.0, counter, me)
    found = -1
    moves = 8 if octile else 4
    while heap > 0:
        node = hn[0]
        # the heap's pop, written out (like the neighbour test below: no arrays bound)
        heap -= 1
        f, gg, cc, nn = hf[heap], hg[heap], hc[heap], hn[heap]
        i = 0
        while True:
            child = 2 * i + 1
            if child >= heap:
                break
            if child + 1 < heap and _less(
                hf[child + 1], hg[child + 1], hc[child + 1], hf[child], hg[child], hc[child]
            ):
                child += 1
            if not _less(hf[child], hg[child], hc[child], f, gg, cc):
                break
            hf[i], hg[i], hc[i], hn[i] = hf[child], hg[child], hc[child], hn[child]
            i = child
        if heap > 0:
            hf[i], hg[i], hc[i], hn[i] = f, gg, cc, nn
        if stamps[node, _CLOSED] == search:
            continue
        y = node // width
        x = node - y * width
        if x0 <= x < x1 and y0 <= y < y1 and target[y - y0, x - x0]:
            found = node
            break
        stamps[node, _CLOSED] = search
        counters[_EXPANDED] += 1
        g_node = g[node]
        for d in range(moves):
            ddx, ddy = _ASTAR_DX[d], _ASTAR_DY[d]
            nx, ny = x + ddx, y + ddy
            if not (wx0 <= nx < wx1 and wy0 <= ny < wy1):
                continue
            neighbour = nx + ny * width
            if stamps[neighbour, _CLOSED] == search:
                continue
            # the neighbour, then a diagonal move's two corner cells: `_passable` written out
            # (an inlined call binds each array it is passed, counting a reference to it,
            # which cost more than the search itself: a cell is judged as the neighbour of
            # several cells)
            passable = True
            for probe in range(3 if d >= 4 else 1):
                px = nx if probe < 2 else x
                py = ny if probe != 1 else y
                c = px + py * width
                if stamps[c, _TOUCHED] != visit:
                    stamps[c, _TOUCHED] = visit
                    if counters[_LOGGED] < touched.shape[0]:
                        touched[counters[_LOGGED]] = c
                    counters[_LOGGED] += 1
                if stamps[c, _MEMORY] == epoch:
                    passable = False
                elif keep and c != me:
                    if read_at[c] > waypoint:
                        read_at[c] = waypoint
                        logs[1, counters[_READ]] = c
                        counters[_READ] += 1
                    if stamps[c, _CORRIDOR] == epoch:
                        passable = corridor[c]
                    else:
                        counters[_JUDGED] += 1
                        passable = _in_corridor(
                            grids, ancestors, held, offsets, ends, stamps, meant, corridor,
                            epoch, corners, px, py,
                        )  # fmt: skip
                if not passable:
                    break
            if not passable:
                continue
            g_new = g_node + (_SQRT2 * 1.0 if d >= 4 else 1.0)
            if stamps[neighbour, _REACHED] != search or g_new < g[neighbour]:
                stamps[neighbour, _REACHED] = search
                g[neighbour] = g_new
                parent[neighbour] = node
                dx = x0 - nx if nx < x0 else nx - tx1 if nx > tx1 else 0
                dy = y0 - ny if ny < y0 else ny - ty1 if ny > ty1 else 0
                if octile:
                    hh = (
                        unit * dx + diagonal_unit * dy
                        if dx > dy
                        else unit * dy + diagonal_unit * dx
                    )
                else:
                    hh = unit * (dx + dy)
                counter += 1
                # `_push`, written out
                f, gg = g_new + hh, -g_new
                i = heap
                while i > 0:
                    up = (i - 1) >> 1
                    if not _less(f, gg, counter, hf[up], hg[up], hc[up]):
                        break
                    hf[i], hg[i], hc[i], hn[i] = hf[up], hg[up], hc[up], hn[up]
                    i = up
                hf[i], hg[i], hc[i], hn[i] = f, gg, counter, neighbour
                heap += 1
    if found < 0:
        return empty
    count = 1
    cell = found
    while parent[cell] >= 0:
        cell = parent[cell]
        count += 1
    path = np.empty(count, dtype=np.int64)
    cell = found
    for i in range(count - 1, -1, -1):
        path[i] = cell
        cell = parent[cell]
    return path


@_inlined
def _contains(o: IntArray, i: IntArray) -> bool:
    return bool(o[0] <= i[0] and o[1] <= i[1] and i[2] <= o[2] and i[3] <= o[3])


@_compiled
def _waypoints(sequence: IntArray, ends: IntArray) -> tuple[IntArray, IntArray]:
    """`execution._targets`: the waypoints (level, x, y, node or -1) of the plan's cells
    `sequence` (the goal's last) and their blocks (x0, y0, x1, y1, unclipped): a block
    containing the last kept or the next is dropped."""
    n = sequence.shape[0]
    kept = np.empty((n + 1, 4), dtype=np.int64)
    boxes = np.empty((n + 1, 4), dtype=np.int64)
    sx, sy = ends[0], ends[1]
    kept[0, 0], kept[0, 1], kept[0, 2], kept[0, 3] = 0, sx, sy, -1
    boxes[0, 0], boxes[0, 1], boxes[0, 2], boxes[0, 3] = sx, sy, sx + 1, sy + 1
    count = 1
    box = np.empty(4, dtype=np.int64)
    for i in range(n):
        level, cx, cy = sequence[i, 0], sequence[i, 1], sequence[i, 2]
        side = 1 << level
        box[0], box[1], box[2], box[3] = cx * side, cy * side, (cx + 1) * side, (cy + 1) * side
        if _contains(box, boxes[count - 1]):
            continue
        while count > 1 and _contains(boxes[count - 1], box):
            count -= 1
        if _contains(box, boxes[count - 1]):
            continue
        kept[count, 0], kept[count, 1], kept[count, 2] = level, cx, cy
        kept[count, 3] = sequence[i, 3]
        boxes[count] = box
        count += 1
    return kept[:count], boxes[:count]


@_compiled
def _flip(
    before: IntArray,
    after: IntArray,
    grids: IntArray,
    ancestors: IntArray,
    held: NDArray[np.bool_],
    tally: IntArray,
    offsets: IntArray,
    stamps: IntArray,
    read_at: IntArray,
    marks: IntArray,
    run: int,
) -> tuple[int, int]:
    """The plan's nodes from `before`'s to `after`'s (rows level, x, y, node or -1): `tally`
    counts each node's rows (the first `len(offsets)` entries past the nodes': each level's
    nodes held), `held` says which are; the cells of a node that flips, and their neighbours,
    lose their corridor and `meant`. Returns the first waypoint that read one of those cells'
    corridor (`_NEVER`: none), and the last waypoint of the last run (number `run`) that
    touched one of them (-1: none)."""
    levels = offsets.shape[0]
    nodes = tally.shape[0] - levels
    height, width = grids.shape[0], grids.shape[1]
    for i in range(before.shape[0]):
        if before[i, 3] >= 0:
            tally[offsets[before[i, 0]] + before[i, 3]] -= 1
    for i in range(after.shape[0]):
        if after[i, 3] >= 0:
            tally[offsets[after[i, 0]] + after[i, 3]] += 1
    first, latest = _NEVER, -1
    for rows in (before, after):
        for i in range(rows.shape[0]):
            level, node = rows[i, 0], rows[i, 3]
            if node < 0:
                continue
            f = offsets[level] + node
            now = tally[f] > 0
            if held[f] == now:
                continue
            held[f] = now
            tally[nodes + level] += 1 if now else -1
            side = 1 << level
            bx, by = rows[i, 1] * side, rows[i, 2] * side
            for y in range(max(0, by - 1), min(height, by + side + 1)):
                for x in range(max(0, bx - 1), min(width, bx + side + 1)):
                    c = x + y * width
                    stamps[c, _MEANT] = 0
                    stamps[c, _CORRIDOR] = 0
                    first = min(first, read_at[c])
                    if stamps[c, _LAST] == run:
                        latest = max(latest, marks[0, c])
    return first, latest


@_compiled
def _follow(
    blocked: NDArray[np.bool_],
    labels: IntArray,
    grids: IntArray,
    ancestors: IntArray,
    held: NDArray[np.bool_],
    offsets: IntArray,
    kept: IntArray,
    boxes: IntArray,
    before: IntArray,
    resume: int,
    ends: IntArray,
    stamps: IntArray,
    meant: NDArray[np.bool_],
    corridor: NDArray[np.bool_],
    read_at: IntArray,
    logs: IntArray,
    touched: IntArray,
    marks: IntArray,
    latest: int,
    counters: IntArray,
    checkpoints: IntArray,
    g: NDArray[np.float64],
    parent: IntArray,
    keys: NDArray[np.float64],
    items: IntArray,
    route: IntArray,
    octile: bool,
    corners: bool,
) -> float:
    """`execute(plan, blocked, keep_to_plan=True).length` for the plan whose waypoints are
    `kept` (with their `boxes`), resumed from the last plan's state before waypoint `resume`
    (the last plan's waypoints `before`; the two plans agree up to it, and no corridor cell
    read before it differs): the logs are taken back to that point, then waypoint after
    waypoint as `execute` (`offsets`: the levels' first entries in `held`, -1 for a level of
    no node), until the robot stands where the last plan's run stood before a waypoint from
    which the two plans' waypoints are the same to the goal, and nothing the last run touched
    from there (`latest`: the last waypoint that touched a cell whose corridor changed) differs
    between the two runs' memories: from there on the route is the last run's, taken over
    (`_take_over`)."""
    height, width = blocked.shape
    epoch = counters[_EPOCH]
    count = kept.shape[0]
    # the last run's end is reusable when it ran to the goal with its touched log whole (and
    # no route is asked for: the end's steps are not kept)
    reusable = counters[_WHOLE] == 1 and route.shape[0] == 0
    counters[_WHOLE] = 0
    counters[_RUN] += 1
    run = counters[_RUN]
    resume = min(resume, count, counters[_COUNT], before.shape[0])
    for i in range(resume):  # the waypoints the two plans share
        for k in range(4):
            if kept[i, k] != before[i, k]:
                resume = i
                break
        if resume == i:
            break
    if resume > 0:
        x, y, straight, diagonal, steps = checkpoints[resume, :5]
    else:
        x, y, straight, diagonal, steps = ends[0], ends[1], 0, 0, 0
    seen = checkpoints[resume, 5] if resume > 0 else 0
    read = checkpoints[resume, 6] if resume > 0 else 0
    # the last run from the checkpoint on (its checkpoints, the cells it saw and touched), kept
    # before the logs are taken back: its end may be taken over
    last_count = before.shape[0]
    if reusable:
        previous = checkpoints[resume : last_count + 1].copy()
        previous[0, 0], previous[0, 1], previous[0, 2] = x, y, straight
        previous[0, 3], previous[0, 4], previous[0, 5], previous[0, 6] = diagonal, steps, seen, read
        if resume == 0:
            previous[0, 7] = 0
        seen_before = logs[0, seen : counters[_SEEN]].copy()
        touched_before = touched[previous[0, 7] : counters[_LOGGED]].copy()
        for k in range(seen_before.shape[0]):
            stamps[seen_before[k], _PREVIOUS] = run
            marks[1, seen_before[k]] = k
    else:
        previous = np.zeros((1, _CHECKPOINT), dtype=np.int64)
        seen_before = np.zeros(0, dtype=np.int64)
        touched_before = np.zeros(0, dtype=np.int64)
    counters[_LOGGED] = checkpoints[resume, 7] if resume > 0 else 0
    while counters[_SEEN] > seen:  # what the robot saw after the checkpoint: unseen
        counters[_SEEN] -= 1
        stamps[logs[0, counters[_SEEN]], _MEMORY] = 0
    while counters[_READ] > read:
        counters[_READ] -= 1
        read_at[logs[1, counters[_READ]]] = _NEVER
    # the waypoints from which the last run's end may be taken over: the two plans' the same to
    # the goal, none before `resume` (the last run's state kept starts there) or before the
    # last one whose cells changed corridor
    shift = count - last_count
    same = 0
    while reusable and same < min(count, last_count) - 1:
        a, b = count - 1 - same, last_count - 1 - same
        if not (
            kept[a, 0] == before[b, 0]
            and kept[a, 1] == before[b, 1]
            and kept[a, 2] == before[b, 2]
            and kept[a, 3] == before[b, 3]
        ):
            break
        same += 1
    first_taken = max(resume, count - same, resume + shift, latest + 1 + shift)
    start_label = labels[ends[1], ends[0]]
    for i in range(resume, count):
        checkpoints[i, 0], checkpoints[i, 1] = x, y
        checkpoints[i, 2], checkpoints[i, 3], checkpoints[i, 4] = straight, diagonal, steps
        checkpoints[i, 5], checkpoints[i, 6] = counters[_SEEN], counters[_READ]
        checkpoints[i, 7] = counters[_LOGGED]
        if reusable and i >= first_taken:
            j = i - shift - resume  # the last run's row in `previous`
            if (
                previous[j, 0] == x
                and previous[j, 1] == y
                and _same_memory(
                    stamps, marks, logs, seen_before, previous, counters, epoch, run, j, j + resume
                )
                and _take_over(
                    stamps, read_at, logs, touched, counters, checkpoints, previous,
                    seen_before, touched_before, epoch, i, j,
                )
            ):  # fmt: skip
                x, y = previous[-1, 0], previous[-1, 1]
                straight, diagonal, steps = checkpoints[count, 2:5]
                break
        counters[_VISIT] += 1
        visit = counters[_VISIT]
        level, node = kept[i, 0], kept[i, 3]
        x0, y0 = max(0, boxes[i, 0]), max(0, boxes[i, 1])
        x1, y1 = min(width, boxes[i, 2]), min(height, boxes[i, 3])
        bw, bh = x1 - x0, y1 - y0
        # the target cells: reachable, and of the waypoint's node when any of them is
        target = np.zeros((bh, bw), dtype=np.bool_)
        aimed = False
        reachable = False
        for yy in range(bh):
            for xx in range(bw):
                if labels[y0 + yy, x0 + xx] == start_label:
                    target[yy, xx] = True
                    reachable = True
                    base = grids[y0 + yy, x0 + xx]
                    if node >= 0 and level > 0 and base >= 0 and ancestors[base, level] == node:
                        aimed = True
        if aimed:
            for yy in range(bh):
                for xx in range(bw):
                    base = grids[y0 + yy, x0 + xx]
                    if base < 0 or ancestors[base, level] != node:
                        target[yy, xx] = False
        if x0 <= x < x1 and y0 <= y < y1 and target[y - y0, x - x0]:
            continue
        if not reachable:
            continue
        stepped = False
        for d in range(8 if octile else 4):
            nx, ny = x + _STEP_DX[d], y + _STEP_DY[d]
            if not (x0 <= nx < x1 and y0 <= ny < y1) or not target[ny - y0, nx - x0]:
                continue
            if d >= 4 and (blocked[y, nx] or blocked[ny, x]):
                continue
            if d >= 4:
                diagonal += 1
            else:
                straight += 1
            x, y = nx, ny
            if steps < route.shape[0]:
                route[steps] = x + y * width
            steps += 1
            stepped = True
            break
        if stepped:
            continue
        # execution._feel_into, with the plan's corridor until the true map cuts it
        keep = True
        _see(blocked, stamps, logs, touched, counters, epoch, visit, x, y)
        while not (x0 <= x < x1 and y0 <= y < y1 and target[y - y0, x - x0]):
            margin = 8
            while True:
                wx0, wy0 = max(0, min(x, x0) - margin), max(0, min(y, y0) - margin)
                wx1 = min(width, max(x + 1, x1) + margin)
                wy1 = min(height, max(y + 1, y1) + margin)
                path = _astar(
                    (wx0, wy0, wx1, wy1),
                    (x, y),
                    (x0, y0, x1, y1),
                    target,
                    keep,
                    i,
                    visit,
                    grids,
                    ancestors,
                    held,
                    offsets,
                    ends,
                    stamps,
                    meant,
                    corridor,
                    read_at,
                    logs,
                    touched,
                    counters,
                    g,
                    parent,
                    keys,
                    items,
                    octile,
                    corners,
                )
                if path.shape[0] > 0:
                    break
                if (wx0, wy0, wx1, wy1) != (0, 0, width, height):
                    margin *= 4
                elif keep:
                    keep, margin = False, 8
                else:
                    return math.inf  # no way in (cannot be: the block is reachable)
            for j in range(1, path.shape[0]):
                ny = path[j] // width
                nx = path[j] - ny * width
                if stamps[path[j], _MEMORY] == epoch or (
                    nx != x
                    and ny != y
                    and (
                        stamps[nx + y * width, _MEMORY] == epoch
                        or stamps[x + ny * width, _MEMORY] == epoch
                    )
                ):
                    break  # seen blocked since the path was planned: plan again from here
                if nx != x and ny != y:
                    diagonal += 1
                else:
                    straight += 1
                x, y = nx, ny
                if steps < route.shape[0]:
                    route[steps] = x + y * width
                steps += 1
                _see(blocked, stamps, logs, touched, counters, epoch, visit, x, y)
    checkpoints[count, 0], checkpoints[count, 1] = x, y
    checkpoints[count, 2], checkpoints[count, 3], checkpoints[count, 4] = straight, diagonal, steps
    checkpoints[count, 5], checkpoints[count, 6] = counters[_SEEN], counters[_READ]
    checkpoints[count, 7] = counters[_LOGGED]
    counters[_STEPS] = steps
    counters[_COUNT] = count
    if counters[_LOGGED] <= touched.shape[0]:  # the last waypoint touching each cell
        for i in range(count):
            for k in range(checkpoints[i, 7], checkpoints[i + 1, 7]):
                stamps[touched[k], _LAST] = run
                marks[0, touched[k]] = i
        counters[_WHOLE] = 1
    return float(straight + _SQRT2 * diagonal)


@_compiled
def _same_memory(
    stamps: IntArray,
    marks: IntArray,
    logs: IntArray,
    seen_before: IntArray,
    previous: IntArray,
    counters: IntArray,
    epoch: int,
    run: int,
    j: int,
    waypoint: int,
) -> bool:
    """Whether the robot's memory now and the last run's before its waypoint `waypoint` (row `j`
    of `previous`) differ in no cell that run touched from there on (both runs resumed from
    `previous[0]`: the cells each saw since, `logs[0]` from `previous[0, 5]` and
    `seen_before`)."""
    last_run = run - 1
    for k in range(previous[0, 5], counters[_SEEN]):  # seen now, maybe not then
        c = logs[0, k]
        then = stamps[c, _PREVIOUS] == run and marks[1, c] < previous[j, 5] - previous[0, 5]
        if not then and stamps[c, _LAST] == last_run and marks[0, c] >= waypoint:
            return False
    for k in range(previous[j, 5] - previous[0, 5]):  # seen then, maybe not now
        c = seen_before[k]
        if stamps[c, _MEMORY] != epoch and stamps[c, _LAST] == last_run and marks[0, c] >= waypoint:
            return False
    return True


@_compiled
def _take_over(
    stamps: IntArray,
    read_at: IntArray,
    logs: IntArray,
    touched: IntArray,
    counters: IntArray,
    checkpoints: IntArray,
    previous: IntArray,
    seen_before: IntArray,
    touched_before: IntArray,
    epoch: int,
    i: int,
    j: int,
) -> bool:
    """The last run's end from row `j` of `previous` as this run's from waypoint `i` (the robot
    where that run's was, the same waypoints to the goal, the same memory and corridor wherever
    that run looked): its checkpoints with this run's moves before, and its logs (the cells
    it saw, those it touched, as corridor reads: a superset, so a later plan resumes no later
    than it must). False when the touched log would not fit (nothing changed but the logs past
    their lengths)."""
    base = previous[0, 7]
    if counters[_LOGGED] + previous[-1, 7] - previous[j, 7] > touched.shape[0]:
        return False
    moved = checkpoints[i, 2:5] - previous[j, 2:5]
    for row in range(j, previous.shape[0]):
        n = i + row - j
        checkpoints[n, 0], checkpoints[n, 1] = previous[row, 0], previous[row, 1]
        checkpoints[n, 2:5] = previous[row, 2:5] + moved
        checkpoints[n, 5], checkpoints[n, 6] = counters[_SEEN], counters[_READ]
        checkpoints[n, 7] = counters[_LOGGED]
        if row == previous.shape[0] - 1:
            break
        for k in range(previous[row, 5] - previous[0, 5], previous[row + 1, 5] - previous[0, 5]):
            c = seen_before[k]
            if stamps[c, _MEMORY] != epoch:
                stamps[c, _MEMORY] = epoch
                logs[0, counters[_SEEN]] = c
                counters[_SEEN] += 1
        for k in range(previous[row, 7] - base, previous[row + 1, 7] - base):
            c = touched_before[k]
            if read_at[c] > n:
                read_at[c] = n
                logs[1, counters[_READ]] = c
                counters[_READ] += 1
            touched[counters[_LOGGED]] = c
            counters[_LOGGED] += 1
    counters[_REUSED] += previous.shape[0] - 1 - j
    return True


def _segmentized(position: Position, top: int) -> IntArray:
    """`planner.segmentize(position, top)`'s segments as `Follower._segment`'s rows (level, x,
    y, -1), made at once: a plan's head and tail (`MultiPath.head`) are not kept with it."""
    levels = np.arange(top, dtype=np.int64)
    rows = np.full((top, 4), -1, dtype=np.int64)
    rows[:, 0] = levels
    rows[:, 1] = position[0] >> levels
    rows[:, 2] = position[1] >> levels
    return rows


class Follower:
    """The length of the route `execution.execute(plan, blocked, movement=movement,
    keep_to_plan=True)` follows, compiled (see the module docstring): pass it to `planner.atp`
    as `follow`. Build it once per map: it labels the map's connected cells and keeps, per
    abstraction, each level-0 node's ancestors.

    Called plan after plan (a refinement changes one segment), it resumes from the last plan
    followed: the route up to the first waypoint the two plans do not share, or the first whose
    searches read a corridor cell the change touched, is the same, and is not walked again; nor
    is the route from where the robot stands as it stood in the last plan's run, the waypoints
    to the goal the same and nothing that run touched from there different (`taken_over`)."""

    #: The plans it follows are made on the map it follows them on (`blocked`), and the robot
    #: keeps to their corridor, which that map never cuts: a route that is the shortest through
    #: cells holding a plan's corridor (`atp`'s `direct_width` route, through the first plan's
    #: nodes and their neighbours') is followed no longer than that plan, without following
    #: either (a planner may rely on it to skip the follower there).
    planned_on_its_map = True

    def __init__(self, blocked: BoolGrid, movement: int = 8) -> None:
        from scipy import ndimage

        # Its own writable copy: numba compiles (or loads) a function once per argument type,
        # and a read-only array (a `World`'s map) is another type than a writable one (a
        # MovingAI map's): `compile_searches` warms the follower on a world, and the first map
        # followed would otherwise pay for `_follow` again.
        self.blocked = np.array(blocked, dtype=bool, order="C", copy=True)
        self.movement = movement
        four = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)
        labels, _ = ndimage.label(~self.blocked, structure=four)  # `world.reachable`'s
        self.labels = np.asarray(labels, dtype=np.int64)
        self._described: (
            tuple[Components, IntArray, IntArray, IntArray, NDArray[np.bool_], IntArray] | None
        )
        self._described = None
        self._cells: dict[int, tuple[Segment, IntArray]] = {}
        cells = self.blocked.size
        self._stamps = _untouched((cells, 8), np.int64)
        self._meant = _untouched((cells,), np.bool_)
        self._corridor = _untouched((cells,), np.bool_)
        self._read_at = np.full(cells, _NEVER, dtype=np.int64)
        self._logs = _untouched((2, cells), np.int64)
        # the touched log: a cell once per waypoint (a longer log is not kept, `_touch`), and
        # per cell the last waypoint that touched it and its place among the cells last seen
        self._touched = _untouched((cells,), np.int64)
        self._marks = _untouched((2, cells), np.int64)
        self._g = _untouched((cells,), np.float64)
        self._parent = _untouched((cells,), np.int64)
        # obstacle avoidance's heap: (f, -g) and (order pushed, cell), for windows of up to
        # 8,192 cells (a block of 16 x 16 and a margin of 8 around it and the robot)
        self._keys = np.zeros((2, _HEAP))
        self._items = np.zeros((2, _HEAP), dtype=np.int64)
        self._counters = np.zeros(13, dtype=np.int64)
        self._counters[_EPOCH] = 1
        self._checkpoints = np.zeros((0, _CHECKPOINT), dtype=np.int64)
        self._route = np.zeros(0, dtype=np.int64)  # `route`'s
        self._ends: tuple[int, int, int, int] | None = None
        self._sequence = np.zeros((0, 4), dtype=np.int64)  # the last plan's cells
        self._kept = np.zeros((0, 4), dtype=np.int64)  # and its waypoints

    def _abstraction(
        self, components: Components
    ) -> tuple[IntArray, IntArray, IntArray, NDArray[np.bool_], IntArray]:
        if self._described is None or self._described[0] is not components:
            if components.grids[0].shape != self.blocked.shape:
                raise ValueError(
                    f"the plan's abstraction is of a {components.grids[0].shape} map, the"
                    f" follower's is {self.blocked.shape}"
                )
            # a cell's level-k node is its level-0 node's ancestor k levels up: a table per
            # level-0 node (a row per free cell's node, its levels side by side), not a grid
            # per level (on a 1,024 x 1,024 map the levels' grids stacked were 40 MB, written
            # by the first plan followed on the map: 0.1-0.2 s)
            grids = np.ascontiguousarray(components.grids[0], dtype=np.int64)
            levels = len(components.levels)
            ancestors = np.empty((len(components.levels[0]), levels), dtype=np.int64)
            ancestors[:, 0] = np.arange(len(components.levels[0]))
            for k in range(1, levels):
                ancestors[:, k] = components.levels[k - 1].parent[ancestors[:, k - 1]]
            sizes = [len(level) for level in components.levels]
            offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
            held = np.zeros(sum(sizes), dtype=bool)
            tally = np.zeros(sum(sizes) + len(sizes), dtype=np.int64)
            self._described = (components, grids, ancestors, offsets, held, tally)
            self.reset()
        _, grids, ancestors, offsets, held, tally = self._described
        return grids, ancestors, offsets, held, tally

    def _segment(self, segment: Segment) -> IntArray:
        """A segment's cells as rows (level, x, y, node or -1), kept while the segment is
        (a refinement replaces one segment of the plan: the others' rows are reused)."""
        known = self._cells.get(id(segment))
        if known is not None and known[0] is segment:
            return known[1]
        rows = np.empty((len(segment.cells), 4), dtype=np.int64)
        rows[:, 0] = segment.level
        rows[:, 1:3] = segment.cells
        rows[:, 3] = segment.nodes if segment.nodes else -1
        self._cells[id(segment)] = (segment, rows)
        return rows

    def reset(self) -> None:
        """Forget the plans followed so far: the next call follows its plan from the start."""
        counters = self._counters
        counters[_EPOCH] += 1  # the memory, `meant` and the corridor: none holds
        self._read_at[self._logs[1, : counters[_READ]]] = _NEVER
        counters[_SEEN] = counters[_READ] = counters[_COUNT] = counters[_LOGGED] = 0
        counters[_WHOLE] = 0  # nothing of the last run is taken over
        if self._described is not None:  # the last plan's nodes: no longer held
            _, _, _, offsets, held, tally = self._described
            rows = self._sequence[self._sequence[:, 3] >= 0]
            flat = offsets[rows[:, 0]] + rows[:, 3]
            held[flat] = False
            tally[flat] = 0
            tally[len(held) :] = 0
        self._cells.clear()
        self._ends = None
        self._sequence = np.zeros((0, 4), dtype=np.int64)
        self._kept = np.zeros((0, 4), dtype=np.int64)

    @property
    def taken_over(self) -> int:
        """How many waypoints' routes were taken over from the last plan's run so far (not
        walked again), over every plan followed (statistics)."""
        return int(self._counters[_REUSED])

    def route(self, plan: MultiPath) -> tuple[tuple[int, int], ...]:
        """The route itself, `execute(...).route`, followed from the start (for tests:
        `__call__` keeps no route)."""
        self.reset()
        self._route = np.zeros(4 * self.blocked.size, dtype=np.int64)
        try:
            self(plan)
        finally:
            cells = self._route[: self._counters[_STEPS]]
            self._route = np.zeros(0, dtype=np.int64)
        width = self.blocked.shape[1]
        return (plan.start, *((int(c % width), int(c // width)) for c in cells))

    def __call__(self, plan: MultiPath) -> float:
        if plan.abstraction is None:
            raise ValueError("a plan without its abstraction has no corridor to keep to")
        grids, ancestors, offsets, held, tally = self._abstraction(plan.abstraction)
        ends = (*plan.start, *plan.goal)
        if ends != self._ends:  # another problem: nothing of the last one's holds
            self.reset()
            self._ends = ends
        at = np.array(ends, dtype=np.int64)
        goal = np.array([[0, plan.goal[0], plan.goal[1], -1]], dtype=np.int64)
        head, tail = plan.segments[0].level, plan.segments[-1].level
        sequence = np.concatenate(
            [
                _segmentized(plan.start, head),
                *(self._segment(s) for s in plan.segments),
                _segmentized(plan.goal, tail)[::-1],
                goal,
            ]
        )
        kept, boxes = _waypoints(sequence, at)
        if len(self._checkpoints) < len(kept) + 1:
            grown = np.zeros((2 * len(kept) + 1, _CHECKPOINT), dtype=np.int64)
            grown[: len(self._checkpoints)] = self._checkpoints
            self._checkpoints = grown
        resume, latest = _flip(
            self._sequence,
            sequence,
            grids,
            ancestors,
            held,
            tally,
            offsets,
            self._stamps,
            self._read_at,
            self._marks,
            self._counters[_RUN],
        )
        # the levels of no node are not read (`_in_corridor`)
        used = np.where(tally[len(held) :] > 0, offsets, -1)
        length = _follow(
            self.blocked,
            self.labels,
            grids,
            ancestors,
            held,
            used,
            kept,
            boxes,
            self._kept,
            resume,
            at,
            self._stamps,
            self._meant,
            self._corridor,
            self._read_at,
            self._logs,
            self._touched,
            self._marks,
            latest,
            self._counters,
            self._checkpoints,
            self._g,
            self._parent,
            self._keys,
            self._items,
            self._route,
            self.movement == 8,
            plan.abstraction.movement == 8,
        )
        self._sequence, self._kept = sequence, kept
        # keep the rows of this plan's segments only: the next plan shares all but one
        self._cells = {id(s): self._cells[id(s)] for s in plan.segments}
        return float(length)
