"""The situation "obstacle overcoming" as a schema (`schemas/obstacles.any`, issue 8 part 3):

    (defschema overcome-obstacle (situation)
      (best-of (when (left-clear? situation) (detour-left situation))
               (when (right-clear? situation) (detour-right situation))
               (when (can-wait? situation) (wait situation))))

`situation` is an `overcoming.Encounter` (the traffic and its world, the plan, the conflict the
deadline fixed). The modules:

- `left-clear?`, `right-clear?` (elementary): the `DETOUR_WIDTH` cells beside the conflict
  cell on that side are inside the map and free (no wall, not the map's edge);
- `can-wait?` (elementary): the obstacle nearest the conflict cell is moving (a parked one
  never passes);
- `detour-left`, `detour-right`, `wait` (contract): the concretisations of `overcoming`, run
  within `ctx.allocation` ticks of the work clock; value an `Attempt` (the name and the
  `Candidate`, or None when nothing valid was found in time), quality the candidate's
  `T_orig / T_alt` (0 without a candidate).

Their profiles are *measured* (`OvercomingProblems`), not `DiscreteVariants`: for one
situation the quality of an alternative is a step function of its time (nothing until the
search or the waiting checks finish, then a fixed quality), but the step's time and height
vary from situation to situation (the detour's length, how long the obstacle takes to pass),
so over the situations the robot meets the profile is a distribution that rises gradually;
a handful of deterministic variants would misstate it. All three are measured on the
encounters the compiled schema is promised for (`program_problems.EncounterProblems`, which
`anytime verify` runs it on): those where every alternative applies. Regenerate them (from the
repository's root; about 3 to 5 minutes each on one core) with

    for m in detour-left detour-right wait; do
      .venv/bin/anytime profile $m --trials 500 \
        -o domains/navigation/anytime_navigation/profiles/$m.yaml
    done

Not with `--upstream`: the alternatives take no quality-carrying input, so what the program
hands them is the encounter itself, whatever the allocation; `OvercomingProblems` draws the
same encounters, and a fixed point over the allocations has nothing to iterate.

Deciding with the schema (`schema_decider`): the robot computes T_d with `deadline_from`, fixes
the encounter, and runs the compiled `overcome-obstacle` (`overcoming_program`) as a contract
algorithm with what is left of T_d (and before the branch time) on the work clock:
`CompiledProgram.run` evaluates the preconditions (elementary: no time), re-splits the time
among the applicable alternatives and returns the best.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from attrs import frozen

from anytime import (
    AnytimeLibrary,
    Budget,
    CompiledProgram,
    LibraryEntry,
    RunRecord,
    compile_program,
    run_program,
)
from anytime.plugin import (
    Clock,
    Context,
    Instance,
    Measurement,
    Result,
    WorkClock,
    contract,
    elementary,
)
from anytime.plugin.compose import Deadline, deadline_from

from ..planning.search import find_path
from ..resources import data_file, load_schema_file, profile_file
from ..world import random_world
from .moving import Plan, Traffic, random_obstacles
from .overcoming import (
    ALTERNATIVES,
    DETOUR_WIDTH,
    Candidate,
    Decide,
    Decision,
    Encounter,
    ObstacleSituation,
    Outcome,
    encounter_at,
    obstacle_arrival,
    side_clear,
)

__all__ = [
    "PROBLEM_SETS",
    "SCHEMA_FILE",
    "Attempt",
    "OvercomingProblems",
    "all_applicable",
    "can_wait",
    "detour_left",
    "detour_right",
    "left_clear",
    "overcoming_program",
    "right_clear",
    "schema_decider",
    "situations",
    "wait",
]

#: The schema file of the situation.
SCHEMA_FILE = data_file("schemas", "obstacles.any")

#: The totals the program is compiled for (ticks); T_d above the last gets the last split
#: scaled up. Allocations are multiples of `RESOLUTION`.
TIME_GRID = np.arange(0.0, 301.0, 5.0)
RESOLUTION = 5.0

#: The profiles' time axis (ticks) and quality bins.
PROFILE_TIME = np.arange(0.0, 301.0, 10.0)
PROFILE_BINS = [0.0, 0.02, 0.2, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0]


@frozen
class Attempt:
    """What an alternative gave: its name and candidate (None: nothing valid in time)."""

    name: str
    candidate: Candidate | None

    @property
    def plan(self) -> Plan | None:
        return None if self.candidate is None else self.candidate.plan


# --- preconditions (elementary) -------------------------------------------------------------------


def _side(encounter: Encounter, side: int) -> bool:
    cells = encounter.plan.cells
    return side_clear(encounter.world, cells, encounter.conflict.conflict, side, DETOUR_WIDTH)


@elementary("left-clear?", inputs=[])
def left_clear(situation: Encounter) -> bool:
    """No wall and not the map's edge beside the conflict cell on the left."""
    return _side(situation, +1)


