"""The anytime abstract planner, ATP (Zilberstein & Russell, "Anytime abstract planning",
Figure 3 of the second paper; issue 6, part 4).

    ATP(start, goal, domain-description)
    1  multi-path <- [SEGMENTIZE(start),
                      PATH-FINDER(PROJECT(start, top), PROJECT(goal, top), domain-description),
                      SEGMENTIZE(goal)]
    2  REGISTER-RESULT(multi-path)
    3  while REFINABLE(multi-path) do
    4      REFINE(WORST-SEGMENT(multi-path), domain-description)
    5      REGISTER-RESULT(multi-path)
    6  SIGNAL(TERMINATION)

`atp` is that loop as a generator: REGISTER-RESULT is a `yield Result(plan, quality)`, and
SIGNAL(TERMINATION) is the generator's return. The plan is a `MultiPath`, "a list of successive
path segments of arbitrary abstraction level".

Junctions. Consecutive segments meet at a junction cell: the last cell of one and the first of
the next are the same cell when both segments have one level, and otherwise the finer one's
cell lies inside the coarser one's (projected up to the coarser level they are equal). An
executor can therefore follow a mixed-level plan segment by segment: a level-k cell means "go
into that 2^k x 2^k block". The only exception is the rare fallback of `_descend` (a block with
no child reachable at the finer level), where the junction moves to the nearest reachable cell.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt
from attrs import field, frozen

from anytime.plugin import Context, Result

from .abstraction import Pyramid, project
from .search import SQRT2, SearchLimit, find_path_to_box
from .world import BoolGrid, Position, reachable

__all__ = ["MultiPath", "Segment", "atp", "quality_estimate", "segmentize", "worst_segment"]


def _cells(value: object) -> tuple[Position, ...]:
    cells = tuple((int(x), int(y)) for x, y in value)  # type: ignore[attr-defined]
    if not cells:
        raise ValueError("a segment needs at least one cell")
    return cells


@frozen
class Segment:
    """A path at one abstraction level: `cells` are positions at `level`, in order; consecutive
    cells are neighbours at that level (4- or 8-connected)."""

    level: int
    cells: tuple[Position, ...] = field(converter=_cells)

    @property
    def source(self) -> Position:
        """The first cell (at `level`)."""
        return self.cells[0]

    @property
    def target(self) -> Position:
        """The last cell (at `level`)."""
        return self.cells[-1]

    @property
    def moves(self) -> int:
        """The segment's length in moves at its level (what refinement keeps invariant)."""
        return len(self.cells) - 1


@frozen
class MultiPath:
    """A plan: `head` (what is left of SEGMENTIZE(start)), the route `segments`, and `tail`
    (what is left of SEGMENTIZE(goal)). `parts` is the whole list of the pseudocode.

    The head holds the one-cell segments start@0 .. start@(L-1) below the level L of the first
    route segment, the tail likewise for the goal in descending order; refining the first (last)
    route segment plans its new half from start@(L-1) (to goal@(L-1)), which absorbs that
    connector. When every route segment is at level 0, head and tail are empty.
    """

    start: Position
    goal: Position
    head: tuple[Segment, ...]
    segments: tuple[Segment, ...]
    tail: tuple[Segment, ...]

    @property
    def parts(self) -> tuple[Segment, ...]:
        return self.head + self.segments + self.tail

    @property
    def refinable(self) -> bool:
        """REFINABLE: some route segment is above the base level."""
        return any(s.level > 0 for s in self.segments)

    def base_route(self) -> tuple[Position, ...] | None:
        """The base-level route when the plan is fully refined (junction cells once), else
        None."""
        if self.refinable:
            return None
        route: list[Position] = list(self.segments[0].cells)
        for segment in self.segments[1:]:
            route.extend(segment.cells[1:])
        return tuple(route)


def segmentize(position: Position, top: int) -> tuple[Segment, ...]:
    """SEGMENTIZE: the vertical path from a base cell up to the level-`top` cell containing it,
    as one-cell segments at levels 0, 1, .., top - 1 (the level-`top` cell is the first cell of
    the top-level route). The papers use it to tie the base-level start and goal to the abstract
    plan; here it is also where refinement takes the endpoints of the first and last halves
    (the cell containing the start one level lower, not an arbitrary child)."""
    return tuple(Segment(level, (project(position, 0, level),)) for level in range(top))


