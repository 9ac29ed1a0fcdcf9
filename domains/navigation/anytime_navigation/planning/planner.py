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
cell lies inside the coarser one's (projected up to the coarser level they are equal), and so
does its node. An executor can therefore follow a mixed-level plan segment by segment: a
level-k cell with its node means "go into that connected region of the 2^k x 2^k block"
(`MultiPath.region`).

PATH-FINDER and REFINE work on the connectivity-aware abstraction (`components`): a level-k plan
is a path of neighbouring nodes, each a connected free region of one block. PATH-FINDER searches
the top level from node centre to node centre, and the next step searches it again through the
doors between nodes (`doors`: where a route crosses from node to node, so that pieces of rooms
are costed by the way through them, not by their centres) and goes on from that route when it
is cheaper. A refinement searches the children of the refined segment's nodes and of their
neighbours (three rings of them at level 2: `_RINGS`), a corridor that always holds a path (A*
over it, compiled: `corridor_search`; a tick is a node an A* search would expand).
"""

from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt
from attrs import field, frozen

from anytime.plugin import Context, Result

from ..world import BoolGrid, Position
from .abstraction import Pyramid
from .components import Components, NodePath
from .search import (
    STEP_NO_PATH,
    STEP_NONE_LEFT,
    STEP_OVER,
    GridAstar,
    SearchLimit,
    compiled,
    find_path,
)

#: The level of the first plan by default: blocks of 8 x 8 cells (measured on the MovingAI maps of
#: every kind, benchmarks/bench_navigation.py: coarser first plans confine the refinements to
#: worse corridors; finer ones cost more to refine). Against the compiled A* (issue 36), `top=4`
#: pays on the 512 x 512 maps (less time and fewer expansions on all 14 of the per-kind table,
#: final plans within 0.001 but on random 10% and rooms of 8 and 32: 0.985-0.987 against
#: 0.989-0.999) and not on the task's 128 x 128 worlds (docs/navigation.md: with its profile and
#: calibrations measured again, the monitor realised less), so the default stays and large maps
#: are planned with `LARGE_MAP_OPTIONS`.
DEFAULT_TOP = 3

#: The options that measured best on the 512 x 512 MovingAI maps of every kind (issue 36; the
#: per-kind table of benchmarks/bench_navigation.py): `anytime plan`'s by default on every map
#: but those of scattered, dense obstacles or solid ones (`map_options`). Not the navigation
#: task's, whose 128 x 128 worlds are planned better with the defaults. `jump_points` joined
#: them last (the same plans; scratch runs, the 16 longest problems, interleaved, time with the
#: build against the compiled A*'s, without -> with: mazes of width 4 16.5% -> 11.6-12.1%,
#: width 8 14.6% -> 13.5-13.7%, rooms of 8 and 64 0.1-0.9 points less, random 10% and 20%
#: within 0.4 of a point either way; the maze of width 1 then searched its direct route cell by
#: cell, until the scans read a byte a cell).
#: `direct_width` went from 12 to 20 with jump points: the mazes of width 8, 15-18 cells per
#: unit of length, are then planned by the direct route too (the 16 longest problems, scratch
#: runs, time against the compiled A*'s without the build: 11.9% -> 5.9%, final plans 1.000,
#: and no fall of the executed quality: two plans, the second never followed longer); rooms of
#: 8 and 16, at 27 or more, lose with it (0.985 -> 0.957 on rooms of 8: their first plan's
#: corridor holds the wrong doors).
LARGE_MAP_OPTIONS: Mapping[str, Any] = MappingProxyType(
    {
        "top": 4,
        "direct": 4,
        "direct_width": 20,
        "no_ring_when_open": 0.05,
        "one_ring_when_open": 0.1,
        "landmarks": 8,
        "no_ring_when_clear": 0.7,
        "jump_points": True,
    }
)

#: The options of maps of walls (no scattered obstacles, not dense: rooms, mazes of corridors
#: four cells wide or more, streets, the games' caves and halls): the first plan over blocks
#: of 8 x 8, then the direct route through the cells of its nodes and of their neighbours
#: (`direct_width` unbounded), no refinement level by level: the curve never falls
#: (`registers_no_fall`), two plans a problem.
#: Refined level by level, the executed quality fell at 3-30 steps in 112-240 on every map of
#: walls measured but the narrow mazes and random 30% (issue 36, MovingAI's maps, the 16
#: longest problems, the benchmark's per-kind table, time against the compiled A*'s with the
#: build, refined -> direct: rooms of 8 9.5% -> 7.1%, of 16 8.6% -> 7.0%, of 32 and 64 (each
#: refinement followed, to keep it from falling) 21.3% -> 7.0% and 18.7% -> 6.8%, the maze of
#: width 16 16.8% -> 10.2%, final plans 0.985 -> 0.972 on rooms of 8 (min 0.950), 0.990 ->
#: 0.975 on rooms of 16, 0.981-0.996 -> 0.989-1.000 on rooms of 32 and 64; the streets and the
#: games' maps 0.987-0.997 -> 1.000 but ht_chantry 0.979, at about the same time: Dragon Age's
#: brc203d, den520d, hrt201n 19-23% and Baldur's Gate II's 11-16% with the build; the caves of
#: about 200 x 200 cells, where A* takes 2-4 ms, measured in one run: ht_chantry 25.8% -> 24.8%,
#: lak303d 24.8% -> 28.0%, ost003d 26.5% -> 28.7%).
#: The first plan over blocks of 16 x 16 would be cheaper, but its corridor's direct route
#: costs more (brc202d: 28.4% of A*'s time without the build, 16.3% from blocks of 8 x 8), and
#: on rooms it holds the wrong doors (rooms of 8: 0.957). Also the options of maps of scattered
#: obstacles neither sparse nor dense (`MapShape`: MovingAI's random maps of 20% blocked).
#: Refined level by level with `LARGE_MAP_OPTIONS`, as until issue 36's curve that never falls,
#: their executed quality fell at 17-27 steps in 240; the direct route registers none that falls,
#: its final plans as good or better (issue 36, the 16 longest problems, time against the
#: compiled A*'s with the build, refined -> direct, searched cell by cell then: random512-20-0
#: 18.8% -> 16.0%, final plans 0.975 -> 0.977; random512-20-1, not tuned on, 0.977 -> 0.980 at
#: 17.5%). Searched by jump points since they read a byte a cell: 1.2-2.6 points of A*'s time
#: less on random 10-30% (scratch runs, interleaved, without the build: random 20% 11.0-11.4%
#: -> 9.6-10.1%).
WALLED_MAP_OPTIONS: Mapping[str, Any] = MappingProxyType(
    {**LARGE_MAP_OPTIONS, "top": 3, "direct_width": math.inf, "doors": False}
)


#: The options of maps of sparse scattered obstacles (`MapShape.sparse`: MovingAI's random maps
#: of 10-15%): `WALLED_MAP_OPTIONS` with the direct route's ring of neighbours one level lower
#: (`direct_ring_level`, blocks of 4 x 4). Where few cells are blocked the shortest route keeps
#: close to the first plan's blocks, and the ring of blocks of 8 x 8 costs more than it gains
#: (issue 36, the 16 longest problems, with the build, against the compiled A*'s time and
#: expansions: random512-10-0 27.8% and 33.3% with the ring of 8 x 8 (final plans 0.989), 20.5%
#: and 23.1% with these (0.987), against 22.7% and 15.0% refined with `LARGE_MAP_OPTIONS`
#: (0.977, falling at 30 steps in 240); not tuned on: random512-10-1 22.5% (0.988), -15-0 and
#: -15-1 15.6-15.8% (0.977-0.978; 21.6% and 0.984 with the ring of 8 x 8)).
SPARSE_MAP_OPTIONS: Mapping[str, Any] = MappingProxyType(
    {**WALLED_MAP_OPTIONS, "direct_ring_level": 2}
)

#: The options of maps of scattered, dense obstacles (`MapShape`: MovingAI's random maps of
#: 25-40%): `WALLED_MAP_OPTIONS` with the direct route's corridor through a second plan over
#: blocks of 4 x 4 and two rings of their neighbours (`direct_via`, `direct_rings`), and the
#: first plan's cells with one ring. Among dense obstacles a first plan over blocks of 8 x 8
#: goes round them the wrong way (its corridor's direct route, one ring: random 30% 0.958, min
#: 0.912; two rings 0.966, min 0.926), and one over blocks of 4 x 4 chooses better but costs
#: 2.1-3.5% of the compiled A*'s time as a first plan. Refined level by level from blocks of
#: 8 x 8 with the door search, as until issue 36's curve that never falls (`LARGE_MAP_OPTIONS`
#: with `top=3, direct_width=8`, no jump points), the final plans were 0.975-0.981 but 0.979
#: at 40%, and the executed quality fell at up to 5 steps in 112; these register two plans, the
#: second never followed longer (issue 36, the 16 longest problems, in one run, time against the
#: compiled A*'s with the build, refined -> these: random512-25-0 27.6% -> 26.1%, final plans
#: 0.981 -> 0.982; -30-0 24.1% -> 20.5%, 0.975 (min 0.951) -> 0.981 (0.966); -30-1 28.9% ->
#: 28.8%, 0.979 -> 0.994; -35-0 18.3% -> 16.4%, 0.981 -> 0.983; -40-0 14.3% -> 16.6%, 0.979 ->
#: 1.000; a noisy run: the first two read 22-24% refined in others).
SCATTERED_MAP_OPTIONS: Mapping[str, Any] = MappingProxyType(
    {**WALLED_MAP_OPTIONS, "direct_via": 2, "direct_rings": 2}
)

#: The options of small maps (fewer free cells than `SMALL_MAP_FREE_CELLS`): no abstraction
#: above the cells, one jump point search over all of them (its straight jumps read off the
#: map's table, `corridor_search.jump_distances`), which registers the optimal route as the
#: first plan and the last. There the compiled A* answers the longest problems in under
#: about 2 ms (about 0.3 µs per free cell on MovingAI's maps), so 2% of its time is less than a
#: first plan's fixed costs from Python (30-40 µs), and the abstraction cannot pay: on six
#: Dragon Age maps of 954-11,334 free cells (issue 36, the 16 longest problems, against the
#: compiled A*'s time) the walled-map options' first plan took 2.5-31% and their route to
#: completion 18-151%, with the build 32-273%, where one jump point search of the whole map
#: took 13-46%.
SMALL_MAP_OPTIONS: Mapping[str, Any] = MappingProxyType(
    {"top": 0, "jump_points": True, "doors": False}
)

#: A map with fewer free cells than this is planned with `SMALL_MAP_OPTIONS` (`map_options`):
#: about where the compiled A*'s longest problems take 2 ms. Above it the first plan keeps
#: within 2% of that time (the caves of 7,461-14,784 free cells: 1.4-2.3%), and the ATP to
#: completion is about as fast as one jump point search of the whole map (ht_chantry, 7,461
#: free cells: 14.3% of A*'s time against 12.7%; lak303d, 14,784: 18.0% against 18.7%).
SMALL_MAP_FREE_CELLS = 6000

#: The options of maps of walls with fewer free cells than `SMALL_WALLED_MAP_FREE_CELLS` (and
#: at least `SMALL_MAP_FREE_CELLS`): `WALLED_MAP_OPTIONS` with the direct route over the whole
#: map (`direct_whole`), one jump point search of every cell reading the map's jumps, the
#: optimal route. On such maps it costs a third to a half less than the corridor's search
#: (issue 36, Dragon Age's maps, the 16 longest problems, against the compiled A*'s time, the
#: benchmark's quick protocol, walled-map options -> these: ht_chantry 13.6% -> 8.1%, with the
#: build 24.2% -> 20.9%; ost003d 15.9% -> 9.0%, 25.2% -> 18.3%; den520d 8.6% -> 3.9%, 17.0% ->
#: 12.7%; not tuned on, in one run: lak202d 15.4% -> 8.3%, 26.1% -> 21.3%; den901d 11.9% ->
#: 6.7%, 19.6% -> 16.2%; final plans 1.000, against 0.978-0.979 on ht_chantry and den901d).
#: On MovingAI's 512 x 512 maps (120,000 free cells or more; a scratch loop, warm, without the
#: build) it gained on rooms of 32 and 64, streets and Baldur's Gate II (1-2 points of A*'s
#: time) and lost on rooms of 8 and 16, Boston and the maze of width 4, whose walls close
#: together make a search of the whole map settle more jump points than the corridor has cells.
SMALL_WALLED_MAP_OPTIONS: Mapping[str, Any] = MappingProxyType(
    {**WALLED_MAP_OPTIONS, "direct_whole": True}
)

#: A map of walls with fewer free cells than this is planned with `SMALL_WALLED_MAP_OPTIONS`
#: (`map_options`): between the Dragon Age maps measured (brc202d, 43,151) and MovingAI's
#: 512 x 512 maps (Baldur's Gate II's AR0011SR, 120,458, the fewest).
SMALL_WALLED_MAP_FREE_CELLS = 50_000

#: The base cells of the direct route's corridor per jump point settled past which a search of
#: the whole map (`atp(direct_whole=True)`) stops and the corridor is searched: on MovingAI's
#: maps (issue 36, the 16 longest and 16 random problems of each, compiled) the corridor's
#: search takes 0.04-0.12 µs a cell, the whole map's 0.25-0.84 µs a jump point settled.
WHOLE_ROUTE_RATIO = 8


def made_ahead(components: Components, level: int, options: Mapping[str, Any]) -> None:
    """Make now what `atp(**options)` with its first plan at `level` makes of `components` when
    first needed and keeps: the level's doors when it searches them (`doors`, on by default),
    the room of its search over the level with its `landmarks` (`Components.search_room`), and
    `direct_via`'s level's; at level 0 with `jump_points`, the room of its search over every
    cell (`Components.whole_room`), and so with `direct_whole`. Call it with the abstraction's
    build, once per map, so that no problem's time holds them."""
    jumps = bool(options.get("jump_points")) and components.movement == 8
    if jumps and (level <= 0 or options.get("direct_whole")):
        components.whole_room()
    if level <= 0:
        return
    if options.get("doors", True):
        components.doors(level)
    landmarks = options.get("landmarks") or 0
    components.search_room(level, landmarks)
    via = options.get("direct_via")
    if via is not None and 1 <= via < level:
        components.search_room(via, landmarks)