@elementary("right-clear?", inputs=[])
def right_clear(situation: Encounter) -> bool:
    """No wall and not the map's edge beside the conflict cell on the right."""
    return _side(situation, -1)


@elementary("can-wait?", inputs=[])
def can_wait(situation: Encounter) -> bool:
    """The obstacle nearest the conflict cell, when the robot would get there, is moving."""
    plan, conflict = situation.plan, situation.conflict
    tick = conflict.branch_time + math.ceil((conflict.conflict - conflict.branch) / plan.speed)
    x, y = plan.cells[conflict.conflict]
    obstacles = situation.traffic.at(max(tick, 0))
    if not obstacles:
        return True
    nearest = min(obstacles, key=lambda o: abs(o.position[0] - x) + abs(o.position[1] - y))
    return math.hypot(*nearest.velocity) > 0.0


# --- the alternatives (contract) ------------------------------------------------------------------


def _attempt(index: int, ctx: Context, encounter: Encounter) -> Result:
    alternative = ALTERNATIVES[index]
    candidate = alternative.concretise(ctx, encounter.situation, encounter.conflict)
    quality = 0.0 if candidate is None else float(candidate.quality)
    return Result(Attempt(alternative.name, candidate), quality)


@contract("detour-left", inputs=[], profile=profile_file("detour-left.yaml"))
def detour_left(ctx: Context, situation: Encounter) -> Result:
    """A detour on the left of the conflict: A* in a box, one tick per expansion."""
    return _attempt(0, ctx, situation)


@contract("detour-right", inputs=[], profile=profile_file("detour-right.yaml"))
def detour_right(ctx: Context, situation: Encounter) -> Result:
    """A detour on the right of the conflict: A* in a box, one tick per expansion."""
    return _attempt(1, ctx, situation)


@contract("wait", inputs=[], profile=profile_file("wait.yaml"))
def wait(ctx: Context, situation: Encounter) -> Result:
    """Wait in the branch cell for the fewest steps that make the plan conflict-free."""
    return _attempt(2, ctx, situation)


MODULES = (left_clear, right_clear, can_wait, detour_left, detour_right, wait)


# --- situations from navigation with moving obstacles ---------------------------------------------


def situations(
    world: Any,
    k: int,
    seed: int,
    speed: float,
    *,
    min_t_d: float = 1.0,
    limit: int | None = None,
) -> list[tuple[Encounter, Deadline]]:
    """The encounters a robot meets following its shortest route at `speed` among `k`
    obstacles (`random_obstacles(world, k, seed)`) without deciding: at every cell it enters,
    the deadline from `obstacle-arrival`; each one with T_d >= `min_t_d` gives an encounter
    (one per conflict: the next after the robot has passed the conflict cell)."""
    found = find_path(world.blocked, world.start, world.goal, movement=world.movement)
    if found is None:
        return []
    traffic = Traffic(world, random_obstacles(world, k, seed))
    plan = Plan(0.0, found.path, speed)
    clock = WorkClock()
    out: list[tuple[Encounter, Deadline]] = []
    after = -1
    while clock.now() < plan.end and (limit is None or len(out) < limit):
        situation = ObstacleSituation(traffic, plan, clock.now())
        deadline = deadline_from(situation, [obstacle_arrival], clock, margin=2.0 / speed)
        if deadline.event is not None and deadline.t_d >= min_t_d:
            encounter = encounter_at(situation, deadline)
            if encounter.conflict.conflict > after:
                out.append((encounter, deadline))
                after = encounter.conflict.rejoin
        clock.advance(max(plan.next_step(clock.now()) - clock.now(), 0.0))
    return out


@functools.lru_cache(maxsize=512)
def _encounters(size: int, k: int, seed: int, speed: float) -> list[Encounter]:
    """The encounters of one generated world (cached: the builder makes a contract module's
    instance afresh for every time of its grid)."""
    world = random_world(size, seed=seed, density=0.1)
    return [e for e, _ in situations(world, k, seed, speed, min_t_d=5.0)]


def all_applicable(encounter: Encounter) -> bool:
    """Whether every alternative of `overcome-obstacle` applies (each precondition holds)."""
    return all(applies(encounter) for applies in PRECONDITIONS.values())