def _score(level: int, obstacleness: float) -> float:
    return (1 << level) * (1.0 + obstacleness)


def worst_segment(plan: MultiPath, pyramid: Pyramid) -> int | None:
    """WORST-SEGMENT: the index of the route segment to refine, or None when none is refinable.

    Score of a segment at level k > 0 with mean obstacleness o over its cells:
    `2^k * (1 + o)`. The level dominates (a segment one level higher scores at least as much
    unless the lower one is fully blocked), and within a level the most blocked one wins. Ties go
    to the earliest segment. (`atp` keeps the scores in a heap instead of rescanning the plan;
    its ties go to the segment created first.)
    """
    best, best_score = None, -1.0
    for i, segment in enumerate(plan.segments):
        if segment.level == 0:
            continue
        score = _score(segment.level, _mean_obstacleness(segment, pyramid))
        if score > best_score:
            best, best_score = i, score
    return best


def _credit(segment: Segment, obstacleness: float, top: int) -> tuple[float, float]:
    """A segment's (extent, credit) in the quality estimate."""
    extent = max(segment.moves, 1) * float(1 << segment.level)
    if segment.level == 0:
        return extent, extent
    coarseness = 1.0 - segment.level / (top + 1)
    return extent, extent * (1.0 - obstacleness) * coarseness


def quality_estimate(plan: MultiPath, pyramid: Pyramid) -> float:
    """The plan's quality estimate in [0, 1], computable without the optimal path.

    Each route segment covers about `e = max(moves, 1) * 2^k` base cells (k its level). A base
    segment counts fully; a level-k segment counts `(1 - o) * (1 - k / (T + 1))`, where o is its
    mean obstacleness and T the pyramid's top: abstract parts are discounted by how coarse they
    are and by how much of them is blocked (what obstacle avoidance will have to make up for).
    The estimate is the e-weighted mean, so it is 1 exactly when the plan is fully refined (a
    base route through free cells) and grows as segments are lowered. (`atp` keeps the two sums
    up to date instead of recomputing them.)
    """
    total = credit = 0.0
    for segment in plan.segments:
        extent, part = _credit(segment, _mean_obstacleness(segment, pyramid), pyramid.top)
        total += extent
        credit += part
    return _clip(credit / total) if total else 1.0


def _clip(quality: float) -> float:
    return min(1.0, max(0.0, quality))


