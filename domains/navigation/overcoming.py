"""The situation "obstacle overcoming" (issue 8, part 3; Romanenko, "Decision-making in real
time on the basis of actions planning"): when a moving obstacle (`obstacles`) will block the
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
whose split of T_d is the compiler's. `follow` runs a robot along a plan among the traffic with
either; with `fallback=True` it adds the reflex `evade` (a space-time search) for when no
decision gives a plan in time and the plan would really collide.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from anytime.clocks import Clock, WorkClock
from anytime.modules import Context
from anytime.runtime.deadline import Deadline, critical_event, deadline_from, proportional_split

from .obstacles import EPS, LOOKAHEAD, PAIRS_PER_TICK, SAFETY_RADIUS, MovingObstacle, Plan, Traffic
from .search import SearchLimit, find_path_to_box
from .world import Position, World

__all__ = [
    "ALTERNATIVES",
    "Alternative",
    "Candidate",
    "Decision",
    "ObstacleSituation",
    "SimulationReport",
    "Encounter",
    "Followed",
    "decide_best",
    "encounter_at",
    "evade",
    "follow",
    "obstacle_arrival",
    "side_clear",
    "simulate",
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
    the traffic, the plan, the time) and the conflict the deadline fixed. `outcomes` collects
    what each alternative did when it ran (for reports; not part of the value)."""

    situation: ObstacleSituation
    conflict: Conflict
    outcomes: list[Outcome] = field(factory=list, eq=False, repr=False)

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


@frozen
class SimulationReport:
    """How a run went: goal reached?, ticks in collision (must be 0), the decisions."""

    reached_goal: bool
    collisions: int
    finish: float
    decisions: tuple[Decision, ...]
    plans: tuple[Plan, ...]
    evasions: tuple[float, ...] = ()


def simulate(
    world: World,
    obstacles: Sequence[MovingObstacle],
    route: Sequence[Position],
    speed: float,
    decide: Decide = decide_best,
    *,
    radius: float = SAFETY_RADIUS,
    lookahead: float = LOOKAHEAD,
    margin: float | None = None,
    max_time: float | None = None,
    fallback: bool = False,
) -> SimulationReport:
    """Run the robot along `route` (from the start) among the obstacles, on a work clock.

    At every cell it enters, the robot computes the deadline from `obstacle-arrival`; when an
    arrival is predicted it calls `decide` (the clock runs on while it thinks, and so does the
    robot) and switches to the chosen plan at the deadline. A decision made after its deadline
    is void (the robot keeps its plan and looks again at the next cell). With `fallback`, when
    no decision gives a plan and the plan would actually collide, the robot takes the reflex
    `evade` (see `follow`). Collisions are ticks at which the robot's cell is occupied by an
    obstacle (no safety radius).
    """
    traffic = Traffic(world, obstacles)
    clock = WorkClock()
    plan = Plan(0.0, route, speed)
    limit = max_time if max_time is not None else 20.0 * plan.end + 2000.0
    followed = follow(
        traffic,
        plan,
        clock,
        decide,
        radius=radius,
        lookahead=lookahead,
        margin=margin,
        limit=limit,
        fallback=fallback,
    )
    plan = followed.plans[-1]
    finish = clock.now()
    reached = finish >= plan.end and plan.cells[-1] == world.goal
    return SimulationReport(
        reached,
        _collisions(traffic, followed.plans, min(finish, plan.end)),
        finish,
        followed.decisions,
        followed.plans,
        followed.evasions,
    )


@frozen
class Followed:
    """How a plan was followed: the plans in force (the first is the given one, each later one
    from its `start`), the decisions, and the times the reflex `evade` was taken."""

    plans: tuple[Plan, ...]
    decisions: tuple[Decision, ...]
    evasions: tuple[float, ...] = ()


