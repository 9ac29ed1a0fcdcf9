"""Running a navigation task frame by frame (see `task` for the task, the monitor's model and
the quantities reported): each frame senses and plans with the compiled frame program
(`frame_program`) under the contract the policy chooses, then executes the plan up to the
sensor window's edge while the next frame's planning overlaps; with moving obstacles, the
robot decides how to overcome them within the time stock they leave (`overcoming`)."""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence
from typing import Any

import numpy as np

from anytime.clocks import Clock, Unit, WorkClock
from anytime.compiler.compile import CompiledProgram
from anytime.runtime.monitor import Adjustment, EventLog, Monitor

from .execution import execute, optimal_length, route_length
from .frame_program import PlanTrace
from .obstacles import MovingObstacle, Plan, Traffic
from .task import (
    MIN_QUALITY,
    POLICIES,
    FrameRecord,
    FrameState,
    NavigationTask,
    TaskModel,
    TaskReport,
    optimal_utility,
)
from .vision import Sensor
from .world import BoolGrid, Position

__all__ = ["WallTicks", "run_task"]


class WallTicks:
    """A wall clock that reads in tick-equivalents: seconds of `time.perf_counter` times a rate
    (ticks per second) measured by running the program once on the work clock."""

    unit: Unit = "ticks"

    def __init__(self, rate: float) -> None:
        self.rate = rate
        self._start = _time.perf_counter()

    def now(self) -> float:
        return (_time.perf_counter() - self._start) * self.rate

    def advance(self, n: float) -> None:
        pass


def _segment(route: Sequence[Position], window: tuple[int, int, int, int]) -> list[Position]:
    """The route from its start up to the last cell before it first leaves `window`."""
    x0, y0, x1, y1 = window
    cut = [route[0]]
    for x, y in route[1:]:
        if not (x0 <= x < x1 and y0 <= y < y1):
            break
        cut.append((x, y))
    if len(cut) == 1 and len(route) > 1:
        cut.append(route[1])
    return cut


def _belief_distance(known: BoolGrid, start: Position, goal: Position, movement: int) -> float:
    free = np.array(known, dtype=bool)
    for x, y in (start, goal):
        free[y, x] = False
    length = optimal_length(free, start, goal, movement=movement)
    if length is None:  # the robot's map walls the goal off: fall back on the prior map
        length = optimal_length(np.zeros_like(free), start, goal, movement=movement)
    assert length is not None
    return float(length)


