"""Calibration: how many ticks a module reports per second, and profiles converted between units.

Profiles are measured on the work clock, in the ticks a module reports (see docs/plugins.md):
deterministic and machine-independent. A system that runs on the wall clock needs them in
seconds, and the factor between the two is a property of the module on this machine.
`calibrate` measures it: it runs the module on instances of its registered problem set until a
wall-time budget is spent and divides the ticks each run reported by the seconds it took.

Each run is given the largest time of the module's grid, *in ticks*, on a work clock, so the
module does the very work it does when it is profiled (a contract module reads its allocation
in ticks, an interruptible one stops where its profile ends); the seconds are measured around
the run with `time.perf_counter`, and a run still going when the budget is spent is stopped
from outside. The answer is the median of the runs' rates with its spread: the smallest and
largest, and a distribution-free 95% interval of the median (order statistics).

Isolated (the default, `Isolated()`), the runs are made in turn in a child process
(`anytime.isolation.calls`), each timed there: a run whose process dies is a `CalibrationError`
saying how it died, and so is one still going `GRACE` seconds of wall time after the budget is
spent (a module that loops or sleeps without reporting work cannot be stopped by its clock: the
watchdog, the smaller of the mode's and the budget plus `GRACE`, ends it). `SOFT` runs them in
this process (such a module then hangs the calibration).

`convert_profile` rescales a profile's time axis by the factor and changes its `time_unit`;
nothing else changes. The time values are rounded to the shortest decimal within a few units
in the last place when (and only when) that decimal converts back to the input, so a grid
written with up to 12 significant digits comes back exactly after ticks -> seconds -> ticks.
"""

from __future__ import annotations

import math
import threading
import time as _time
from collections.abc import Callable, Generator
from contextlib import closing
from functools import partial
from typing import Any

import attrs
import numpy as np
from attrs import frozen

from anytime.clocks import Unit, WorkClock
from anytime.errors import AnytimeError, ProfileError
from anytime.isolation import Lost, calls, counting_interrupts
from anytime.measure.trials import Trial, run_trial
from anytime.modules import AnytimeModule
from anytime.problems import Measurement, registered_problems
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.runtime.executor import Status
from anytime.runtime.modes import ISOLATED, SOFT, Budget, Isolated, RunMode, Soft
from anytime.vocabulary import PROFILE_KINDS

__all__ = ["Calibration", "CalibrationError", "calibrate", "convert_profile"]

#: Significant digits a converted time value may be rounded to, and how far it may move.
_DIGITS, _ULPS = 12, 4
#: Wall-clock seconds an isolated calibration run may go on after the budget is spent (its
#: clock stops it at its next report of work) before the watchdog ends it.
GRACE = 2.0


class CalibrationError(AnytimeError, ValueError):
    """A module cannot be calibrated (it reports no ticks, or it fails while running), or a
    calibration or conversion is asked for with a bad budget, rate or unit."""


@frozen
class Calibration:
    """A module's measured speed in ticks per wall-clock second.

    Attributes:
        module: the module's name.
        rates: ticks per second of each run that reported ticks, in run order.
        runs: runs in all (including any that reported no ticks).
        ticks: ticks reported over all runs.
        seconds: wall time spent in the runs.
    """

    module: str
    rates: tuple[float, ...]
    runs: int
    ticks: float
    seconds: float

    @property
    def ticks_per_second(self) -> float:
        """The median rate over runs."""
        return float(np.median(self.rates))

    @property
    def low(self) -> float:
        return min(self.rates)

    @property
    def high(self) -> float:
        return max(self.rates)

    @property
    def interval(self) -> tuple[float, float]:
        """An approximate 95% confidence interval of the median: the order statistics at
        n/2 -/+ 1.96 sqrt(n)/2 (the whole range for a handful of runs)."""
        ordered = sorted(self.rates)
        n = len(ordered)
        half = 1.96 * math.sqrt(n) / 2
        lower = max(0, math.floor(n / 2 - half) - 1)
        upper = min(n - 1, math.ceil(n / 2 + half))
        return ordered[lower], ordered[upper]

    def summary(self) -> str:
        low, high = self.interval
        return (
            f"{self.module}: {self.ticks_per_second:.4g} ticks/s (median of {len(self.rates)}"
            f" runs; 95% interval of the median {low:.4g} to {high:.4g}; min {self.low:.4g},"
            f" max {self.high:.4g}) in {self.seconds:.2f} s"
        )

    def to_dict(self) -> dict[str, Any]:
        low, high = self.interval
        return {
            "module": self.module,
            "ticks_per_second": self.ticks_per_second,
            "interval": [low, high],
            "min": self.low,
            "max": self.high,
            "runs": self.runs,
            "ticks": self.ticks,
            "seconds": self.seconds,
        }


