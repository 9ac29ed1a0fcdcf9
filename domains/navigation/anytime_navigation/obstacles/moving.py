"""Moving obstacles and the situation "obstacle overcoming" (issue 8, part 3; Romanenko,
"Decision-making in real time on the basis of actions planning").

Time is in ticks of the work clock, the world's time: thinking moves it as moving does. The
robot follows a `Plan` (cells, speed in cells per tick as in `task.model`); it is in cell
`cells[floor((t - start) * speed)]` at tick t (a jump model: one cell at a time).

Obstacles. A `MovingObstacle` is an axis-parallel square of side `size` centred at `position`
(cell (x, y) spans [x - 1/2, x + 1/2] x [y - 1/2, y + 1/2]); it occupies every cell it overlaps,
and with a safety radius r every cell within r more. It moves `velocity` cells per tick, one
tick at a time, axis by axis: a move along an axis that would overlap a blocked cell or leave
the map is not made and that velocity component is reversed (a bounce). Obstacles pass through
each other. Motion is deterministic, so the robot predicts it exactly (`Traffic`); it does not
model noisy sensing of the obstacles.

The situation "obstacle overcoming" they give rise to is in `overcoming`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from ..world import BoolGrid, Position, World

__all__ = ["MovingObstacle", "Plan", "Traffic", "random_obstacles"]

SAFETY_RADIUS = 1  # cells kept free around an obstacle when predicting conflicts
LOOKAHEAD = 300  # ticks the robot looks ahead for conflicts


PAIRS_PER_TICK = 1024  # (tick, obstacle) pairs of predicted motion checked per tick of work


EPS = 1e-9  # tolerance of the cell and tick arithmetic (floating-point motion)


def _pair(value: Any) -> tuple[float, float]:
    return (float(value[0]), float(value[1]))


def _cells(value: Any) -> tuple[Position, ...]:
    return tuple((int(x), int(y)) for x, y in value)


@frozen
class MovingObstacle:
    """A square obstacle: centre `position` (x, y), `velocity` in cells per tick, side `size`."""

    position: tuple[float, float] = field(converter=_pair)
    velocity: tuple[float, float] = field(converter=_pair)
    size: float = 1.0

    def span(self, radius: float = 0.0) -> tuple[int, int, int, int]:
        """The cells it occupies, grown by `radius`: inclusive (x0, y0, x1, y1), unclipped."""
        half = (self.size + 1.0) / 2.0 + radius
        x, y = self.position
        return (
            math.floor(x - half + EPS) + 1,
            math.floor(y - half + EPS) + 1,
            math.ceil(x + half - EPS) - 1,
            math.ceil(y + half - EPS) - 1,
        )

    def fits(self, blocked: BoolGrid) -> bool:
        """Whether it lies inside the map on free cells only."""
        x0, y0, x1, y1 = self.span()
        n_rows, n_cols = blocked.shape
        if x0 < 0 or y0 < 0 or x1 >= n_cols or y1 >= n_rows:
            return False
        return not bool(blocked[y0 : y1 + 1, x0 : x1 + 1].any())

    def step(self, blocked: BoolGrid) -> MovingObstacle:
        """Its state one tick later: x then y, bouncing off walls and the map's edge."""
        (x, y), (vx, vy) = self.position, self.velocity
        moved = MovingObstacle((x + vx, y), (vx, vy), self.size)
        if moved.fits(blocked):
            x = x + vx
        else:
            vx = -vx
        moved = MovingObstacle((x, y + vy), (vx, vy), self.size)
        if moved.fits(blocked):
            y = y + vy
        else:
            vy = -vy
        return MovingObstacle((x, y), (vx, vy), self.size)


@frozen
class Plan:
    """The robot's timed route: in `cells[floor((t - start) * speed)]` at time t, then on the
    last cell. `speed` is in cells per tick."""

    start: float
    cells: tuple[Position, ...] = field(converter=_cells)
    speed: float

    def index_at(self, t: float) -> int:
        steps = math.floor((t - self.start) * self.speed + EPS)
        return min(max(steps, 0), len(self.cells) - 1)

    def cell_at(self, t: float) -> Position:
        return self.cells[self.index_at(t)]

    @property
    def end(self) -> float:
        """When the robot reaches the last cell."""
        return self.start + (len(self.cells) - 1) / self.speed

    def next_step(self, t: float) -> float:
        """The first time after t at which the robot enters a new cell (or `end`)."""
        k = math.floor((t - self.start) * self.speed + EPS) + 1
        return min(max(self.start + k / self.speed, t), self.end)

    def cells_over(self, ticks: NDArray[np.int64]) -> NDArray[np.int64]:
        """The robot's cells at the given ticks, shape (len(ticks), 2)."""
        steps = np.floor((ticks - self.start) * self.speed + EPS).astype(np.int64)
        index = np.clip(steps, 0, len(self.cells) - 1)
        cells: NDArray[np.int64] = np.asarray(self.cells, dtype=np.int64)[index]
        return cells


