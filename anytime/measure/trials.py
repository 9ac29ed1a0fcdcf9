"""The worker side of the profile builder: what a domain supplies, and running trials.

Everything here is sent to worker processes (or Dask workers), so it must pickle: chunks of
trials carry the module (pickled by reference), the problem set and the grid.
"""

from __future__ import annotations

import inspect
import math
import mmap
import struct
import traceback
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Literal

import attrs
import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from anytime.clocks import Clock, WallClock, WorkClock
from anytime.errors import interrupt_behind
from anytime.isolation import interrupt_signals
from anytime.modules import AnytimeModule, Result
from anytime.problems import BuildError, Grid, Instance, ProblemSet
from anytime.profiles.profile import Array
from anytime.runtime.executor import RunRecord, Status, run
from anytime.runtime.modes import ISOLATED, SOFT, Budget, Hard, Isolated, RunMode, Soft
from anytime.runtime.observe import Decision, Observer
from anytime.runtime.records import RunInterrupted
from anytime.vocabulary import Unit

if TYPE_CHECKING:
    from anytime.measure.isolated_trials import Sender

ClockName = Literal["work", "wall"]


CLOCKS: dict[str, tuple[Callable[[], Clock], Unit]] = {
    "work": (WorkClock, "ticks"),
    "wall": (WallClock, "seconds"),
}


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
    # Isolated: the trials in child processes (see `measure_chunk`), its watchdog the wall
    # seconds an isolated run may take (see `isolated_outcomes`); else each trial's run() here.
    mode: RunMode = ISOLATED


@frozen(eq=False)
class Done:
    start: int
    quality: Array  # (stop - start, len(time)): the score at each grid time
    failures: int
    overruns: int
    first_failure: tuple[int, str] | None  # (flat trial index, description)
    step: float = (
        0.0  # the largest step of the chunk's runs (see `run_interruptible`, `run_contract`)
    )
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


@frozen(eq=False)
class Measured:
    """What one trial gives (see `measure_chunk`): its row of scores, whether it had a result,
    and what it reported, per grid time; when it ended; its failures, overruns and step."""

    row: tuple[Array, NDArray[np.bool_], Array]
    finished: float
    failed: Failures
    overruns: int
    step: float


def trial_of(chunk: Chunk, flat: int) -> Trial:
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
        in_process(chunk.mode),
    )


def in_process(mode: RunMode) -> Soft | Hard:
    """The mode of a trial's `run` where the trial runs: an isolated build's trials run soft in
    their child process, the others as the mode says."""
    return SOFT if isinstance(mode, Isolated) else mode


def measured(
    chunk: Chunk,
    flat: int,
    sender: Sender | None = None,
    begin: int = 0,
    end: int | None = None,
) -> Measured:
    """Run trial `flat` of the chunk (a contract module's from grid index `begin` on, up to
    `end` if given: the rows outside stay without a result). Isolated, `sender` keeps the
    caller informed of what the run has done, should its process die (see `Sender`)."""
    times = chunk.grid.time
    out = empty_row(times)
    trial = trial_of(chunk, flat)
    if chunk.module.kind == "interruptible":
        failed, overran, longest = run_interruptible(trial, times, out, sender)
    else:
        failed, overran, longest = run_contract(trial, times, out, sender, begin, end)
    row = (out.quality, out.scored, out.reported)
    return Measured(row, float(out.finished[0]), failed, overran, longest)


def empty_row(times: Array) -> Row:
    n = len(times)
    return Row(np.zeros(n), np.zeros(n, dtype=np.bool_), np.zeros(n), np.full(1, float(times[-1])))


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
    mode: Soft | Hard = SOFT  # how each of its runs is run (see `in_process`)

    def problem(self) -> tuple[Instance, tuple[Any, ...]]:
        rng = np.random.default_rng(self.seeds)
        signals = interrupt_signals()
        try:
            instance = self.problems.instance(rng, self.qualities)
        except BaseException as exc:
            _raise_interrupt(exc, signals)
            raise BuildError(
                f"{_name(self.problems)}.instance failed ({self.where}): {_headline(exc)}"
            ) from exc
        return instance, _arguments(self.module, self.problems, instance, self.qualities)

    def score(self, instance: Instance, value: Any) -> float:
        where = f"{_name(self.problems)}.score ({self.where})"
        signals = interrupt_signals()
        try:
            quality = self.problems.score(instance, value)
        except BaseException as exc:
            _raise_interrupt(exc, signals)
            raise BuildError(f"{where} failed: {_headline(exc)}") from exc
        try:
            q = float(quality)
        except (TypeError, ValueError):
            q = math.nan
        if not 0.0 <= q <= 1.0:  # also refuses NaN
            raise BuildError(f"{where}: expected a quality in [0, 1], got {quality!r}")
        return q


