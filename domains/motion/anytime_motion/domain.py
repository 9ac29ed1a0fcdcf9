"""The motion-planning world: obstacles (balls and axis-aligned boxes) in the D-dimensional unit
box, a start and a goal, a range sensor that sees them through noise, the occupancy map it
builds, and how a path is scored on the true obstacles.

Everything here is numpy and seeded: the same seed gives the same world, the same scans, the
same map.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "CELLS",
    "INFLATION",
    "MAX_RANGE",
    "NOISE",
    "OBSTACLES",
    "RAYS",
    "SEGMENT",
    "OccupancyMap",
    "Path",
    "Query",
    "Sensor",
    "World",
    "collides",
    "path_quality",
    "random_world",
]

FloatArray = npt.NDArray[np.float64]

#: Obstacles in the measured distribution, and the dimension.
OBSTACLES = 10
#: Occupancy cells per side (a map is CELLS**D cells): 2-D and 3-D.
CELLS = {2: 128, 3: 48}
#: How far the sensed (and the reference) obstacles are inflated: a hit point marks the cells
#: within this distance as occupied; the reference path keeps this far from the true obstacles.
INFLATION = 0.03
#: The range sensor: rays per scan (one tick each), the range's noise (standard deviation) and
#: the most it sees.
RAYS = {2: 25, 3: 50}
NOISE = 0.004
MAX_RANGE = 0.6
#: The spacing of the points a path is checked at on the true obstacles.
SEGMENT = 0.002
#: Free space kept around the start and the goal (beyond the inflation and the noise).
CLEARANCE = 0.08
#: Points sampled on the true obstacles' surfaces, per obstacle, to score a map.
SURFACE_SAMPLES = 60


class World:
    """N obstacles in the unit box [0, 1]^D: balls (centre, radius) and axis-aligned boxes
    (centre, half-widths), a start and a goal in free space."""

    def __init__(
        self,
        centres: FloatArray,
        sizes: FloatArray,
        boxes: npt.NDArray[np.bool_],
        start: FloatArray,
        goal: FloatArray,
        surface: FloatArray,
    ) -> None:
        self.centres = centres
        self.sizes = sizes  # half-widths of a box; a ball's radius in every column
        self.boxes = boxes
        self.start = start
        self.goal = goal
        self.surface = surface  # points on the obstacles' outer surfaces (for a map's quality)

    @property
    def dimension(self) -> int:
        return int(self.centres.shape[1])

    @property
    def obstacles(self) -> int:
        return int(len(self.centres))

    def distance(self, points: FloatArray) -> FloatArray:
        """Each point's distance to the nearest obstacle (negative inside one), shape (M,)."""
        points = np.atleast_2d(points)
        if not len(self.centres):
            return np.full(len(points), np.inf)
        offset = points[:, None, :] - self.centres[None, :, :]  # (M, N, D)
        ball = np.linalg.norm(offset, axis=2) - self.sizes[None, :, 0]
        q = np.abs(offset) - self.sizes[None, :, :]
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=2)
        box = outside + np.minimum(q.max(axis=2), 0.0)
        return np.asarray(np.where(self.boxes[None, :], box, ball).min(axis=1))

    def inside(self, points: FloatArray, margin: float = 0.0) -> npt.NDArray[np.bool_]:
        """Whether each point is within `margin` of an obstacle (inside one for 0)."""
        return np.asarray(self.distance(points) <= margin)

    def ray_distances(self, origin: FloatArray, directions: FloatArray) -> FloatArray:
        """How far each ray from `origin` along the unit `directions` (R, D) goes before it
        hits an obstacle (inf: none)."""
        hits = np.full(len(directions), np.inf)
        if not len(self.centres):
            return hits
        o = origin[None, None, :] - self.centres[None, :, :]  # (1, N, D)
        d = directions[:, None, :]  # (R, 1, D)
        # balls: |o + t d|^2 = r^2
        b = (o * d).sum(axis=2)
        c = (o * o).sum(axis=2) - self.sizes[None, :, 0] ** 2
        disc = b * b - c
        root = np.sqrt(np.maximum(disc, 0.0))
        t_ball = np.where(disc >= 0, -b - root, np.inf)
        t_ball = np.where(t_ball >= 0, t_ball, np.where(disc >= 0, -b + root, np.inf))
        t_ball = np.where(t_ball >= 0, t_ball, np.inf)
        # boxes: the slab method
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            t1 = (-self.sizes[None, :, :] - o) * inv
            t2 = (self.sizes[None, :, :] - o) * inv
        near = np.nan_to_num(np.minimum(t1, t2), nan=-np.inf).max(axis=2)
        far = np.nan_to_num(np.maximum(t1, t2), nan=np.inf).min(axis=2)
        t_box = np.where((far >= near) & (far >= 0), np.maximum(near, 0.0), np.inf)
        t = np.where(self.boxes[None, :], t_box, t_ball)
        return np.asarray(t.min(axis=1))

    def free_point(
        self, rng: np.random.Generator, margin: float, low: Any = 0.0, high: Any = 1.0
    ) -> FloatArray:
        """A point uniform in [low, high] at least `margin` from every obstacle."""
        for _ in range(10_000):
            point = rng.uniform(low, high, self.dimension)
            if not self.inside(point, margin)[0]:
                return np.asarray(point, dtype=np.float64)
        raise RuntimeError("no free point found")