@frozen
class MapShape:
    """What `map_options` reads of a map: how scattered its obstacles are, and how dense they
    are where the robot can go. On MovingAI's random maps (10-40% blocked) 0.065-0.098 lone
    blocked cells (no blocked cell beside them) per free cell; on every other kind of the
    benchmark (rooms, mazes, streets, games, caves: maps of walls) 0.001 or fewer."""

    #: blocked cells none of whose four neighbours is blocked, per free cell
    lone_obstacles_per_free_cell: float
    #: the blocked share of the cells one move or less from a free cell
    blocked_near_free: float

    #: Scattered: at least this many lone blocked cells per free cell.
    SCATTERED = 0.01
    #: Dense: at least this share blocked near free cells (0.22: between MovingAI's random maps
    #: of 20%, which the large-map options plan at 0.975, and 25%, at 0.965).
    DENSE = 0.22
    #: Sparse: less than this share blocked near free cells (0.175: between MovingAI's random
    #: maps of 15%, 0.150, and 20%, 0.202).
    SPARSE = 0.175

    @classmethod
    def of(cls, blocked: BoolGrid) -> MapShape:
        """The shape of a map (True: blocked); outside it counts as blocked. Shifted views
        only, combined in place: about 2 ms on 1024 x 1024."""
        grid = np.asarray(blocked, dtype=bool)
        free = np.zeros((grid.shape[0] + 2, grid.shape[1] + 2), dtype=bool)  # a blocked border
        np.logical_not(grid, out=free[1:-1, 1:-1])
        free_cells = int(np.count_nonzero(free))
        if free_cells == 0:
            return cls(0.0, 1.0)
        middle = free[1:-1, 1:-1]
        lone = free[:-2, 1:-1] & free[2:, 1:-1]  # all four sides free, in place
        lone &= free[1:-1, :-2]
        lone &= free[1:-1, 2:]
        lone &= ~middle
        across = free[:, :-2] | free[:, 1:-1]  # a free cell within one move: rows, then columns
        across |= free[:, 2:]
        near = across[:-2] | across[1:-1]
        near |= across[2:]
        near_cells = int(np.count_nonzero(near))
        blocked_near = near_cells - free_cells
        return cls(int(np.count_nonzero(lone)) / free_cells, blocked_near / near_cells)

    @property
    def scattered(self) -> bool:
        return self.lone_obstacles_per_free_cell >= self.SCATTERED

    @property
    def dense(self) -> bool:
        return self.blocked_near_free >= self.DENSE

    @property
    def sparse(self) -> bool:
        return self.blocked_near_free < self.SPARSE


