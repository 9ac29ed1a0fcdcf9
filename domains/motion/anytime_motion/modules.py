"""The motion modules and their problem sets (how `anytime profile` measures them).

Ticks of the work clock: one ray cast (`sense-obstacles`), one state validity check (the OMPL
planners `rrt-star` and `bit-star`, and `shorten-path`). Ray casts and validity checks are both
one geometric query, and both are deterministic, so the profiles are the same on any machine.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from anytime.plugin import Context, Instance, Measurement, Result, interruptible
from anytime.plugin.solvers import resume

from .domain import OBSTACLES, OccupancyMap, Path, Query, Sensor, World, path_quality, random_world
from .planners import OmplPlanner, Shortcutter

__all__ = [
    "MODULES",
    "PLANNER_TIME",
    "PROBLEM_SETS",
    "SENSE_TIME",
    "SHORTEN_TIME",
    "MapInputs",
    "MotionReference",
    "PathInputs",
    "Scenes",
    "bit_star",
    "map_of_quality",
    "rrt_star",
    "sense_obstacles",
    "shorten_path",
]

#: The modules' time grids (ticks: rays, validity checks).
SENSE_TIME = list(range(0, 2001, 250))
PLANNER_TIME = list(range(0, 6001, 500))
SHORTEN_TIME = list(range(0, 2001, 250))
#: Input-quality grids: a map's coverage, a path's quality.
MAP_GRID = [0.0, 0.4, 0.6, 0.8, 0.9, 0.95, 0.975, 1.0]
#: Paths are bimodal: those that collide (0) and those of 0.8-1; paths below 0.825 are rare
#: (one in tens of planner runs) and take the 0.85 cell's profile.
PATH_GRID = [0.0, 0.85, 0.9, 0.95, 1.0]
#: The slices OMPL's `solve` is called with (validity checks).
SLICE = 100
#: A long run of the best planner, for the reference path: checks of BIT*, then of shortcutting.
REFERENCE_CHECKS = 10_000
REFERENCE_SHORTCUT = 3_000
#: Inputs of a given quality are accepted within this much of it.
TOLERANCE = 0.01
PATH_TOLERANCE = 0.025
#: The most a slice of OMPL's `solve` goes past its limit, with a margin: the planners' steps
#: (measured: 265 checks for RRT* and 220 for BIT* over 20 problems of 6000 checks in slices of
#: 100; `anytime check`, 5 trials a cell: 282 and 144).
RRT_STEP = 400
BIT_STEP = 300
MAX_DRAWS = 2_000


# --- sense-obstacles --------------------------------------------------------------------------


@interruptible(
    "sense-obstacles",
    inputs=[],
    profile="profiles/sense-obstacles.yaml",
    reports="estimate",
    step=0,
)
def sense_obstacles(ctx: Context, sensor: Sensor) -> Iterator[Result]:
    """Integrate range scans into an occupancy map, a tick a ray: the empty map at once (what
    a planner given all the time plans on), then the map after every scan. Its self-estimate
    of the map's coverage: the fraction of the last scan's hits that fell on cells already
    occupied (a capture-recapture estimate)."""
    map = OccupancyMap(sensor.world.dimension)
    yield Result(map.copy(), 0.0)
    rays = sensor.rays
    for hits in sensor.scans():
        if ctx.expired or ctx.remaining < rays:
            return
        ctx.tick(rays)
        seen = 1.0 - float(map.free_points(hits).mean()) if len(hits) else 0.0
        map.mark(hits)
        yield Result(map.copy(), seen)


# --- the planners -----------------------------------------------------------------------------


@interruptible(
    "rrt-star",
    inputs=["map"],
    profile="profiles/rrt-star.yaml",
    reports="estimate",
    step=RRT_STEP,
)
def rrt_star(ctx: Context, map: Result, query: Query) -> Iterator[Result]:
    """OMPL's RRT* on the sensed map, minimising path length, a tick a validity check, called
    in slices of SLICE checks; a path whenever its cost improves, with the self-estimate the
    straight-line distance over its cost."""
    yield from resume(ctx, OmplPlanner("rrt-star", map.value, query), step=SLICE)


@interruptible(
    "bit-star",
    inputs=["map"],
    profile="profiles/bit-star.yaml",
    reports="estimate",
    step=BIT_STEP,
)
def bit_star(ctx: Context, map: Result, query: Query) -> Iterator[Result]:
    """OMPL's BIT* (batch informed trees), as `rrt-star`."""
    yield from resume(ctx, OmplPlanner("bit-star", map.value, query), step=SLICE)


# --- shorten-path -----------------------------------------------------------------------------


@interruptible(
    "shorten-path",
    inputs=["path"],
    profile="profiles/shorten-path.yaml",
    reports="estimate",
    step=0,
)
def shorten_path(ctx: Context, path: Result, query: Query) -> Iterator[Result]:
    """Random shortcutting on the map the path was planned on (`planners.Shortcutter`), a tick
    a validity check: the path as given at once, then a path after every shortcut that
    shortens it. Self-estimate: the straight-line distance over the cost. It checks no more
    states than the whole ticks it has left, so it never passes its allocation (step 0)."""
    given: Path = path.value
    yield Result(given, path.quality)
    cutter = Shortcutter(given, query.straight, query.seed)
    last = None
    while not ctx.expired and ctx.remaining >= 1:
        left = ctx.remaining
        spent = cutter.advance(SLICE if left >= SLICE else math.floor(left))
        ctx.tick(spent)
        found = cutter.best()
        if found is not None and found is not last:
            last = found
            yield found
        if spent == 0:
            return


# --- problem sets -----------------------------------------------------------------------------


