"""Crossing the map among moving obstacles: following a plan on the work clock, deciding at
every critical event (the situation "obstacle overcoming", `overcoming`) within the time stock
it leaves, the reflex evasion when deliberation gives no safe plan in time, and a simulation
that checks a whole route (no collision, every decision within its T_d)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from attrs import frozen

from anytime.plugin import Clock, WorkClock
from anytime.plugin.compose import deadline_from

from ..world import Position, World
from .moving import EPS, LOOKAHEAD, SAFETY_RADIUS, MovingObstacle, Plan, Traffic
from .overcoming import (
    Decide,
    Decision,
    ObstacleSituation,
    decide_best,
    obstacle_arrival,
)

__all__ = ["Followed", "SimulationReport", "collisions", "evade", "follow", "simulate"]


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
        collisions(traffic, followed.plans, min(finish, plan.end)),
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


def collisions(traffic: Traffic, plans: Sequence[Plan], end: float) -> int:
    count = 0
    for plan, following in zip(plans, [*plans[1:], None], strict=True):
        stop = end if following is None else following.start - EPS
        ticks = np.arange(math.ceil(plan.start - EPS), math.floor(stop) + 1, dtype=np.int64)
        count += int(traffic.hits(plan, ticks, 0.0).sum())
    return count