def _raise_interrupt(exc: BaseException, signals: int) -> None:
    """Raise the user's interrupt if `exc` is one: a KeyboardInterrupt (or an error compiled code
    raised for one, `interrupt_behind`) while a SIGINT or SIGTERM reached this process
    (`signals` was the count before). Anything else a plugin's code raises, its own
    KeyboardInterrupt and `sys.exit()` included, is its fault."""
    behind = interrupt_behind(exc)
    if behind is not None and interrupt_signals() != signals:
        raise behind


def run_trial(
    module: AnytimeModule,
    args: Sequence[Any],
    budget: Budget,
    mode: Soft | Hard,
    observer: Observer | None = None,
) -> RunRecord:
    """`anytime.runtime.run` of one trial's (or catalogue's) run, where whatever the module
    raises is a failed run: a `KeyboardInterrupt` it raised itself (no SIGINT or SIGTERM
    reached this process meanwhile, see `anytime.isolation.interrupt_signals`) too, and any
    other `BaseException` the executor lets through. The user's Ctrl-C still stops the
    caller."""
    signals = interrupt_signals()
    start = budget.clock.now()
    try:
        return run(module, args, budget=budget, mode=mode, observer=observer)
    except RunInterrupted as exc:
        if interrupt_signals() != signals:
            raise
        cause = exc.__cause__ if exc.__cause__ is not None else exc
        return attrs.evolve(
            exc.record,
            status=Status.FAILED,
            error=_headline(cause),
            traceback="".join(traceback.format_exception(cause)),
        )
    except BaseException as exc:
        if isinstance(exc, KeyboardInterrupt) and interrupt_signals() != signals:
            raise
        used = budget.clock.now() - start
        return RunRecord(
            module.name,
            Status.FAILED,
            None,
            used,
            budget.allocation,
            error=_headline(exc),
            traceback="".join(traceback.format_exception(exc)),
        )


def _name(problems: ProblemSet) -> str:
    return type(problems).__qualname__


def _headline(exc: BaseException) -> str:
    return "".join(traceback.format_exception_only(exc)).strip().splitlines()[-1]


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


def run_interruptible(
    trial: Trial,
    time: Array,
    out: Row,
    sender: Sender | None = None,
    limit: int | None = None,
) -> tuple[Failures, int, float]:
    """One run up to the last grid time; `out` records at each `time[j]` the score of the
    answer there and the quality the module reported of it, where there is one (before its
    first result the run has none). The run is `anytime.runtime.run`'s, watched by a
    `_Trace`; a run that fails keeps the last result it registered before. With a `limit`, the
    run ends once it has registered that many results (a replay, see `_Progress.lost`).

    Also returns the run's step: the largest gap between the moments it gave control back (its
    start, every result, the end of the run), so the gap to a result past the last grid time
    (the one that ends the run) counts, and so does the time from its last result to its
    return or failure. Except for a run that ends by itself right after the report of work that
    spent its allocation (its last `ctx.tick` began before the allocation and ended at or past
    it): such a module watches its time between reports of work, and would have stopped after
    any of them at an earlier deadline, so its stretch after its last result counts as the
    longest interval between its reports of work there, not as one gap. The clean-up after the
    run is closed counts as part of its last stretch.
    """
    if sender is not None:
        sender.run_begins()
    instance, args = trial.problem()
    allocation = float(time[-1])
    clock = _Watch(trial.clock(), None if sender is None else sender.memory)
    trace = _Trace(time, clock, sender, limit)
    # The last grid time is the trace's stop time, not the run's allocation, so that a module
    # that returns by itself after it (having watched its time) is told apart from a run ended
    # at a result past it (status stopped).
    record = run_trial(trial.module, args, Budget(clock=clock), trial.mode, trace)
    failed: Failures = []
    if record.status in (Status.FAILED, Status.CRASHED):
        failed.append((record.error or "failed", record.traceback or ""))
    end = record.time_used
    cut = record.status is Status.STOPPED  # at (or after) the last grid time, or the limit
    if not cut and end < allocation:  # it returned (or failed) by itself, before the end
        out.finished[0] = end
    stretch = end - trace.last
    if not cut and clock.spent_by_last_report(trace.start + allocation):
        stretch = max(clock.longest, clock.now() - clock.previous)
    step = max(trace.step, stretch)
    # Scored after the run, so that the scorer's time is never charged to the module. No answer
    # at all (the first came after the last grid time, as a slow wall clock can make it) leaves
    # the row at quality 0, without a result.
    answers = trace.answers
    ends = [first for first, _ in answers[1:]] + [len(time)] if answers else []
    for (first, result), end_index in zip(answers, ends, strict=True):
        out.record(slice(first, end_index), trial.score(instance, result.value), result.quality)
    return failed, 0, step


