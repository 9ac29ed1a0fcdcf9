"""The worker side of the profile builder: what a domain supplies, and running trials.

Everything here is sent to worker processes (or Dask workers), so it must pickle: chunks of
trials carry the module (pickled by reference), the problem set and the grid.
"""

from __future__ import annotations

import inspect
import math
import mmap
import pickle
import struct
import time as _time
import traceback
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from itertools import islice
from typing import Any, Literal

import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from anytime.clocks import Clock, WallClock, WorkClock
from anytime.isolation import WATCHDOG, Channel, Child, Isolation, Lost, calls, died
from anytime.modules import AnytimeModule, Result
from anytime.problems import BuildError, Grid, Instance, ProblemSet
from anytime.profiles.profile import Array
from anytime.runtime.executor import Status, run
from anytime.runtime.modes import Budget
from anytime.runtime.observe import Decision, Observer

ClockName = Literal["work", "wall"]

CLOCKS: dict[str, tuple[Callable[[], Clock], Literal["ticks", "seconds"]]] = {
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
    isolation: Isolation = "process"  # each trial's run in a child process (see `measure_chunk`)
    watchdog: float = WATCHDOG  # wall seconds an isolated run may take (see `_isolated`)


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
    (see `_isolated`): a trial whose process dies, or that takes longer than the watchdog, is a
    failed trial that keeps what its run had registered before, as `anytime.runtime.run` keeps
    it, and the next trials go on in a new process."""
    return next(measure_chunks([chunk]))


def measure_chunks(chunks: Sequence[Chunk]) -> Iterator[Done]:
    """`measure_chunk` of each of `chunks` (of one build) in turn; isolated, one process runs
    them all (a process per chunk would cost a fork each)."""
    if not chunks:
        return
    first = chunks[0]
    flats = [flat for chunk in chunks for flat in range(chunk.start, chunk.stop)]
    outcomes: Iterator[Measured]
    if first.isolation == "process":
        outcomes = _isolated(first, flats)
    else:
        outcomes = (_measured(first, flat) for flat in flats)
    for chunk in chunks:
        yield _done(chunk, islice(outcomes, chunk.stop - chunk.start))


def _done(chunk: Chunk, outcomes: Iterator[Measured]) -> Done:
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


def _measured(chunk: Chunk, flat: int, sender: _Sender | None = None, begin: int = 0) -> Measured:
    """Run trial `flat` of the chunk (a contract module's from grid index `begin` on: the
    rows before it stay without a result). Isolated, `sender` keeps the caller informed of
    what the run has done, should its process die (see `_Sender`)."""
    times = chunk.grid.time
    out = _empty_row(times)
    trial = _trial(chunk, flat)
    if chunk.module.kind == "interruptible":
        failed, overran, longest = _interruptible(trial, times, out, sender)
    else:
        failed, overran, longest = _contract(trial, times, out, sender, begin)
    row = (out.quality, out.scored, out.reported)
    return Measured(row, float(out.finished[0]), failed, overran, longest)


def _empty_row(times: Array) -> Row:
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


def _interruptible(
    trial: Trial,
    time: Array,
    out: Row,
    sender: _Sender | None = None,
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
    record = run(trial.module, args, budget=Budget(clock=clock), observer=trace)
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
        self, time: Array, clock: _Watch, sender: _Sender | None, limit: int | None
    ) -> None:
        self.time, self.clock, self.sender, self.limit = time, clock, sender, limit
        self.answers: list[tuple[int, Result]] = []  # (first grid index it answers for, result)
        self.registered_count = 0
        self.start = self.last = self.step = 0.0  # the start; the last result, the largest gap

    def started(self, module: AnytimeModule, allocation: float) -> Decision:
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
    With `memory` (an isolated trial, see `_Sender`), it writes its time there at each."""

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
            _NOW.pack_into(self.memory, 8, now)

    def mark(self) -> None:
        self.longest, self.previous, self.reports = 0.0, self.clock.now(), 0

    def spent_by_last_report(self, deadline: float) -> bool:
        """Whether the last report since the mark began before `deadline` and reached it."""
        slack = 1e-9 * max(1.0, abs(deadline))  # as `Context.remaining` rounds
        return self.reports > 0 and self.began < deadline - slack <= self.previous


def _contract(
    trial: Trial, time: Array, out: Row, sender: _Sender | None = None, begin: int = 0
) -> tuple[Failures, int, float]:
    """One run per grid time (from index `begin` on) on the same instance, with that time as
    its allocation; `out` records at `time[j]` the score of its result and the quality it
    reported, where it returned one (a run that raised or returned None has none).

    Also returns the step: the most any of the runs used past its allocation (0 if none did),
    whether it returned a result, none, or raised.
    """
    failed: Failures = []
    overruns = 0
    step = 0.0
    for j in range(begin, len(time)):
        ran_failed, overran, past = _contract_run(trial, j, float(time[j]), out, sender)
        failed += ran_failed
        overruns += overran
        step = max(step, past)
        if sender is not None:
            sender.ran(j, out, ran_failed, overran, past)
    return failed, overruns, step


def _contract_run(
    trial: Trial, j: int, allocation: float, out: Row, sender: _Sender | None
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
    record = run(trial.module, args, budget=Budget(allocation, clock=clock))
    past = float(record.time_used - allocation)
    overran = int(record.status is Status.CONTRACT_EXPIRED)
    if record.status in (Status.FAILED, Status.CRASHED):
        return [(record.error or "failed", record.traceback or "")], 0, past
    if record.result is not None:  # None: the row keeps quality 0, unscored
        out.record(j, trial.score(instance, record.result.value), record.result.quality)
    return [], overran, past


# Isolated trials. The trials of a sequential build (or of a worker's chunk) run in turn in a
# child process (`anytime.isolation.Child`). A trial whose process dies, or that the watchdog
# ends, keeps what `anytime.runtime.run` keeps of such a run:
# - An interruptible trial, the last result it registered up to each grid time (after its
#   death, the last one before it). `run` has each result sent to it as it comes, which costs
#   pickling every result (find-path's are 3 MB each: sending them doubled the time of its
#   isolated build), so the child here notes, in memory the fork shares, only how many results
#   the run has registered, when the last came, its largest gap so far and its clock's time.
#   After a death, the trial runs again in a fresh child, on the same instance from the same
#   seed, and stops right after that many results: it registers the same results (on the work
#   clock a run is determined by its instance), and is scored there as any trial is.
# - A contract trial, the runs it finished (each sent to the caller, scored: a few numbers);
#   the lost run has no result, and the trial goes on at its next grid time in a new process,
#   as separate runs of `run` would.

# In the shared memory: the run's start, its clock's latest time (at each report of work), and
# of what it registered: how many results, when the last came, its largest gap so far.
_NOTE = struct.Struct("5d")
_NOW = struct.Struct("d")


class _Noting:
    """A clock that writes its time, at every report of work, to memory the caller can read."""

    def __init__(self, clock: Clock, memory: mmap.mmap) -> None:
        self.clock, self.memory = clock, memory
        self.unit = clock.unit

    def now(self) -> float:
        return self.clock.now()

    def advance(self, n: float) -> None:
        clock = self.clock
        clock.advance(n)
        _NOW.pack_into(self.memory, 8, clock.now())


class _Sender:
    """The child's side of an isolated trial (see above)."""

    def __init__(self, channel: Channel, memory: mmap.mmap) -> None:
        self.channel, self.memory = channel, memory

    def noting(self, clock: Clock) -> Clock:
        return _Noting(clock, self.memory)

    def run_begins(self) -> None:
        """A run begins: nothing yet (a process that dies now has used no time)."""
        _NOTE.pack_into(self.memory, 0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def started(self, start: float) -> None:
        struct.pack_into("dd", self.memory, 0, start, start)

    def registered(self, count: int, at: float, step: float) -> None:
        """An interruptible run has registered `count` results, the last at `at`, with
        `step` the largest gap between its yields so far."""
        struct.pack_into("3d", self.memory, 16, count, at, step)

    def ran(self, j: int, out: Row, failed: Failures, overran: int, past: float) -> None:
        """The contract run at grid index `j` ended as `out[j]` says."""
        row = (float(out.quality[j]), bool(out.scored[j]), float(out.reported[j]))
        self.channel.send(("ran", j, row, failed, overran, past))


def _measuring(
    chunk: Chunk, flats: Sequence[int], position: int, begin: int, memory: mmap.mmap, out: Channel
) -> None:
    """The child: trials `flats[position:]` in turn, the first from grid index `begin` on."""
    sender = _Sender(out, memory)
    for index in range(position, len(flats)):
        sender.run_begins()  # nothing of the trial before is its
        try:
            value = _measured(chunk, flats[index], sender, begin if index == position else 0)
        except BaseException as exc:  # a problem set that breaks its contract, and the like
            out.send(("raised", _portable(exc)))
            return
        out.send(("value", value))


def _portable(exc: BaseException) -> BaseException:
    """`exc` if it pickles, else a RuntimeError carrying its traceback's text."""
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:
        text = "".join(traceback.format_exception(exc)).rstrip()
        return RuntimeError(f"in an isolated process:\n{text}")
    return exc


def _isolated(chunk: Chunk, flats: Sequence[int]) -> Iterator[Measured]:
    """The outcomes of trials `flats` of the chunk's build, in order, run in child processes:
    one makes them in turn, and a new one goes on after a trial whose process dies or that
    takes longer than the watchdog (an interruptible trial, or each run of a contract trial).
    An error the trial raises in the caller's code (the problem set) is raised here."""
    if not flats:
        return
    memory = mmap.mmap(-1, _NOTE.size)  # anonymous and shared with the forks
    watchdog = chunk.watchdog
    position = 0
    progress = _Progress(chunk, flats[0])
    while True:
        target = partial(_measuring, chunk, flats, position, progress.begin, memory)
        process = Child(target)
        lost = ""
        try:
            since = _time.monotonic()
            while not lost:
                gone = process.gone  # then whatever it sent before it went is read below
                messages = process.receive(
                    min(0.05, max(0.0, since + watchdog - _time.monotonic()))
                )
                for kind, *data in messages:
                    if kind == "raised":
                        raise data[0]
                    if kind == "value":
                        yield progress.measured(data[0])
                        position += 1
                        if position == len(flats):
                            return
                        progress = _Progress(chunk, flats[position])
                        since = _time.monotonic()
                    elif kind == "ran":
                        progress.ran(*data)
                        since = _time.monotonic()  # each contract run has its watchdog
                if messages:
                    continue
                if gone:
                    lost = died(process.exit_code)
                elif _time.monotonic() - since >= watchdog:
                    lost = f"watchdog: no answer after {watchdog:g} s of wall time"
        finally:
            process.end()
        done = progress.lost(lost, _NOTE.unpack_from(memory, 0))
        if done is not None:
            yield done
            position += 1
            if position == len(flats):
                return
            progress = _Progress(chunk, flats[position])


class _Progress:
    """What the caller has of the isolated trial under way (see `_isolated`)."""

    def __init__(self, chunk: Chunk, flat: int) -> None:
        self.chunk, self.flat = chunk, flat
        self.time = chunk.grid.time
        # A contract trial: the grid index it goes on from (after a lost run), its row, and
        # each finished (or lost) run's failures, overrun and step.
        self.begin = 0
        self.row = _empty_row(self.time)
        self.runs: dict[int, tuple[Failures, int, float]] = {}

    def ran(
        self, j: int, row: tuple[float, bool, float], failed: Failures, overran: int, past: float
    ) -> None:
        quality, scored, reported = row
        if scored:
            self.row.record(j, quality, reported)
        self.runs[j] = (failed, overran, past)

    def measured(self, value: Measured) -> Measured:
        """The trial's outcome, from what the last process measured (`value`: a contract
        trial's runs from `begin` on) and the runs before."""
        if self.begin == 0:
            return value
        b = self.begin
        row = self.row  # the runs before `begin`, and from it on the last process's
        row.quality[b:], row.scored[b:], row.reported[b:] = (part[b:] for part in value.row)
        before = [self.runs[j] for j in range(b)]
        return Measured(
            (row.quality, row.scored, row.reported),
            value.finished,
            [f for run_failed, _, _ in before for f in run_failed] + value.failed,
            sum(overran for _, overran, _ in before) + value.overruns,
            max([value.step, *(past for _, _, past in before)]),
        )

    def lost(self, reason: str, note: tuple[float, ...]) -> Measured | None:
        """The trial's process died, or the watchdog ended it, with `note` in the shared
        memory (see `_NOTE`): its outcome, or None for a contract trial that goes on at its
        next grid time."""
        failed = [(reason, "")]
        start, now, count, last, step = note
        elapsed = now - start  # as far as its clock's reports of work say
        if self.chunk.module.kind != "interruptible":
            j = max(self.runs, default=-1) + 1  # the run under way (they come in order)
            if j < len(self.time):  # (else it went after its last run: none is lost)
                self.runs[j] = (failed, 0, elapsed - float(self.time[j]))
                j += 1
            self.begin = j
            if self.begin < len(self.time):
                return None
            runs = [self.runs[i] for i in range(len(self.time))]
            return Measured(
                (self.row.quality, self.row.scored, self.row.reported),
                float(self.time[-1]),
                [f for run_failed, _, _ in runs for f in run_failed],
                sum(overran for _, overran, _ in runs),
                max([0.0, *(past for _, _, past in runs)]),
            )
        end = max(elapsed, last)
        allocation = float(self.time[-1])
        finished = end if end < allocation else allocation
        return Measured(self._replayed(int(count)), finished, failed, 0, max(step, end - last))

    def _replayed(self, count: int) -> tuple[Array, NDArray[np.bool_], Array]:
        """The row of an interruptible trial whose process died after registering `count`
        results: the trial run again in a child of its own up to its `count`-th result, and
        scored there (no result at any time if it registered none, or if the replay dies too,
        as a run whose crash does not come from its instance may)."""
        if count > 0:
            replay = partial(_replay, self.chunk, self.flat)
            [value] = list(calls(replay, [count], watchdog=self.chunk.watchdog))
            if not isinstance(value, Lost):
                return value  # type: ignore[no-any-return]
        out = _empty_row(self.time)
        return out.quality, out.scored, out.reported


def _replay(chunk: Chunk, flat: int, count: int) -> tuple[Array, NDArray[np.bool_], Array]:
    """(In a child process.) Trial `flat` run up to its `count`-th result: its row."""
    out = _empty_row(chunk.grid.time)
    _interruptible(_trial(chunk, flat), chunk.grid.time, out, limit=count)
    return out.quality, out.scored, out.reported
