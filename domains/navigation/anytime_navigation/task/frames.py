"""Running a navigation task frame by frame (see `model` for the task, the monitor's model and
the quantities reported): each frame senses and plans with the compiled frame program
(`frame_program`) under the contract the policy chooses, then executes the plan up to the
sensor window's edge while the next frame's planning overlaps; with moving obstacles, the
robot decides how to overcome them within the time stock they leave (`overcoming`).

What the robot knows: its map is vision's best reading of each cell it sensed (the reading of
the longest vision time; a frame whose contract leaves vision no time to read, under `T_A`,
keeps the map as it was, and a poorer reading does not replace a better one: with a window's
reading replaced by the prior, a robot whose contract dropped to 200 ticks planned through a
wall it had read clearly the frame before) and the prior (every cell free) elsewhere, except
the cells next to those it stood on, whose true state it saw as it moved: vision's later
readings, with their errors, do not overwrite them,
and obstacle avoidance keeps the blocked ones among them from frame to frame (`execute`'s
memory). With a memory begun afresh each frame, a robot whose plan led behind an obstacle felt
its way into the same dead end frame after frame and walked several times the shortest
route. Where a frame's plan runs through cells blocked on the map it was made on, obstacle
avoidance plans its detours on the robot's map (`PENALTY`) rather than assuming free every
cell it has not bumped into."""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from attrs import define, frozen
from attrs import evolve as replace

from anytime import Budget, CompiledProgram, OptimalStopping, StoppingPolicy, run_program
from anytime.plugin import Clock, Unit, WorkClock
from anytime.plugin.compose import Adjustment, EventLog, Monitor, VisionHyperbola

from ..obstacles.moving import MovingObstacle, Plan, Traffic
from ..world import BoolGrid, Position
from .calibration import shipped
from .execution import execute, optimal_length, route_length
from .frame_program import PlanTrace
from .model import (
    MIN_QUALITY,
    POLICIES,
    FirstDecision,
    FrameRecord,
    FrameState,
    FromPlannerStart,
    NavigationTask,
    TaskModel,
    TaskReport,
    optimal_utility,
)
from .vision import Q_A, T_A, T_B, Sensor

__all__ = ["NO_DYNAMIC_PROFILE", "WallTicks", "run_task"]

#: Why the `stopping` policy cannot run.
NO_DYNAMIC_PROFILE = (
    "the stopping policy needs the planner's dynamic profile (find-path.dynamic.yaml beside"
    " find-path.yaml; `anytime profile find-path --dynamic` measures it)"
)


#: `execute(give_up=)` in the frames: the plan a frame executes was made while the segment
#: before it was walked, on a map without what the robot saw there; a waypoint the way to which
#: has turned longer than this many times its distance is given up for the next one. On 100
#: validation worlds (seeds 2000-2099) under fixed contracts of 100 and 200 ticks the routes
#: were 0.018 and 0.021 (64 x 64) and 0.009 and 0.006 (128 x 128) of the shortest route
#: shorter than reaching every waypoint; from 300 ticks on within 0.001 (it seldom acts there).
GIVE_UP: float | None = 2.0

#: `execute(believed=, penalty=)` in the frames, for a plan that runs through cells its own map
#: says are blocked (`_crosses_its_map`): obstacle avoidance plans around the obstacles of the
#: robot's map, each cell of them costing this many cells more to cross than a free one,
#: rather than with the free-space assumption alone. 0: never. On 200 validation worlds (seeds
#: 2000-2199) it moved the mean route by at most 0.002 of the shortest under the monitor and
#: fixed contracts of 300, 400 and 600 ticks at 128 x 128, 300 and 400 at 64 x 64 (a few worlds
#: by 0.06-0.27 shorter: the plans that cross their own map are rare, 5 of 171 frames at 64 x 64).
PENALTY = 8.0


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
    on_frame: Callable[[int], object] | None = None,
    calibrated: bool = True,
) -> TaskReport:
    """Run `task` under `policy` (`fixed` needs `contract`) and report what happened.

    With `calibrated` (the default) and a calibration shipped for the task's size, sensor
    radius and movement (`calibration.shipped`), the monitor plans with the frame program's
    profile measured in the task (`TaskCalibration.profile`, its contracts the monitored
    policy's grid) and the measured first frame's progress; else with the compiled program's
    profile.

    `on_frame(n)`, if given, is called after each frame with the number of frames done (for a
    progress bar).

    `compiled` and `trace` come from `navigation_program`. Raises ValueError for an unknown
    policy, a missing contract, the `stopping` policy without the planner's dynamic profile,
    or a goal unreachable from the start.

    With moving `obstacles` (the situation "obstacle overcoming", `overcoming`), each phase in
    which the robot is on the map (waiting for the first plan at the start, executing a
    segment, standing at its end until the next plan is ready) is followed by
    `crossing.follow` on the work clock of the task: the robot predicts arrivals along what
    it is about to do and, when a critical event arises, decides with `overcome` (default: the
    compiled `overcome-obstacle`, `overcoming_modules.schema_decider`), with the reflex
    `evade` as a fallback. Then the speed is the frame's speed throughout its segment (no
    intra-frame adjustments), and detours are searched on the true map near the robot.
    """
    run = _TaskRun(task, compiled, trace, policy, contract, clock, obstacles, overcome, calibrated)
    return run.run(max_frames, on_frame)