class _MeteredClock:
    """A work clock that also stops the run once the wall-clock budget is spent."""

    unit: Unit = "ticks"

    def __init__(self, stop: threading.Event, deadline: float) -> None:
        self._ticks = 0.0
        self._stop = stop
        self._deadline = deadline  # on time.perf_counter

    def now(self) -> float:
        return self._ticks

    def advance(self, n: float) -> None:
        self._ticks += n
        if _time.perf_counter() >= self._deadline:
            self._stop.set()


def calibrate(
    module: AnytimeModule,
    seconds: float = 1.0,
    *,
    measurement: Measurement | None = None,
    seed: int = 0,
    max_runs: int = 100_000,
    mode: RunMode = ISOLATED,
) -> Calibration:
    """Measure `module`'s ticks per second on instances of its problem set.

    Args:
        seconds: the wall-time budget (the last run is stopped when it is spent).
        measurement: the problem set and grid (default: the ones registered for the module).
        seed: instance i at input-quality cell c is made from `SeedSequence(seed, spawn_key=(c,
            i))`, as the profile builder makes them; runs cycle through the cells.
        max_runs: stop after this many runs even if budget is left.
        mode: `Isolated(watchdog=..., limits=...)` (the default: the runs in a child process,
            see the module docstring; with limits, a process per run) or `SOFT` (here).

    Raises:
        BuildError: no problem set is registered for the module.
        CalibrationError: the module is elementary, fails on an instance (raises, its process
            dies, or it does not answer in time), or reports no ticks; or `seconds` is not a
            positive budget, or the mode is neither `Soft()` nor `Isolated()`.
    """
    if module.kind not in PROFILE_KINDS:
        raise CalibrationError(
            f"module '{module.name}' is {module.kind}: only interruptible and contract modules"
            " report ticks to calibrate"
        )
    if not seconds > 0:
        raise CalibrationError(f"seconds: expected a positive budget, got {seconds!r}")
    if not isinstance(mode, Soft | Isolated):
        raise CalibrationError(f"mode: expected Soft() or Isolated(), got {mode!r}")
    plan = measurement if measurement is not None else registered_problems(module.name)
    grid = plan.grid
    cells = [
        tuple(float(g[i]) for g, i in zip(grid.input_grids, index, strict=True))
        for index in np.ndindex(*grid.cell_shape)
    ]
    rates: list[float] = []
    ticks = spent = 0.0
    runs = 0
    deadline = _time.perf_counter() + seconds  # perf_counter: one monotonic clock for the forks
    one = partial(_one_run, module, plan, cells, float(grid.time[-1]), seed, deadline)
    with counting_interrupts(), closing(_outcomes(one, range(max_runs), mode, seconds)) as ran:
        for index, outcome in enumerate(ran):
            if outcome is None:  # the budget was spent before it began
                break
            where = _where(cells, index)
            if isinstance(outcome, Lost):
                how, hint = "crashed", ""
                if outcome.exit_code is None:
                    how = "did not answer"
                    hint = (
                        f" (the budget was {seconds:g} s: it must report its work with"
                        " ctx.tick(n) often enough to be stopped)"
                    )
                raise CalibrationError(
                    f"module '{module.name}' {how} while being calibrated ({where}):"
                    f" {outcome.reason}{hint}"
                )
            status, error, used, took = outcome
            runs += 1
            if status is Status.FAILED:
                raise CalibrationError(
                    f"module '{module.name}' failed while being calibrated ({where}): {error}"
                )
            ticks += used
            spent += took
            if used > 0 and took > 0:
                rates.append(used / took)
    if not rates:
        raise CalibrationError(
            f"module '{module.name}' reported no ticks while being calibrated: it must report"
            " its work with ctx.tick(n)"
        )
    return Calibration(module.name, tuple(rates), runs, ticks, spent)


#: What one calibration run gives: its status, its error, the ticks it used and its seconds.
_Ran = tuple[Status, str | None, float, float]