@frozen
class OvercomingProblems:
    """Encounters from navigation with moving obstacles where every alternative applies: a
    random world of side `size`, `obstacles` random obstacles, the robot on its shortest route
    at a speed of the navigation task's grid; one of the encounters it meets, drawn again until
    all three preconditions hold. Score: the quality of the alternative's candidate (0 without
    one).

    These are the encounters the compiled best-of is promised for (the compiler splits T_d
    assuming every alternative applicable; `program_problems.EncounterProblems` draws these
    very ones), so each alternative is measured on them, not on all the encounters where its
    own precondition holds: detour-right delivers about 0.28 on them with 100 ticks or more,
    against 0.20 on every encounter where the right side is clear, and the compiled split, and
    its promise, follow the alternatives' qualities on the program's encounters. The
    alternatives have no quality-carrying input, so nothing else of the program reaches them
    (`anytime profile --upstream` would measure them on the same encounters)."""

    size: int = 32
    obstacles: int = 3
    speeds: tuple[float, ...] = (0.05, 0.1, 0.15, 0.2)

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        while True:
            seed = int(rng.integers(2**31))
            speed = float(self.speeds[int(rng.integers(len(self.speeds)))])
            met = _encounters(self.size, self.obstacles, seed, speed)
            if met:
                encounter = met[int(rng.integers(len(met)))]
                if all_applicable(encounter):
                    return Instance((encounter,), None)

    def score(self, instance: Instance, value: Any) -> float:
        if not isinstance(value, Attempt) or value.candidate is None:
            return 0.0
        return float(value.candidate.quality)


PRECONDITIONS = {"detour-left": left_clear, "detour-right": right_clear, "wait": can_wait}

#: How `anytime profile MODULE` measures the alternatives: all three on the same encounters.
PROBLEM_SETS = {
    module.name: Measurement.of(OvercomingProblems(), time=PROFILE_TIME, bins=PROFILE_BINS)
    for module in (detour_left, detour_right, wait)
}


# --- the compiled program and the decision -------------------------------------------------------


def overcoming_library() -> AnytimeLibrary:
    """The six modules with their profiles (from `profiles/`)."""
    library = AnytimeLibrary()
    for module in MODULES:
        library.add(LibraryEntry.of_module(module))
    return library


@functools.cache
def overcoming_program(allocator: str = "auto") -> CompiledProgram:
    """`overcome-obstacle` of `schemas/obstacles.any`, compiled for `TIME_GRID` (cached)."""
    schemas = load_schema_file("obstacles.any")
    return compile_program(
        schemas["overcome-obstacle"],
        overcoming_library(),
        TIME_GRID,
        allocator=allocator,
        resolution=RESOLUTION,
        source=schemas.source,
    )


def schema_decider(compiled: CompiledProgram | None = None) -> Decide:
    """A `Decide` that runs the compiled `overcome-obstacle` with what is left of T_d (no later
    than the branch time) on the decision's clock, and takes the best alternative's plan."""
    program = compiled if compiled is not None else overcoming_program()

    def decide(situation: ObstacleSituation, deadline: Deadline, clock: Clock) -> Decision:
        encounter = encounter_at(situation, deadline)
        conflict = encounter.conflict
        left = math.floor(min(deadline.remaining(clock), conflict.branch_time - clock.now()))
        taken = clock.now() - deadline.computed_at
        if left < 1:  # no time to deliberate: no decision (the robot keeps its plan)
            return Decision(deadline.computed_at, deadline.t_d, taken, None)
        applicable = [left_clear(encounter), right_clear(encounter), can_wait(encounter)]
        record = run_program(program, [encounter], Budget(float(left), clock=clock))
        result = record.result
        names = {a.name for a in ALTERNATIVES}
        ran = {r.module: _outcome(r) for r in record.records if r.module in names}
        outcomes = tuple(
            ran.get(a.name, Outcome(a.name, ok))
            for a, ok in zip(ALTERNATIVES, applicable, strict=True)
        )
        attempt = None if result is None else result.value
        chosen = attempt if isinstance(attempt, Attempt) and attempt.plan is not None else None
        return Decision(
            computed_at=deadline.computed_at,
            t_d=deadline.t_d,
            taken=clock.now() - deadline.computed_at,
            chosen=None if chosen is None else chosen.name,
            plan=None if chosen is None else chosen.plan,
            outcomes=outcomes,
        )

    return decide


def _outcome(record: RunRecord) -> Outcome:
    """What an alternative's run gave, from its record: its share of T_d, the ticks it took,
    its candidate's quality (None: no candidate)."""
    attempt = None if record.result is None else record.result.value
    found = isinstance(attempt, Attempt) and attempt.candidate is not None
    quality = float(record.result.quality) if found and record.result is not None else None
    return Outcome(record.module, True, float(record.allocation), float(record.time_used), quality)