class _Trace(Observer):
    """An interruptible trial's view of its run: the results it registered, each with the first
    grid time it answers for (a result superseded before the next grid time is dropped), and
    the largest gap between them so far."""

    def __init__(
        self, time: Array, clock: _Watch, sender: Sender | None, limit: int | None
    ) -> None:
        self.time, self.clock, self.sender, self.limit = time, clock, sender, limit
        self.answers: list[tuple[int, Result]] = []  # (first grid index it answers for, result)
        self.registered_count = 0
        self.start = self.last = self.step = 0.0  # the start; the last result, the largest gap

    def started(self, module: AnytimeModule, args: Sequence[Any], allocation: float) -> Decision:
        self.start = self.clock.now()
        if self.sender is not None:
            self.sender.started(self.start)
        return Decision(False, stop_at=float(self.time[-1]))

    def registered(self, elapsed: float, result: Result) -> Decision | None:
        self.step, self.last = max(self.step, elapsed - self.last), elapsed
        self.clock.mark()
        first = int(np.searchsorted(self.time, elapsed, side="left"))  # the grid times >= it
        if self.answers and self.answers[-1][0] == first:
            self.answers[-1] = (first, result)  # superseded before the next grid time
        else:
            self.answers.append((first, result))
        self.registered_count += 1
        if self.sender is not None:  # for the caller, should the process die
            self.sender.registered(self.registered_count, elapsed, self.step)
        if self.registered_count == self.limit:
            return Decision.now("the replay has registered what the lost run had")
        return None


class _Watch:
    """A clock that notes, since its last `mark()`, the longest interval between the module's
    reports of work (from the mark to the first, between them), and when the last one began.
    With `memory` (an isolated trial, see `Sender`), it writes its time there at each."""

    def __init__(self, clock: Clock, memory: mmap.mmap | None = None) -> None:
        self.clock = clock
        self.memory = memory
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
        if self.memory is not None:
            NOW.pack_into(self.memory, 8, now)

    def mark(self) -> None:
        self.longest, self.previous, self.reports = 0.0, self.clock.now(), 0

    def spent_by_last_report(self, deadline: float) -> bool:
        """Whether the last report since the mark began before `deadline` and reached it."""
        slack = 1e-9 * max(1.0, abs(deadline))  # as `Context.remaining` rounds
        return self.reports > 0 and self.began < deadline - slack <= self.previous


def run_contract(
    trial: Trial,
    time: Array,
    out: Row,
    sender: Sender | None = None,
    begin: int = 0,
    end: int | None = None,
) -> tuple[Failures, int, float]:
    """One run per grid time (from index `begin` on, up to `end` if given) on the same
    instance, with that time as its allocation; `out` records at `time[j]` the score of its
    result and the quality it reported, where it returned one (a run that raised or returned
    None has none).

    Also returns the step: the most any of the runs used past its allocation (0 if none did),
    whether it returned a result, none, or raised.
    """
    failed: Failures = []
    overruns = 0
    step = 0.0
    for j in range(begin, len(time) if end is None else end):
        ran_failed, overran, past = _contract_run(trial, j, float(time[j]), out, sender)
        failed += ran_failed
        overruns += overran
        step = max(step, past)
        if sender is not None:
            sender.ran(j, out, ran_failed, overran, past)
    return failed, overruns, step


def _contract_run(
    trial: Trial, j: int, allocation: float, out: Row, sender: Sender | None
) -> tuple[Failures, int, float]:
    """The run at grid index `j` (`anytime.runtime.run`'s): its failures, whether it overran
    (0 or 1), and how much it used past its allocation (negative when it used less)."""
    if sender is not None:
        sender.run_begins()
    instance, args = trial.problem()  # made afresh: a module may change its arguments
    clock = trial.clock()
    if sender is not None:
        clock = sender.noting(clock)
        sender.started(clock.now())
    record = run_trial(trial.module, args, Budget(allocation, clock=clock), trial.mode)
    past = float(record.time_used - allocation)
    overran = int(record.status is Status.CONTRACT_EXPIRED)
    if record.status in (Status.FAILED, Status.CRASHED):
        return [(record.error or "failed", record.traceback or "")], 0, past
    if record.result is not None:  # None: the row keeps quality 0, unscored
        out.record(j, trial.score(instance, record.result.value), record.result.quality)
    return [], overran, past


# In the shared memory: the run's start, its clock's latest time (at each report of work), and
# of what it registered: how many results, when the last came, its largest gap so far.
NOTE = struct.Struct("5d")
NOW = struct.Struct("d")