def _outcomes(
    one: Callable[[int], _Ran | None], indices: range, mode: Soft | Isolated, seconds: float
) -> Generator[_Ran | Lost | None, None, None]:
    """`one(i)` for each index, here or (isolated) in child processes, each run watched."""
    if not isinstance(mode, Isolated):
        yield from map(one, indices)
        return
    watchdog = min(mode.watchdog, seconds + GRACE)
    if mode.limits is None:
        yield from calls(one, indices, watchdog=watchdog)
        return
    for index in indices:  # a process per run: the limits are each run's
        yield from calls(one, [index], watchdog=watchdog, limits=mode.limits)


def _where(cells: list[tuple[float, ...]], index: int) -> str:
    cell, instance = index % len(cells), index // len(cells)
    at = f" at input qualities {list(cells[cell])}" if cells[cell] else ""
    return f"trial {instance}{at}"


def _one_run(
    module: AnytimeModule,
    plan: Measurement,
    cells: list[tuple[float, ...]],
    allocation: float,
    seed: int,
    deadline: float,
    index: int,
) -> _Ran | None:
    """(Here, or in a child process.) Calibration run `index`, timed; None once the budget is
    spent (the first run is always made)."""
    if index > 0 and _time.perf_counter() >= deadline:
        return None
    cell, instance = index % len(cells), index // len(cells)
    trial = Trial(
        module,
        plan.problems,
        cells[cell],
        np.random.SeedSequence(seed, spawn_key=(cell, instance)),
        WorkClock,  # unused: the trial only makes the problem; `run` gets its clock
        _where(cells, index),
    )
    _, args = trial.problem()
    stop = threading.Event()
    clock = _MeteredClock(stop, deadline)
    started = _time.perf_counter()
    record = run_trial(module, args, Budget(allocation, clock=clock, stop=stop), SOFT)
    took = _time.perf_counter() - started
    return record.status, record.error, record.time_used, took


def convert_profile(
    profile: ConditionalPerformanceProfile, ticks_per_second: float, to: Unit = "seconds"
) -> ConditionalPerformanceProfile:
    """`profile` with its time axis in `to` ("seconds" or "ticks"), at `ticks_per_second`.

    Only the time grid and `time_unit` change. The grid's values are the exact quotient or
    product, except that one within a few units in the last place of a short decimal (at most
    12 significant digits) becomes that decimal when it converts back to the given value: a grid
    written in such decimals survives a round trip exactly.

    Raises:
        ProfileError: the profile is already in `to`.
        CalibrationError: the rate is not a positive finite number, or `to` is not a unit.
    """
    if to not in ("seconds", "ticks"):
        raise CalibrationError(f"to: expected 'seconds' or 'ticks', got {to!r}")
    rate = float(ticks_per_second)
    if not (math.isfinite(rate) and rate > 0):
        raise CalibrationError(
            f"ticks_per_second: expected a positive number, got {ticks_per_second!r}"
        )
    if profile.time_unit == to:
        raise ProfileError(
            f"{profile.module or 'profile'}: time_unit: the profile is already in {to}"
        )
    if to == "seconds":
        forward, backward = (lambda x: x / rate), (lambda x: x * rate)
    else:
        forward, backward = (lambda x: x * rate), (lambda x: x / rate)
    time = [_rescale(t, forward, backward) for t in profile.time]
    step = None if profile.step is None else _rescale(profile.step, forward, backward)
    return attrs.evolve(profile, time=np.array(time), time_unit=to, step=step)


def _rescale(
    value: float, forward: Callable[[float], float], backward: Callable[[float], float]
) -> float:
    """`forward(value)`, or the short decimal next to it if that goes back to `value`.

    The test accepts a candidate when `value` is what a conversion of the candidate back could
    give (the plain product or its short decimal); so converting the result back picks `value`
    whenever `value` is itself a short decimal.
    """
    value = float(value)
    raw = forward(value)
    short = _short(raw)
    if short != raw and value not in (backward(short), _short(backward(short))):
        return raw
    return short


def _short(value: float) -> float:
    """The 12-significant-digit decimal of `value` if it is within a few ulps, else `value`."""
    if value == 0 or not math.isfinite(value):
        return value
    candidate = float(f"{value:.{_DIGITS - 1}e}")
    return candidate if abs(candidate - value) <= _ULPS * math.ulp(value) else value