def random_world(rng: np.random.Generator, obstacles: int = OBSTACLES, dimension: int = 2) -> World:
    """N obstacles, half of them boxes on average, centred in [0.15, 0.85]^D (radius or
    half-width 0.05-0.12, smaller in 3-D by the cube root of the volume), a start on the box's
    low side (first coordinate in [0.02, 0.12]) and a goal on its high side, each at least
    CLEARANCE from every obstacle."""
    scale = 1.0 if dimension == 2 else 1.3
    while True:
        centres = rng.uniform(0.15, 0.85, (obstacles, dimension))
        boxes = rng.random(obstacles) < 0.5
        radius = rng.uniform(0.05, 0.12, obstacles) * scale
        widths = rng.uniform(0.04, 0.1, (obstacles, dimension)) * scale
        sizes = np.where(boxes[:, None], widths, radius[:, None] * np.ones(dimension))
        origin = np.zeros(dimension)
        world = World(centres, sizes, boxes, origin, origin, np.zeros((0, dimension)))
        others = [0.05] * (dimension - 1), [0.95] * (dimension - 1)
        try:
            start = world.free_point(rng, CLEARANCE, [0.02, *others[0]], [0.12, *others[1]])
            goal = world.free_point(rng, CLEARANCE, [0.88, *others[0]], [0.98, *others[1]])
        except RuntimeError:
            continue
        world.start, world.goal = start, goal
        world.surface = _surface(world, rng)
        return world


def _surface(world: World, rng: np.random.Generator) -> FloatArray:
    """SURFACE_SAMPLES points on each obstacle's surface, those on the outer surface of the
    union (not inside another obstacle) and inside the unit box: what a sensor can see."""
    d = world.dimension
    points = []
    for centre, size, box in zip(world.centres, world.sizes, world.boxes, strict=True):
        u = rng.standard_normal((SURFACE_SAMPLES, d))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        if box:  # a point of the box's surface: push the direction out to the nearest face
            scale = np.abs(u / size).max(axis=1, keepdims=True)
            points.append(centre + u / scale)
        else:
            points.append(centre + u * size[0])
    surface = np.concatenate(points)
    keep = (world.distance(surface) > -1e-9) & np.all((surface > 0) & (surface < 1), axis=1)
    return np.asarray(surface[keep])