def map_options(blocked: BoolGrid) -> Mapping[str, Any]:
    """The options of `atp` (and of its abstraction's build) chosen by the map's size and shape
    (`anytime plan`'s by default; on MovingAI's maps of 194 x 194 to 512 x 512 of every kind
    they measured better than the planner's defaults, made for the navigation task's 128 x 128
    worlds): `SMALL_MAP_OPTIONS` on maps of fewer than `SMALL_MAP_FREE_CELLS` free cells; else
    on maps of walls (no scattered obstacles) not dense `SMALL_WALLED_MAP_OPTIONS` under
    `SMALL_WALLED_MAP_FREE_CELLS` free cells and `WALLED_MAP_OPTIONS` over it; on maps
    of scattered obstacles `SPARSE_MAP_OPTIONS`, `WALLED_MAP_OPTIONS` or
    `SCATTERED_MAP_OPTIONS` as they are sparse, neither or dense; else `LARGE_MAP_OPTIONS`:
    mazes of corridors one or two cells wide (dense walls, 0.33-0.50 blocked near free cells),
    where a first plan over blocks of 8 x 8 costs more than 2% of the compiled A*'s time
    (width 1: 2.5%, against 1.8% over blocks of 16 x 16, whose corridors are narrow enough
    there for the direct route)."""
    grid = np.asarray(blocked, dtype=bool)
    free = grid.size - np.count_nonzero(grid)  # no copy made
    if free < SMALL_MAP_FREE_CELLS:
        return SMALL_MAP_OPTIONS
    shape = MapShape.of(grid)
    if shape.scattered:
        if shape.dense:
            return SCATTERED_MAP_OPTIONS
        return SPARSE_MAP_OPTIONS if shape.sparse else WALLED_MAP_OPTIONS
    if shape.dense:
        return LARGE_MAP_OPTIONS
    return SMALL_WALLED_MAP_OPTIONS if free < SMALL_WALLED_MAP_FREE_CELLS else WALLED_MAP_OPTIONS


def registers_no_fall(options: Mapping[str, Any]) -> bool:
    """Whether `atp(**options)`, planning on the map its plans are followed on, registers no
    plan followed longer than the one before, without following any: the first plan (above
    the base level), then the direct route through the cells of its nodes and of their
    neighbours alone (`direct_width` unbounded: `WALLED_MAP_OPTIONS`, `SPARSE_MAP_OPTIONS`,
    `SCATTERED_MAP_OPTIONS`; the neighbours at any level, `direct_ring_level`, or a second
    plan's besides, `direct_via`), or over the whole map (`direct_whole`:
    `SMALL_WALLED_MAP_OPTIONS`, the optimal route). Followed on its map, the
    first plan keeps to its corridor, inside the cells that route is the shortest through. Or
    a first plan of cells (`top=0`: `SMALL_MAP_OPTIONS`), the one plan registered."""
    top = options.get("top", DEFAULT_TOP)
    return top == 0 or options.get("direct_width") == math.inf


#: How many rings of neighbouring nodes around a refined segment's nodes join its corridor, by
#: the segment's level (one where not listed). Level 2 gets three: on dense random maps (20-30%
#: of cells blocked, scattered) the centres of 4 x 4 blocks choose blindly among ways of about
#: equal length, and a corridor of one ring ties the finer levels to that choice (MovingAI's
#: random512-20-0 and -30-0, 16 longest problems: final plans 0.963 and 0.962 of the optimal
#: length with one ring, 0.976 and 0.975 with three; rooms and random 10%: up by 0.004-0.010;
#: mazes, streets, games and caves: unchanged, at about 1% more of A*'s time on caves). More
#: rings at level 1 cost more at the base level than they gain.
_RINGS = {2: 3}

__all__ = [
    "DEFAULT_TOP",
    "LARGE_MAP_OPTIONS",
    "SCATTERED_MAP_OPTIONS",
    "SMALL_MAP_FREE_CELLS",
    "SMALL_MAP_OPTIONS",
    "SMALL_WALLED_MAP_FREE_CELLS",
    "SMALL_WALLED_MAP_OPTIONS",
    "SPARSE_MAP_OPTIONS",
    "WALLED_MAP_OPTIONS",
    "WHOLE_ROUTE_RATIO",
    "MapShape",
    "MultiPath",
    "Segment",
    "atp",
    "compile_searches",
    "made_ahead",
    "map_options",
    "quality_estimate",
    "registers_no_fall",
    "segmentize",
]


def _cells(value: object) -> tuple[Position, ...]:
    if isinstance(value, np.ndarray) and value.dtype.kind in "iu" and value.shape[1:] == (2,):
        cells = tuple(map(tuple, value.tolist()))  # the planner's: ints already, made at once
    else:
        cells = tuple((int(x), int(y)) for x, y in value)  # type: ignore[attr-defined]
    if not cells:
        raise ValueError("a segment needs at least one cell")
    return cells


def _nodes(value: Iterable[int]) -> tuple[int, ...]:
    return tuple(map(int, value))


@frozen
class Segment:
    """A path at one abstraction level: `cells` are positions at `level`, in order; consecutive
    cells are neighbours at that level (4- or 8-connected)."""

    level: int
    cells: tuple[Position, ...] = field(converter=_cells)
    # The abstraction's nodes the cells stand for (`components.Components`): the connected
    # free region of each cell's block the segment goes through; empty for a segment made
    # without them (then a cell means its whole block).
    nodes: tuple[int, ...] = field(default=(), converter=_nodes)

    @classmethod
    def _made(cls, level: int, cells: tuple[Position, ...], nodes: tuple[int, ...]) -> Segment:
        """The segment of cells and nodes already in the fields' types (tuples of ints), their
        converters skipped: the planner makes several segments per refinement, and converting
        the long ones at the base level cell by cell cost a fifth of its time on mazes."""
        segment = object.__new__(cls)
        _SET_LEVEL(segment, level)
        _SET_CELLS(segment, cells)
        _SET_NODES(segment, nodes)
        return segment

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


# The slots' own setters (a frozen class's `__setattr__` refuses): `Segment._made`'s, faster
# than `object.__setattr__` by name
_SET_LEVEL, _SET_CELLS, _SET_NODES = (
    Segment.__dict__[name].__set__ for name in ("level", "cells", "nodes")
)


