"""The situation "obstacle overcoming" (issue 8, part 3; Romanenko, "Decision-making in real
time on the basis of actions planning"): when a moving obstacle (`moving`) will block the
robot's plan, decide among alternatives within the time stock the critical event leaves.

When, following its plan, the robot would come within the safety radius of an
obstacle (the critical event `obstacle-arrival`, `Traffic.arrival`), `deadline_from` gives the
time stock T_d: the time until that moment, minus the estimator's own cost, minus a margin
(`margin`, default two steps). The robot keeps moving during the decision; the decision is
about the *branch cell*, where the plan has it at the deadline. Three alternatives, each with
an elementary precondition (1 tick) and a lower bound T_i* on its concretisation time:

- `detour-left` / `detour-right`: applicable when the `DETOUR_WIDTH` cells beside the conflict
  cell on that side (relative to the direction of travel) are inside the map and free. Concretised
  by A* (`search.find_path_to_box`, one tick per expansion, stopped at its share of T_d) from the
  branch cell to a rejoin cell a little past the conflict, in a box around them, with the other
  side of the line branch-rejoin, and the cells the obstacles sweep meanwhile, impassable.
  T_i* = the Manhattan distance from branch to rejoin (A* expands at least that many cells).
- `wait`: always applicable; stay in the branch cell for the fewest steps after which the plan is
  conflict-free. T_i* = 1.

Every concretised plan is checked against the predicted motion (safety radius included) for
`LOOKAHEAD` ticks beyond its detour; one that fails is dropped. Quality of an alternative, in
[0, 1]: `T_orig / T_alt`, the steps the original plan needs from the branch cell to the rejoin
cell over the steps the alternative needs to get there (a wait counts its waiting steps), capped
at 1. The best valid alternative is chosen (ties in the order above); T_d is split among the
applicable ones by `proportional_split`. Checks of the predicted motion cost one tick per
`PAIRS_PER_TICK` (tick, obstacle) pairs.

`decide_best` is the hand-written reference of that procedure. The same situation as a
schema (`schemas/obstacles.any`, `overcoming_modules`) takes an `Encounter` (the situation
and the conflict) and is decided by the compiled program (`overcoming_modules.schema_decider`),
whose split of T_d is the compiler's. `crossing.follow` runs a robot along a plan among the
traffic with either; with `fallback=True` it adds the reflex `crossing.evade` (a space-time
search) for when no decision gives a plan in time and the plan would really collide.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from attrs import frozen
from numpy.typing import NDArray

from anytime.plugin import Clock, Context, critical_event
from anytime.plugin.compose import Deadline, proportional_split

from ..planning.search import SearchLimit, find_path_to_box
from ..world import Position, World
from .moving import EPS, LOOKAHEAD, PAIRS_PER_TICK, SAFETY_RADIUS, Plan, Traffic

__all__ = [
    "ALTERNATIVES",
    "Alternative",
    "Candidate",
    "Decision",
    "ObstacleSituation",
    "Encounter",
    "decide_best",
    "encounter_at",
    "obstacle_arrival",
    "side_clear",
]

DETOUR_WIDTH = 2  # free cells needed beside the conflict cell for a detour on that side
REJOIN_AHEAD = 3  # the rejoin cell is this many cells past the conflict (plus size and radius)
ARRIVAL_COST_BOUND = 4  # ticks: the declared bound of the `obstacle-arrival` estimator
PRECONDITION_COST = 1  # ticks per precondition
MAX_WAIT = 60  # steps a wait may last
DETOUR_SLACK = 2 * DETOUR_WIDTH + 2  # steps a detour may lag behind the Manhattan distance
AFTER_REJOIN = 10  # steps past the rejoin cell a new plan is checked for
DETOUR_PAD = 8  # cells the search box extends beyond the branch and rejoin cells
DETOUR_EFFORT = 4  # expansions per cell of Manhattan distance a detour search is expected to need


@frozen
class ObstacleSituation:
    """What the robot knows when it looks ahead: the traffic, its plan, the time."""

    traffic: Traffic
    plan: Plan
    now: float
    radius: float = SAFETY_RADIUS
    lookahead: float = LOOKAHEAD


@critical_event("obstacle-arrival", cost_bound=ARRIVAL_COST_BOUND)
def obstacle_arrival(ctx: Context, situation: ObstacleSituation) -> float | None:
    """Time until the plan meets an obstacle. Looks no further than its cost bound allows."""
    traffic = situation.traffic
    affordable = ctx.remaining * PAIRS_PER_TICK / max(len(traffic.obstacles), 1)
    horizon = min(situation.lookahead, affordable)
    ctx.tick(traffic.check_cost(horizon))
    return traffic.first_conflict(situation.plan, situation.now, situation.radius, horizon)


@frozen
class Conflict:
    """Where the decision is about: the branch (plan at the deadline), conflict and rejoin."""

    branch_time: int
    branch: int  # indices into the plan's cells
    conflict: int
    rejoin: int


@frozen
class Encounter:
    """The argument of the schema `overcome-obstacle` (`schemas/obstacles.any`): everything its
    preconditions and alternatives read, i.e. the situation (the world through the traffic,
    the traffic, the plan, the time) and the conflict the deadline fixed. What each
    alternative did when it ran is in the program's record (`overcoming_modules.schema_decider`);
    nothing is written into the encounter."""

    situation: ObstacleSituation
    conflict: Conflict

    @property
    def traffic(self) -> Traffic:
        return self.situation.traffic

    @property
    def world(self) -> World:
        return self.situation.traffic.world

    @property
    def plan(self) -> Plan:
        return self.situation.plan


def encounter_at(situation: ObstacleSituation, deadline: Deadline) -> Encounter:
    """The encounter a deadline defines: where the robot branches, the conflict, the rejoin."""
    return Encounter(situation, _conflict(situation, deadline))


@frozen
class Candidate:
    """A concretised alternative: the plan from the branch cell, and its quality in [0, 1]."""

    plan: Plan
    quality: float


Concretise = Callable[[Context, ObstacleSituation, Conflict], Candidate | None]


@frozen
class Alternative:
    """One way out of the situation: precondition, lower bound T_i*, concretisation."""

    name: str
    precondition: Callable[[ObstacleSituation, Conflict], bool]
    lower_bound: Callable[[ObstacleSituation, Conflict], float]
    concretise: Concretise


def side_clear(world: World, cells: Sequence[Position], index: int, side: int, width: int) -> bool:
    """Whether the `width` cells beside `cells[index]` on `side` (+1 left, -1 right of the
    direction of travel there) are inside the map and free."""
    a = cells[max(index - 1, 0)] if index + 1 >= len(cells) else cells[index]
    b = cells[index] if index + 1 >= len(cells) else cells[index + 1]
    dx, dy = b[0] - a[0], b[1] - a[1]
    nx, ny = side * dy, -side * dx  # left of (dx, dy) with y pointing down
    if nx == ny == 0:
        return False
    x, y = cells[index]
    for k in range(1, width + 1):
        cx, cy = x + k * nx, y + k * ny
        if not (0 <= cx < world.size and 0 <= cy < world.size) or world.blocked[cy, cx]:
            return False
    return True


def _quality(original_steps: int, alternative_steps: int) -> float:
    return min(1.0, original_steps / max(alternative_steps, 1))


def _validated(ctx: Context, situation: ObstacleSituation, plan: Plan, check: float) -> bool:
    """Whether `plan` is conflict-free for `check` ticks (its cost charged first)."""
    cost = situation.traffic.check_cost(check)
    if cost > ctx.remaining:
        return False
    ctx.tick(cost)
    hit = situation.traffic.first_conflict(plan, plan.start, situation.radius, check)
    return hit is None


def _swept(
    situation: ObstacleSituation,
    conflict: Conflict,
    box: tuple[int, int, int, int],
    duration: float,
) -> NDArray[np.bool_]:
    """The cells of `box` an obstacle (grown by the safety radius) occupies around the time the
    robot, leaving the branch cell, could get there: from one step before its Manhattan
    distance to `DETOUR_SLACK` steps after. Indexed [y - y0, x - x0]."""
    x0, y0, x1, y1 = box
    traffic, plan = situation.traffic, situation.plan
    bx, by = plan.cells[conflict.branch]
    ys, xs = np.mgrid[y0 : y1 + 1, x0 : x1 + 1]
    cells = np.stack([xs.ravel(), ys.ravel()], axis=1)  # (C, 2)
    ticks = np.arange(conflict.branch_time, conflict.branch_time + math.ceil(duration) + 1)
    centres = traffic.centres(ticks)  # (T, n, 2)
    reach = traffic.halves + situation.radius  # (n,)
    near = np.asarray(
        np.abs(cells[:, None, None, :] - centres[None]) < reach[None, None, :, None] - EPS
    )
    occupied = np.asarray(near.all(axis=3)).any(axis=2)  # (C, T)
    distance = np.abs(cells[:, 0] - bx) + np.abs(cells[:, 1] - by)
    after = (ticks - conflict.branch_time)[None, :] * plan.speed
    soon = (after >= distance[:, None] - 1) & (after <= distance[:, None] + 1 + DETOUR_SLACK)
    return np.asarray((occupied & soon).any(axis=1).reshape(xs.shape))


def _detour(side: int) -> Concretise:
    def concretise(
        ctx: Context, situation: ObstacleSituation, conflict: Conflict
    ) -> Candidate | None:
        old, traffic, world = situation.plan, situation.traffic, situation.traffic.world
        bx, by = old.cells[conflict.branch]
        rx, ry = old.cells[conflict.rejoin]
        span = abs(rx - bx) + abs(ry - by)
        duration = (span + DETOUR_SLACK + 1) / old.speed
        check = duration + AFTER_REJOIN / old.speed
        # the box, the chosen side of the line branch -> rejoin, and the swept cells
        n = world.size
        pad = DETOUR_PAD
        x0, y0 = max(min(bx, rx) - pad, 0), max(min(by, ry) - pad, 0)
        x1, y1 = min(max(bx, rx) + pad, n - 1), min(max(by, ry) + pad, n - 1)
        ys, xs = np.mgrid[0:n, 0:n]
        across = (xs - bx) * (ry - by) - (ys - by) * (rx - bx)  # > 0: left of branch->rejoin
        closed = np.array(world.blocked, copy=True)
        closed |= side * across < 0
        outside = np.ones_like(closed)
        outside[y0 : y1 + 1, x0 : x1 + 1] = False
        closed |= outside
        start = conflict.branch_time
        closed[y0 : y1 + 1, x0 : x1 + 1] |= _swept(situation, conflict, (x0, y0, x1, y1), duration)
        closed[by, bx] = closed[ry, rx] = False
        limit = ctx.remaining - traffic.check_cost(check)
        if limit < 1:
            return None
        try:
            found = find_path_to_box(
                closed, [(bx, by)], (rx, ry, rx, ry), movement=world.movement, ctx=ctx, limit=limit
            )
        except SearchLimit:
            return None
        if found is None:
            return None
        plan = Plan(start, found.path + old.cells[conflict.rejoin + 1 :], old.speed)
        if not _validated(ctx, situation, plan, check):
            return None
        return Candidate(plan, _quality(conflict.rejoin - conflict.branch, len(found.path) - 1))

    return concretise


def _wait(ctx: Context, situation: ObstacleSituation, conflict: Conflict) -> Candidate | None:
    old = situation.plan
    ahead = old.cells[conflict.branch :]
    original = conflict.rejoin - conflict.branch
    for steps in range(1, MAX_WAIT + 1):
        plan = Plan(conflict.branch_time, (ahead[0],) * steps + ahead, old.speed)
        check = (steps + original + AFTER_REJOIN) / old.speed
        if situation.traffic.check_cost(check) > ctx.remaining:
            return None
        if _validated(ctx, situation, plan, check):
            return Candidate(plan, _quality(original, steps + original))
    return None


def _side_precondition(side: int) -> Callable[[ObstacleSituation, Conflict], bool]:
    def precondition(situation: ObstacleSituation, conflict: Conflict) -> bool:
        world = situation.traffic.world
        return side_clear(world, situation.plan.cells, conflict.conflict, side, DETOUR_WIDTH)

    return precondition


def _detour_bound(situation: ObstacleSituation, conflict: Conflict) -> float:
    (bx, by), (rx, ry) = (situation.plan.cells[i] for i in (conflict.branch, conflict.rejoin))
    return float(DETOUR_EFFORT * max(abs(rx - bx) + abs(ry - by), 1))


def _wait_bound(situation: ObstacleSituation, conflict: Conflict) -> float:
    """The steps the obstacle nearest the conflict cell needs to cross its own width and the
    safety zone (each step waited costs at least one check)."""
    plan = situation.plan
    tick = conflict.branch_time + math.ceil((conflict.conflict - conflict.branch) / plan.speed)
    x, y = plan.cells[conflict.conflict]
    blocker = min(
        situation.traffic.at(tick),
        key=lambda o: abs(o.position[0] - x) + abs(o.position[1] - y),
    )
    crossing = blocker.size + 2 * situation.radius + 1
    pace = max(math.hypot(*blocker.velocity), 1e-3)
    return float(min(math.ceil(crossing / pace * plan.speed), MAX_WAIT))


#: The situation "obstacle overcoming": its alternatives, in order of preference on ties.
ALTERNATIVES: tuple[Alternative, ...] = (
    Alternative("detour-left", _side_precondition(+1), _detour_bound, _detour(+1)),
    Alternative("detour-right", _side_precondition(-1), _detour_bound, _detour(-1)),
    Alternative("wait", lambda s, c: True, _wait_bound, _wait),
)


@frozen
class Outcome:
    """One alternative in one decision: applicable?, its share of T_d, what it gave."""

    name: str
    applicable: bool
    allocation: float = 0.0
    ticks: float = 0.0
    quality: float | None = None


@frozen
class Decision:
    """One decision: T_d, the time it took (from when T_d was computed), what was chosen.

    `plan` is the chosen alternative's plan (it starts at the deadline), None when no
    alternative could be concretised in time."""

    computed_at: float
    t_d: float
    taken: float
    chosen: str | None
    plan: Plan | None = None
    outcomes: tuple[Outcome, ...] = ()

    @property
    def within(self) -> bool:
        """Whether it was made within its time stock."""
        return self.taken <= self.t_d + EPS


Decide = Callable[[ObstacleSituation, Deadline, Clock], Decision]


def _conflict(situation: ObstacleSituation, deadline: Deadline) -> Conflict:
    plan = situation.plan
    branch_time = max(math.floor(deadline.at), math.ceil(deadline.computed_at))
    conflict = plan.index_at(deadline.at + deadline.margin)
    reach = math.ceil(max(o.size for o in situation.traffic.obstacles) + situation.radius)
    rejoin = min(conflict + REJOIN_AHEAD + reach, len(plan.cells) - 1)
    return Conflict(branch_time, plan.index_at(branch_time), conflict, rejoin)


def decide_best(situation: ObstacleSituation, deadline: Deadline, clock: Clock) -> Decision:
    """Romanenko's steps 2-5: preconditions, proportional split of what is left of T_d,
    concretisation of each applicable alternative within its share, the best one chosen."""
    conflict = _conflict(situation, deadline)
    if deadline.remaining(clock) < PRECONDITION_COST * len(ALTERNATIVES):
        # no time to deliberate: no decision (the robot keeps its plan)
        return Decision(
            deadline.computed_at, deadline.t_d, clock.now() - deadline.computed_at, None
        )
    applicable = []
    for alternative in ALTERNATIVES:
        clock.advance(PRECONDITION_COST)
        applicable.append(alternative.precondition(situation, conflict))
    left = max(min(deadline.remaining(clock), conflict.branch_time - clock.now()), 0.0)
    bounds = [
        a.lower_bound(situation, conflict)
        for a, ok in zip(ALTERNATIVES, applicable, strict=True)
        if ok
    ]
    shares = iter(proportional_split(left, bounds))
    outcomes, best = [], None
    for alternative, ok in zip(ALTERNATIVES, applicable, strict=True):
        if not ok:
            outcomes.append(Outcome(alternative.name, False))
            continue
        share = next(shares)
        ctx = Context(allocation=math.floor(share), clock=clock)
        candidate = alternative.concretise(ctx, situation, conflict)
        quality = None if candidate is None else candidate.quality
        outcomes.append(Outcome(alternative.name, True, share, ctx.elapsed, quality))
        if candidate is not None and (best is None or candidate.quality > best[1].quality):
            best = (alternative.name, candidate)
    return Decision(
        computed_at=deadline.computed_at,
        t_d=deadline.t_d,
        taken=clock.now() - deadline.computed_at,
        chosen=None if best is None else best[0],
        plan=None if best is None else best[1].plan,
        outcomes=tuple(outcomes),
    )
