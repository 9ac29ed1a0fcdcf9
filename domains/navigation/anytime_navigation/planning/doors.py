"""Doors: the top level searched again where a route crosses from node to node (issue 17).

Why. A plan of neighbouring nodes costed from centre to centre misjudges a route where the
nodes are pieces of rooms: a block cut by a room's wall has a piece on each side, its centre is
off the way through, and the search then picks the wrong doors. Measured on the 16 longest
problems of MovingAI's 8room_000: final plans 0.966 of the optimal length when the first plan
is made from centres, 0.995 when it is then searched again through the doors (`atp`'s
`doors`), refinement unchanged (benchmarks/bench_navigation.py has the other kinds).

What. The *door* from a node to a neighbour is the mean of the midpoints of the legal base
moves that join them: where a route crosses. A route through nodes n0, n1, .., nm costs its
length from the start through the doors n0|n1, n1|n2, .. to the goal (straight lines, Manhattan
or octile as the robot moves), plus `CROSSING` per door: between routes of about equal length
the one through fewer nodes wins, the one a robot follows straightest (at a tie, a staircase of
side doors is as long as a diagonal through corners: measured on random512-10-0, first plans
0.858 with no charge, 0.930 with one cell).

How. The states are the directed doors u -> v (one per entry of the level's compressed rows); a
state u -> v is followed by v -> w for every neighbour w of v but u. A* over them, compiled
(`corridor_search.door_search`), with a consistent heuristic: the straight distance from a
door to the goal plus a crossing per block still to cross. A known route's cost through its
doors (the first plan's) bounds it: what is dearer is not searched. Its work is counted as
corridor searches count theirs: the states an A* expands, those whose cost plus heuristic is
below the route's cost. (Landmarks, ALT, halved the states expanded on street and game maps but
not the time, once the search is bounded: not used.)

Arrays are indexed [y, x]; positions are (x, y).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from attrs import frozen
from numpy.typing import NDArray

from ..world import Position, move_distance
from .search import SearchLimit, compiled

__all__ = ["CROSSING", "Doors"]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

#: What crossing a door costs on top of the route's length, in cells (see the module docstring).
CROSSING = 1.0

#: The forward base moves (dx, dy): each legal move once.
_FORWARD_MOVES = {4: ((1, 0), (0, 1)), 8: ((1, 0), (0, 1), (1, 1), (-1, 1))}


@frozen(eq=False)
class Doors:
    """The directed doors of one level: state j is the level's compressed-rows entry j, from
    node `tail[j]` to node `head[j]` through `point[j]`; `reverse[j]` is the state back. The
    states that may follow j are `after[after_first[j]:after_first[j + 1]]`, each `length[...]`
    away (door to door). `first` holds the level's rows: the states leaving node i are
    `first[i]:first[i + 1]`."""

    level: int
    # Each base cell's node at the level is `up[grid[y, x]]` (none where `grid` is -1, blocked):
    # `grid` the level's own grid and `up` the identity, or level 0's grid and each cell's
    # ancestor at the level (`Components.build`: the top level's grid is then not made).
    grid: IntArray
    up: IntArray
    head_block: IntArray  # each state's head's block at the level: x in row 0, y in row 1
    movement: int
    first: IntArray
    tail: IntArray
    head: IntArray
    reverse: IntArray
    point: FloatArray
    after_first: IntArray
    after: IntArray
    after_tail: IntArray  # the state each entry of `after` follows
    length: FloatArray
    keys: IntArray  # tail * nodes + head of each state, ascending
    order: IntArray  # the state of each of `keys`

    @classmethod
    def build(
        cls,
        level: int,
        grid: IntArray,
        block: IntArray,
        first: IntArray,
        neighbour: IntArray,
        movement: int,
        up: IntArray | None = None,
    ) -> Doors:
        """The doors of a level from its node of each base cell (`grid`; with `up`, the node of
        a cell is `up[grid[y, x]]`), its nodes' blocks and its compressed rows (`first`,
        `neighbour`: node i's neighbours are `neighbour[first[i]:first[i + 1]]`)."""
        count, states = len(first) - 1, len(neighbour)
        if up is None:
            up = np.arange(count, dtype=np.int64)
        tail = np.repeat(np.arange(count, dtype=np.int64), np.diff(first))
        head = np.asarray(neighbour, dtype=np.int64)
        keys = tail * count + head
        order = np.argsort(keys, kind="stable")
        reverse = order[np.searchsorted(keys[order], head * count + tail)]
        point = compiled().door_points(grid, up, level, movement, keys[order], order, count, states)
        downward = tail > head
        point[downward] = point[reverse[downward]]  # the same door both ways
        # Each state followed by the states leaving its head but the one back.
        counts = np.diff(first)[head]
        from_tail = np.repeat(np.arange(states, dtype=np.int64), counts)
        after = np.repeat(first[head] - np.cumsum(counts) + counts, counts) + np.arange(
            counts.sum()
        )
        keep = after != reverse[from_tail]
        after, from_tail = after[keep], from_tail[keep]
        after_first = np.zeros(states + 1, dtype=np.int64)
        np.cumsum(np.bincount(from_tail, minlength=states), out=after_first[1:])
        step = point[after] - point[from_tail]
        length = move_distance(np.abs(step[:, 0]), np.abs(step[:, 1]), movement)
        head_block = np.ascontiguousarray(block[head].T)
        return cls(
            level, grid, up, head_block, movement, first, tail, head, reverse, point,
            after_first, after, from_tail, length, keys[order], order,
        )  # fmt: skip

    def route(
        self,
        start: Position,
        goal: Position,
        *,
        bound: Sequence[int] | None = None,
        within: NDArray[np.bool_] | None = None,
        limit: float = math.inf,
    ) -> tuple[tuple[int, ...], float, int]:
        """The cheapest route of nodes from the start's node to the goal's (they must be
        connected): (the nodes, its cost, the states an A* search for it expands). `bound`, a
        route of nodes between them, cuts the search at its cost (`cost_of`): what is dearer
        is not searched. `within`, one entry per node of the level, confines the route to the
        nodes it marks (they must hold a route: `bound`'s, say).

        Raises:
            SearchLimit: that work is more than `limit`.
        """
        (sx, sy), (gx, gy) = start, goal
        # one compiled call (`corridor_search.door_route`): the glue around the search was most
        # of its time when caches are cold, as the first search after a plan begins finds them
        source, nodes, cost, expansions = compiled().door_route(
            self.grid, self.up, self.first, self.keys, self.order, self.point, self.after_first,
            self.after, self.length, self.head_block, self.head, self.level, self.movement,
            CROSSING, sx, sy, gx, gy,
            np.zeros(0, dtype=np.int64) if bound is None else np.asarray(bound, dtype=np.int64),
            np.zeros(0, dtype=np.bool_) if within is None else within,
        )  # fmt: skip
        if len(nodes) == 1:  # the goal in the start's node
            return (source,), float(self._distance_to(np.array([[sx + 0.5, sy + 0.5]]), goal)[0]), 0
        if not len(nodes):
            target = int(self.up[self.grid[gy, gx]])
            raise AssertionError(f"no route from node {source} to node {target}")
        if expansions > limit:
            raise SearchLimit(int(limit))
        return tuple(nodes.tolist()), cost, expansions

    def cost_of(self, nodes: Sequence[int], start: Position, goal: Position) -> float:
        """What a route of neighbouring nodes from the start's to the goal's costs through
        their doors (as `route` costs it)."""
        tails, heads = np.asarray(nodes[:-1], np.int64), np.asarray(nodes[1:], np.int64)
        count = len(self.first) - 1
        states = self.order[np.searchsorted(self.keys, tails * count + heads)]
        (sx, sy), (gx, gy) = start, goal
        points = np.concatenate(
            [[(sx + 0.5, sy + 0.5)], self.point[states], [(gx + 0.5, gy + 0.5)]]
        )
        step = np.abs(np.diff(points, axis=0))
        length = move_distance(step[:, 0], step[:, 1], self.movement).sum()
        return float(length + CROSSING * len(states))

    def _distance_to(self, points: FloatArray, goal: Position) -> FloatArray:
        gx, gy = goal
        return move_distance(
            np.abs(points[:, 0] - (gx + 0.5)), np.abs(points[:, 1] - (gy + 0.5)), self.movement
        )