Choices = tuple[tuple[str, tuple[Position, ...]], ...]


@frozen
class _Planned:
    """What one frame's sensing and planning gave: the sensor window, the plan and its quality,
    the sensing time and quality, the robot's map after sensing, the time the program took,
    the planner's quality trace (program time, quality), and the program time at which a
    stopping policy stopped the planner (None: it did not)."""

    window: tuple[int, int, int, int]
    plan: Any
    quality: float
    sensing_time: float
    sensing_quality: float
    known: BoolGrid
    spent: float
    trace: tuple[tuple[float, float], ...]
    stopped: float | None = None
    crosses: bool = False


@frozen
class _Counts:
    """Among moving obstacles: the decisions made, the ticks in collision, the reflex evasions."""

    decisions: int = 0
    collisions: int = 0
    evasions: int = 0

    def __add__(self, other: _Counts) -> _Counts:
        return _Counts(
            self.decisions + other.decisions,
            self.collisions + other.collisions,
            self.evasions + other.evasions,
        )


@define
class _Executed:
    """One frame's execution: the cells walked, its time and energy, the speed at its end, the
    intra-frame adjustments, the alternatives chosen around obstacles and what happened among
    them."""

    segment: list[Position]
    time: float
    energy: float
    speed: float
    adjustments: list[str]
    choices: Choices
    counts: _Counts = _Counts()


