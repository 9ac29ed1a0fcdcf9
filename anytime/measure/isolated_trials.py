"""Isolated trials: a build's trials run in turn in a child process, and a trial whose process
dies, or that the watchdog ends, keeps what `anytime.runtime.run` keeps of such a run
(the process is an `anytime.isolation.Child`):
- An interruptible trial, the last result it registered up to each grid time (after its
  death, the last one before it). `run` has each result sent to it as it comes, which costs
  pickling every result (find-path's are 3 MB each: sending them doubled the time of its
  isolated build), so the child here notes, in memory the fork shares, only how many results
  the run has registered, when the last came, its largest gap so far and its clock's time.
  After a death, the trial runs again in a fresh child, on the same instance from the same
  seed, and stops right after that many results: it registers the same results (on the work
  clock a run is determined by its instance), and is scored there as any trial is.
- A contract trial, the runs it finished (each sent to the caller, scored: a few numbers);
  the lost run has no result, and the trial goes on at its next grid time in a new process,
  as separate runs of `run` would.

With `Isolated(limits=...)` every run has a process of its own, as `run` gives it, so that the
limits are each run's (an interruptible trial's one run, each of a contract trial's runs); the
limits also cover making the trial's problem, which the child does before the run.
"""

from __future__ import annotations

import mmap
import struct
import time as _time
from collections.abc import Iterator, Sequence
from functools import partial

import numpy as np
from numpy.typing import NDArray

from anytime.clocks import Clock
from anytime.isolation import Channel, Child, Lost, calls, died, portable
from anytime.measure.trials import (
    NOTE,
    NOW,
    Chunk,
    Failures,
    Measured,
    Row,
    empty_row,
    measured,
    run_interruptible,
    trial_of,
)
from anytime.profiles.profile import Array
from anytime.runtime.modes import Isolated


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
        NOW.pack_into(self.memory, 8, clock.now())


class Sender:
    """The child's side of an isolated trial (see above)."""

    def __init__(self, channel: Channel, memory: mmap.mmap) -> None:
        self.channel, self.memory = channel, memory

    def noting(self, clock: Clock) -> Clock:
        return _Noting(clock, self.memory)

    def run_begins(self) -> None:
        """A run begins: nothing yet (a process that dies now has used no time)."""
        NOTE.pack_into(self.memory, 0, 0.0, 0.0, 0.0, 0.0, 0.0)

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
    chunk: Chunk,
    flats: Sequence[int],
    position: int,
    begin: int,
    memory: mmap.mmap,
    single: bool,
    out: Channel,
) -> None:
    """The child: trials `flats[position:]` in turn, the first from grid index `begin` on;
    `single`, only one run (the first trial's, or its contract run at `begin`)."""
    sender = Sender(out, memory)
    times = len(chunk.grid.time)
    for index in range(position, len(flats)):
        sender.run_begins()  # nothing of the trial before is its
        first = begin if index == position else 0
        end = first + 1 if single and chunk.module.kind == "contract" else None
        try:
            value = measured(chunk, flats[index], sender, first, end)
        except BaseException as exc:  # a problem set that breaks its contract, and the like
            out.send(("raised", portable(exc)))
            return
        if end is None or end == times:  # the trial is done (else "ran" said what it did)
            out.send(("value", value))
        if single:
            return


def isolated_outcomes(chunk: Chunk, flats: Sequence[int], mode: Isolated) -> Iterator[Measured]:
    """The outcomes of trials `flats` of the chunk's build, in order, run in child processes:
    one makes them in turn, and a new one goes on after a trial whose process dies or that
    takes longer than the mode's watchdog (an interruptible trial, or each run of a contract
    trial); with the mode's limits, a new one for every run (see above). An error the trial
    raises in the caller's code (the problem set) is raised here."""
    if not flats:
        return
    memory = mmap.mmap(-1, NOTE.size)  # anonymous and shared with the forks
    watchdog = mode.watchdog
    single = mode.limits is not None  # a process per run: the limits are each run's
    last = len(chunk.grid.time) - 1
    position = 0
    progress = _Progress(chunk, flats[0], mode)
    while True:
        target = partial(_measuring, chunk, flats, position, progress.begin, memory, single)
        process = Child(target, mode.limits)
        lost = ""
        renew = False  # the process did its one run (`single`): the next goes on in a new one
        try:
            since = _time.monotonic()
            while not lost and not renew:
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
                        progress = _Progress(chunk, flats[position], mode)
                        since = _time.monotonic()
                        renew = single
                    elif kind == "ran":
                        progress.ran(*data)
                        since = _time.monotonic()  # each contract run has its watchdog
                        if single and data[0] < last:
                            progress.begin, renew = data[0] + 1, True
                if messages:
                    continue
                if gone:
                    lost = process.unsent or died(process.exit_code)
                elif _time.monotonic() - since >= watchdog:
                    lost = f"watchdog: no answer after {watchdog:g} s of wall time"
        finally:
            process.end()
        if renew:
            continue
        done = progress.lost(lost, NOTE.unpack_from(memory, 0))
        if done is not None:
            yield done
            position += 1
            if position == len(flats):
                return
            progress = _Progress(chunk, flats[position], mode)


class _Progress:
    """What the caller has of the isolated trial under way (see `isolated_outcomes`)."""

    def __init__(self, chunk: Chunk, flat: int, mode: Isolated) -> None:
        self.chunk, self.flat, self.mode = chunk, flat, mode
        self.time = chunk.grid.time
        # A contract trial: the grid index it goes on from (after a lost run), its row, and
        # each finished (or lost) run's failures, overrun and step.
        self.begin = 0
        self.row = empty_row(self.time)
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
        memory (see `NOTE`): its outcome, or None for a contract trial that goes on at its
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
            mode = self.mode
            [value] = list(calls(replay, [count], watchdog=mode.watchdog, limits=mode.limits))
            if not isinstance(value, Lost):
                return value  # type: ignore[no-any-return]
        out = empty_row(self.time)
        return out.quality, out.scored, out.reported


def _replay(chunk: Chunk, flat: int, count: int) -> tuple[Array, NDArray[np.bool_], Array]:
    """(In a child process.) Trial `flat` run up to its `count`-th result: its row."""
    out = empty_row(chunk.grid.time)
    run_interruptible(trial_of(chunk, flat), chunk.grid.time, out, limit=count)
    return out.quality, out.scored, out.reported
