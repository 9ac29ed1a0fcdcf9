"""The worker side of the profile builder: what a domain supplies, and running trials.

Everything here is sent to worker processes (or Dask workers), so it must pickle: chunks of
trials carry the module (pickled by reference), the problem set and the grid.
"""

from __future__ import annotations

import inspect
import math
import traceback
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from itertools import islice
from typing import Any, Literal, Protocol

import numpy as np
from attrs import cmp_using, field, frozen
from numpy.typing import ArrayLike, NDArray

from anytime.clocks import Clock, WallClock, WorkClock
from anytime.errors import AnytimeError
from anytime.isolation import WATCHDOG, Isolation, Lost, calls
from anytime.modules import AnytimeModule, Context, Result
from anytime.profiles.profile import Array, default_bins

ClockName = Literal["work", "wall"]

CLOCKS: dict[str, tuple[Callable[[], Clock], Literal["ticks", "seconds"]]] = {
    "work": (WorkClock, "ticks"),
    "wall": (WallClock, "seconds"),
}


class BuildError(AnytimeError, ValueError):
    """A profile cannot be built as asked: bad grids, a problem set that breaks its contract."""


def _as_tuple(values: Sequence[Any]) -> tuple[Any, ...]:
    return tuple(values)


@frozen
class Instance:
    """One problem: the module's arguments after the context, and what the scorer needs.

    A quality-carrying argument may be a `Result` (whose quality must be the one asked for) or a
    plain value, which the builder wraps as `Result(value, asked quality)`.

    Attributes:
        args: the positional arguments after `ctx`, in the module's parameter order.
        reference: anything `ProblemSet.score` compares an output against (an optimal answer).
    """

    args: tuple[Any, ...] = field(converter=_as_tuple)
    reference: Any = None


