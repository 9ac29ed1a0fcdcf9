"""The navigation domain's anytime modules, by the names `schemas/navigation.any` calls them:

- `get-domain-description` (contract): anytime vision, `(get-domain-description sensor)` -> a
  `DomainDescription`, the map the planner sees, with quality the fraction of cells identified
  correctly (`vision`);
- `find-path` (interruptible): the anytime abstract planner, `(find-path start goal domain)` ->
  a `MultiPath`, with the ATP's own quality estimate (`planner`).

Each comes with a problem set for the profile builder (`anytime profile get-domain-description`,
`anytime profile find-path`), whose score is the papers' true quality: the fraction of cells a
map gets right, and optimal length / executed length for a plan followed on the true map
(`execution`). The measured profiles ship in `profiles/` next to this file.

The modules of the situation "obstacle overcoming" (`left-clear?`, `right-clear?`,
`can-wait?`, `detour-left`, `detour-right`, `wait`) are defined in `overcoming_modules` and
imported here so that the plugin exposes them.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from attrs import frozen

from anytime.plugin import (
    Context,
    Instance,
    Measurement,
    Result,
    contract,
    elementary,
    interruptible,
)

# the situation "obstacle overcoming": part of the plugin
from .obstacles.overcoming_modules import (
    can_wait,
    detour_left,
    detour_right,
    left_clear,
    right_clear,
    wait,
)
from .planning.abstraction import Pyramid, project
from .planning.planner import MultiPath, Segment, atp, quality_estimate
from .planning.search import SearchLimit, find_path_to_box
from .task.execution import Execution, execute, optimal_length, plan_quality
from .task.vision import (
    Q_A,
    DomainDescription,
    Sensor,
    error_draws,
    fraction_correct,
    prior_map,
    sense,
    sensed_map,
)
from .world import Position, random_world

__all__ = [
    "PROBLEM_SETS",
    "PlannerProblems",
    "VisionProblems",
    "can_wait",
    "detour_left",
    "detour_right",
    "find_path",
    "get_domain_description",
    "left_clear",
    "right_clear",
    "wait",
]

#: The world the profiles are measured on (the papers' setting: 4-connected, random rectangles).
PROFILE_SIZE = 128


# The steps are declared: each module watches its time (vision buys what its allocation pays
# for, the planners search with `limit=ctx.remaining`), so none runs past its deadline, as
# `anytime check` verifies; the builder's measure (the longest gap between results) would keep
# back over a thousand ticks of the planner's share.
@contract(
    "get-domain-description",
    inputs=[],
    profile="profiles/get-domain-description.yaml",
    step=0,
)
def get_domain_description(ctx: Context, sensor: Sensor) -> Result:
    """Anytime vision under a contract: the map bought with `ctx.allocation` ticks inside the
    sensor's window, what the robot already knew outside it. Quality: the fraction of cells of
    the whole map identified correctly."""
    seen = sense(
        ctx, sensor.truth, t_a=sensor.t_a, q_a=sensor.q_a, t_b=sensor.t_b, seed=sensor.seed
    )
    blocked = np.array(seen.value, dtype=bool)
    if sensor.window is not None:
        x0, y0, x1, y1 = sensor.window
        outside = (
            np.zeros_like(blocked) if sensor.known is None else np.array(sensor.known, dtype=bool)
        )
        outside[y0:y1, x0:x1] = blocked[y0:y1, x0:x1]
        blocked = outside
    quality = fraction_correct(blocked, sensor.truth)
    return Result(DomainDescription(blocked, sensor.movement), quality)


@interruptible(
    "find-path",
    inputs=["domain"],
    profile="profiles/find-path.yaml",
    reports="estimate",
    step=0,
)
def find_path(ctx: Context, start: Position, goal: Position, domain: Result) -> Iterator[Result]:
    """The anytime abstract planner on the map `domain` describes: a `MultiPath` after the first
    plan and after every refinement, with the ATP's quality estimate. The robot knows the cells
    it stands on and heads for, so those count as free whatever the map says. Its first plan is
    not searched again through the doors (`atp`'s `doors`): on the task's worlds that seldom
    finds better and costs more ticks than the first plan."""
    description: DomainDescription = domain.value
    blocked = np.array(description.blocked, dtype=bool)
    for x, y in (start, goal):
        blocked[y, x] = False
    yield from atp(
        ctx, start, goal, Pyramid.build(blocked), movement=description.movement, doors=False
    )


@contract("a-star", inputs=["domain"], profile="profiles/a-star.yaml", step=0)
def a_star(ctx: Context, start: Position, goal: Position, domain: Result, level: int = 2) -> Result:
    """Plain A* at one abstraction level of the map `domain` describes (the level's cells of
    2^level x 2^level base cells), as a contract: the plan if the search finishes within the
    allocation (one tick per expansion), with the ATP's quality estimate; else no plan
    (`None`, quality 0). A baseline the anytime planner can be compared with in a schema."""
    description: DomainDescription = domain.value
    blocked = np.array(description.blocked, dtype=bool)
    for x, y in (start, goal):
        blocked[y, x] = False
    pyramid = Pyramid.build(blocked)
    top = min(int(level), pyramid.top)
    try:
        found = find_path_to_box(
            pyramid.levels[top],
            [project(start, 0, top)],
            _point(project(goal, 0, top)),
            movement=description.movement,
            impassable=pyramid.levels[top] >= 1.0,
            limit=ctx.remaining,
        )
    except SearchLimit as stopped:
        ctx.tick(stopped.expansions)
        return Result(None, 0.0)
    if found is None:
        return Result(None, 0.0)
    ctx.tick(found.expansions)
    plan = MultiPath(start, goal, (Segment(top, found.path),))
    return Result(plan, quality_estimate(plan, pyramid))


@elementary("better-plan", combine=max)
def better_plan(first: Result, second: Result) -> Any:
    """The plan of higher quality (the first on ties); its quality is the better one."""
    return (first if first.quality >= second.quality else second).value


@elementary("execute-plan", inputs=["plan"])
def execute_plan(plan: Result, sensor: Sensor) -> Execution:
    """Follow the plan in the world the sensor looks at (`execution.execute`): the route the
    robot walks. Elementary: walking is not planning time; its quality is the plan's."""
    return execute(plan.value, sensor.truth, movement=sensor.movement)


def _point(position: Position) -> tuple[int, int, int, int]:
    return (position[0], position[1], position[0], position[1])


# --- problem sets for the profile builder --------------------------------------------------------


@frozen
class VisionProblems:
    """Random worlds for `get-domain-description`; the score is the fraction of cells right."""

    size: int = PROFILE_SIZE
    movement: int = 4

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        world = random_world(self.size, seed=int(rng.integers(2**31)), movement=self.movement)
        sensor = Sensor(world.blocked, seed=int(rng.integers(2**31)), movement=self.movement)
        return Instance((sensor,), reference=world.blocked)

    def score(self, instance: Instance, value: Any) -> float:
        return fraction_correct(value.blocked, instance.reference)


@frozen
class PlannerProblems:
    """Random worlds seen through the maps vision gives, for `find-path`; the score is the
    papers' plan quality on the true map.

    A map of quality q >= Q_A is a sensed map (each cell wrong with probability 1 - q); below
    Q_A vision has no description and the planner gets the prior, every cell free (whose
    fraction correct is about 0.8 at the default density, but whose errors are all of one kind:
    it misses every obstacle). So the profile's rows below Q_A are the planner on the prior:
    what it is worth to plan without sensing.
    """

    size: int = PROFILE_SIZE
    movement: int = 4

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (quality,) = input_qualities
        world = random_world(self.size, seed=int(rng.integers(2**31)), movement=self.movement)
        if quality < Q_A:
            seen = prior_map(world.blocked)
        else:
            draws = error_draws(world.blocked.shape, int(rng.integers(2**31)))
            seen = sensed_map(world.blocked, draws, quality)
        domain = Result(DomainDescription(seen, self.movement), quality)
        optimal = optimal_length(world.blocked, world.start, world.goal, movement=self.movement)
        return Instance((world.start, world.goal, domain), reference=(world.blocked, optimal))

    def score(self, instance: Instance, value: Any) -> float:
        if value is None:  # no plan (a contract planner out of time)
            return 0.0
        truth, optimal = instance.reference
        executed = execute(value, truth, movement=self.movement)
        return plan_quality(executed.length, optimal)


#: Quality bins finer near 1, where good maps and plans are: the compiler computes expected
#: qualities from bin midpoints, and 10 equal bins would cap every expectation at 0.95 (and
#: count "no result" as 0.05).
BINS = [
    0.0,
    0.02,
    0.2,
    0.4,
    0.5,
    0.6,
    0.7,
    0.75,
    0.8,
    0.85,
    0.9,
    0.925,
    0.95,
    0.97,
    0.98,
    0.99,
    1.0,
]

_PLANNER_TIME = np.arange(0.0, 2001.0, 100.0)
_MAP_QUALITIES = [[0.6, 0.8, 0.85, 0.9, 0.95, 1.0]]

#: How `anytime profile MODULE` measures each module (its problem set and grid).
PROBLEM_SETS = {
    "get-domain-description": Measurement.of(
        VisionProblems(), time=np.arange(0.0, 1201.0, 50.0), bins=BINS
    ),
    "find-path": Measurement.of(
        PlannerProblems(), time=_PLANNER_TIME, input_grids=_MAP_QUALITIES, bins=BINS
    ),
    "a-star": Measurement.of(
        PlannerProblems(), time=_PLANNER_TIME, input_grids=_MAP_QUALITIES, bins=BINS
    ),
}
