"""The problems the navigation plugin's schemas are promised for: `anytime verify` runs each
compiled schema on fresh ones and checks what it delivers against what it promises.

- `navigate`, `navigate-nested`, `navigate-two-planners` and `sense-plan-act`
  (`schemas/navigation.any`, inputs `start goal sensor`): `WorldProblems`, fresh random worlds
  of the profiles' setting (128 x 128, 4-connected, random rectangles) with their sensor. The
  result is scored as the planner's profile scores a plan: the papers' plan quality, optimal
  length over the length of the route the plan makes the robot walk on the true map
  (`sense-plan-act`'s result is that route already).
- `overcome-obstacle` (`schemas/obstacles.any`, input `situation`): `EncounterProblems`,
  encounters from navigation among moving obstacles where every alternative is applicable (the
  compiler splits the time for the best-of assuming all applicable; `dsl.md`), the very ones
  the alternatives' profiles are measured on (`OvercomingProblems`). Scored as the
  alternatives' profiles score one: the quality of the chosen alternative's candidate.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from attrs import frozen

from anytime.plugin import Instance, ProgramProblems

from .modules import PROFILE_SIZE
from .obstacles.overcoming_modules import RESOLUTION, Attempt, OvercomingProblems
from .task.execution import Execution, execute, optimal_length, plan_quality
from .task.vision import Sensor
from .world import random_world

__all__ = ["PROGRAM_PROBLEMS", "EncounterProblems", "WorldProblems"]

#: The totals the navigation schemas are compiled for (ticks), as the docs compile them.
NAVIGATION_GRID = tuple(float(t) for t in range(0, 3001, 250))
#: The totals `overcome-obstacle` is checked at: every fifth of the totals it is compiled for
#: (`overcoming_modules.TIME_GRID`, 5 ticks apart), on its lattice of 5 ticks.
OVERCOMING_GRID = tuple(float(t) for t in range(0, 301, 25))


@frozen
class WorldProblems:
    """A fresh random world and its sensor, the inputs `start goal sensor`; the reference is
    the true map and the length of a shortest route on it."""

    size: int = PROFILE_SIZE
    movement: int = 4

    def instance(self, rng: np.random.Generator) -> Instance:
        world = random_world(self.size, seed=int(rng.integers(2**31)), movement=self.movement)
        sensor = Sensor(world.blocked, seed=int(rng.integers(2**31)), movement=self.movement)
        optimal = optimal_length(world.blocked, world.start, world.goal, movement=self.movement)
        return Instance((world.start, world.goal, sensor), reference=(world.blocked, optimal))

    def score(self, instance: Instance, value: Any) -> float:
        """The plan quality of a plan (`MultiPath`) or of a route walked (`Execution`); 0
        without one."""
        if value is None:  # no plan (a contract planner out of time), or no result
            return 0.0
        truth, optimal = instance.reference
        if not isinstance(value, Execution):
            value = execute(value, truth, movement=self.movement)
        return plan_quality(value.length, optimal)


ALTERNATIVES = ("detour-left", "detour-right", "wait")


@frozen
class EncounterProblems:
    """An encounter where every alternative of `overcome-obstacle` applies, drawn as the
    alternatives' profiles draw theirs (`OvercomingProblems`, the same encounters: a random
    32 x 32 world, three moving obstacles, the robot on its shortest route at one of the task's
    speeds). Its `score_step` scores an alternative's result as `score` does the best-of's."""

    draws: OvercomingProblems = OvercomingProblems()

    def instance(self, rng: np.random.Generator) -> Instance:
        (encounter,) = self.draws.instance(rng, ()).args
        return Instance((encounter,))

    def score(self, instance: Instance, value: Any) -> float:
        if not isinstance(value, Attempt) or value.candidate is None:
            return 0.0
        return float(value.candidate.quality)

    def score_step(self, instance: Instance, module: str, value: Any) -> float:
        """The true quality of `value`, the result of alternative `module`, as its own problem
        set scores it: its candidate's quality, 0 without one."""
        if module not in ALTERNATIVES:
            raise ValueError(f"EncounterProblems.score_step: no true quality for module '{module}'")
        return self.score(instance, value)


#: How `anytime verify` checks each schema of the plugin.
PROGRAM_PROBLEMS = {
    **{
        name: ProgramProblems.of(WorldProblems(), time_grid=NAVIGATION_GRID)
        for name in ("navigate", "navigate-nested", "navigate-two-planners", "sense-plan-act")
    },
    "overcome-obstacle": ProgramProblems.of(
        EncounterProblems(), time_grid=OVERCOMING_GRID, resolution=RESOLUTION
    ),
}