@frozen
class MultiPath:
    """A plan: the route `segments` from `start` to `goal`, with `head` (what is left of
    SEGMENTIZE(start)) and `tail` (what is left of SEGMENTIZE(goal)) read off them. `parts` is
    the whole list of the pseudocode.

    The head holds the one-cell segments start@0 .. start@(L-1) below the level L of the first
    route segment, the tail likewise for the goal in descending order; refining the first (last)
    route segment plans its new half from start@(L-1) (to goal@(L-1)), which absorbs that
    connector. When every route segment is at level 0, head and tail are empty. They follow
    from the segments' levels, so a plan holds them only when read (a first plan is made in
    tens of microseconds, and two SEGMENTIZEs were a tenth of it).
    """

    start: Position
    goal: Position
    segments: tuple[Segment, ...]
    # The abstraction the segments' nodes are of (None for a plan made without one): what an
    # executor reads a node's cells from, to aim at the region a node means, not its block.
    abstraction: Components | None = field(default=None, eq=False, repr=False)

    def region(self, level: int, node: int | None) -> BoolGrid | None:
        """The cells of its block a node of the plan holds, a (2^level, 2^level) mask [y, x];
        None when the plan does not say (no abstraction or node: the whole block is meant)."""
        if self.abstraction is None or node is None or level == 0:
            return None
        return self.abstraction.region(node, level)

    def corridor(self) -> BoolGrid | None:
        """The base cells the plan's nodes hold, a mask [y, x] shaped like the map planned on:
        where the plan means the route to run (the start and goal among them, and the corner
        cells of the diagonal moves that join two nodes: without cutting corners, such a move
        needs them free, and they may be a third node's); None when the plan has no
        abstraction."""
        if self.abstraction is None:
            return None
        grids = self.abstraction.grids
        meant = np.zeros(grids[0].shape, dtype=bool)
        by_level: dict[int, list[int]] = {}
        for segment in self.parts:
            if segment.nodes:  # SEGMENTIZE's one-cell segments have none
                by_level.setdefault(segment.level, []).extend(segment.nodes)
        for level, nodes in by_level.items():
            held = np.zeros(len(self.abstraction.levels[level]) + 1, dtype=bool)  # last: -1
            held[nodes] = True
            meant |= held[grids[level]]
        for x, y in (self.start, self.goal):
            meant[y, x] = True
        if self.abstraction.movement == 8:
            free = grids[0] >= 0
            corners = np.zeros_like(meant)
            for low, high in ((slice(None, -1), slice(1, None)), (slice(1, None), slice(None, -1))):
                # the moves from (x, y) to (x + 1, y + 1) and to (x + 1, y - 1)
                move = meant[low, :-1] & meant[high, 1:] & free[low, 1:] & free[high, :-1]
                corners[low, 1:] |= move
                corners[high, :-1] |= move
            meant |= corners
        return meant

    @property
    def head(self) -> tuple[Segment, ...]:
        """SEGMENTIZE(start) below the first route segment's level."""
        return segmentize(self.start, self.segments[0].level) if self.segments else ()

    @property
    def tail(self) -> tuple[Segment, ...]:
        """SEGMENTIZE(goal) below the last route segment's level, from the highest down."""
        return segmentize(self.goal, self.segments[-1].level)[::-1] if self.segments else ()

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
    x, y = int(position[0]), int(position[1])  # projected up: (x >> k, y >> k), `project`
    made = Segment._made
    return tuple([made(level, ((x >> level, y >> level),), ()) for level in range(top)])


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
    top: int | None = None,
    segment_moves: int | None = None,
    components: Components | None = None,
    doors: bool = True,
    follow: Callable[[MultiPath], float] | None = None,
    door_rings: int | None = None,
    direct: int | None = None,
    direct_width: float | None = None,
    no_ring_when_open: float | None = None,
    one_ring_when_open: float | None = None,
    landmarks: int | None = None,
    no_ring_when_clear: float | None = None,
    skip_level_1: bool = False,
    jump_points: bool = False,
    direct_ring_level: int | None = None,
    direct_via: int | None = None,
    direct_rings: int | None = None,
    direct_steps: bool = False,
    direct_whole: bool = False,
) -> Iterator[Result]:
    """The anytime abstract planner: yields `Result(MultiPath, quality_estimate)` after the first
    plan and after every refinement (with `follow`, each that is followed no worse than the last
    registered); returns (SIGNAL(TERMINATION)) when nothing is refinable or
    when `ctx` has expired. Work is the expansions PATH-FINDER reports; a search is given what
    is left of the allocation and stopped when it runs out, so the planner never works past its
    deadline (the refinement under way is dropped; the last plan yielded stands).

    PATH-FINDER plans over the connectivity-aware abstraction (`components`): a level-k plan is
    a path of neighbouring *nodes*, each a connected free region of one 2^k x 2^k block, so a
    coarse plan never runs through a wall that splits a block; the first plan is costed from
    node centre to node centre, then searched again through the doors between nodes
    (`doors`). The pyramid's obstacleness chooses the worst segment and makes the quality
    estimate.

    Args:
        ctx: the context; each node a search expands is one tick.
        start: the base-level start (x, y), a free cell.
        goal: the base-level goal (x, y), a free cell.
        pyramid: the obstacleness pyramid of the map planned on (possibly a noisy one).
        movement: 4 or 8, at every level.
        top: the level of the first plan (the papers' "highest level of abstraction"). By
            default `DEFAULT_TOP`, blocks of 8 x 8 cells (the pyramid's top on smaller maps).
            At 0 the first plan is one search of every cell, the optimal route, and the only
            plan registered (`SMALL_MAP_OPTIONS`).
        segment_moves: the first plan is cut into segments of at most this many moves, of
            equal length (None, the default: one segment, as in the pseudocode). Segment length
            is what refinement keeps invariant, so it sets the grain of the anytime behaviour:
            how much one refinement costs and improves.
        components: the abstraction of the pyramid's map (`Components.build(pyramid.levels[0]
            >= 1, movement, top=top)`; its top level's doors are made when first searched),
            built here when not given; pass it to plan many times on one map.
        doors: after the first plan (a path of nodes costed from centre to centre), search
            the top level again through the doors between nodes (`doors`) and, when that
            route is cheaper through its doors, go on from it (the second result). Centres
            misjudge the way through pieces of rooms (MovingAI's rooms of 8: final plans 0.966
            of the optimal length without, 0.995 with), and a door search costs more than
            the first plan (each node's doors are expanded, several per node), so it comes
            second. Where nodes are whole blocks or rooms, it finds no better: `find-path`
            goes without (the navigation task's 128 x 128 worlds, 60 of them: final plans
            0.997 either way, 1,261 ticks to completion with it against 1,021 without).
            The door route is not registered by itself (issue 36: followed on the map it was
            worse than the first plan on 9 of 12 MovingAI problems): by centre-to-centre
            length, the one measure both plans have, it is never shorter than the first plan
            (the cheapest by it), so the planner goes on from it without registering it, and
            registers its refinements as they come. Nor with `follow`: following it cost a
            whole walk of the route, its refinements compared with the first plan cost about
            as much (issue 36, the 16 longest problems, the ATP with `following.Follower`
            against the compiled A*: rooms of 8 27.4% -> 23.2%, of 64 16.3% -> 14.4%,
            random 10% 44.6% -> 38.2%, final plans the same but on rooms of 16, 0.9996 ->
            0.9903, where the door route was kept to the end).
        follow: how long a route the robot will follow a plan by (the caller's robot and map:
            `execution.execute(plan, ...).length`, or a cheaper prediction). When given, a plan
            is registered only when it is followed no longer than the last one registered (the
            better is kept; the planner goes on refining from the new plan either way), so the
            quality executed never falls from one registered plan to the next; it is called
            once per plan after the first (the first is registered at once and followed when
            the second is compared with it), and its time is the planner's.
            `following.Follower(blocked, movement)` is `execute`'s length for plans made on
            the map they are followed on, compiled; a `follow` whose `planned_on_its_map` is
            true is not called for the `direct_width` route, never followed longer than the
            first plan there.
        door_rings: the search through the doors keeps to the first plan's nodes and those up
            to this many edges from them (None, the default: the whole level, bounded by the
            first plan's cost alone). Issue 36: the door search is a fifth to a quarter of the
            planner's time on MovingAI maps, most of it spent away from the first plan.
        direct: when the first plan has at most this many nodes (a short problem), search the
            base cells of its nodes and of their neighbours at once (A* over that corridor,
            compiled) and register that route alone, fully refined (None, the default: never).
            A short problem is then one search instead of a refinement per level, each with
            its fixed cost.
        direct_width: when the base cells of the first plan's nodes and of their neighbours
            are at most this many per unit of the first plan's length (a narrow corridor: the
            abstraction says a search through it costs little more than the route's own
            cells), register the first plan, then search those cells at once (`direct`'s
            search) and register that route, fully refined, instead of refining level by
            level (None, the default: never). Issue 36: on MovingAI's mazes the corridor is
            4-16 cells per unit of length (widths 1-8), on brc202d 20, on every other map of
            the benchmark 28 or more (blocks of 16 x 16, the 16 longest and 16 random
            problems).
        no_ring_when_open: a level-1 segment whose mean obstacleness is at most this is
            refined through the cells of its own nodes only, without the ring of neighbouring
            nodes (None, the default: always with it). Where the 2 x 2 blocks of a segment are
            free, the best route keeps to them, and the ring about triples the cells searched
            (issue 36: on brc202d, a Dragon Age cave, 0.05 takes expansions from 29% of the
            compiled A*'s to 23% at the same final quality; a dense random map's segments are
            seldom that open, and there a ring pays).
        one_ring_when_open: a level-2 segment whose mean obstacleness is at most this is
            refined through its nodes' children and one ring of neighbouring nodes', as at
            every other level, not `_RINGS`' three (None, the default: three). The three
            rings are for dense random maps, whose 4 x 4 blocks are seldom that open (issue 36,
            with top=4, direct=4, direct_width=12 and no_ring_when_open=0.05, the 16 longest
            problems: 0.1 takes brc202d, a Dragon Age cave, from 23.1% of the compiled A*'s
            expansions to 19.3% and its time with the abstraction's build from 30% to 24%, at
            the same final quality; random512-10-0's final plans 0.983 -> 0.977, rooms of 16
            0.995 -> 0.990, the other maps' unchanged; 0.05 changes no map's quality).
        landmarks: the first plan's search over the top level bounds its heuristic by this many
            landmarks' distances (`Components.landmarks`, made once per abstraction: pass
            `components` to plan many times on one map), the ALT heuristic: a first plan as
            cheap, fewer nodes expanded (None, the default: the distance as the robot moves
            alone). Issue 36: on MovingAI's mazes that search was most of the first plan's
            time, over most of level 4's nodes; 8 landmarks expand 6% as many of them, and a
            quarter on the other maps. The bound is exact along many routes, so many nodes tie
            (within rounding) with the cheapest cost: the deeper of two goes first, and the
            plan found costs the cheapest within a relative 1e-9 (on MovingAI's caves of
            200 x 200, a third fewer nodes settled).
        no_ring_when_clear: a level-2 segment at least this share of whose nodes are clear
            blocks (4 x 4 cells, none blocked) is refined through its own nodes' children
            only, without rings (None, the default: never). Where most of a segment's blocks are
            open ground, the best route keeps to them (issue 36, with the options above, the 16
            longest problems: brc202d, a Dragon Age cave, whose level-2 refinements all had one
            ring, 0.7 takes the planner from 18.9% of the compiled A*'s time to 14.7%, final
            plans 0.9996 -> 0.9973 of the optimal length; rooms of 32 0.9856 -> 0.9805;
            random 10%, rooms of 8 and 16 unchanged: their segments are seldom that clear).
            The price is the blocks' staircase: across an open 64 x 64 map the route keeps to
            the level-2 plan's blocks and is followed at 0.9855 of the optimum, not 1.0.
        skip_level_1: a level-2 segment is refined straight to the base cells, through its own
            nodes' cells (no rings), not to level 1 (False, the default), so no segment is ever
            of level 1. Half as many refinements below level 2, each searching the
            cells the two levels below would have searched through; where walls are thick, the
            finer level's rings changed little (issue 36: with it on MovingAI's
            Dragon Age caves 10-25% less time, final plans within 0.006; the solid-map
            options before issue 36's walled-map options),
            where they are one cell thick or obstacles scattered, much (rooms of 8: 0.985 ->
            0.962, random 20%: 0.975 -> 0.926 of the optimal length).
        jump_points: the searches over the base cells (octile moves) from one source, the
            refinements', the direct route's and a first plan's at level 0, are jump point searches
            (`corridor_search.jump_search`), not A* over every cell (False, the default): the
            same cheapest costs through the same corridors, a path of equal length (ties may
            go another way), fewer nodes pushed and expanded; the expansions reported are the
            jump points expanded. A first plan's at level 0 searches the whole map and reads
            its straight jumps off the map's table (`corridor_search.jump_distances`, made
            with the build by `made_ahead`: Rabin's JPS+), without scanning. Its scans read a
            byte a cell: on the direct route's corridors it takes 9-33% of A*'s time among
            walls (rooms, streets, caves, mazes of corridors two cells wide or more), 85% in
            corridors one cell wide and 67-81% among scattered obstacles (docs/navigation.md,
            "Jump points in the base cells"; every option set of `map_options` takes it).
        direct_ring_level: the level whose ring of neighbouring nodes joins the direct
            route's corridor (`direct`, `direct_width`): the cells of the first plan's nodes
            and of their neighbours at this level (None, the default: at the first plan's
            level; at most that level, at least 1). One level lower, the ring is half as wide
            on each side, and so is the search (issue 36, MovingAI's random maps of 10%, the 16
            longest problems, from blocks of 8 x 8: the ring at level 3 -> at level 2, 18.3-20.8%
            -> 13.3% of the compiled A*'s time without the build, final plans 0.989 -> 0.987;
            at 20% 0.977 -> 0.967: there the shortest route strays further from the first
            plan's blocks). Any level holds the cells the first plan is followed through (a
            free cell beside one of them is in its node or in a neighbouring one at every
            level), so the route is never followed longer than the first plan either way.
        direct_via: the direct route's corridor also holds the nodes of a second plan at this
            level (below the first plan's), the cheapest over the whole level from centre to
            centre (with `landmarks`, bounded by theirs at that level), and `direct_rings`
            rings of their neighbours; not registered (None, the default, or a level not below
            the first plan's: no second plan).
            The corridor keeps the first plan's cells and one ring of their neighbours at the
            level below the first plan's, so the route is still never followed longer than
            the first plan. Where obstacles are scattered and dense, a first plan over blocks
            of 8 x 8 goes round them the wrong way, and one over blocks of 4 x 4 chooses
            better, at more than 2% of the compiled A*'s time (`SCATTERED_MAP_OPTIONS`).
        direct_rings: the rings of neighbouring nodes around `direct_via`'s plan (None, the
            default: one).
        direct_steps: the direct route after the first plan (`direct_width`) is registered in
            steps (False, the default: once): first the route through the first plan's cells
            and a ring of neighbours at level 1, then at level 2, and so on up to its own
            corridor (`direct_ring_level`, `direct_via`). Each corridor holds the one before
            (a neighbour's cells lie in its parent, which is the parent of a first-plan node or
            its neighbour), so each route is the shortest through a set holding the last
            one's and is never followed longer: a curve of more, smaller steps, each a search.
        direct_whole: the direct route (`direct`, `direct_width`; with `direct_steps`, its last
            step) is the cheapest over the whole map, one jump point search of every cell, its
            straight jumps read off the map's table (`corridor_search.jump_distances`, made
            with the build by `made_ahead`), not the cheapest through the first plan's
            corridor; a problem whose search would settle more jump points than the corridor
            has cells over `WHOLE_ROUTE_RATIO` stops there and searches the corridor (False,
            the default: the corridor). Only with `jump_points` and octile moves (otherwise the
            corridor). The route is the optimal one, never followed longer than the first plan.
            Among walls on maps of some thousands of free cells it costs half the corridor's
            search or less; on large maps of walls close together it explores more than the
            corridor holds (`SMALL_WALLED_MAP_OPTIONS`).

    REFINE re-plans the chosen level-k segment one level lower, through the children of its
    nodes only (they are connected: see `components`), so the search is local and always finds
    a path. Its ends are the junctions with its neighbours: a fixed node when the neighbour is
    already finer (its end's node one level lower), otherwise any child of the shared node (the
    search chooses the best one, with the cost each adds to the neighbour's side, which the
    neighbour will then have to meet). The path found is split at its middle into two halves of
    equal length (a path of n moves into n // 2 and n - n // 2), each a segment one level lower:
    the length in moves of a segment stays about invariant, and so does a refinement's cost.

    A goal the map given does not connect to the start (a noisy map can wall it off) is not an
    error: the planner then opens the walls in the way (the cells of the cheapest route that
    counts a blocked cell as two free ones) and plans on that map; execution on the true map
    avoids the obstacles. Such a plan's quality is its estimate on the opened map times that
    route's length over its cost (its blocked cells counted twice): below 1 even fully refined,
    for it crosses cells blocked on the map given (a plan crossing 10 of 100 cells: 100 / 110).

    Raises:
        ValueError: a start or goal outside the map or blocked, a top outside the pyramid,
            segment_moves < 1, direct_ring_level or direct_via < 1, or components of another map
            or movement.
    """
    highest = pyramid.top
    top = min(DEFAULT_TOP, highest) if top is None else top
    if not 0 <= top <= highest:
        raise ValueError(f"top must be in [0, {highest}], got {top}")
    options = _checked_options(
        top, segment_moves, door_rings, direct, direct_width, no_ring_when_open,
        one_ring_when_open, landmarks, no_ring_when_clear, skip_level_1, jump_points,
        direct_ring_level, direct_via, direct_rings, direct_steps, direct_whole,
    )  # fmt: skip
    if components is None:
        components = Components.build(pyramid.levels[0] >= 1.0, movement, top=top)
    elif components.movement != movement or components.top < top:
        raise ValueError(
            f"the components are for movement {components.movement} up to level"
            f" {components.top}; planning needs movement {movement} up to level {top}"
        )
    elif components.cell.shape != pyramid.levels[0].shape:
        raise ValueError(
            f"the components are of a {components.cell.shape} map, the pyramid's is"
            f" {pyramid.levels[0].shape}"
        )
    share = 1.0  # the quality's share a plan across opened walls keeps (`_opened`)
    ends = components.joined(start, goal, top)  # (the map is the pyramid's: free cells alike)
    if ends is None:
        opened, share = _opened(pyramid.levels[0] >= 1.0, start, goal, movement)
        components = Components.build(opened, movement, top=top)
        ends = components.joined(start, goal, top)
        assert ends is not None, "the walls between start and goal were opened"
    planner = _Planner(components, pyramid, start, goal, ctx, options)
    try:
        found, first_made = planner.first(top, segment_moves, ends)
    except SearchLimit as stopped:  # the deadline came before the first plan
        ctx.tick(stopped.expansions)
        return
    if direct is not None and top > 0 and len(found.nodes) <= direct:
        try:
            route = planner.direct(top, found)
        except SearchLimit as stopped:  # the deadline came first: register the first plan
            ctx.tick(stopped.expansions)
        else:
            yield Result(MultiPath(start, goal, (route,), components), share)
            return

    def begin(
        path: NodePath, made: list[tuple[Segment, float]] | None = None
    ) -> tuple[list[tuple[Segment, float]], MultiPath, float]:
        """The segments of a top-level route with their mean obstacleness (`made` when they
        are), its plan and the estimate made for it (the sums in the order `_Steps` keeps
        them)."""
        if made is None:
            runs = _runs(len(path.nodes) - 1, segment_moves)
            made = planner.segments(top, path.nodes, runs, path.array)
        extent = credit = 0.0
        route = []
        for segment, o in made:
            extent_, credit_ = _credit(segment, o, highest)
            extent += extent_
            credit += credit_
            route.append(segment)
        plan = MultiPath(start, goal, tuple(route), components)
        return made, plan, _clip(credit / extent)

    # How long the last plan registered is followed (`follow`), or that plan itself until a
    # later one is compared with it: the first plan is registered without being followed.
    kept: float | MultiPath = math.inf

    def better(plan: MultiPath) -> bool:
        """Whether to register `plan`: always without `follow`, else when it is followed no
        longer than the last one registered."""
        nonlocal kept
        if follow is None:
            return True
        if isinstance(kept, MultiPath):
            kept = follow(kept)
        length = follow(plan)
        if length > kept:
            return False
        kept = length
        return True

    made, plan, estimate = begin(found, first_made)
    kept = plan  # the first plan: always registered (nothing is before it)
    yield Result(plan, share * estimate)
    if top == 0:  # a plan of cells: nothing is left to refine
        return
    if direct_width is not None and planner.width(top, found) <= direct_width:
        # Followed on the map it was made on, the first plan keeps to its corridor, inside the
        # cells each route is the shortest through: it is never followed longer (not where
        # walls were opened: then the map planned on is not the map followed); each step's
        # corridor holds the last one's
        trusted = share == 1.0 and getattr(follow, "planned_on_its_map", False)
        for ring in planner.direct_rings_by_step(top) if direct_steps else (None,):
            try:
                route = planner.direct(top, found, ring)
            except SearchLimit as stopped:  # the deadline came first: keep the last plan
                ctx.tick(stopped.expansions)
                return
            plan = MultiPath(start, goal, (route,), components)
            if trusted or better(plan):
                yield Result(plan, share)
        return
    if doors:
        try:
            rerouted = planner.through_doors(top, found)
        except SearchLimit as stopped:  # the deadline came first: keep the first plan
            ctx.tick(stopped.expansions)
            return
        if rerouted is not None:  # not registered by itself: its refinements are
            made, plan, estimate = begin(rerouted)
    # The plan in arrays, made after the first plan is registered (its time is the first plan's)
    steps = _Steps(planner, pyramid, top)
    steps.begin(made)
    segments = [segment for segment, _ in made]
    while not ctx.expired:
        # REFINE(WORST-SEGMENT(plan)) in one compiled call (`_Steps.refine`); here, only the
        # new segments made objects for the plan registered
        limit = ctx.remaining
        done, index, lower, _, expansions, estimate, path, blocks = steps.refine(limit)
        if done == STEP_NONE_LEFT:
            return
        if done == STEP_OVER:  # the deadline came mid-refinement: keep the last plan
            ctx.tick(int(limit))
            return
        if done == STEP_NO_PATH:
            raise AssertionError(f"no path at level {lower} through the children of a path")
        ctx.tick(expansions)
        nodes = tuple(path.tolist())
        cells = tuple(zip(blocks[:, 0].tolist(), blocks[:, 1].tolist(), strict=True))
        n = len(nodes) - 1
        halves = [(0, n)] if n < 2 else [(0, n // 2), (n // 2, n)]
        segments[index : index + 1] = [
            Segment._made(lower, cells[first : last + 1], nodes[first : last + 1])
            for first, last in halves
        ]
        plan = MultiPath(start, goal, tuple(segments), components)
        if better(plan):
            yield Result(plan, share * estimate)


class _Steps:
    """The plan as `corridor_search.refine_step` refines it: its segments in arrays (numbered in
    the order they are made: WORST-SEGMENT's ties go to the one made first), the heap of the
    refinable ones by score `2^k * (1 + o)` (k the level, o the mean obstacleness: the level
    dominates, and within a level the most blocked one wins), the quality estimate's two sums
    (`quality_estimate`, kept up to date rather than recomputed), and the arrays of the
    abstraction and pyramid the step reads."""

    def __init__(self, planner: _Planner, pyramid: Pyramid, top: int) -> None:
        c = planner.components
        no_ring = planner.options.no_ring_when_open
        one_ring = planner.options.one_ring_when_open
        clear = planner.options.no_ring_when_clear
        self.top, self.pyramid_top = top, pyramid.top
        self.reads = (
            *_map_reads(c, pyramid),
            c.node(planner.start, 0),
            c.node(planner.goal, 0),
            math.nan if no_ring is None else no_ring,  # NaN: no segment is that open
            math.nan if one_ring is None else one_ring,
            math.nan if clear is None else clear,
            bool(planner.options.skip_level_1),
            bool(planner.options.jump_points),
        )

    def begin(self, made: list[tuple[Segment, float]]) -> float:
        """The plan of the segments `made` (route order, each with its mean obstacleness); its
        quality estimate."""
        room = len(made) << (self.top + 1)  # a segment at level k is refined into < 2^(k+1)
        self.level = np.empty(room, dtype=np.int64)
        self.begin_at = np.empty(room, dtype=np.int64)
        self.end_at = np.empty(room, dtype=np.int64)
        self.obstacleness = np.empty(room)
        self.order = np.empty(room, dtype=np.int64)
        self.heap_keys = np.empty(room)
        self.heap_items = np.empty(room, dtype=np.int64)
        used = 0
        for s, (segment, o) in enumerate(made):
            self.level[s], self.obstacleness[s], self.order[s] = segment.level, o, s
            self.begin_at[s] = used
            used += len(segment.nodes)
            self.end_at[s] = used
        self.pool = np.empty(4 * used, dtype=np.int64)
        self.pool[:used] = [node for segment, _ in made for node in segment.nodes]
        self.counts = np.array([len(made), len(made), used, 0], dtype=np.int64)
        self.sums = np.zeros(2)
        estimate: float = compiled().begin_plan(
            self.level, self.begin_at, self.end_at, self.obstacleness,
            self.heap_keys, self.heap_items, self.counts, self.sums, self.pyramid_top,
        )  # fmt: skip
        return estimate

    def refine(
        self, limit: float
    ) -> tuple[int, int, int, int, int, float, npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """`corridor_search.refine_step` on the plan: what it did, the index of the segment
        refined, the new segments' level, the rings searched, the expansions, the estimate after
        it, the path's nodes and their blocks."""
        done, index, lower, rings, expansions, estimate, path, blocks, self.pool = (
            compiled().refine_step(
                self.level, self.begin_at, self.end_at, self.obstacleness, self.pool,
                self.order, self.heap_keys, self.heap_items, self.counts, self.sums,
                *self.reads, limit,
            )
        )  # fmt: skip
        return done, index, lower, rings, expansions, estimate, path, blocks


# The arrays `_Steps` reads of the last abstraction and pyramid planned on (`_map_reads`), with
# weak references to them: made once for the many plans on one map.
_last_map: tuple[weakref.ref[Components], weakref.ref[Pyramid], tuple[object, ...]] | None = None


def _map_reads(components: Components, pyramid: Pyramid) -> tuple[object, ...]:
    """The arguments of `corridor_search.refine_step` that are the map's: levels 0 and 1's
    arrays and the other levels' stacked (`Components.stacked`), the pyramid's stacked
    (`Pyramid.stacked`, copied when its levels are apart), the movement, the pyramid's top
    (the estimate's) and the rings of each level (`_RINGS`)."""
    global _last_map
    last = _last_map
    if last is not None and last[0]() is components and last[1]() is pyramid:
        return last[2]
    base, stacked = components.levels[0], components.stacked()
    none, no_floats = np.zeros(0, dtype=np.int64), np.zeros(0)
    if components.top >= 1:
        one = components.levels[1]
        level_one = (
            one.parent, one.block, one.centre, stacked.one_scratch, one.first, one.neighbour,
            one.cost, one.first_child, one.child,
        )  # fmt: skip
    else:  # nothing to refine
        no_pairs = np.zeros((0, 2), dtype=np.int64)
        level_one = (
            none,
            no_pairs,
            no_pairs.astype(float),
            none,
            none,
            none,
            no_floats,
            none,
            none,
        )
    obstacleness = pyramid.stacked()
    if obstacleness is None:  # levels apart (an unpickled pyramid): copied into one array
        obstacleness = Pyramid(pyramid.levels).stacked()
        assert obstacleness is not None
    reads = (
        base.parent, base.block, base.centre, stacked.base_scratch,
        base.padded if base.padded is not None else none, stacked.cells,
        base.grid.shape[1] + 2 if base.grid is not None else 0,
        *level_one,
        stacked.node_at, stacked.parent, stacked.block, stacked.centre, stacked.scratch,
        stacked.first_at, stacked.first, stacked.edge_at, stacked.neighbour, stacked.cost,
        stacked.child_at, stacked.first_child, stacked.child,
        *obstacleness, components.movement, pyramid.top,
        np.array([_RINGS.get(k, 1) for k in range(components.top + 1)], dtype=np.int64),
    )  # fmt: skip
    _last_map = (weakref.ref(components, _forget), weakref.ref(pyramid, _forget), reads)
    return reads


def _forget(_: object) -> None:
    """The map's arrays let go with its abstraction or pyramid (`_map_reads` holds them)."""
    global _last_map
    _last_map = None


def _runs(moves: int, most: int | None) -> list[tuple[int, int]]:
    """A path of `moves` moves cut into the fewest runs of at most `most` moves, of about equal
    length: each run's (first, last) node index (consecutive runs share their junction node)."""
    if most is None or moves <= most:  # one run: every first plan but with `segment_moves`
        return [(0, moves)]
    count = -(-moves // most)
    bounds = [round(i * moves / count) for i in range(count + 1)]
    return list(zip(bounds, bounds[1:], strict=False))


def _opened(
    blocked: BoolGrid, start: Position, goal: Position, movement: int
) -> tuple[BoolGrid, float]:
    """`blocked` with the walls between start and goal opened: the blocked cells of the
    cheapest route that counts a blocked cell as two free ones; and that route's length over
    its cost (below 1: the share of its quality a plan across the opened walls keeps, `atp`)."""
    grid = np.asarray(blocked, dtype=bool)
    found = find_path(
        grid, start, goal, movement=movement, weight=1.0, impassable=np.zeros_like(grid)
    )
    assert found is not None  # every cell is passable at a cost
    opened = np.array(blocked, dtype=bool)
    for x, y in found.path:
        opened[y, x] = False
    return opened, found.length / found.cost


@frozen
class _Options:
    """`atp`'s options the planner reads, checked (`_checked_options`)."""

    door_rings: int | None
    no_ring_when_open: float | None
    one_ring_when_open: float | None
    no_ring_when_clear: float | None
    landmarks: int
    skip_level_1: bool
    jump_points: bool
    direct_ring_level: int | None
    direct_via: int | None  # None where no level is below the first plan's
    direct_rings: int
    direct_whole: bool  # and `jump_points`


@functools.lru_cache(maxsize=64)
def _checked_options(
    top: int,
    segment_moves: int | None,
    door_rings: int | None,
    direct: int | None,
    direct_width: float | None,
    no_ring_when_open: float | None,
    one_ring_when_open: float | None,
    landmarks: int | None,
    no_ring_when_clear: float | None,
    skip_level_1: bool,
    jump_points: bool,
    direct_ring_level: int | None,
    direct_via: int | None,
    direct_rings: int | None,
    direct_steps: bool,
    direct_whole: bool,
) -> _Options:
    """`atp`'s options checked, and what the planner reads of them; made once per set of
    options and first-plan level (a planner serving queries on a map plans with one set: its
    first plans take tens of microseconds, and the checks were a tenth of that)."""
    if segment_moves is not None and segment_moves < 1:
        raise ValueError(f"segment_moves must be >= 1 or None, got {segment_moves}")
    for name, option in (
        ("door_rings", door_rings),
        ("direct", direct),
        ("direct_width", direct_width),
        ("no_ring_when_open", no_ring_when_open),
        ("one_ring_when_open", one_ring_when_open),
        ("landmarks", landmarks),
        ("no_ring_when_clear", no_ring_when_clear),
        ("direct_rings", direct_rings),
    ):
        if option is not None and option < 0:
            raise ValueError(f"{name} must be >= 0 or None, got {option}")
    if direct_ring_level is not None and direct_ring_level < 1:
        raise ValueError(f"direct_ring_level must be >= 1 or None, got {direct_ring_level}")
    if direct_via is not None and direct_via < 1:
        raise ValueError(f"direct_via must be >= 1 or None, got {direct_via}")
    if direct_steps and direct_width is None:
        raise ValueError("direct_steps needs direct_width: it steps the route after the first plan")
    if direct_whole and direct is None and direct_width is None:
        raise ValueError("direct_whole needs direct or direct_width: it searches the direct route")
    return _Options(
        door_rings=door_rings,
        no_ring_when_open=no_ring_when_open,
        one_ring_when_open=one_ring_when_open,
        no_ring_when_clear=no_ring_when_clear,
        landmarks=landmarks or 0,
        skip_level_1=skip_level_1,
        jump_points=jump_points,
        direct_ring_level=direct_ring_level,
        # no level below a small map's top
        direct_via=direct_via if direct_via is not None and direct_via < top else None,
        direct_rings=1 if direct_rings is None else direct_rings,
        direct_whole=direct_whole and jump_points,
    )


class _Planner:
    """PATH-FINDER and REFINE over one map's connectivity-aware abstraction, with `atp`'s
    options."""

    def __init__(
        self,
        components: Components,
        pyramid: Pyramid,
        start: Position,
        goal: Position,
        ctx: Context,
        options: _Options,
    ) -> None:
        self.components, self.pyramid = components, pyramid
        self.start, self.goal, self.ctx = start, goal, ctx
        self.options = options
        # the last `corridor_cells` counted, by path: `width` and `whole` read the same one
        self._counted: tuple[NodePath, float] | None = None

    def first(
        self, level: int, segment_moves: int | None, ends: tuple[int, int]
    ) -> tuple[NodePath, list[tuple[Segment, float]]]:
        """The first plan: a path of nodes at `level` from the start's node to the goal's
        (`ends`, `Components.joined`), the cheapest from centre to centre, and its segments,
        runs of at most `segment_moves` moves, with their mean obstacleness (`segments`). One
        run above level 0 is searched and read in one compiled call (`Components.read_path`):
        a first plan costs tens of microseconds on maps of 200 x 200, where the compiled A*
        takes 2-3 ms."""
        c = self.components
        start, goal = ends
        if level > 0:
            obstacleness = self.pyramid.levels[level]
            found, xs, ys, mean = c.read_path(
                level,
                start,
                goal,
                obstacleness,
                limit=self.ctx.remaining,
                landmarks=self.options.landmarks,
            )
        else:  # the cells: a search over all of them (by jump points with `jump_points`)
            found = c.path(
                0, start, goal, limit=self.ctx.remaining, jump_points=self.options.jump_points
            )
        self.ctx.tick(found.expansions)
        runs = _runs(len(found.nodes) - 1, segment_moves)
        if level == 0 and len(runs) == 1:  # free cells: nothing to read of the pyramid
            return found, [(self._base_segment(found), 0.0)]
        if level > 0 and len(runs) == 1:  # read with the search
            cells = tuple(zip(xs.tolist(), ys.tolist(), strict=True))
            return found, [(Segment._made(level, cells, found.nodes), mean)]
        return found, self.segments(level, found.nodes, runs, found.array)

    def direct(self, level: int, path: NodePath, ring: int | None = None) -> Segment:
        """The base route through the cells of the nodes of `path` (at `level`) and of their
        neighbours at `direct_ring_level` (by default `level`; a level `ring`, one of
        `direct_rings_by_step`'s steps, instead when given), or `direct_via`'s corridor: one
        segment at level 0, searched by jump points with `jump_points`. With `direct_whole`
        (and no `ring`), the cheapest route over the whole map instead, when its search settles
        few enough jump points (`whole`)."""
        c = self.components
        if ring is None and self.options.direct_whole:
            whole = self.whole(level, path)
            if whole is not None:
                return whole
        if ring is None and self.options.direct_via is not None:
            allowed = self._via(level, path)
        else:
            if ring is None:
                ring = self._ring_level(level)
            allowed = self._down(path.nodes, level, 0, ring)
        found = c.corridor(
            0, allowed, [c.node(self.start, 0)], [c.node(self.goal, 0)],
            limit=self.ctx.remaining, jump_points=self.options.jump_points,
        )  # fmt: skip
        if found is None:
            raise AssertionError("no base route through the children of a path")
        self.ctx.tick(found.expansions)
        return self._base_segment(found)

    def whole(self, level: int, path: NodePath) -> Segment | None:
        """The cheapest route over the whole map, by jump points (`Components.path` at level
        0), when its search settles no more jump points than the cells of `path`'s nodes and
        of their neighbours (at `level`: what the direct route searches) over
        `WHOLE_ROUTE_RATIO`; else None, its work ticked (the corridor is searched)."""
        c = self.components
        if c.movement != 8:
            return None
        most = self.corridor_cells(level, path) / WHOLE_ROUTE_RATIO
        limit = self.ctx.remaining
        try:
            found = c.path(
                0, c.node(self.start, 0), c.node(self.goal, 0), limit=min(limit, most),
                jump_points=True,
            )  # fmt: skip
        except SearchLimit as stopped:
            if limit <= most:  # the deadline: no corridor after it
                raise
            self.ctx.tick(stopped.expansions)
            return None
        self.ctx.tick(found.expansions)
        return self._base_segment(found)

    def _base_segment(self, found: NodePath) -> Segment:
        """A base route's segment (no mean obstacleness: nothing is left to refine)."""
        assert found.array is not None  # a search's path
        blocks = self.components.levels[0].block[found.array]
        cells = tuple(zip(blocks[:, 0].tolist(), blocks[:, 1].tolist(), strict=True))
        return Segment._made(0, cells, found.nodes)

    def _ring_level(self, level: int) -> int:
        """The level of the direct route's ring of neighbours around a first plan at `level`."""
        return (
            level
            if self.options.direct_ring_level is None
            else min(self.options.direct_ring_level, level)
        )

    def direct_rings_by_step(self, level: int) -> list[int | None]:
        """`direct`'s steps after a first plan at `level` (`atp(direct_steps=True)`): the ring
        of neighbours at level 1, 2, .. below the direct route's own (`direct_ring_level`;
        with `direct_via`, below the first plan's level, whose ring its corridor holds), then
        that route (None)."""
        last = level - 1 if self.options.direct_via is not None else self._ring_level(level) - 1
        return [*range(1, last + 1), None]

    def _via(self, level: int, path: NodePath) -> npt.NDArray[np.int64]:
        """The base cells of `direct_via`'s corridor: the nodes of the cheapest path at that
        level and `direct_rings` rings of their neighbours, with the first plan's (`path`, at
        `level`) cells and one ring of their neighbours at `level` - 1."""
        c, via = self.components, self.options.direct_via
        assert via is not None
        second = c.path(
            via, c.node(self.start, via), c.node(self.goal, via),
            limit=self.ctx.remaining, landmarks=self.options.landmarks,
        )  # fmt: skip
        self.ctx.tick(second.expansions)
        allowed = np.union1d(  # at level via - 1
            self._down(path.nodes, level, via - 1, level - 1),
            self._down(second.nodes, via, via - 1, via, self.options.direct_rings),
        )
        return self._down(allowed, via - 1, 0)

    def _down(
        self,
        nodes: Sequence[int] | npt.NDArray[np.int64],
        level: int,
        to: int,
        ring: int = -1,
        rings: int = 1,
    ) -> npt.NDArray[np.int64]:
        """The nodes at level `to` below `nodes` (at `level`): every child, level by level,
        with `rings` rings of neighbours at level `ring` (none at any other)."""
        below = np.asarray(nodes, dtype=np.int64)
        for k in range(level, to, -1):
            below = self.components.widened(k, below, rings if k == ring else 0)
        return below

    def width(self, level: int, path: NodePath) -> float:
        """The base cells of the nodes of `path` (at `level`) and of their neighbours per unit
        of its length (its cost, from centre to centre): what `direct` would search, for each
        cell of the route."""
        return self.corridor_cells(level, path) / max(path.cost, 1.0)

    def corridor_cells(self, level: int, path: NodePath) -> float:
        """The base cells of the nodes of `path` (at `level`) and of their neighbours: the
        direct route's corridor, counted once per path."""
        if self._counted is None or self._counted[0] is not path:
            near = self.components.neighbourhood(level, path.nodes, 1)
            self._counted = (path, float(self.components.levels[level].size[near].sum()))
        return self._counted[1]

    def through_doors(self, level: int, path: NodePath) -> NodePath | None:
        """The cheapest route at `level` through the doors between nodes, when it is cheaper
        there than `path` (None: `path` is as cheap)."""
        found = self.components.route(
            level,
            self.start,
            self.goal,
            bound=path.nodes,
            rings=self.options.door_rings,
            limit=self.ctx.remaining,
        )
        self.ctx.tick(found.expansions)
        return None if found.nodes == path.nodes else found

    def segments(
        self,
        level: int,
        nodes: tuple[int, ...],
        runs: Sequence[tuple[int, int]],
        array: npt.NDArray[np.int64] | None = None,
    ) -> list[tuple[Segment, float]]:
        """The segments through the runs (first, last) of `nodes`, each with its mean
        obstacleness (`_mean_obstacleness`): the cells and their obstacleness looked up once
        for the whole path (a refinement makes two segments per step)."""
        if array is None:  # `nodes` as an array (the search's own, when given)
            array = np.array(nodes, dtype=np.int64)
        # one compiled call, not a few numpy ones: the first plan's, whose caches are cold
        xs, ys, means = compiled().path_reads(
            self.components.levels[level].block,
            self.pyramid.levels[level],
            array,
            np.array([first for first, _ in runs] + [runs[-1][1]], dtype=np.int64),
        )
        cells = tuple(zip(xs.tolist(), ys.tolist(), strict=True))  # at once, not cell by cell
        return [
            (Segment._made(level, cells[first : last + 1], tuple(nodes[first : last + 1])), mean)
            for (first, last), mean in zip(runs, means.tolist(), strict=True)
        ]


def _mean_obstacleness(segment: Segment, pyramid: Pyramid) -> float:
    xs, ys = zip(*segment.cells, strict=True)
    return float(pyramid.levels[segment.level][list(ys), list(xs)].mean())


def compile_searches(movements: Sequence[int] = (4, 8), *, follower: bool = True) -> None:
    """Plan once on a small world, with the planner and with the compiled A*
    (`search.GridAstar`), and follow its plans with `following.Follower` (unless `follower` is
    false), so that numba compiles their searches (`corridor_search`, `following`) into its
    on-disk cache, or loads them from it: otherwise the first plan of a process pays that (tens
    of seconds the first time after an install, about a second from the cache). `make` runs it
    once after installing; `anytime plan` and the benchmarks run it before timing anything."""
    from ..world import random_world
    from .following import Follower  # it imports this module

    for movement in movements:
        world = random_world(64, seed=0, movement=movement)
        pyramid = Pyramid.build(world.blocked)
        follow = Follower(world.blocked, movement) if follower else None
        # the options whose searches the default's plans do not reach: the door search kept
        # near the first plan (`neighbourhood`), the direct route (`widened_children`) and
        # `anytime plan`'s options by map (jump points, landmarks, no door search, the search
        # over every cell)
        for options in (
            {},
            {"door_rings": 1},
            {"direct_width": math.inf},
            LARGE_MAP_OPTIONS,
            SCATTERED_MAP_OPTIONS,
            WALLED_MAP_OPTIONS,
            SPARSE_MAP_OPTIONS,
            SMALL_MAP_OPTIONS,
        ):
            plans = atp(
                Context(), world.start, world.goal, pyramid, movement=movement, follow=follow,
                **options,
            )  # fmt: skip
            for _ in plans:
                pass
        GridAstar(world.blocked, movement=movement, weight=0.0).find_path(world.start, world.goal)
        # a short problem in the open: the direct route searched by jump points from Python
        # (otherwise the first such problem of a process paid 13 ms loading that search)
        open_ground = Pyramid.build(np.zeros((64, 64), dtype=bool))
        for _ in atp(
            Context(), (1, 1), (40, 40), open_ground, movement=movement, **LARGE_MAP_OPTIONS
        ):
            pass