class _TaskRun:
    """One run of a task: the policy's contract grid, the monitors, the clock, the obstacles,
    and what the robot knows and has done so far."""

    def __init__(
        self,
        task: NavigationTask,
        compiled: CompiledProgram,
        trace: PlanTrace,
        policy: str,
        contract: float | None,
        clock: str,
        obstacles: Sequence[MovingObstacle],
        overcome: Any,
        calibrated: bool = True,
    ) -> None:
        if policy not in POLICIES:
            raise ValueError(f"policy must be one of {', '.join(POLICIES)}, got {policy!r}")
        self.task, self.compiled, self.trace = task, compiled, trace
        self.policy, self.clock_kind, self.obstacles = policy, clock, tuple(obstacles)
        world = self.world = task.world
        self.truth = np.asarray(world.blocked, dtype=bool)
        best = optimal_length(self.truth, world.start, world.goal, movement=world.movement)
        if best is None:
            raise ValueError(
                f"the goal {world.goal} cannot be reached from the start {world.start}"
            )
        self.best_length = best
        profile = compiled.profile
        side = int(self.truth.shape[1])
        calibration = (
            shipped(side, task.radius, world.movement)
            if calibrated and self.truth.shape[0] == side and not obstacles
            else None
        )
        n_inputs = profile.n_inputs
        self.input_quality = (1.0,) * n_inputs if n_inputs else None
        expected = np.asarray(profile.expected(np.ones(n_inputs), profile.time)).reshape(-1)
        grid = profile.time[(profile.time > 0) & (expected > MIN_QUALITY)]
        if grid.size == 0:
            grid = profile.time[profile.time > 0]
        if policy == "fixed":
            if contract is None or not contract > 0:
                raise ValueError("the fixed policy needs a contract time > 0")
            self.contracts = np.array([float(contract)])
        elif policy == "min":
            self.contracts = grid[:1]
        elif policy == "max":
            self.contracts = grid[-1:]
        elif calibration is not None:
            self.contracts = np.asarray(calibration.contracts)
        else:
            self.contracts = grid
        # The profile the monitor plans with: what a contract buys in the task when measured
        # there, else the compiled program's (the planner on a whole map sensed at once).
        planning = profile if calibration is None else calibration.profile()
        self.model = TaskModel(
            task,
            planning,
            # A route's quality as measured in the task is what the robot walked: no floor.
            floor=0.5 if calibration is None else MIN_QUALITY,
            progress=1.0 if calibration is None else calibration.progress_ratio,
            route_quality=calibration is not None,
            # the monitor chooses every frame's contract; the baselines keep theirs
            later=self.contracts if policy in ("monitored", "stopping") else None,
            first=None if calibration is None else calibration.first_frame(),
        )
        self.calibration = calibration
        if policy == "stopping" and trace.dynamic is None:
            raise ValueError(NO_DYNAMIC_PROFILE)
        self.log = EventLog()
        self.chooser = Monitor(
            planning,
            self.model,
            self.model,
            grid=self.contracts,
            input_quality=None if calibration is not None else self.input_quality,
        )
        self.checker = Monitor(
            profile,
            self.model,
            self.model,
            grid=grid,
            input_quality=self.input_quality,
            log=self.log,
        )
        self.speeds = list(task.speeds)
        self.run_clock = _make_clock(clock, compiled, task)
        self.traffic = Traffic(world, self.obstacles) if self.obstacles else None
        if self.traffic is not None and overcome is None:
            from ..obstacles.overcoming_modules import schema_decider

            overcome = schema_decider()
        self.overcome = overcome
        # What the monitor learns frame by frame: the progress per frame, and the detour factor
        # (cells walked over the cells the model predicted for that progress), which starts at
        # 1 with the weight of the start-to-goal distance on the prior map, so that one frame's
        # detour moves it by its share of the route, not to that frame's own ratio.
        self.progress: list[float] = []
        prior = _belief_distance(np.zeros_like(self.truth), world.start, world.goal, world.movement)
        self.walked = self.foreseen = prior
        self.predictions: list[float] = []  # the whole task's utility, one per decision
        # The cells whose true state the robot knows for certain: those around the cells it
        # stood on (it sees its eight neighbours as it moves, `execution`).
        self.touched = np.zeros_like(self.truth)
        # The model quality of the reading each cell of the robot's map holds (0: the prior).
        self.reading = np.zeros(self.truth.shape)

    # --- one frame's steps ----------------------------------------------------------------

    def detour(self) -> float:
        return self.walked / self.foreseen if self.foreseen > 0 else 1.0  # start on the goal

    def step(self, position: Position) -> float:
        """The progress expected of a frame planned from `position`: the mean of the frames
        so far, `TaskModel.first_step` before any."""
        return float(np.mean(self.progress)) if self.progress else self.model.first_step(position)

    def decide(
        self,
        now: float,
        position: Position,
        known: BoolGrid,
        current: float | None,
        spent: float = 0.0,
    ) -> tuple[Any, FrameState]:
        """The contract and speed of highest expected utility for the plan made from
        `position` (`current`: the length of the segment executed meanwhile; None: the robot
        waits for this plan), logged as a "contract" event with the utility of the whole task
        it predicts: `spent` (the energy of the frames before the current segment) taken
        from the expected utility of the rest."""
        world = self.world
        remaining = _belief_distance(known, position, world.goal, world.movement)
        best = None
        for speed in self.speeds:
            state = FrameState(
                now,
                remaining,
                speed,
                self.step(position),
                current is None,
                current or 0.0,
                self.detour(),
            )
            decision = self.choose(state, now)
            if best is None or decision.expected_utility > best[0].expected_utility + 1e-12:
                best = (decision, state)
        assert best is not None
        decision, state = best
        self.log.record(
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
                "predicted_utility": self.prediction(state, decision) - spent,
            },
        )
        self.predictions.append(self.prediction(state, decision) - spent)
        return decision, state

    def prediction(self, state: FrameState, decision: Any) -> float:
        """The utility of the rest of the task the monitor predicts for `decision` in `state`:
        with a calibration, the median of its model's distribution (over the training worlds
        for the first frame, over the route qualities of the profile later), the point of least
        expected absolute error; the contract is chosen on the expected utility. Without one,
        the expected utility."""
        if isinstance(decision, FirstDecision):
            return decision.median_utility
        if self.calibration is None:
            return float(decision.expected_utility)
        return self.model.median_utility(state, decision.contract)

    def choose(self, state: FrameState, now: float) -> Any:
        """The contract of highest expected utility in `state`: the first frame's from the
        first frames measured in the task where they were (`TaskModel.first_choice`), else
        the monitor's over the profile it plans with."""
        first = self.model.first_choice(state, self.contracts)
        return first if first is not None else self.chooser.choose_contract(state, now=now)

    def expected_completion(self, state: FrameState, decision: Any) -> float:
        """When the monitor expected the task to end when it made `decision` in `state`."""
        if isinstance(decision, FirstDecision):
            return decision.expected_completion
        return self.model.expected_completion(state, decision.contract, decision.expected_quality)

    def stopper(self, state: FrameState, quality: float, began: float) -> StoppingPolicy:
        """The planner's stopping policy in the frame the monitor chose `state` for, given a
        map of `quality` and starting at program time `began`: optimal stopping over its
        dynamic profile, with the task model's utility (`FromPlannerStart`)."""
        # The policy's quality is its plan's, which stretches its own frame (`TaskModel`).
        shifted = FromPlannerStart(replace(self.model, route_quality=False), began)
        dynamic = self.trace.dynamic
        return OptimalStopping(dynamic, shifted, shifted, state, input_quality=(quality,))

    def plan(
        self,
        position: Position,
        known: BoolGrid,
        decision: Any,
        state: FrameState,
        index: int,
    ) -> _Planned:
        """Sense the window around `position` and plan from it with the compiled program
        under `decision`'s contract (with the `stopping` policy, the planner under a stopping
        policy for `state`: its decisions go to the event log, at task times from
        `state.now`, with the frame's index)."""
        task, world = self.task, self.world
        contract = decision.contract
        window = task.window(position)
        allocation = self.compiled.allocation_at(list(self.input_quality or ()), contract)
        # Vision given less than its first reading's time reads nothing: the robot falls back on
        # what it knows of the window (its prior there is its map, not every cell free).
        reads = bool(allocation[0] >= T_A)
        x0, y0 = window[:2]
        sensor = Sensor(
            self.truth,
            seed=task.seed * 7919 + index,
            window=window if reads else (x0, y0, x0, y0),
            known=known,
            movement=world.movement,
        )
        started = self.run_clock.now()
        self.trace.reset(self.run_clock)
        if self.policy == "stopping":
            self.trace.stop_with(lambda quality, began: self.stopper(state, quality, began))
        inputs = [position, world.goal, sensor]
        try:
            ran = run_program(
                self.compiled,
                inputs,
                Budget(contract, clock=self.run_clock),
                observers={"find-path": self.trace},
            )
        finally:
            self.trace.stop_with(None)
        spent = self.run_clock.now() - started
        for event in self.trace.decisions:
            self.log.record(state.now + event.time, event.kind, {**event.data, "frame": index})
        result = ran.result
        domain = next((r.result for r in ran.records if r.module == "get-domain-description"), None)
        new_known = np.array(known, dtype=bool)
        if reads and domain is not None and domain.value is not None:
            # The robot keeps each cell's better reading: a short contract's poorer one (more
            # errors) does not replace what a longer one read there before.
            x0, y0, x1, y1 = window
            quality = float(VisionHyperbola(T_A, Q_A, T_B)(float(allocation[0])))
            better = self.reading[y0:y1, x0:x1] <= quality
            new_known[y0:y1, x0:x1][better] = np.asarray(domain.value.blocked)[y0:y1, x0:x1][better]
            self.reading[y0:y1, x0:x1][better] = quality
        # What the robot saw around itself is certain: vision's reading of the window (noisy)
        # does not overwrite it in the robot's map.
        new_known[self.touched] = self.truth[self.touched]
        return _Planned(
            window=window,
            plan=result.value if result is not None else None,  # None: no plan this frame
            quality=float(result.quality) if result is not None else 0.0,
            sensing_time=float(allocation[0]),
            sensing_quality=float(domain.quality) if domain is not None else 0.0,
            known=new_known,
            spent=spent,
            trace=tuple(self.trace.qualities),
            stopped=self.trace.stopped,
            crosses=domain is not None
            and result is not None
            and _crosses_its_map(result.value, domain.value.blocked, position, world.goal),
        )

    def planning_time(self, decision: Any, planned: _Planned) -> float:
        """How long a frame's planning takes: its contract (work clock; up to where a stopping
        policy stopped it) or the time it took."""
        if self.clock_kind != "work":
            return planned.spent
        return float(decision.contract) if planned.stopped is None else planned.stopped

    def among_obstacles(
        self, cells: Sequence[Position], start: float, speed: float, hold: float
    ) -> tuple[list[Position], float, Choices, _Counts]:
        """Follow `cells` from `start` at `speed`, then stand on the last until `hold`, deciding
        around the obstacles on the way: the cells moved through, the time at the end, the
        alternatives chosen, and the decisions, collisions and evasions."""
        from ..obstacles.crossing import collisions, follow

        assert self.traffic is not None
        traffic = self.traffic
        work = WorkClock()
        work.advance(start)
        plans: list[Plan] = []
        decisions: list[Any] = []
        evasions = 0
        if len(cells) > 1:
            part = follow(traffic, Plan(start, cells, speed), work, self.overcome, fallback=True)
            plans += part.plans
            decisions += part.decisions
            evasions += len(part.evasions)
        if work.now() < hold - 1e-9:
            steps = max(1, math.ceil((hold - work.now()) * speed))
            standing = Plan(work.now(), [cells[-1]] * (steps + 1), steps / (hold - work.now()))
            part = follow(traffic, standing, work, self.overcome, fallback=True)
            plans += part.plans
            decisions += part.decisions
            evasions += len(part.evasions)
        end = work.now()
        counts = _Counts(len(decisions), collisions(traffic, plans, end), evasions)
        moved = _moved(plans, end) if plans else [cells[0]]
        assert moved[-1] == cells[-1]
        choices = tuple(
            (d.chosen, tuple(d.plan.cells)) for d in decisions if d.plan is not None and d.chosen
        )
        return moved, end, choices, counts

    def execute_segment(
        self,
        segment: list[Position],
        start: float,
        speed_index: int,
        following: tuple[Any, _Planned] | None,
        state: FrameState | None = None,
    ) -> tuple[_Executed, int]:
        """Walk `segment` from time `start` while the next frame plans (`following`: its
        decision and planning, `state` the monitor's state when it chose them; None at the
        last frame). Without obstacles the intra-frame rule is checked at a quarter, half and
        three quarters of the next contract against the planner's quality so far, and the
        speed moves one step when the rule says so and the task model expects the move to pay
        (`pays`); with obstacles the speed is kept and the robot decides around them
        (`among_obstacles`)."""
        task, speeds = self.task, self.speeds
        speed = speeds[speed_index]
        n_cells = route_length(segment)
        if self.traffic is not None:
            hold = start
            if following is not None:
                hold += self.planning_time(*following)
            walked, finished, choices, counts = self.among_obstacles(segment, start, speed, hold)
            length = route_length(walked)
            energy = float(task.energy(speed)) * length
            executed = _Executed(walked, finished - start, energy, speed, [], choices, counts)
            return executed, speed_index
        t, done, energy = 0.0, 0.0, 0.0
        adjustments: list[str] = []
        if following is not None and n_cells > 0:
            decision, planned = following
            c = decision.contract
            for fraction in (0.25, 0.5, 0.75):
                checkpoint = fraction * c
                reach = done + (checkpoint - t) * speed
                if reach >= n_cells:
                    break
                energy += float(task.energy(speed)) * (reach - done)
                done, t = reach, checkpoint
                quality = _quality_at(planned.trace, checkpoint)
                adjustment = self.checker.adjust(
                    checkpoint, quality, done / n_cells, c, now=start + checkpoint
                )
                proposed = speed_index
                if adjustment is Adjustment.FASTER and speed_index < len(speeds) - 1:
                    proposed += 1
                elif adjustment is Adjustment.SLOWER and speed_index > 0:
                    proposed -= 1
                said = str(adjustment)
                if proposed != speed_index and state is not None:
                    at = replace(state, now=start + checkpoint, current=n_cells - done)
                    if self.pays(at, checkpoint, decision, quality, speeds[proposed]):
                        speed_index = proposed
                    else:
                        said += " declined"  # the model expects the move not to pay
                adjustments.append(said)
                speed = speeds[speed_index]
        t += (n_cells - done) / speed
        energy += float(task.energy(speed)) * (n_cells - done)
        return _Executed(segment, t, energy, speed, adjustments, ()), speed_index

    def pays(
        self, state: FrameState, elapsed: float, decision: Any, reached: float, speed: float
    ) -> bool:
        """Whether the task model expects the rest of the task to be worth more at `speed`
        than at the state's, `elapsed` into the contract of `decision`, the plan being made
        having `reached` its quality so far (it is taken at the better of that and the
        contract's expected quality: the planner answers with its best plan)."""
        c, q = decision.contract, decision.expected_quality
        if not self.model.route_quality:  # the quality is the plan's, and it is its best
            q = max(q, reached)
        now = replace(state, elapsed=elapsed)
        return self.model.utility(replace(now, speed=speed), c, q) > self.model.utility(now, c, q)

    def learn(
        self, known: BoolGrid, start: Position, end: Position, walked: float, contract: float
    ) -> None:
        """After a frame from `start` to `end`: the progress it made on the robot's map, and the
        cells it walked against what the model predicted for that progress (its stretch at the
        frame's contract, `TaskModel.later_factor`)."""
        world = self.world
        before = _belief_distance(known, start, world.goal, world.movement)
        after = _belief_distance(known, end, world.goal, world.movement) if end != world.goal else 0
        self.progress.append(max(1.0, before - after))
        self.walked += walked
        stretch = float(self.model.later_factor(np.asarray(contract)))
        self.foreseen += max(before - after, 1.0) * stretch

    # --- the task ------------------------------------------------------------------------

    def run(self, max_frames: int, on_frame: Callable[[int], object] | None = None) -> TaskReport:
        world, truth = self.world, self.truth
        counts = _Counts()  # the whole task's, among moving obstacles
        known = np.zeros_like(truth)
        position = world.start
        now = energy = 0.0
        route: list[Position] = [position]
        records: list[FrameRecord] = []

        decision, state = self.decide(now, position, known, None)
        predicted = self.predictions[0]
        planned = self.plan(position, known, decision, state, 0)
        planned_at = now
        now += self.planning_time(decision, planned)
        if self.traffic is not None:  # the robot waits for its first plan at the start
            _, now, _, waited = self.among_obstacles([position], 0.0, state.speed, now)
            counts += waited
        speed_index = self.speeds.index(state.speed)

        while position != world.goal and len(records) < max_frames:
            index = len(records)
            known = planned.known
            # Obstacle avoidance remembers the blocked cells the robot has seen in every frame
            # so far (a fresh memory each frame let it feel its way into the same dead end
            # frame after frame); the copy keeps what it would see beyond the segment out.
            executed = execute(
                planned.plan if planned.plan is not None else [position, world.goal],
                truth,
                movement=world.movement,
                memory=truth & self.touched,
                give_up=GIVE_UP,
                believed=known if planned.crosses else None,
                penalty=PENALTY,
            )
            segment = _segment(executed.route, planned.window)
            end = segment[-1]
            exec_start = now
            # The next frame's contract is chosen now, for the window around the segment's end.
            following = None
            next_state = None
            if end != world.goal:
                next_decision, next_state = self.decide(
                    now, end, known, route_length(segment), energy
                )
                speed_index = self.speeds.index(next_state.speed)
                next_planned = self.plan(end, known, next_decision, next_state, index + 1)
                following = (next_decision, next_planned)
            else:  # the last segment: no planning to wait for, the speed is the model's
                speed_index = self.speeds.index(self.model.last_speed(now, route_length(segment)))
            done, speed_index = self.execute_segment(
                segment, exec_start, speed_index, following, next_state
            )
            segment = done.segment
            frame_time = done.time
            if following is not None:
                frame_time = max(done.time, self.planning_time(*following))
            energy += done.energy
            counts += done.counts
            route.extend(segment[1:])
            known = _touch(known, truth, segment)
            self.touched |= _near(segment, truth.shape)
            records.append(
                FrameRecord(
                    index=index,
                    start=planned_at,
                    position=position,
                    window=planned.window,
                    contract=decision.contract,
                    expected_quality=decision.expected_quality,
                    plan_quality=planned.quality,
                    sensing_time=planned.sensing_time,
                    sensing_quality=planned.sensing_quality,
                    plan=planned.plan,
                    known=planned.known,
                    planned_at=planned_at,
                    exec_start=exec_start,
                    exec_end=exec_start + done.time,
                    frame_time=frame_time,
                    speed=done.speed,
                    route=tuple(segment),
                    energy=energy,
                    expected_completion=self.expected_completion(state, decision),
                    expected_value=decision.expected_value,
                    adjustments=tuple(done.adjustments),
                    obstacles=()
                    if self.traffic is None
                    else self.traffic.at(math.floor(exec_start + done.time)),
                    choices=done.choices,
                    decisions=done.counts.decisions,
                    collisions=done.counts.collisions,
                    predicted_utility=self.predictions[index],
                    stopped_at=planned.stopped,
                )
            )
            self.learn(known, position, end, route_length(segment), decision.contract)
            position = end
            if on_frame is not None:
                on_frame(len(records))
            if following is None:
                now = exec_start + done.time
                break
            planned_at = exec_start
            now = exec_start + frame_time
            decision, planned = following
            assert next_state is not None
            state = next_state
            planned = replace(planned, known=_touch(planned.known, truth, segment))

        return self.report(position, now, energy, route, records, predicted, counts)

    def report(
        self,
        position: Position,
        now: float,
        energy: float,
        route: list[Position],
        records: list[FrameRecord],
        predicted: float,
        counts: _Counts,
    ) -> TaskReport:
        task = self.task
        reached = position == self.world.goal
        value = float(np.asarray(task.value(now))) if reached else 0.0
        utility = value - energy
        best_utility, _ = optimal_utility(task, self.best_length)
        error = abs(utility - predicted) / abs(predicted) if predicted else math.inf
        ratio = utility / best_utility if best_utility else math.nan
        return TaskReport(
            seed=task.seed,
            size=int(self.truth.shape[1]),
            policy=self.policy if self.policy != "fixed" else f"fixed:{self.contracts[0]:g}",
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
            optimal_length=float(self.best_length),
            reached=reached,
            route=tuple(route),
            records=tuple(records),
            log=self.log,
            moving_obstacles=len(self.obstacles),
            decisions=counts.decisions,
            collisions=counts.collisions,
            evasions=counts.evasions,
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
    near = _near(segment, truth.shape)
    out[near] = np.asarray(truth, dtype=bool)[near]
    return out


def _near(segment: Sequence[Position], shape: tuple[int, ...]) -> BoolGrid:
    """The cells within one move (8 neighbours) of a cell of `segment`: what the robot saw
    around itself while moving along it."""
    out = np.zeros(shape, dtype=bool)
    h, w = shape
    for x, y in segment:
        out[max(0, y - 1) : min(h, y + 2), max(0, x - 1) : min(w, x + 2)] = True
    return out


def _crosses_its_map(plan: Any, blocked: BoolGrid, start: Position, goal: Position) -> bool:
    """Whether a plan's base cells run through cells blocked on the map it was made on (its
    start and goal aside, which the planner takes as free): where that map walls the goal off,
    the planner opens the walls in the way and plans across them (its quality below 1, `atp`),
    and a robot feeling its way past the obstacle with the free-space assumption alone may go
    round the wrong side."""
    if plan is None or not hasattr(plan, "parts"):
        return False
    cells = np.array(
        [c for s in plan.parts if s.level == 0 for c in s.cells if c != start and c != goal],
        dtype=np.int64,
    ).reshape(-1, 2)
    return bool(np.asarray(blocked, dtype=bool)[cells[:, 1], cells[:, 0]].any())


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
    run_program(compiled, [task.world.start, task.world.goal, sensor], Budget(total, clock=work))
    seconds = max(_time.perf_counter() - started, 1e-6)
    return WallTicks(work.now() / seconds)