def run_task(
    task: NavigationTask,
    compiled: CompiledProgram,
    trace: PlanTrace,
    *,
    policy: str = "monitored",
    contract: float | None = None,
    clock: str = "work",
    max_frames: int = 200,
    obstacles: Sequence[MovingObstacle] = (),
    overcome: Any = None,
) -> TaskReport:
    """Run `task` under `policy` (`fixed` needs `contract`) and report what happened.

    `compiled` and `trace` come from `navigation_program`. Raises ValueError for an unknown
    policy, a missing contract, or a goal unreachable from the start.

    With moving `obstacles` (the situation "obstacle overcoming", `overcoming`), each phase in
    which the robot is on the map (waiting for the first plan at the start, executing a
    segment, standing at its end until the next plan is ready) is followed by
    `overcoming.follow` on the work clock of the task: the robot predicts arrivals along what
    it is about to do and, when a critical event arises, decides with `overcome` (default: the
    compiled `overcome-obstacle`, `overcoming_modules.schema_decider`), with the reflex
    `evade` as a fallback. Then the speed is the frame's speed throughout its segment (no
    intra-frame adjustments), and detours are searched on the true map near the robot.
    """
    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {', '.join(POLICIES)}, got {policy!r}")
    world = task.world
    truth = np.asarray(world.blocked, dtype=bool)
    best_length = optimal_length(truth, world.start, world.goal, movement=world.movement)
    if best_length is None:
        raise ValueError(f"the goal {world.goal} cannot be reached from the start {world.start}")
    profile = compiled.profile
    n_inputs = profile.n_inputs
    input_quality = (1.0,) * n_inputs if n_inputs else None
    expected = np.asarray(profile.expected(np.ones(n_inputs), profile.time)).reshape(-1)
    grid = profile.time[(profile.time > 0) & (expected > MIN_QUALITY)]
    if grid.size == 0:
        grid = profile.time[profile.time > 0]
    if policy == "fixed":
        if contract is None or not contract > 0:
            raise ValueError("the fixed policy needs a contract time > 0")
        contracts = np.array([float(contract)])
    elif policy == "min":
        contracts = grid[:1]
    elif policy == "max":
        contracts = grid[-1:]
    else:
        contracts = grid
    model = TaskModel(task)
    log = EventLog()
    chooser = Monitor(profile, model, model, grid=contracts, input_quality=input_quality)
    checker = Monitor(profile, model, model, grid=grid, input_quality=input_quality, log=log)
    speeds = list(task.speeds)

    run_clock = _make_clock(clock, compiled, task)

    def decide(
        now: float, position: Position, known: BoolGrid, step: float, current: float | None
    ) -> tuple[Any, FrameState]:
        remaining = _belief_distance(known, position, world.goal, world.movement)
        best = None
        for speed in speeds:
            state = FrameState(
                now, remaining, speed, step, current is None, current or 0.0, detour()
            )
            decision = chooser.choose_contract(state, now=now)
            if best is None or decision.expected_utility > best[0].expected_utility + 1e-12:
                best = (decision, state)
        assert best is not None
        decision, state = best
        log.record(
            now,
            "contract",
            {
                "contract": decision.contract,
                "speed": state.speed,
                "remaining": remaining,
                "expected_quality": decision.expected_quality,
                "expected_value": decision.expected_value,
                "expected_cost": decision.expected_cost,
                "expected_utility": decision.expected_utility,
            },
        )
        return decision, state

    def plan(
        position: Position, known: BoolGrid, contract_time: float, index: int
    ) -> dict[str, Any]:
        window = task.window(position)
        sensor = Sensor(
            truth,
            seed=task.seed * 7919 + index,
            window=window,
            known=known,
            movement=world.movement,
        )
        started = run_clock.now()
        trace.reset(started)
        result = compiled.run([position, world.goal, sensor], contract_time, run_clock)
        spent = run_clock.now() - started
        allocation = compiled.allocation_at(list(input_quality or ()), contract_time)
        domain = trace.domain[0] if trace.domain else None
        new_known = np.array(known, dtype=bool)
        if domain is not None and domain.value is not None:
            x0, y0, x1, y1 = window
            new_known[y0:y1, x0:x1] = np.asarray(domain.value.blocked)[y0:y1, x0:x1]
        sensing_quality = float(domain.quality) if domain is not None else 0.0
        return {
            "window": window,
            "plan": result.value,
            "quality": float(result.quality),
            "sensing_time": float(allocation[0]),
            "sensing_quality": sensing_quality,
            "known": new_known,
            "spent": spent,
            "trace": list(trace.qualities),
        }

    traffic = Traffic(world, obstacles) if obstacles else None
    counts = {"decisions": 0, "collisions": 0, "evasions": 0}
    if traffic is not None and overcome is None:
        from .overcoming_modules import schema_decider

        overcome = schema_decider()

    def among_obstacles(
        cells: Sequence[Position], start: float, speed: float, hold: float
    ) -> tuple[list[Position], float, tuple[tuple[str, tuple[Position, ...]], ...]]:
        """Follow `cells` from `start` at `speed`, then stand on the last until `hold`."""
        from .overcoming import _collisions, follow

        assert traffic is not None
        work = WorkClock()
        work.advance(start)
        plans: list[Plan] = []
        decisions: list[Any] = []
        if len(cells) > 1:
            part = follow(traffic, Plan(start, cells, speed), work, overcome, fallback=True)
            plans += part.plans
            decisions += part.decisions
            counts["evasions"] += len(part.evasions)
        if work.now() < hold - 1e-9:
            steps = max(1, math.ceil((hold - work.now()) * speed))
            standing = Plan(work.now(), [cells[-1]] * (steps + 1), steps / (hold - work.now()))
            part = follow(traffic, standing, work, overcome, fallback=True)
            plans += part.plans
            decisions += part.decisions
            counts["evasions"] += len(part.evasions)
        end = work.now()
        counts["decisions"] += len(decisions)
        counts["collisions"] += _collisions(traffic, plans, end)
        moved = _moved(plans, end) if plans else [cells[0]]
        assert moved[-1] == cells[-1]
        choices = tuple(
            (d.chosen, tuple(d.plan.cells)) for d in decisions if d.plan is not None and d.chosen
        )
        return moved, end, choices

    known = np.zeros_like(truth)
    position = world.start
    now = 0.0
    energy = 0.0
    route: list[Position] = [position]
    records: list[FrameRecord] = []
    step = float(task.radius)
    progress_per_frame: list[float] = []
    # The detour factor: cells walked over the cells the model predicted for that progress.
    walked, foreseen = [0.0], [0.0]

    def detour() -> float:
        return walked[0] / foreseen[0] if foreseen[0] > 0 else 1.0

    decision, state = decide(now, position, known, step, None)
    predicted = decision.expected_utility
    planned = plan(position, known, decision.contract, 0)
    planned_at = now
    now += decision.contract if clock == "work" else planned["spent"]
    if traffic is not None:  # the robot waits for its first plan at the start
        _, now, _ = among_obstacles([position], 0.0, state.speed, now)
    frame_contract, frame_decision, speed_index = (
        decision.contract,
        decision,
        speeds.index(state.speed),
    )

    while position != world.goal and len(records) < max_frames:
        index = len(records)
        known = planned["known"]
        plan_value = planned["plan"]
        executed = execute(
            plan_value if plan_value is not None else [position, world.goal],
            truth,
            movement=world.movement,
        )
        segment = _segment(executed.route, planned["window"])
        n_cells = route_length(segment)
        end = segment[-1]
        exec_start = now
        # The next frame's contract is chosen now, for the window around the segment's end.
        next_decision = next_state = next_plan = None
        adjustments: list[str] = []
        if end != world.goal:
            next_decision, next_state = decide(now, end, known, step, n_cells)
            speed_index = speeds.index(next_state.speed)
            next_plan = plan(end, known, next_decision.contract, index + 1)
        speed = speeds[speed_index]
        # Execution of this segment, replayed against the next frame's planning.
        t, done, frame_energy = 0.0, 0.0, 0.0
        choices: tuple[tuple[str, tuple[Position, ...]], ...] = ()
        frame_counts = dict(counts)
        if traffic is not None:
            hold = exec_start
            if next_decision is not None:
                assert next_plan is not None
                hold += next_decision.contract if clock == "work" else next_plan["spent"]
            segment, finished, choices = among_obstacles(segment, exec_start, speed, hold)
            n_cells = route_length(segment)
            done, t = n_cells, finished - exec_start
            frame_energy = float(task.energy(speed)) * n_cells
        if traffic is None and next_decision is not None and n_cells > 0:
            c = next_decision.contract
            for fraction in (0.25, 0.5, 0.75):
                checkpoint = fraction * c
                reach = done + (checkpoint - t) * speed
                if reach >= n_cells:
                    break
                frame_energy += float(task.energy(speed)) * (reach - done)
                done, t = reach, checkpoint
                assert next_plan is not None
                trace_q = _quality_at(next_plan["trace"], checkpoint)
                adjustment = checker.adjust(
                    checkpoint, trace_q, done / n_cells, c, now=exec_start + checkpoint
                )
                if adjustment is Adjustment.FASTER and speed_index < len(speeds) - 1:
                    speed_index += 1
                elif adjustment is Adjustment.SLOWER and speed_index > 0:
                    speed_index -= 1
                adjustments.append(str(adjustment))
                speed = speeds[speed_index]
        if traffic is None:
            t += (n_cells - done) / speed
            frame_energy += float(task.energy(speed)) * (n_cells - done)
        exec_time = t
        if next_decision is not None:
            assert next_plan is not None
            next_spent = next_decision.contract if clock == "work" else next_plan["spent"]
            frame_time = max(exec_time, next_spent)
        else:
            frame_time = exec_time
        energy += frame_energy
        route.extend(segment[1:])
        known = _touch(known, truth, segment)
        if next_plan is not None:
            next_plan["known"] = _touch(next_plan["known"], truth, segment)
        records.append(
            FrameRecord(
                index=index,
                start=planned_at,
                position=position,
                window=planned["window"],
                contract=frame_contract,
                expected_quality=frame_decision.expected_quality,
                plan_quality=planned["quality"],
                sensing_time=planned["sensing_time"],
                sensing_quality=planned["sensing_quality"],
                plan=plan_value,
                known=planned["known"],
                planned_at=planned_at,
                exec_start=exec_start,
                exec_end=exec_start + exec_time,
                frame_time=frame_time,
                speed=speed,
                route=tuple(segment),
                energy=energy,
                expected_completion=model.expected_completion(
                    state, frame_decision.contract, frame_decision.expected_quality
                ),
                expected_value=frame_decision.expected_value,
                adjustments=tuple(adjustments),
                obstacles=() if traffic is None else traffic.at(math.floor(exec_start + exec_time)),
                choices=choices,
                decisions=counts["decisions"] - frame_counts["decisions"],
                collisions=counts["collisions"] - frame_counts["collisions"],
            )
        )
        before = _belief_distance(known, position, world.goal, world.movement)
        after = _belief_distance(known, end, world.goal, world.movement) if end != world.goal else 0
        progress_per_frame.append(max(1.0, before - after))
        walked[0] += n_cells
        foreseen[0] += max(before - after, 1.0) / max(frame_decision.expected_quality, 0.5)
        step = float(np.mean(progress_per_frame))
        position = end
        if next_decision is None:
            now = exec_start + exec_time
            break
        planned_at = exec_start
        now = exec_start + frame_time
        assert next_plan is not None and next_state is not None
        planned = next_plan
        frame_contract, frame_decision, state = next_decision.contract, next_decision, next_state

    reached = position == world.goal
    value = float(np.asarray(task.value(now))) if reached else 0.0
    utility = value - energy
    best_utility, _ = optimal_utility(task, best_length)
    error = abs(utility - predicted) / abs(predicted) if predicted else math.inf
    ratio = utility / best_utility if best_utility else math.nan
    return TaskReport(
        seed=task.seed,
        size=int(truth.shape[1]),
        policy=policy if policy != "fixed" else f"fixed:{contracts[0]:g}",
        frames=len(records),
        completion_time=now,
        energy=energy,
        value=value,
        utility=utility,
        predicted_utility=predicted,
        prediction_error=error,
        optimal_utility=best_utility,
        utility_ratio=ratio,
        route_length=route_length(route),
        optimal_length=float(best_length),
        reached=reached,
        route=tuple(route),
        records=tuple(records),
        log=log,
        moving_obstacles=len(obstacles),
        decisions=counts["decisions"],
        collisions=counts["collisions"],
        evasions=counts["evasions"],
    )