def atp(
    ctx: Context,
    start: Position,
    goal: Position,
    pyramid: Pyramid,
    *,
    movement: int = 4,
    weight: float = 1.0,
    top: int | None = None,
    margin: int = 1,
    segment_moves: int | None = None,
) -> Iterator[Result]:
    """The anytime abstract planner: yields `Result(MultiPath, quality_estimate)` after the first
    plan and after every refinement; returns (SIGNAL(TERMINATION)) when nothing is refinable or
    when `ctx` has expired. Work is the A* expansions PATH-FINDER reports; a search is given
    what is left of the allocation and stopped when it runs out, so the planner never works
    past its deadline (the refinement under way is dropped; the last plan yielded stands).

    Args:
        ctx: the context; each A* expansion is one tick.
        start: the base-level start (x, y), a free cell.
        goal: the base-level goal (x, y), a free cell.
        pyramid: the domain description (possibly of a noisy map).
        movement: 4 or 8, at every level.
        weight: the obstacleness weight of PATH-FINDER (see `search.find_path`).
        top: the level of the first plan (the papers' "highest level of abstraction"). By
            default the level whose grid is 16 x 16 cells (the pyramid's top on smaller maps):
            the pyramid's own top is one cell, a first plan that says nothing; measured while
            tuning on the 512 x 512 MovingAI maps, starting at 16 x 16 gave better final routes
            for less work than 8 x 8 or 1 x 1 (0.977 against 0.972 and 0.941 on random512,
            at 14%, 18% and 29% of A*'s time).
        segment_moves: the first plan is cut into segments of at most this many moves, of
            equal length (None, the default: one segment, as in the pseudocode). Segment length
            is what refinement keeps invariant, so it sets the grain of the anytime behaviour:
            how much one refinement costs and improves. Measured on the 512 x 512 benchmark
            maps, one segment gives better final routes for less time than segments of 8 moves
            (benchmarks/bench_navigation.py), at a coarser grain.
        margin: how far (in cells of the lower level) a refinement may stray outside the
            blocks of the segment it refines before the corridor is widened.

    REFINE re-plans the chosen level-k segment one level lower with PATH-FINDER restricted to a
    corridor: the 2x2 children of its cells, widened by `margin` (and, only when that has no
    path, by 4, 16, ... cells up to the whole level). Its ends are the junctions with its
    neighbours: a fixed cell when the neighbour is already finer (its end, projected), otherwise
    any free child of the shared cell (the search chooses the best one, which the neighbour will
    then have to meet). The path found is split at its middle into two halves of equal length
    (a path of n moves into n // 2 and n - n // 2), each a segment one level lower: the length
    in moves of a segment stays about invariant, and so does the cost of a refinement, which is
    a local A* over a few dozen cells.

    A goal the map given does not connect to the start (a noisy map can wall it off) is not an
    error: the planner then treats blocked cells as passable at a cost (obstacleness 1, times
    `weight`) and returns its best-effort plan; execution on the true map avoids the obstacles.

    Raises:
        ValueError: a blocked start or goal, a top outside the pyramid, segment_moves < 1 or a
            negative margin.
    """
    top = max(pyramid.top - 4, 0) if top is None else top
    if segment_moves is not None and segment_moves < 1:
        raise ValueError(f"segment_moves must be >= 1 or None, got {segment_moves}")
    if margin < 0:
        raise ValueError(f"margin must be >= 0, got {margin}")
    if not 0 <= top <= pyramid.top:
        raise ValueError(f"top must be in [0, {pyramid.top}], got {top}")
    for name, position in (("start", start), ("goal", goal)):
        if pyramid.obstacleness(position, 0) >= 1.0:
            raise ValueError(f"{name} {position} is a blocked cell")
    planner = _Planner(pyramid, start, goal, movement, weight, margin, ctx)
    side = pyramid.side(top)
    try:
        path = planner.plan(
            top, [project(start, 0, top)], _point(goal, top), (0, 0, side - 1, side - 1)
        ).cells
    except SearchLimit as stopped:  # the deadline came before the first plan
        ctx.tick(stopped.expansions)
        return
    segments = _pieces(top, path, segment_moves)
    plan = MultiPath(
        start, goal, segmentize(start, top), tuple(segments), segmentize(goal, top)[::-1]
    )
    # WORST-SEGMENT as a heap of (-score, creation order, segment), stale entries skipped; the
    # quality estimate as running sums: no rescan of the plan per refinement.
    order = itertools.count()
    live: set[int] = set()
    heap: list[tuple[float, int, Segment]] = []
    sums = [0.0, 0.0]

    def add(segment: Segment) -> None:
        o = _mean_obstacleness(segment, pyramid)
        extent, credit = _credit(segment, o, pyramid.top)
        sums[0] += extent
        sums[1] += credit
        if segment.level > 0:
            live.add(id(segment))
            heapq.heappush(heap, (-_score(segment.level, o), next(order), segment))

    for segment in segments:
        add(segment)
    yield Result(plan, _clip(sums[1] / sums[0]))
    while not ctx.expired:
        while heap and id(heap[0][2]) not in live:
            heapq.heappop(heap)
        if not heap:
            return
        old = heapq.heappop(heap)[2]
        live.discard(id(old))
        index = next(i for i in range(len(segments)) if segments[i] is old)
        try:
            new = planner.refine(segments, index)
        except SearchLimit as stopped:  # the deadline came mid-refinement: keep the last plan
            ctx.tick(stopped.expansions)
            return
        extent, credit = _credit(old, _mean_obstacleness(old, pyramid), pyramid.top)
        sums[0] -= extent
        sums[1] -= credit
        for segment in new:
            add(segment)
        segments[index : index + 1] = new
        head = plan.head[:-1] if index == 0 else plan.head
        tail = plan.tail[1:] if index == len(segments) - len(new) else plan.tail
        plan = MultiPath(start, goal, head, tuple(segments), tail)
        yield Result(plan, 1.0 if not live else _clip(sums[1] / sums[0]))