class OccupancyMap:
    """Occupied cells of the unit box (CELLS[D] per side): a sensed map (the cells within
    INFLATION of a sensed hit point) or the true obstacles inflated by INFLATION."""

    def __init__(self, dimension: int, occupied: npt.NDArray[np.bool_] | None = None) -> None:
        n = CELLS[dimension]
        self.dimension = dimension
        self.cells = n
        self.occupied = occupied if occupied is not None else np.zeros((n,) * dimension, bool)
        self._flat: bytes | None = None
        self._stencil = _stencil(dimension, n)

    @classmethod
    def of_world(cls, world: World, inflation: float = INFLATION) -> OccupancyMap:
        """The true obstacles inflated by `inflation`: every cell whose centre is that close."""
        n = CELLS[world.dimension]
        axes = [(np.arange(n) + 0.5) / n] * world.dimension
        centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, world.dimension)
        inside = np.concatenate(
            [
                world.inside(chunk, inflation)
                for chunk in np.array_split(centres, max(1, len(centres) // 4096))
            ]
        )
        return cls(world.dimension, inside.reshape((n,) * world.dimension))

    def copy(self) -> OccupancyMap:
        return OccupancyMap(self.dimension, self.occupied.copy())

    def mark(self, points: FloatArray) -> None:
        """Mark the cells within INFLATION of each point as occupied."""
        if not len(points):
            return
        n = self.cells
        base = np.floor(points * n).astype(np.int64)  # (P, D)
        cells = (base[:, None, :] + self._stencil[None, :, :]).reshape(-1, self.dimension)
        centres = (cells + 0.5) / n
        near = np.linalg.norm(centres - np.repeat(points, len(self._stencil), axis=0), axis=1)
        keep = (near <= INFLATION) & np.all((cells >= 0) & (cells < n), axis=1)
        self.occupied[tuple(cells[keep].T)] = True
        self._flat = None

    def index(self, point: Any) -> int:
        n = self.cells
        flat = 0
        for k in range(self.dimension):
            i = int(point[k] * n)
            flat = flat * n + (0 if i < 0 else n - 1 if i >= n else i)
        return flat

    def free(self, point: Any) -> bool:
        """Whether `point` (anything indexable by coordinate) is in a free cell."""
        if self._flat is None:
            self._flat = self.occupied.tobytes()
        return not self._flat[self.index(point)]

    def free_points(self, points: FloatArray) -> npt.NDArray[np.bool_]:
        n = self.cells
        cells = np.clip(np.floor(points * n).astype(np.int64), 0, n - 1)
        return np.asarray(~self.occupied[tuple(cells.T)])

    def coverage(self, surface: FloatArray) -> float:
        """The fraction of the `surface` points in occupied cells: the map's quality."""
        if not len(surface):
            return 1.0
        return float(1.0 - self.free_points(surface).mean())


def _stencil(dimension: int, cells: int) -> npt.NDArray[np.int64]:
    reach = int(math.ceil(INFLATION * cells)) + 1
    axes = [np.arange(-reach, reach + 1)] * dimension
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dimension)


class Sensor:
    """A range sensor over a world, seeded: scans from viewpoints uniform in free space, RAYS[D]
    rays each (evenly spaced angles from a random offset in 2-D, random directions in 3-D),
    each range seen with Gaussian noise NOISE up to MAX_RANGE."""

    def __init__(self, world: World, seed: int = 0) -> None:
        self.world = world
        self.seed = seed

    @property
    def rays(self) -> int:
        return RAYS[self.world.dimension]

    def scans(self) -> Iterator[FloatArray]:
        """The sensed hit points of each scan in turn, (hits, D)."""
        world = self.world
        rng = np.random.default_rng(self.seed)
        d, rays = world.dimension, self.rays
        while True:
            origin = world.free_point(rng, 0.01)
            if d == 2:
                angle = rng.uniform(0, 2 * math.pi / rays) + np.arange(rays) * 2 * math.pi / rays
                directions = np.stack([np.cos(angle), np.sin(angle)], axis=1)
            else:
                directions = rng.standard_normal((rays, d))
                directions /= np.linalg.norm(directions, axis=1, keepdims=True)
            seen = world.ray_distances(origin, directions) + NOISE * rng.standard_normal(rays)
            hit = seen <= MAX_RANGE
            yield np.asarray(origin + seen[hit, None] * directions[hit])


class Query:
    """What a planner is asked: from `start` to `goal`, with the seed of OMPL's random numbers
    (drawn from the framework's seed stream, so a profile is the same on any number of
    workers)."""

    def __init__(self, start: FloatArray, goal: FloatArray, seed: int = 0) -> None:
        self.start = np.asarray(start, dtype=np.float64)
        self.goal = np.asarray(goal, dtype=np.float64)
        self.seed = seed

    @property
    def dimension(self) -> int:
        return int(len(self.start))

    @property
    def straight(self) -> float:
        """The straight-line distance: a lower bound on any path's cost."""
        return float(np.linalg.norm(self.goal - self.start))


class Path:
    """A path through the unit box (its waypoints, (K, D)) and the map it was planned on."""

    def __init__(self, points: FloatArray, map: OccupancyMap | None = None) -> None:
        self.points = np.asarray(points, dtype=np.float64)
        self.map = map

    @property
    def cost(self) -> float:
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())

    def __repr__(self) -> str:
        return f"Path({len(self.points)} waypoints, cost {self.cost:.4f})"


def dense(points: FloatArray, spacing: float = SEGMENT) -> FloatArray:
    """The path's points every `spacing` (at most) along each segment, both ends included."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        k = max(1, int(math.ceil(float(np.linalg.norm(b - a)) / spacing)))
        t = np.arange(1, k + 1)[:, None] / k
        out.append(a + t * (b - a))
    return np.concatenate(out)


def collides(path: Path, world: World) -> bool:
    """Whether the path touches a true obstacle (checked every SEGMENT) or leaves the box."""
    points = dense(path.points)
    if np.any(points < 0) or np.any(points > 1):
        return True
    return bool(world.inside(points).any())


def path_quality(path: Any, world: World, reference: float) -> float:
    """The reference cost over the path's, at most 1; 0 for no path or one that collides with
    the true obstacles."""
    if not isinstance(path, Path) or len(path.points) < 2 or collides(path, world):
        return 0.0
    cost = path.cost
    return 1.0 if cost <= reference else reference / cost