class ProblemSet(Protocol):
    """What a domain supplies to measure a module. It must pickle (a top-level class instance)
    to reach worker processes, and should be small: instances are made on the workers."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        """A random problem whose quality-carrying inputs have `input_qualities` (axis order)."""
        ...

    def score(self, instance: Instance, value: Any) -> float:
        """The true quality in [0, 1] of the output `value` on `instance`."""
        ...


def _array(value: ArrayLike) -> Array:
    array = np.array(value, dtype=np.float64)
    array.setflags(write=False)
    return array


def _arrays(value: Sequence[ArrayLike]) -> tuple[Array, ...]:
    return tuple(_array(grid) for grid in value)


def _grids_equal(a: tuple[Array, ...], b: tuple[Array, ...]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


@frozen
class Grid:
    """The grids a profile is measured on.

    Attributes:
        time: increasing time allocations (ticks for the work clock, seconds for the wall clock).
        input_grids: one increasing grid of qualities per quality-carrying input.
        bins: K+1 edges of the quality histogram (default: 10 equal bins).
    """

    time: Array = field(converter=_array, eq=cmp_using(eq=np.array_equal), hash=False)
    input_grids: tuple[Array, ...] = field(
        default=(), converter=_arrays, eq=cmp_using(eq=_grids_equal), hash=False
    )
    bins: Array = field(
        factory=default_bins, converter=_array, eq=cmp_using(eq=np.array_equal), hash=False
    )

    @property
    def cell_shape(self) -> tuple[int, ...]:
        """The input-quality cells (no time axis)."""
        return tuple(len(grid) for grid in self.input_grids)


@frozen(eq=False)
class Chunk:
    """Trials `start` to `stop` of one build, by flat index `cell * trials + instance`."""

    module: AnytimeModule
    problems: ProblemSet
    grid: Grid
    clock: str
    entropy: int
    trials: int
    start: int
    stop: int
    isolation: Isolation = "process"  # each trial's run in a child process (see `measure_chunk`)
    watchdog: float = WATCHDOG  # seconds of wall time a trial may take, isolated


@frozen(eq=False)
class Done:
    start: int
    quality: Array  # (stop - start, len(time)): the score at each grid time
    failures: int
    overruns: int
    first_failure: tuple[int, str] | None  # (flat trial index, description)
    step: float = 0.0  # the largest step of the chunk's runs (see `_interruptible`, `_contract`)
    # (stop - start, len(time)): whether the run had a result at each grid time (None: always)
    scored: NDArray[np.bool_] | None = None
    # (stop - start, len(time)): the quality the module reported of its result at each grid time
    # (its `Result.quality`; 0 where it had none), or None: not recorded
    reported: Array | None = None
    # (stop - start,): when each run ended, by itself or at the last grid time (see `Row`), or
    # None: not recorded
    finished: Array | None = None
    # why runs failed: each reason (an error's first line, or how a process died) and how often
    reasons: dict[str, int] = field(factory=dict)


def measure_chunk(chunk: Chunk) -> Done:
    """Run one chunk of trials. Isolated (the default), they run in turn in a child process
    (`anytime.isolation.calls`): a trial whose process dies, or that takes longer than the
    watchdog, is a failed trial without a result (its row scores 0), and the next trials go
    on in a new process."""
    return next(measure_chunks([chunk]))


def measure_chunks(chunks: Sequence[Chunk]) -> Iterator[Done]:
    """`measure_chunk` of each of `chunks` (of one build) in turn; isolated, one process runs
    them all (a process per chunk would cost a fork each)."""
    if not chunks:
        return
    first = chunks[0]
    flats = [flat for chunk in chunks for flat in range(chunk.start, chunk.stop)]
    measure = partial(_measured, first)
    outcomes: Iterator[Measured | Lost]
    if first.isolation == "process":
        outcomes = calls(measure, flats, watchdog=first.watchdog)
    else:
        outcomes = map(measure, flats)
    for chunk in chunks:
        yield _done(chunk, islice(outcomes, chunk.stop - chunk.start))


def _done(chunk: Chunk, outcomes: Iterator[Measured | Lost]) -> Done:
    """The chunk's measurements from its trials' outcomes (in trial order)."""
    grid = chunk.grid
    quality = np.zeros((chunk.stop - chunk.start, len(grid.time)))
    scored = np.zeros(quality.shape, dtype=np.bool_)  # no result until one is scored
    reported = np.zeros(quality.shape)
    finished = np.full(len(quality), float(grid.time[-1]))
    failures = overruns = 0
    step = 0.0
    first: tuple[int, str] | None = None
    reasons: dict[str, int] = {}
    flats = range(chunk.start, chunk.stop)
    for row, (flat, outcome) in enumerate(zip(flats, outcomes, strict=True)):
        if isinstance(outcome, Lost):
            failed = [(outcome.reason, "")]
        else:
            quality[row], scored[row], reported[row] = outcome.row
            finished[row] = outcome.finished
            failed = outcome.failed
            overruns += outcome.overruns
            step = max(step, outcome.step)
        failures += len(failed)
        for headline, _ in failed:
            reasons[headline] = reasons.get(headline, 0) + 1
        if failed and first is None:
            headline, details = failed[0]
            first = (flat, f"{headline} ({_trial(chunk, flat).where})\n{details}".rstrip())
    return Done(
        chunk.start, quality, failures, overruns, first, step, scored, reported, finished, reasons
    )


@frozen(eq=False)
class Measured:
    """What one trial gives (see `measure_chunk`): its row of scores, whether it had a result,
    and what it reported, per grid time; when it ended; its failures, overruns and step."""

    row: tuple[Array, NDArray[np.bool_], Array]
    finished: float
    failed: Failures
    overruns: int
    step: float


def _trial(chunk: Chunk, flat: int) -> Trial:
    """Trial `flat` (`cell * trials + instance`) of the chunk's build."""
    grid = chunk.grid
    cell, instance = divmod(flat, chunk.trials)
    position = np.unravel_index(cell, grid.cell_shape) if grid.cell_shape else ()
    qualities = tuple(float(g[i]) for g, i in zip(grid.input_grids, position, strict=True))
    return Trial(
        chunk.module,
        chunk.problems,
        qualities,
        np.random.SeedSequence(chunk.entropy, spawn_key=(cell, instance)),
        CLOCKS[chunk.clock][0],
        f"trial {instance} at input qualities {list(qualities)}",
    )


def _measured(chunk: Chunk, flat: int) -> Measured:
    """Run trial `flat` of the chunk."""
    times = chunk.grid.time
    n = len(times)
    out = Row(np.zeros(n), np.zeros(n, dtype=np.bool_), np.zeros(n), np.full(1, float(times[-1])))
    measure = _interruptible if chunk.module.kind == "interruptible" else _contract
    failed, overran, longest = measure(_trial(chunk, flat), times, out)
    row = (out.quality, out.scored, out.reported)
    return Measured(row, float(out.finished[0]), failed, overran, longest)