def _moved(plans: Sequence[Plan], end: float) -> list[Position]:
    """The cells the robot moved through, following each plan from its start until the next
    one's (the last until `end`), without repeats of a cell it stood on."""
    cells: list[Position] = []
    for plan, following in zip(plans, [*plans[1:], None], strict=True):
        stop = end if following is None else following.start - 1e-9
        last = plan.index_at(stop) if stop >= plan.start else -1
        for cell in plan.cells[: last + 1]:
            if not cells or cells[-1] != cell:
                cells.append(cell)
    return cells


def _touch(known: BoolGrid, truth: BoolGrid, segment: Sequence[Position]) -> BoolGrid:
    """`known` plus the true state of the cells next to the route (what the robot bumped into
    while moving: its memory of obstacles, whatever vision was given)."""
    out = np.array(known, dtype=bool)
    h, w = truth.shape
    for x, y in segment:
        y0, y1, x0, x1 = max(0, y - 1), min(h, y + 2), max(0, x - 1), min(w, x + 2)
        out[y0:y1, x0:x1] = truth[y0:y1, x0:x1]
    return out


def _quality_at(trace: Sequence[tuple[float, float]], elapsed: float) -> float:
    best = 0.0
    for t, q in trace:
        if t <= elapsed + 1e-9:
            best = q
    return min(1.0, max(0.0, best))


def _make_clock(kind: str, compiled: CompiledProgram, task: NavigationTask) -> Clock:
    if kind == "work":
        return WorkClock()
    if kind != "wall":
        raise ValueError(f"clock must be 'work' or 'wall', got {kind!r}")
    # Calibrate: ticks per second of the program on this machine, from one run.
    sensor = Sensor(np.asarray(task.world.blocked), seed=task.seed, movement=task.world.movement)
    work = WorkClock()
    started = _time.perf_counter()
    total = float(compiled.profile.time[-1])
    compiled.run([task.world.start, task.world.goal, sensor], total, work)
    seconds = max(_time.perf_counter() - started, 1e-6)
    return WallTicks(work.now() / seconds)
