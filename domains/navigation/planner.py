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

from collections.abc import Iterator

import numpy as np
from attrs import field, frozen

from anytime.modules import Context, Result

from .abstraction import Pyramid, project
from .search import find_path
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


def worst_segment(plan: MultiPath, pyramid: Pyramid) -> int | None:
    """WORST-SEGMENT: the index of the route segment to refine, or None when none is refinable.

    Score of a segment at level k > 0 with mean obstacleness o over its cells:
    `2^k * (1 + o)`. The level dominates (a segment one level higher scores at least as much
    unless the lower one is fully blocked), and within a level the most blocked one wins. Ties go
    to the earliest segment, so refinement proceeds from the start.
    """
    best, best_score = None, -1.0
    for i, segment in enumerate(plan.segments):
        if segment.level == 0:
            continue
        score = (1 << segment.level) * (1.0 + _mean_obstacleness(segment, pyramid))
        if score > best_score:
            best, best_score = i, score
    return best


def quality_estimate(plan: MultiPath, pyramid: Pyramid) -> float:
    """The plan's quality estimate in [0, 1], computable without the optimal path.

    Each route segment covers about `e = max(moves, 1) * 2^k` base cells (k its level). A base
    segment counts fully; a level-k segment counts `(1 - o) * (1 - k / (T + 1))`, where o is its
    mean obstacleness and T the pyramid's top: abstract parts are discounted by how coarse they
    are and by how much of them is blocked (what obstacle avoidance will have to make up for).
    The estimate is the e-weighted mean, so it is 1 exactly when the plan is fully refined (a
    base route through free cells) and grows as segments are lowered.
    """
    top = pyramid.top
    total = credit = 0.0
    for segment in plan.segments:
        extent = max(segment.moves, 1) * float(1 << segment.level)
        total += extent
        if segment.level == 0:
            credit += extent
        else:
            coarseness = 1.0 - segment.level / (top + 1)
            credit += extent * (1.0 - _mean_obstacleness(segment, pyramid)) * coarseness
    return min(1.0, max(0.0, credit / total)) if total else 1.0


def atp(
    ctx: Context,
    start: Position,
    goal: Position,
    pyramid: Pyramid,
    *,
    movement: int = 4,
    weight: float = 1.0,
    top: int | None = None,
) -> Iterator[Result]:
    """The anytime abstract planner: yields `Result(MultiPath, quality_estimate)` after the first
    plan and after every refinement; returns (SIGNAL(TERMINATION)) when nothing is refinable or
    when `ctx` has expired after a yield. Work is the A* expansions `find_path` reports.

    Args:
        ctx: the context; each A* expansion is one tick.
        start: the base-level start (x, y), a free cell.
        goal: the base-level goal (x, y), a free cell reachable from the start.
        pyramid: the domain description (possibly of a noisy map).
        movement: 4 or 8, at every level.
        weight: the obstacleness weight of PATH-FINDER (see `find_path`).
        top: the level of the first plan; the pyramid's top by default (the papers' "highest
            level of abstraction", usually one cell: the first plan is then that one cell and
            its first refinement plans start to goal one level lower without splitting).

    REFINE (`_Planner.refine`) splits the chosen level-k segment of m moves at its middle (a
    child of cell m // 2, or of cell (m + 1) // 2 when m is odd, chosen so both halves are about
    m moves long) and re-plans each half with PATH-FINDER at level k - 1 between the projected
    endpoints: the length of a segment stays about invariant (within one move on an open map)
    and so does the cost of a refinement. Endpoints project down to the start's or goal's own
    cell (from SEGMENTIZE), to the junction of a finer neighbour, or else to a child of the
    block reachable from the start at level k - 1 (so every PATH-FINDER call has a solution
    when the goal is reachable on the map given).

    Raises:
        ValueError: a blocked start or goal, a top outside the pyramid, or (from PATH-FINDER) a
            goal not reachable from the start on this map.
    """
    top = pyramid.top if top is None else top
    if not 0 <= top <= pyramid.top:
        raise ValueError(f"top must be in [0, {pyramid.top}], got {top}")
    for name, position in (("start", start), ("goal", goal)):
        if pyramid.obstacleness(position, 0) >= 1.0:
            raise ValueError(f"{name} {position} is a blocked cell")
    planner = _Planner(pyramid, start, goal, movement, weight, ctx)
    first = planner.plan(top, project(start, 0, top), project(goal, 0, top))
    plan = MultiPath(start, goal, segmentize(start, top), (first,), segmentize(goal, top)[::-1])
    yield Result(plan, quality_estimate(plan, pyramid))
    while not ctx.expired:
        index = worst_segment(plan, pyramid)
        if index is None:
            return
        plan = planner.refine(plan, index)
        yield Result(plan, quality_estimate(plan, pyramid))