@frozen(eq=False)
class Row:
    """Where one trial's measurements go, one entry per grid time: the score of its result,
    whether it had one, and the quality it reported of it (`Result.quality`)."""

    quality: Array
    scored: NDArray[np.bool_]
    reported: Array
    # When the run ended: by itself (an interruptible module that returned or failed before the
    # last grid time), else at the last grid time; one entry.
    finished: Array

    def record(self, where: slice | int, score: float, reported: float) -> None:
        self.quality[where] = score
        self.scored[where] = True
        self.reported[where] = reported


@frozen(eq=False)
class Trial:
    """One instance at one input-quality cell; `problem()` makes it afresh from its seed."""

    module: AnytimeModule
    problems: ProblemSet
    qualities: tuple[float, ...]
    seeds: np.random.SeedSequence
    clock: Callable[[], Clock]
    where: str

    def problem(self) -> tuple[Instance, tuple[Any, ...]]:
        rng = np.random.default_rng(self.seeds)
        try:
            instance = self.problems.instance(rng, self.qualities)
        except Exception as exc:
            raise BuildError(
                f"{_name(self.problems)}.instance failed ({self.where}): {_headline(exc)}"
            ) from exc
        return instance, _arguments(self.module, self.problems, instance, self.qualities)

    def score(self, instance: Instance, value: Any) -> float:
        where = f"{_name(self.problems)}.score ({self.where})"
        try:
            quality = self.problems.score(instance, value)
        except Exception as exc:
            raise BuildError(f"{where} failed: {_headline(exc)}") from exc
        try:
            q = float(quality)
        except (TypeError, ValueError):
            q = math.nan
        if not 0.0 <= q <= 1.0:  # also refuses NaN
            raise BuildError(f"{where}: expected a quality in [0, 1], got {quality!r}")
        return q


def _name(problems: ProblemSet) -> str:
    return type(problems).__qualname__


def _headline(exc: BaseException) -> str:
    return "".join(traceback.format_exception_only(exc)).strip().splitlines()[-1]


def _failure(exc: BaseException) -> tuple[str, str]:
    return _headline(exc), "".join(traceback.format_exception(exc))


def _arguments(
    module: AnytimeModule, problems: ProblemSet, instance: Instance, qualities: tuple[float, ...]
) -> tuple[Any, ...]:
    """The instance's arguments, quality-carrying ones as `Result`s of the asked quality."""
    where = f"{_name(problems)}.instance"
    if not isinstance(instance, Instance):
        raise BuildError(f"{where}: expected an Instance, got {type(instance).__name__}")
    args = list(instance.args)
    try:
        inspect.signature(module.function).bind(None, *args)
    except TypeError as exc:
        params = ", ".join(module.parameters) or "none"
        raise BuildError(
            f"{where}: {len(args)} argument(s) do not fit module '{module.name}'"
            f" (parameters after ctx: {params}): {exc}"
        ) from exc
    for name, asked in zip(module.inputs, qualities, strict=True):
        position = module.parameters.index(name)
        if position >= len(args):
            raise BuildError(f"{where}: no argument for the quality-carrying input '{name}'")
        arg = args[position]
        if not isinstance(arg, Result):
            args[position] = Result(arg, asked)
        elif abs(arg.quality - asked) > 1e-9:
            raise BuildError(
                f"{where}: input '{name}' was asked at quality {asked:g}, got a Result of"
                f" quality {arg.quality:g}"
            )
    return tuple(args)


Failures = list[tuple[str, str]]  # (headline, traceback) of each failed run


