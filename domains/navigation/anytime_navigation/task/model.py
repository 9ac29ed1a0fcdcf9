"""The navigation task: a robot covers a route frame by frame under a monitor (Zilberstein &
Russell, "The run-time system"). This module defines the task, the monitor's environment model
and what a run reports; `frames.run_task` runs it, with the frame program of `frame_program`.

The robot senses only a square window of radius `radius` around itself, so it reaches the goal
in *frames*. In each frame the compiled program `schemas/navigation.any` (`navigate`: sense,
then plan) is run by the runtime executor under a contract time chosen by a *policy*, and the
robot then follows its plan on the true map (`execution.execute`) up to the edge of the window,
at a speed taken from a grid. Planning for the next frame overlaps that execution (the sensor
looks around the point where the current segment ends, which the robot knows in advance), so a
frame lasts `max(next contract, execution time)`; the first frame's planning is not overlapped
(the robot waits). While a frame runs, the monitor's intra-frame rule (`Monitor.adjust`) is
checked at a quarter, half and three quarters of the contract, against the plan quality the
planner had actually reached by then; when it asks for a speed one step up or down the grid,
the speed moves if `TaskModel` expects the rest of the task to be worth more at it. The last
segment (no plan to wait for) goes at `TaskModel.last_speed`.

Time is in ticks of the work clock (or, with a wall clock, in tick-equivalents measured with a
calibrated rate). Quantities:

- completion time `T`: when the robot stands on the goal;
- value `V(T)`: a pluggable function of completion time; by default `DeadlineValue` (full
  value until a deadline, then a linear decay);
- energy `E = sum over cells moved of energy_per_cell(speed)`, with
  `energy_per_cell(v) = e0 * (1 + (v / v0)^2)` (`QuadraticEnergy`; pluggable): faster costs
  more per cell;
- utility `U = V(T) - E`.

The profile the monitor plans with: where a calibration is shipped for the task's size and
sensor radius (`calibration`: 64 x 64 and 128 x 128, radius a quarter of the side), the frame
program's profile measured in the task (the route's quality per contract on training worlds),
else the compiled program's (the planner's plan quality on a whole map sensed at once, which
the task's windowed sensing and re-planning do not reach).

Policies: `monitored` (the monitor's inter-frame rule: contract and speed of highest expected
utility, see `TaskModel`; its contracts are the calibration's grid; the first frame's, for which
the robot waits, from the first frames measured in the task, `TaskModel.first_choice`), `fixed`
(a given contract every frame; the speed as the monitor would choose for it), `min` and `max`
(the smallest and largest contract of the compiled program's grid, the papers' MIN/MAX
baselines), and `stopping`: the monitor's contract and speed as `monitored`, the contract an
upper bound only: within the frame the planner is run under an `OptimalStopping` policy (Hansen
& Zilberstein 2001) over its dynamic profile (`find-path.dynamic.yaml`), whose utility of
stopping `t` into the planner's run with plan quality `q` is the `TaskModel`'s value minus cost
of the rest of the task with the frame's program ending at sensing time + `t`
(`FromPlannerStart`), the robot moving meanwhile as in `TaskModel`; the frame's planning then
lasts until the policy stops it.

Two references:

- `predicted_utility`: the utility of the whole task that the monitor predicts when the task
  is presented, at its first inter-frame decision: the contract and speed of highest
  E_q[V(T_hat) - E_hat] over the contract grid and the speed grid, where the expectation is
  over the output quality distribution at the contract of the profile the monitor plans with,
  and `T_hat`, `E_hat` come from the environment model `TaskModel` with the remaining
  distance the shortest route on the prior map (nothing known: every cell free, i.e. the
  Manhattan distance for 4-connected movement). Where the calibration measured the first frame
  apart (`TaskModel.first_choice`), the distribution is over the training worlds instead: the
  first frame's route and the later frames' stretch of the rest, world by world. Without a
  calibration the prediction is that expected utility; with one, the median of the same
  distribution at the chosen contract (`FirstDecision.median_utility`,
  `TaskModel.median_utility`): the point of least expected absolute error, which is what
  `prediction_error` measures (a few worlds in which the robot wanders pull the mean below
  what most worlds realise: on 200 validation worlds, seeds 2000-2199, the mean error was
  1.56% and 2.03% at 64 x 64 and 128 x 128 with the expected utility, 1.18% and 1.78% with
  the median).
- `optimal_utility`: a clairvoyant bound on the same world: the true map known, no sensing or
  planning time, a shortest route `L*`, at the best constant speed of the grid:
  `max_v V(L* / v) - energy_per_cell(v) * L*`.

and `prediction_error = |U - predicted_utility| / |predicted_utility|`,
`utility_ratio = U / optimal_utility`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from attrs import Factory, field, frozen

from anytime.plugin import ConditionalPerformanceProfile
from anytime.plugin.compose import Array, DeadlineValue, EventLog

from ..obstacles.moving import MovingObstacle
from ..world import BoolGrid, Position, World

__all__ = [
    "POLICIES",
    "EnergyModel",
    "FirstDecision",
    "FirstFrame",
    "FromPlannerStart",
    "FrameRecord",
    "FrameState",
    "NavigationTask",
    "QuadraticEnergy",
    "TaskModel",
    "TaskReport",
    "optimal_utility",
    "weighted_median",
]

POLICIES = ("monitored", "fixed", "min", "max", "stopping")

#: The schema file of the papers' program.

#: Plan qualities below this count as this in the environment model (no division by 0).
MIN_QUALITY = 0.05


class EnergyModel(Protocol):
    def __call__(self, speed: Any) -> Any:
        """Energy per cell moved at `speed` (cells per tick); works on arrays."""
        ...


@frozen
class QuadraticEnergy:
    """`energy_per_cell(v) = e0 * (1 + (v / v0)^2)`: a base cost plus a cost of going fast."""

    e0: float = 1.0
    v0: float = 0.2

    def __call__(self, speed: Any) -> Any:
        return self.e0 * (1.0 + (np.asarray(speed, dtype=np.float64) / self.v0) ** 2)


@frozen
class NavigationTask:
    """One task: a world, the sensor's reach, the speeds, the value and the energy.

    Attributes:
        world: the true map, start, goal and movement.
        radius: the sensor sees the cells within `radius` (Chebyshev) of the robot.
        speeds: the speed grid, cells per tick, increasing.
        value: the value of completion time (a callable on arrays).
        energy: energy per cell as a function of speed.
        seed: fixes vision's errors (frame i uses seed * 7919 + i).
    """

    world: World
    radius: int = 32
    speeds: tuple[float, ...] = field(default=(0.05, 0.1, 0.15, 0.2), converter=tuple)
    value: Callable[[Any], Any] = DeadlineValue(1000.0, 6000.0, 0.25)
    energy: EnergyModel = QuadraticEnergy()
    seed: int = 0

    def window(self, position: Position) -> tuple[int, int, int, int]:
        """The half-open box (x0, y0, x1, y1) the sensor sees from `position`."""
        h, w = self.world.blocked.shape
        x, y = position
        r = self.radius
        return (max(0, x - r), max(0, y - r), min(w, x + r + 1), min(h, y + r + 1))


# --- the environment model the monitor plans with ------------------------------------------------


@frozen
class FrameState:
    """What the monitor knows when it chooses a contract: the time now, the remaining distance
    from where the plan will start (shortest route on the robot's map), the speed considered,
    the progress in remaining distance expected per frame, either that the robot waits for
    this plan (the first frame) or the length of the segment it executes meanwhile (what is
    left of it, at an intra-frame check), the detour factor learned so far (see `TaskModel`),
    and how much of the plan's contract has already run (at an intra-frame check; 0 when the
    contract is being chosen)."""

    now: float
    remaining: float
    speed: float
    step: float
    waiting: bool
    current: float = 0.0
    detour: float = 1.0
    elapsed: float = 0.0


def _later_route_factor(profile: ConditionalPerformanceProfile | None, floor: float) -> Array:
    """E[1 / max(q, floor)] over the profile's output quality at each time of its grid (bins at
    the qualities the monitor evaluates them at: midpoints shifted to the exact means)."""
    if profile is None:
        return np.zeros(0)
    times = profile.time
    inputs = np.ones((times.size, profile.n_inputs))
    dist = profile.distribution(inputs, times)
    shift = profile.expected(inputs, times) - dist @ profile.values
    quality = np.clip(profile.values[None, :] + shift[:, None], 0.0, 1.0)
    factor: Array = np.einsum("gk,gk->g", dist, 1.0 / np.maximum(quality, floor))
    return factor


def _contracts(value: Any) -> tuple[float, ...] | None:
    return None if value is None else tuple(float(c) for c in value)


@frozen
class FirstFrame:
    """The first frame apart from the later ones, measured on training worlds
    (`calibration`): per contract of `contracts` (rows) and per world (columns), the cells the
    first frame walked, the distance left after it on the robot's map as a fraction of the
    distance at the start, and how much the later frames, at that contract each, stretched the
    rest of the route (the cells walked after the first frame over that distance left). Every
    contract ran on the same worlds, so a column is one world: a world whose later frames
    wander at one contract wanders at the others."""

    contracts: Array
    walked: Array
    left: Array
    stretch: Array

    def rows(self, contracts: Array) -> np.ndarray[Any, np.dtype[np.intp]] | None:
        """The row of each of `contracts` (None: one of them was not measured)."""
        c = np.asarray(contracts, dtype=np.float64).reshape(-1)
        rows = np.searchsorted(self.contracts, c)
        rows = np.clip(rows, 0, self.contracts.size - 1)
        if not np.allclose(self.contracts[rows], c):
            return None
        return rows


@frozen
class FirstDecision:
    """The first frame's contract (`TaskModel.first_choice`), with what the monitor expects of
    the whole task at it (over the training worlds) and the curves over the grid."""

    contract: float
    expected_quality: float
    expected_value: float
    expected_cost: float
    expected_utility: float
    expected_completion: float
    grid: Array
    utility_curve: Array
    #: The median over the training worlds of the whole task's utility at this contract: the
    #: prediction of least expected absolute error (the mean is pulled down by the few worlds
    #: in which the robot wanders).
    median_utility: float = math.nan


def weighted_median(values: Array, weights: Array) -> float:
    """The smallest of `values` at which the cumulative share of `weights` reaches one half:
    a point of least expected absolute error for a distribution of `values` with `weights`."""
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    keep = w > 0
    if not keep.any():
        raise ValueError("weighted_median needs a positive weight")
    v, w = v[keep], w[keep]
    order = np.argsort(v, kind="stable")
    share = np.cumsum(w[order]) / w.sum()
    return float(v[order][np.searchsorted(share, 0.5 - 1e-12)])


@frozen
class TaskModel:
    """The monitor's value and cost models for navigation.

    With `d` the remaining distance from where the plan starts (times the detour factor: what
    the frames so far walked per cell of progress, over what this model predicted for them,
    1 before any frame), `q` a quality of the profile's distribution at the contract `c` and
    `s = min(d, step)` (one frame's progress, stretched likewise), the route left is

    - a plan's quality (the compiled program's profile): `L = s / q + (d - s) * R(c)`: the
      plan being made covers one frame, and each later frame makes a plan of its own (assumed
      to get the same contract), so the rest of the route is stretched by the expected
      `R(c) = E[1 / q]` of the profile at `c`, not by this plan's `1 / q` (charging one plan's
      quality to the whole route made the monitor expect lateness from a poor first plan).
      Without a profile, `R(c)` is taken as `1 / q` (one plan for the whole route);
    - with `route_quality`, the whole route's quality as the task walks it (optimal length /
      route length, frame after frame: the profile of `calibration`):
      `L = (s + (d - s) * R(c_L) / R(c)) / q`, the later frames at the contract `c_L` of
      `later` (the monitor's grid: it chooses each frame's contract when the frame comes)
      that does best for this route, or `c_L = c` without `later` (a fixed contract). The
      expectation over `q` is then one of the value itself, which is not linear in the route
      (a route a little longer than the mean can make the robot late).

    The route makes `x = r / step` frames' progress (`r` the remaining distance, not stretched
    by the detour), so it takes `f = ceil(x)` frames: `f - 1` full ones of `e = L / (x u)`
    ticks each, each overlapped with the next frame's planning, and a last one of
    `e_1 = (x - f + 1) e`. Before that the robot either waits for the plan (first frame: `c`)
    or walks its current segment, `n` cells left, at the state's speed `v` meanwhile
    (`max(c - a, n / v)`, `a` the contract time already run), so

        T_hat = now + (c or max(c - a, n / v)) + (f - 1) * max(c_L, e) + e_1,
        E_hat = energy(v) * n + energy(u) * L,

    value `V(T_hat)`, cost `E_hat`. The robot chooses each frame's speed when the frame comes,
    knowing more of its route, so the plan's frames go at the `u` of highest utility for this
    route among the mixes of two neighbouring speeds of the grid (a share of the frames at
    each: energy is convex in the speed, so a mix arrives on time for less than the faster
    speed throughout; `energy(u)` is the mix's energy per cell, `1 / u` its ticks per cell).
    A plan of quality below `floor` is not taken at its word: the robot's obstacle avoidance
    still follows it toward the goal, so its part of the route is counted as if of quality
    `floor` (without a floor, a profile's few failed runs at quality ~0 would dominate the
    expectation of `1 / q`). `progress` scales `first_step` (measured: `calibration`).
    """

    task: NavigationTask
    profile: ConditionalPerformanceProfile | None = None
    floor: float = 0.5
    progress: float = 1.0
    route_quality: bool = False
    later: tuple[float, ...] | None = field(default=None, converter=_contracts)
    first: FirstFrame | None = None
    _cache: dict[Any, tuple[Array, Array]] = field(init=False, eq=False, repr=False, factory=dict)
    _later: Array = field(
        init=False,
        eq=False,
        repr=False,
        default=Factory(
            lambda self: _later_route_factor(self.profile, max(self.floor, MIN_QUALITY)),
            takes_self=True,
        ),
    )

    def _parts(self, state: FrameState, contract: Array, quality: Array) -> tuple[Array, Array]:
        """The completion time and the energy of the rest of the task, each shaped as
        `contract` and `quality` broadcast together, at the later contract and speeds of
        highest utility (the monitor asks for the value, then the cost, of the same arrays:
        the last answer is kept)."""
        c, q = np.asarray(contract), np.asarray(quality)
        key = (state, c.shape, q.shape, c.tobytes(), q.tobytes())
        if key not in self._cache:
            self._cache.clear()
            self._cache[key] = self._outcome(state, contract, quality)
        return self._cache[key]

    def _outcome(self, state: FrameState, contract: Array, quality: Array) -> tuple[Array, Array]:
        q = np.maximum(np.asarray(quality, dtype=np.float64), max(self.floor, MIN_QUALITY))
        c = np.asarray(contract, dtype=np.float64)
        d = state.remaining * state.detour
        # Frames are counted in progress on the robot's map, which the detour does not stretch.
        x = max(1.0, state.remaining / max(state.step, 1.0))
        this = min(d, max(state.step, 1.0) * state.detour)
        if self.route_quality:
            # This plan's frame at contract c, the later ones at the contract c_L chosen when
            # they come (last axis but one), or c again: a route of quality q at c is one of
            # quality q * R(c) / R(c_L) at c_L.
            c_later = c[..., None] if self.later is None else np.asarray(self.later)
            ratio = self.later_factor(c_later) / self.later_factor(c)[..., None]
            path = (this + (d - this) * ratio) / q[..., None]
        else:
            stretch = 1.0 / q if self.profile is None else self.later_factor(c)
            path = (this / q + (d - this) * stretch)[..., None]
            c_later = c[..., None]
        path, c_later, c = np.broadcast_arrays(path, c_later, c[..., None])
        completion, energy = self._timed(state, path, c, c_later, x)
        utility = np.asarray(self.task.value(completion), dtype=np.float64) - energy
        shape = utility.shape[:-2]
        best = np.argmax(utility.reshape(*shape, -1), axis=-1)[..., None]  # ties: the slowest
        return (
            np.take_along_axis(completion.reshape(*shape, -1), best, axis=-1)[..., 0],
            np.take_along_axis(energy.reshape(*shape, -1), best, axis=-1)[..., 0],
        )

    def _timed(
        self, state: FrameState, path: Array, c: Array, c_later: Array, x: Array | float
    ) -> tuple[Array, Array]:
        """The completion time and energy of a route of `path` cells making `x` frames'
        progress, this frame's plan at contract `c` and the later ones at `c_later` (arrays
        of one shape), at each mix of speeds of the grid (a last axis)."""
        # The robot chooses each frame's speed when the frame starts, knowing more of its
        # route: the plan's own frames go at the best mix of speeds of the grid for that route.
        pace, spend = self._mixes
        x = np.asarray(x, dtype=np.float64)
        frames = np.ceil(x)[..., None]
        per_frame = path[..., None] / x[..., None] * pace
        if state.waiting:
            wait = c
        else:
            wait = np.maximum(c - state.elapsed, state.current / state.speed)
        last = (x[..., None] - frames + 1) * per_frame
        completion = (
            state.now
            + wait[..., None]
            + (frames - 1) * np.maximum(c_later[..., None], per_frame)
            + last
        )
        energy = self.task.energy(state.speed) * state.current + spend * path[..., None]
        return completion, energy

    def first_choice(self, state: FrameState, grid: Array) -> FirstDecision | None:
        """The first frame's contract of highest expected utility over `grid` (the robot waits
        for this plan), from the first frame measured on the training worlds (`first`): at
        contract `c` in world `w` the route is `W[c, w] + d F[c, w] S[c_L, w]` (`W` the first
        frame's cells walked, `F` the fraction of the distance `d` left after it, `S` the later
        frames' stretch at their contract `c_L`), `1 + d F / step` frames' progress, and
        its utility, at the later contract and mix of speeds of highest utility in that world
        (as `value` does per quality), averaged over the worlds. None without `first`, when
        the state is not the first frame's, or when a contract of `grid` or of `later` was not
        measured: the caller falls back on the monitor over the profile."""
        first = self.first
        if first is None or not state.waiting:
            return None
        c = np.asarray(grid, dtype=np.float64).reshape(-1)
        rows = first.rows(c)
        later_rows = first.rows(np.asarray(self.later)) if self.later is not None else rows
        if rows is None or later_rows is None:
            return None
        d = state.remaining * state.detour
        walked = first.walked[rows]  # (G, W)
        left = d * first.left[rows]
        if self.later is None:  # the later frames keep this frame's contract
            stretch = first.stretch[rows][..., None]  # (G, W, 1)
            c_later = c[:, None, None]
        else:
            stretch = first.stretch[later_rows].T[None, :, :]  # (1, W, L)
            c_later = np.asarray(self.later)[None, None, :]
        path = walked[..., None] + left[..., None] * np.maximum(stretch, 1.0)
        x = 1.0 + left / max(state.step, 1.0)
        path, c_later, c_this, x = np.broadcast_arrays(
            path, c_later, c[:, None, None], x[..., None]
        )
        completion, energy = self._timed(state, path, c_this, c_later, x)  # (G, W, L, M)
        value = np.asarray(self.task.value(completion), dtype=np.float64)
        utility = value - energy
        # Each world's frames at the mix of speeds best for its route (the robot chooses a
        # frame's speed when the frame comes, knowing its route better), the later contract
        # best over the worlds (chosen now, for a world the robot does not know yet).
        mix = np.argmax(utility, axis=-1)[..., None]  # ties: the slowest

        def at_mix(a: Array) -> Array:
            at = np.take_along_axis(a, mix, axis=-1)[..., 0]
            return np.asarray(at.mean(axis=1), dtype=np.float64)  # (G, L)

        by_later = at_mix(utility)
        later = np.argmax(by_later, axis=-1)  # ties: the shortest
        u_curve = by_later[np.arange(c.size), later]
        top = u_curve.max()
        i = int(np.argmax(u_curve >= top - 1e-9 * max(1.0, abs(top))))
        j = int(later[i])
        # The quality the monitor expects: the distance over the expected route, as the
        # calibration measures a route's quality.
        route = float(path[i, :, j].mean())
        per_world = np.take_along_axis(utility, mix, axis=-1)[i, :, j, 0]
        return FirstDecision(
            contract=float(c[i]),
            expected_quality=min(1.0, d / route) if route > 0 else 1.0,
            expected_value=float(at_mix(value)[i, j]),
            expected_cost=float(at_mix(energy)[i, j]),
            expected_utility=float(u_curve[i]),
            expected_completion=float(at_mix(completion)[i, j]),
            grid=c,
            utility_curve=u_curve,
            median_utility=float(np.median(per_world)),
        )

    @property
    def _mixes(self) -> tuple[Array, Array]:
        """Ticks and energy per cell of the mixes of two neighbouring speeds of the grid (a
        share of the cells at each), from the slowest to the fastest: frame by frame the robot
        can walk some frames faster than others, which arrives on time for less energy than
        one faster speed throughout (energy per cell is convex in the speed)."""
        v = np.asarray(self.task.speeds, dtype=np.float64)
        e = np.asarray(self.task.energy(v), dtype=np.float64)
        share = np.linspace(0.0, 1.0, 11)[:-1, None]  # of the faster of each pair
        pace = ((1 - share) / v[:-1] + share / v[1:]).T.reshape(-1)
        spend = ((1 - share) * e[:-1] + share * e[1:]).T.reshape(-1)
        return np.append(pace, 1.0 / v[-1]), np.append(spend, e[-1])

    def later_factor(self, contract: Array) -> Array:
        """`R(c)`: how much the later frames' plans stretch the route, contract `c` each
        (interpolated between the profile's times; needs the profile)."""
        if self.profile is None:
            raise ValueError("the task model has no profile: later frames are not modelled")
        return np.asarray(np.interp(contract, self.profile.time, self._later), dtype=np.float64)

    def value(self, state: FrameState, contract: Array, quality: Array) -> Array:
        completion, _ = self._parts(state, contract, quality)
        return np.asarray(self.task.value(completion), dtype=np.float64)

    def cost(self, state: FrameState, contract: Array, quality: Array) -> Array:
        _, energy = self._parts(state, contract, quality)
        return np.asarray(energy, dtype=np.float64)

    def utility(self, state: FrameState, contract: float, quality: float) -> float:
        """Value minus cost of the rest of the task for one contract and plan quality."""
        c, q = np.asarray(contract, dtype=np.float64), np.asarray(quality, dtype=np.float64)
        return float(self.value(state, c, q) - self.cost(state, c, q))

    def median_utility(self, state: FrameState, contract: float) -> float:
        """The median of the rest of the task's utility at `contract` over the quality
        distribution of the profile at it (`weighted_median`: the prediction of least expected
        absolute error; the expected utility is the one the contract is chosen on)."""
        if self.profile is None:
            raise ValueError("the task model has no profile: no distribution to take it over")
        inputs = np.ones(self.profile.n_inputs)
        t = np.asarray(float(contract))
        weights = self.profile.distribution(inputs, t)
        qualities = self.profile.representatives(inputs, t)
        c = np.full(qualities.shape, float(contract))
        utilities = self.value(state, c, qualities) - self.cost(state, c, qualities)
        return weighted_median(utilities, weights)

    def expected_completion(self, state: FrameState, contract: float, quality: float) -> float:
        completion, _ = self._parts(
            state, np.asarray(contract, dtype=np.float64), np.asarray(quality, dtype=np.float64)
        )
        return float(completion)

    def first_step(self, position: Position) -> float:
        """The progress a frame is expected to make before one has been seen: the distance
        on the prior map (every cell free) that a straight line from `position` toward the
        goal covers before it leaves the sensor's window (where a frame's segment ends),
        e.g. `2 r` along the diagonal with 4-connected movement, `r` along an axis, times
        `progress` (what a first frame made of that on the training worlds: a plan is no
        straight line, `calibration`)."""
        (x, y), (gx, gy) = position, self.task.world.goal
        scale = min(1.0, self.task.radius / max(abs(gx - x), abs(gy - y), 1))
        dx, dy = abs(gx - x) * scale, abs(gy - y) * scale
        if self.task.world.movement == 8:  # octile
            straight = max(dx, dy) + (math.sqrt(2.0) - 1.0) * min(dx, dy)
        else:
            straight = dx + dy
        return max(1.0, straight * self.progress)

    def last_speed(self, now: float, cells: float) -> float:
        """The speed of the grid of highest utility for a last segment of `cells` cells to the
        goal, started at `now` (no planning left to wait for): `V(now + n / v) - energy(v) n`."""
        speeds = np.asarray(self.task.speeds, dtype=np.float64)
        utility = self.task.value(now + cells / speeds) - self.task.energy(speeds) * cells
        return float(speeds[int(np.argmax(utility))])


@frozen
class FromPlannerStart:
    """The task model with time counted from the planner's start, as a stopping policy over
    the planner's profile reads it: stopping the planner `t` into its run ends the frame's
    program at `offset + t` (`offset`: the sensing before it), which the model takes as the
    frame's contract."""

    model: TaskModel
    offset: float

    def value(self, state: FrameState, time: Array, quality: Array) -> Array:
        return self.model.value(state, self.offset + np.asarray(time, dtype=np.float64), quality)

    def cost(self, state: FrameState, time: Array, quality: Array) -> Array:
        return self.model.cost(state, self.offset + np.asarray(time, dtype=np.float64), quality)


# --- what a run reports -----------------------------------------------------------------------


@frozen
class FrameRecord:
    """One frame: its planning (the program run for it) and its execution.

    Times are task times in ticks. `plan` is the program's output (a `MultiPath`, or None);
    `route` the cells the robot moved along in this frame (its first cell is where it stood);
    `predicted_utility` the utility of the whole task the monitor predicted when it chose this
    frame's contract (the energy spent until then taken from the predicted value minus energy
    of the rest, `frames._TaskRun.prediction`: the first frame's is the report's
    `predicted_utility`); `adjustments` what the
    intra-frame rule said at each check during it ("faster declined", "slower declined": a
    move the task model expected not to pay, so not made); `stopped_at`, under the `stopping`
    policy, the program time at which the policy stopped the planner (None: it ran to the
    contract).
    """

    index: int
    start: float
    position: Position
    window: tuple[int, int, int, int]
    contract: float
    expected_quality: float
    plan_quality: float
    sensing_time: float
    sensing_quality: float
    plan: Any = field(eq=False, repr=False)
    known: BoolGrid = field(eq=False, repr=False)
    planned_at: float
    exec_start: float
    exec_end: float
    frame_time: float
    speed: float
    route: tuple[Position, ...] = field(repr=False)
    energy: float
    expected_completion: float
    expected_value: float
    adjustments: tuple[str, ...] = ()
    obstacles: tuple[MovingObstacle, ...] = field(default=(), repr=False)
    choices: tuple[tuple[str, tuple[Position, ...]], ...] = field(default=(), repr=False)
    decisions: int = 0
    collisions: int = 0
    predicted_utility: float = math.nan
    stopped_at: float | None = None


@frozen
class TaskReport:
    """The outcome of a task (see the module docstring for the definitions)."""

    seed: int
    size: int
    policy: str
    frames: int
    completion_time: float
    energy: float
    value: float
    utility: float
    predicted_utility: float
    prediction_error: float
    optimal_utility: float
    utility_ratio: float
    route_length: float
    optimal_length: float
    reached: bool
    route: tuple[Position, ...] = field(repr=False)
    records: tuple[FrameRecord, ...] = field(repr=False)
    log: EventLog = field(repr=False, eq=False)
    moving_obstacles: int = 0
    decisions: int = 0
    collisions: int = 0
    evasions: int = 0

    def as_json(self) -> dict[str, Any]:
        keys = (
            "seed size frames completion_time energy value utility predicted_utility "
            "prediction_error optimal_utility utility_ratio route_length optimal_length policy"
        ).split()
        if self.moving_obstacles:
            keys += ["moving_obstacles", "decisions", "collisions", "evasions"]
        return {k: getattr(self, k) for k in keys}


def optimal_utility(task: NavigationTask, length: float) -> tuple[float, float]:
    """The clairvoyant bound: (utility, speed) of the best constant speed of the grid on a
    route of the shortest length `length`, with no sensing or planning time."""
    speeds = np.asarray(task.speeds, dtype=np.float64)
    utility = np.asarray(task.value(length / speeds)) - task.energy(speeds) * length
    i = int(np.argmax(utility))
    return float(utility[i]), float(speeds[i])