def follow(
    traffic: Traffic,
    plan: Plan,
    clock: Clock,
    decide: Decide = decide_best,
    *,
    radius: float = SAFETY_RADIUS,
    lookahead: float = LOOKAHEAD,
    margin: float | None = None,
    limit: float = math.inf,
    fallback: bool = False,
) -> Followed:
    """Follow `plan` from `clock.now()` (which must lie in [plan.start, plan.end]) to its end
    among the traffic, deciding as `simulate` describes; the clock ends at the plan's end (or at
    `limit`). Times are absolute ticks of the traffic's motion.

    The fallback (`fallback=True`): when the decision gives no plan in time (no time to
    deliberate, every alternative failed, or none applicable) and the current plan would
    really collide (an obstacle on the robot's cell, no safety radius) within the lookahead,
    the robot takes `evade` at once, a reflex not charged on the clock. Its guarantee: if some
    step-by-step route inside `EVADE_STEPS` steps keeps the robot off every obstacle's cells
    (first with the safety radius, then without) and ends on a cell of the plan from which
    the rest of the plan is conflict-free for the lookahead, the robot takes it; otherwise the
    robot keeps its plan (and may collide).
    """
    margin = 2.0 / plan.speed if margin is None else margin
    plans, decisions, evasions = [plan], [], []
    while clock.now() < plan.end and clock.now() < limit:
        situation = ObstacleSituation(traffic, plan, clock.now(), radius, lookahead)
        deadline = deadline_from(situation, [obstacle_arrival], clock, margin=margin)
        if deadline.event is not None:
            decision = decide(situation, deadline, clock)
            decisions.append(decision)
            if decision.plan is not None and clock.now() <= decision.plan.start:
                plan = decision.plan
                plans.append(plan)
                clock.advance(plan.start - clock.now())  # nothing new to see until the switch
            elif fallback and traffic.first_conflict(plan, clock.now(), 0.0, lookahead) is not None:
                evasive = evade(traffic, plan, clock.now(), radius=radius, lookahead=lookahead)
                if evasive is not None:
                    plan = evasive
                    plans.append(plan)
                    evasions.append(clock.now())
        clock.advance(max(plan.next_step(clock.now()) - clock.now(), 0.0))
    return Followed(tuple(plans), tuple(decisions), tuple(evasions))


EVADE_STEPS = 60  # steps the reflex `evade` looks ahead
EVADE_CHECKS = 400  # candidate rejoins it validates at most


def _neighbours(world: World, cell: Position) -> list[Position]:
    x, y = cell
    moves = [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)]
    if world.movement == 8:
        moves += [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    n = world.size
    out = []
    for dx, dy in moves:
        cx, cy = x + dx, y + dy
        if 0 <= cx < n and 0 <= cy < n and not world.blocked[cy, cx]:
            out.append((cx, cy))
    return out


def evade(
    traffic: Traffic,
    plan: Plan,
    now: float,
    *,
    radius: float = SAFETY_RADIUS,
    lookahead: float = LOOKAHEAD,
    steps: int = EVADE_STEPS,
) -> Plan | None:
    """The reflex when deliberation gave nothing: a breadth-first search in space and time.

    From the robot's cell at `now`, one step (1 / speed ticks) at a time, the robot may stay or
    move to a free neighbour not occupied by an obstacle grown by the safety radius during that
    step; it looks for the earliest step at which it stands on a cell of the rest of the plan
    from which the rest is conflict-free (same radius) for the lookahead; then without the
    safety radius. Returns the plan (evasive steps, then the rest of the old plan), or None."""
    world, speed = traffic.world, plan.speed
    i = plan.index_at(now)
    here = plan.cells[i]
    ahead: dict[Position, list[int]] = {}
    for j in range(i, len(plan.cells)):
        ahead.setdefault(plan.cells[j], []).append(j)
    for r in sorted({float(radius), 0.0}, reverse=True):
        occupied = []
        for k in range(steps + 1):
            first = math.ceil(now + k / speed - EPS)
            last = math.ceil(now + (k + 1) / speed - EPS) - 1
            cells: set[Position] = set()
            for tick in range(max(first, 0), max(last, first) + 1):
                cells |= traffic.cells_at(tick, r)
            occupied.append(cells)
        layer: dict[Position, Position | None] = {here: None}
        parents: list[dict[Position, Position | None]] = [layer]
        checks = 0
        for k in range(steps + 1):
            if k > 0:
                layer = {}
                for cell in parents[-1]:
                    for nxt in _neighbours(world, cell):
                        if nxt not in layer and nxt not in occupied[k]:
                            layer[nxt] = cell
                if not layer:
                    break
                parents.append(layer)
            for cell in layer:
                for j in reversed(ahead.get(cell, [])):
                    if checks >= EVADE_CHECKS:
                        break
                    checks += 1
                    path = [cell]
                    for back in range(k, 0, -1):
                        parent = parents[back][path[-1]]
                        assert parent is not None
                        path.append(parent)
                    path.reverse()
                    candidate = Plan(now, path + list(plan.cells[j + 1 :]), speed)
                    if traffic.first_conflict(candidate, now, r, lookahead) is None:
                        return candidate
    return None


def _collisions(traffic: Traffic, plans: Sequence[Plan], end: float) -> int:
    count = 0
    for plan, following in zip(plans, [*plans[1:], None], strict=True):
        stop = end if following is None else following.start - EPS
        ticks = np.arange(math.ceil(plan.start - EPS), math.floor(stop) + 1, dtype=np.int64)
        count += int(traffic.hits(plan, ticks, 0.0).sum())
    return count