class MotionReference:
    """A world's query and its reference: the cost of a long run of BIT* (REFERENCE_CHECKS
    validity checks) on the true obstacles inflated as a sensed map inflates them, shortcut
    for REFERENCE_SHORTCUT more and checked collision-free on the true obstacles."""

    def __init__(self, world: World, query: Query) -> None:
        self.world = world
        self.query = query
        self.path = reference_path(world, query)

    @property
    def cost(self) -> float:
        return self.path.cost if self.path is not None else float("inf")


def reference_path(world: World, query: Query) -> Path | None:
    """The reference path (see `MotionReference`); None when none is found."""
    truth = OccupancyMap.of_world(world)
    planner = OmplPlanner("bit-star", truth, query)
    while planner.checks < REFERENCE_CHECKS and planner.advance(1000) > 0:
        pass
    found = planner.best()
    if found is None:
        return None
    shortcut = Shortcutter(found.value, query.straight, query.seed)
    while shortcut.checks < REFERENCE_SHORTCUT and shortcut.advance(500) > 0:
        pass
    best = shortcut.best()
    path: Path = (best if best is not None else found).value
    if path_quality(path, world, path.cost) <= 0:  # collides with the truth: not a reference
        return None
    return path


def motion_problem(
    rng: np.random.Generator, obstacles: int | None = None, dimension: int = 2
) -> tuple[World, Query, MotionReference]:
    """A world with a reference path (worlds without one are drawn again), its query seeded
    from `rng`."""
    while True:
        count = OBSTACLES if obstacles is None else obstacles
        world = random_world(rng, count, dimension)
        query = Query(world.start, world.goal, int(rng.integers(2**31)))
        reference = MotionReference(world, query)
        if reference.path is not None:
            return world, query, reference


class Scenes:
    """Problems for `sense-obstacles`: a world and its sensor; a map is scored by its
    coverage, the fraction of the obstacles' visible surface in its occupied cells."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        world = random_world(rng)
        return Instance(args=(Sensor(world, int(rng.integers(2**31))),), reference=world)

    def score(self, instance: Instance, value: Any) -> float:
        if not isinstance(value, OccupancyMap):
            return 0.0
        return value.coverage(instance.reference.surface)


def map_of_quality(rng: np.random.Generator, world: World, q: float) -> OccupancyMap | None:
    """A sensed map of `world` of coverage within TOLERANCE of `q`, made by the sensor itself
    (scans integrated until the coverage reaches it); None when a scan jumps past it."""
    map = OccupancyMap(world.dimension)
    if q <= TOLERANCE:
        return map
    sensor = Sensor(world, int(rng.integers(2**31)))
    for hits, _ in zip(sensor.scans(), range(400), strict=False):
        map.mark(hits)
        coverage = map.coverage(world.surface)
        if coverage >= q - TOLERANCE:
            return map if coverage <= q + TOLERANCE else None
    return None


class MapInputs:
    """Problems for the planners: a world with its reference path and a sensed map of the
    coverage asked for (`map_of_quality`); a path is scored by `path_quality` on the true
    obstacles (0 when it collides)."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (q,) = input_qualities
        for _ in range(MAX_DRAWS):
            world = random_world(rng)
            map = map_of_quality(rng, world, q)
            if map is None:
                continue
            query = Query(world.start, world.goal, int(rng.integers(2**31)))
            reference = MotionReference(world, query)
            if reference.path is not None:
                return Instance(args=(Result(map, q), query), reference=reference)
        raise RuntimeError(f"no map of coverage {q} in {MAX_DRAWS} draws")

    def score(self, instance: Instance, value: Any) -> float:
        reference: MotionReference = instance.reference
        return path_quality(value, reference.world, reference.cost)


class PathInputs:
    """Problems for `shorten-path`: a world with its reference and a path of the true quality
    asked for (within PATH_TOLERANCE), made by the upstream modules themselves: on each world, up
    to 4 times, a map of a coverage drawn from the planners' grid, then `rrt-star` or
    `bit-star` (drawn) for the planners' longest time; one of the paths it registered on the
    way, of a quality close enough, is kept (drawn among them: rejection)."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (q,) = input_qualities
        for _ in range(MAX_DRAWS):
            world, query, reference = motion_problem(rng)
            for _ in range(4):
                coverage = float(rng.choice(MAP_GRID[1:] if q > 0 else MAP_GRID[:3]))
                map = map_of_quality(rng, world, coverage)
                if map is None:
                    continue
                planner = OmplPlanner(str(rng.choice(["rrt-star", "bit-star"])), map, query)
                close = []
                last = None
                while planner.checks < PLANNER_TIME[-1] and planner.advance(SLICE) > 0:
                    found = planner.best()
                    if found is not None and found is not last:
                        last = found
                        quality = path_quality(found.value, world, reference.cost)
                        if abs(quality - q) <= PATH_TOLERANCE:
                            close.append(found.value)
                if close:
                    path = close[int(rng.integers(len(close)))]
                    return Instance(args=(Result(path, q), query), reference=reference)
        raise RuntimeError(f"no path of quality {q} in {MAX_DRAWS} draws")

    def score(self, instance: Instance, value: Any) -> float:
        reference: MotionReference = instance.reference
        return path_quality(value, reference.world, reference.cost)


MODULES = (sense_obstacles, rrt_star, bit_star, shorten_path)

PROBLEM_SETS = {
    "sense-obstacles": Measurement.of(Scenes(), time=SENSE_TIME),
    "rrt-star": Measurement.of(MapInputs(), time=PLANNER_TIME, input_grids=[MAP_GRID]),
    "bit-star": Measurement.of(MapInputs(), time=PLANNER_TIME, input_grids=[MAP_GRID]),
    "shorten-path": Measurement.of(PathInputs(), time=SHORTEN_TIME, input_grids=[PATH_GRID]),
}