class _Planner:
    """PATH-FINDER and REFINE over one pyramid, with the cells reachable from the start at each
    level (computed lazily) so that every junction chosen is connected to the goal."""

    def __init__(
        self,
        pyramid: Pyramid,
        start: Position,
        goal: Position,
        movement: int,
        weight: float,
        ctx: Context,
    ) -> None:
        self.pyramid, self.start, self.goal = pyramid, start, goal
        self.movement, self.weight, self.ctx = movement, weight, ctx
        self._reachable: dict[int, BoolGrid] = {}

    def reachable(self, level: int) -> BoolGrid:
        if level not in self._reachable:
            blocked = self.pyramid.levels[level] >= 1.0
            origin = project(self.start, 0, level)
            self._reachable[level] = reachable(blocked, origin, self.movement)
        return self._reachable[level]

    def plan(self, level: int, source: Position, target: Position) -> Segment:
        """PATH-FINDER at `level`."""
        found = find_path(
            self.pyramid.levels[level],
            source,
            target,
            movement=self.movement,
            weight=self.weight,
            ctx=self.ctx,
        )
        if found is None:
            raise ValueError(f"no path from {source} to {target} at level {level}")
        return Segment(level, found.path)

    def refine(self, plan: MultiPath, index: int) -> MultiPath:
        """REFINE the route segment `index`: halves re-planned one level lower."""
        segments = plan.segments
        segment = segments[index]
        k, cells = segment.level, segment.cells
        lower = k - 1
        if index == 0:
            first = project(self.start, 0, lower)
        elif segments[index - 1].level <= lower:
            prev = segments[index - 1]
            first = project(prev.target, prev.level, lower)
        else:
            first = self._descend(cells[0], k, cells[0])
        if index == len(segments) - 1:
            last = project(self.goal, 0, lower)
        elif segments[index + 1].level <= lower:
            nxt = segments[index + 1]
            last = project(nxt.source, nxt.level, lower)
        else:
            last = self._descend(cells[-1], k, cells[-1])
        m = segment.moves
        if m == 0:
            new: tuple[Segment, ...] = (self.plan(lower, first, last),)
        else:
            middle = self._middle((cells[m // 2], cells[(m + 1) // 2]), k, first, last, m)
            new = (self.plan(lower, first, middle), self.plan(lower, middle, last))
        head = plan.head[:-1] if index == 0 else plan.head
        tail = plan.tail[1:] if index == len(segments) - 1 else plan.tail
        return MultiPath(
            plan.start, plan.goal, head, segments[:index] + new + segments[index + 1 :], tail
        )

    def _middle(
        self,
        middle: tuple[Position, Position],
        level: int,
        first: Position,
        last: Position,
        moves: int,
    ) -> Position:
        """The junction between the two halves: a child of the middle cell (of either middle
        cell when the segment has an odd number of moves), reachable from the start, whose
        straight-line move counts (Manhattan or Chebyshev) from `first` and to `last` are nearest
        `moves` each (the invariant), least obstacleness breaking ties."""
        lower = level - 1
        grid, ok = self.pyramid.levels[lower], self.reachable(lower)
        candidates = []
        for cell in dict.fromkeys(middle):
            x0, y0 = project(cell, level, lower)
            candidates += [(x, y) for y in (y0, y0 + 1) for x in (x0, x0 + 1) if ok[y, x]]
        if not candidates:
            return self._descend(middle[0], level, middle[1])

        def distance(a: Position, b: Position) -> int:
            dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
            return dx + dy if self.movement == 4 else max(dx, dy)

        return min(
            candidates,
            key=lambda c: (
                max(abs(distance(first, c) - moves), abs(distance(c, last) - moves)),
                abs(distance(first, c) - moves) + abs(distance(c, last) - moves),
                grid[c[1], c[0]],
            ),
        )

    def _descend(self, cell: Position, level: int, toward: Position) -> Position:
        """A junction one level below `cell`: the child (of the four) reachable from the start at
        that level that is nearest the boundary with `toward` (a neighbour at `level`, or `cell`
        itself: then its centre), least obstacleness breaking ties. Without such a child (rare:
        the block's free part is walled off at the finer level), the nearest reachable cell."""
        lower = level - 1
        grid = self.pyramid.levels[lower]
        ok = self.reachable(lower)
        # The point to be near, in level-(lower) coordinates: the centre of a level cell c is
        # 2c + 1 there, so the midpoint of the centres of `cell` and `toward` is their sum + 1.
        aim = (cell[0] + toward[0] + 1.0, cell[1] + toward[1] + 1.0)
        x0, y0 = project(cell, level, lower)
        candidates = [(x, y) for y in (y0, y0 + 1) for x in (x0, x0 + 1) if ok[y, x]]
        if not candidates:
            ys, xs = np.nonzero(ok)
            d = (xs + 0.5 - aim[0]) ** 2 + (ys + 0.5 - aim[1]) ** 2
            i = int(np.argmin(d))
            return (int(xs[i]), int(ys[i]))
        return min(
            candidates,
            key=lambda c: (
                (c[0] + 0.5 - aim[0]) ** 2 + (c[1] + 0.5 - aim[1]) ** 2,
                grid[c[1], c[0]],
            ),
        )


def _mean_obstacleness(segment: Segment, pyramid: Pyramid) -> float:
    xs, ys = zip(*segment.cells, strict=True)
    return float(pyramid.levels[segment.level][list(ys), list(xs)].mean())