def _interruptible(trial: Trial, time: Array, out: Row) -> tuple[Failures, int, float]:
    """One run up to the last grid time; `out` records at each `time[j]` the score of the
    answer there and the quality the module reported of it, where there is one (before its
    first result the run has none).

    Also returns the run's step: the largest gap between the moments it gave control back (its
    start, every yield, the end of the run), so the gap to a yield past the last grid time (the
    one that ends the run) counts, and so does the time from its last yield to its return or
    failure. Except for a run that ends by itself right after the report of work that spent its
    allocation (its last `ctx.tick` began before the allocation and ended at or past it): such
    a module watches its time between reports of work, and would have stopped after any of
    them at an earlier deadline, so its stretch after its last yield counts as the longest
    interval between its reports of work there, not as one gap. The clean-up after the run is
    closed counts as part of its last stretch.
    """
    instance, args = trial.problem()
    allocation = float(time[-1])
    clock = _Watch(trial.clock())
    ctx = Context(allocation=allocation, clock=clock)
    answers: list[tuple[int, Result]] = []  # (first grid index it answers for, the result)
    failed: Failures = []
    last = step = 0.0  # the last moment it gave control back, and the largest gap so far
    cut = False  # the run was ended here, at a yield past the last grid time
    generator = trial.module(ctx, *args)
    try:
        while True:
            try:
                item = next(generator)
            except StopIteration:
                break
            except Exception as exc:  # the module failed: its last result stands
                failed.append(_failure(exc))
                break
            at = ctx.elapsed
            step, last = max(step, at - last), at
            clock.mark()
            if at > time[-1]:
                cut = True
                break
            if not isinstance(item, Result):
                failed.append((f"yielded a {type(item).__name__}, not a Result", ""))
                break
            first = int(np.searchsorted(time, at, side="left"))  # the grid times >= at
            if answers and answers[-1][0] == first:
                answers[-1] = (first, item)  # superseded before the next grid time
            else:
                answers.append((first, item))
    finally:
        try:
            generator.close()
        except Exception as exc:
            failed.append(_failure(exc))
        end = ctx.elapsed
        if not cut and end < allocation:  # it returned (or failed) by itself, before the end
            out.finished[0] = end
        stretch = end - last
        if not cut and clock.spent_by_last_report(ctx.start + allocation):
            stretch = max(clock.longest, clock.now() - clock.previous)
        step = max(step, stretch)
    # Scored after the run, so that the scorer's time is never charged to the module. No answer
    # at all (the first came after the last grid time, as a slow wall clock can make it) leaves
    # the row at quality 0, without a result.
    ends = [first for first, _ in answers[1:]] + [len(time)] if answers else []
    for (first, result), end in zip(answers, ends, strict=True):
        out.record(slice(first, end), trial.score(instance, result.value), result.quality)
    return failed, 0, step


class _Watch:
    """A clock that notes, since its last `mark()`, the longest interval between the module's
    reports of work (from the mark to the first, between them), and when the last one began."""

    def __init__(self, clock: Clock) -> None:
        self.clock = clock
        self.unit = clock.unit
        self.longest = 0.0
        self.previous = self.began = clock.now()  # the last report's end, and its start
        self.reports = 0

    def now(self) -> float:
        return self.clock.now()

    def advance(self, n: float) -> None:
        began = self.clock.now()
        self.clock.advance(n)
        now = self.clock.now()
        self.longest = max(self.longest, now - self.previous)
        self.began, self.previous = began, now
        self.reports += 1

    def mark(self) -> None:
        self.longest, self.previous, self.reports = 0.0, self.clock.now(), 0

    def spent_by_last_report(self, deadline: float) -> bool:
        """Whether the last report since the mark began before `deadline` and reached it."""
        slack = 1e-9 * max(1.0, abs(deadline))  # as `Context.remaining` rounds
        return self.reports > 0 and self.began < deadline - slack <= self.previous


def _contract(trial: Trial, time: Array, out: Row) -> tuple[Failures, int, float]:
    """One run per grid time on the same instance, with that time as its allocation; `out`
    records at `time[j]` the score of its result and the quality it reported, where it
    returned one (a run that raised or returned None has none).

    Also returns the step: the most any of the runs used past its allocation (0 if none did),
    whether it returned a result, none, or raised.
    """
    failed: Failures = []
    overruns = 0
    step = 0.0
    for j, allocation in enumerate(time):
        instance, args = trial.problem()  # made afresh: a module may change its arguments
        ctx = Context(allocation=float(allocation), clock=trial.clock())
        try:
            result = trial.module(ctx, *args)
        except Exception as exc:
            failed.append(_failure(exc))
            step = max(step, float(ctx.elapsed - allocation))
            continue
        used = ctx.elapsed
        step = max(step, float(used - allocation))
        if result is None:  # no result: the row keeps quality 0, unscored
            overruns += used > allocation
            continue
        if not isinstance(result, Result):
            failed.append((f"returned a {type(result).__name__}, not a Result", ""))
            continue
        if used > allocation:  # counted as a plain int (a numpy bool would make it int64)
            overruns += 1
        out.record(j, trial.score(instance, result.value), result.quality)
    return failed, overruns, step