class Traffic:
    """The obstacles of one world and their predicted motion, tick by tick (cached)."""

    def __init__(self, world: World, obstacles: Sequence[MovingObstacle]) -> None:
        self.world = world
        self.obstacles = tuple(obstacles)
        for obstacle in self.obstacles:
            if not obstacle.fits(world.blocked):
                raise ValueError(f"{obstacle} does not lie on free cells inside the map")
        self._states: list[tuple[MovingObstacle, ...]] = [self.obstacles]
        self._centres = np.zeros((0, len(self.obstacles), 2))
        self.halves = np.array([(o.size + 1.0) / 2.0 for o in self.obstacles])

    def at(self, t: int) -> tuple[MovingObstacle, ...]:
        """The obstacles at tick t (>= 0)."""
        while len(self._states) <= t:
            self._states.append(tuple(o.step(self.world.blocked) for o in self._states[-1]))
        return self._states[t]

    def centres(self, ticks: NDArray[np.int64]) -> NDArray[np.float64]:
        """The obstacles' centres at the given ticks (>= 0), shape (len(ticks), n, 2)."""
        last = int(ticks.max(initial=0))
        if len(self._centres) <= last:
            self.at(last)
            self._centres = np.array(
                [[o.position for o in state] for state in self._states], dtype=np.float64
            ).reshape(len(self._states), len(self.obstacles), 2)
        return self._centres[ticks]

    def cells_at(self, t: int, radius: float = 0.0) -> set[Position]:
        """The cells some obstacle occupies at tick t (grown by `radius`), inside the map."""
        n = self.world.size
        cells: set[Position] = set()
        for obstacle in self.at(t):
            x0, y0, x1, y1 = obstacle.span(radius)
            cells.update(
                (x, y)
                for x in range(max(x0, 0), min(x1, n - 1) + 1)
                for y in range(max(y0, 0), min(y1, n - 1) + 1)
            )
        return cells

    def hits(self, plan: Plan, ticks: NDArray[np.int64], radius: float) -> NDArray[np.bool_]:
        """For each tick, whether the robot's cell is occupied (within `radius`) then."""
        if not self.obstacles or ticks.size == 0:
            return np.zeros(ticks.shape, dtype=bool)
        robot = plan.cells_over(ticks)[:, None, :]
        reach = self.halves[None, :, None] + radius
        near = np.asarray(np.abs(robot - self.centres(ticks)) < reach - EPS)
        return np.asarray(np.asarray(near.all(axis=2)).any(axis=1))

    def first_conflict(
        self, plan: Plan, since: float, radius: float, horizon: float
    ) -> float | None:
        """The time from `since` until the robot, on `plan`, first comes within `radius` of an
        obstacle, looking at the ticks in [since, min(since + horizon, plan.end)]; or None."""
        first, last = math.ceil(since - EPS), math.floor(min(since + horizon, plan.end) + EPS)
        ticks = np.arange(max(first, 0), last + 1, dtype=np.int64)
        hit = np.flatnonzero(self.hits(plan, ticks, radius))
        return None if hit.size == 0 else float(ticks[hit[0]] - since)

    def arrival(
        self,
        route: Sequence[Position],
        speed: float,
        now: float,
        *,
        radius: float = SAFETY_RADIUS,
        horizon: float = math.inf,
    ) -> float | None:
        """The time until an obstacle first occupies (within `radius`) the cell of `route` the
        robot is in, the robot leaving `route[0]` at `now` at `speed`; None if it never does
        before the route ends (or within `horizon`)."""
        return self.first_conflict(Plan(now, route, speed), now, radius, horizon)

    def check_cost(self, ticks: float) -> int:
        """The work, in ticks, of checking `ticks` ticks of predicted motion."""
        return math.ceil(max(ticks, 0.0) * max(len(self.obstacles), 1) / PAIRS_PER_TICK)


def random_obstacles(
    world: World,
    k: int,
    seed: int,
    *,
    speeds: tuple[float, float] = (0.02, 0.05),
    size: float = 1.0,
    clearance: int = 8,
) -> tuple[MovingObstacle, ...]:
    """`k` obstacles on free cells, none within `clearance` cells (Chebyshev) of the start or
    the goal, heading in uniform random directions at speeds uniform in `speeds` (cells per
    tick). Reproducible: the same arguments give the same obstacles."""
    rng = np.random.default_rng(seed)
    n = world.size
    far = np.ones((n, n), dtype=bool)
    for x, y in (world.start, world.goal):
        far[
            max(y - clearance, 0) : y + clearance + 1, max(x - clearance, 0) : x + clearance + 1
        ] = False
    ys, xs = np.nonzero(far & ~world.blocked)
    order = rng.permutation(len(xs))
    found: list[MovingObstacle] = []
    for i in order:
        if len(found) == k:
            break
        angle, speed = rng.uniform(0.0, 2.0 * math.pi), rng.uniform(*speeds)
        candidate = MovingObstacle(
            (float(xs[i]), float(ys[i])), (speed * math.cos(angle), speed * math.sin(angle)), size
        )
        if candidate.fits(world.blocked):
            found.append(candidate)
    if len(found) < k:
        raise ValueError(f"room for only {len(found)} obstacles of size {size}, asked for {k}")
    return tuple(found)