def _pieces(level: int, path: tuple[Position, ...], most: int | None) -> list[Segment]:
    """`path` cut into the fewest segments of at most `most` moves, of about equal length."""
    n = len(path) - 1
    count = 1 if most is None or n <= most else -(-n // most)
    bounds = [round(i * n / count) for i in range(count + 1)]
    return [Segment(level, path[a : b + 1]) for a, b in zip(bounds, bounds[1:], strict=False)]


def _point(position: Position, level: int = 0) -> tuple[int, int, int, int]:
    x, y = position if level == 0 else project(position, 0, level)
    return (x, y, x, y)


def _children(cell: Position) -> tuple[int, int, int, int]:
    """The box of a cell's four children one level lower."""
    x, y = cell
    return (2 * x, 2 * y, 2 * x + 1, 2 * y + 1)


class _Planner:
    """PATH-FINDER and REFINE over one pyramid, with the cells each level lets the planner use:
    those connected to the start (computed lazily per level), or every cell when the goal is not
    connected to the start on this map (the best-effort mode of `atp`)."""

    def __init__(
        self,
        pyramid: Pyramid,
        start: Position,
        goal: Position,
        movement: int,
        weight: float,
        margin: int,
        ctx: Context,
    ) -> None:
        self.pyramid, self.start, self.goal = pyramid, start, goal
        self.movement, self.weight, self.margin, self.ctx = movement, weight, margin, ctx
        self._passable: dict[int, BoolGrid] = {}
        gx, gy = goal
        self.connected = bool(self.passable(0)[gy, gx])
        if not self.connected:
            self._passable.clear()

    def passable(self, level: int) -> BoolGrid:
        if level not in self._passable:
            grid = self.pyramid.levels[level]
            if getattr(self, "connected", True):
                origin = project(self.start, 0, level)
                self._passable[level] = reachable(grid >= 1.0, origin, self.movement)
            else:
                self._passable[level] = np.ones(grid.shape, dtype=bool)
        return self._passable[level]

    def plan(
        self,
        level: int,
        sources: list[Position],
        box: tuple[int, int, int, int],
        corridor: tuple[Position, ...] | tuple[int, int, int, int],
        source_costs: list[float] | None = None,
        box_costs: npt.NDArray[np.float64] | None = None,
    ) -> Segment:
        """PATH-FINDER at `level` from any of `sources` into `box`, first inside `corridor` (a
        box, or the cells of the segment being refined, one level up) widened by the margin,
        then by wider margins up to the whole level."""
        grid, ok = self.pyramid.levels[level], self.passable(level)
        side = grid.shape[0]
        if not any(ok[y, x] for x, y in sources):
            sources, source_costs = [self._nearest(level, box)], None
        bx0, by0, bx1, by1 = box
        if not ok[by0 : by1 + 1, bx0 : bx1 + 1].any():
            box, box_costs = _point(self._nearest(level, box)), None
        margin, whole = self.margin, (0, 0, side - 1, side - 1)
        while True:
            mask, (x0, y0) = self._corridor(level, corridor, sources, box, margin)
            found = find_path_to_box(
                grid[y0 : y0 + mask.shape[0], x0 : x0 + mask.shape[1]],
                [(x - x0, y - y0) for x, y in sources],
                (box[0] - x0, box[1] - y0, box[2] - x0, box[3] - y0),
                movement=self.movement,
                weight=self.weight,
                impassable=~mask,
                source_costs=source_costs,
                box_costs=box_costs,
                limit=self.ctx.remaining,
            )
            if found is not None:
                self.ctx.tick(found.expansions)
                return Segment(level, [(x + x0, y + y0) for x, y in found.path])
            # A failed search expanded every usable cell it could reach in the window.
            self.ctx.tick(min(int(np.count_nonzero(mask)), self.ctx.remaining))
            if corridor == whole:
                raise AssertionError(f"no path at level {level} between connected cells")
            margin = max(4 * margin, 4)
            if margin >= side:
                corridor = whole

    def _corridor(
        self,
        level: int,
        corridor: tuple[Position, ...] | tuple[int, int, int, int],
        sources: list[Position],
        box: tuple[int, int, int, int],
        margin: int,
    ) -> tuple[BoolGrid, Position]:
        """The passable cells of the corridor and the window's upper-left corner."""
        side = self.pyramid.levels[level].shape[0]
        if isinstance(corridor[0], int):
            boxes = [corridor]
        else:
            boxes = [_children(cell) for cell in corridor]
        boxes += [_point(s) for s in sources] + [box]
        x0 = max(min(b[0] for b in boxes) - margin, 0)
        y0 = max(min(b[1] for b in boxes) - margin, 0)
        x1 = min(max(b[2] for b in boxes) + margin, side - 1)
        y1 = min(max(b[3] for b in boxes) + margin, side - 1)
        mask = np.zeros((y1 - y0 + 1, x1 - x0 + 1), dtype=bool)
        for bx0, by0, bx1, by1 in boxes:
            mask[
                max(by0 - margin - y0, 0) : by1 + margin - y0 + 1,
                max(bx0 - margin - x0, 0) : bx1 + margin - x0 + 1,
            ] = True
        mask &= self.passable(level)[y0 : y1 + 1, x0 : x1 + 1]
        return mask, (x0, y0)

    def _nearest(self, level: int, box: tuple[int, int, int, int]) -> Position:
        """The usable cell nearest the centre of `box` (when none of the box is usable: rare, a
        block whose free part is walled off at this level)."""
        ys, xs = np.nonzero(self.passable(level))
        cx, cy = (box[0] + box[2]) / 2.0, (box[1] + box[3]) / 2.0
        i = int(np.argmin((xs - cx) ** 2 + (ys - cy) ** 2))
        return (int(xs[i]), int(ys[i]))

    def refine(self, segments: list[Segment], index: int) -> tuple[Segment, ...]:
        """REFINE route segment `index`: its replacement, two halves one level lower (one
        segment when the path found has fewer than two moves)."""
        segment = segments[index]
        lower = segment.level - 1
        source_costs = box_costs = None
        if index == 0:
            sources = [project(self.start, 0, lower)]
        elif segments[index - 1].level <= lower:
            prev = segments[index - 1]
            sources = [project(prev.target, prev.level, lower)]
        else:
            x, y, _, _ = _children(segment.source)
            sources = [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)]
            before = segments[index - 1].cells
            costs = self._approach(
                sources, segments[index - 1].level, before[max(len(before) - 2, 0)], lower
            )
            source_costs = list(costs)
        if index == len(segments) - 1:
            box = _point(self.goal, lower)
        elif segments[index + 1].level <= lower:
            nxt = segments[index + 1]
            box = _point(project(nxt.source, nxt.level, lower))
        else:
            box = _children(segment.target)
            x, y, _, _ = box
            after = segments[index + 1].cells
            costs = self._approach(
                [(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)],
                segments[index + 1].level,
                after[min(1, len(after) - 1)],
                lower,
            )
            box_costs = costs.reshape(2, 2)
        path = self.plan(lower, sources, box, segment.cells, source_costs, box_costs).cells
        n = len(path) - 1
        if n < 2:
            return (Segment(lower, path),)
        return (Segment(lower, path[: n // 2 + 1]), Segment(lower, path[n // 2 :]))

    def _approach(
        self, cells: list[Position], level: int, neighbour: Position, lower: int
    ) -> npt.NDArray[np.float64]:
        """How much farther each of `cells` (at `lower`) is from the centre of the neighbouring
        segment's next cell (at `level`) than the nearest of them: the cost a flexible junction
        adds to the neighbour, so that the junction is chosen for both sides."""
        scale = float(1 << (level - lower))
        cx, cy = (neighbour[0] + 0.5) * scale, (neighbour[1] + 0.5) * scale
        xy = np.asarray(cells, dtype=np.float64) + 0.5
        dx, dy = np.abs(xy[:, 0] - cx), np.abs(xy[:, 1] - cy)
        if self.movement == 4:
            d = dx + dy
        else:
            d = np.maximum(dx, dy) + (SQRT2 - 1.0) * np.minimum(dx, dy)
        return np.asarray(d - d.min())


def _mean_obstacleness(segment: Segment, pyramid: Pyramid) -> float:
    xs, ys = zip(*segment.cells, strict=True)
    return float(pyramid.levels[segment.level][list(ys), list(xs)].mean())
