"""Isolated mode: the module runs in a `Child` (`anytime.isolation`) as it would run in soft
mode, sending each result it keeps as it keeps it; the caller keeps the best of them and answers
at the deadline (or on the watchdog, or when the child dies) as hard mode does. An observer's
`started` runs in the caller, its `registered` and `look` in the child (on its copy), its log
(an observer's `log` attribute, if it has one) is sent to the caller's as it records.
A `KeyboardInterrupt` in the child is the module's own (the child leads a process group of its
own, which a terminal's Ctrl-C does not reach: the caller gets it, and ends the child): a failed
run, as any other error the module raises.
"""

from __future__ import annotations

import mmap
import struct
import threading
import time
from collections.abc import Mapping, Sequence
from functools import partial
from typing import Any

from anytime.clocks import Clock, Unit
from anytime.isolation import Channel, Child, died
from anytime.modules import AnytimeModule, Context, Result
from anytime.runtime.driving import (
    Outcome,
    Slot,
    Watcher,
    answer,
    context,
    describe,
    drive,
    failure,
    interrupted,
    keeps_latest,
    late,
    recorded,
)
from anytime.runtime.modes import Isolated
from anytime.runtime.records import RunRecord, Status


class _SharedTicks:
    """A work clock whose time the caller can read while the child moves it: the ticks the
    child's module reports live in memory the fork shares. The tick that takes the module past
    its allocation ends its run there: the child says so and waits to be ended, so the record
    is the same however busy the machine is (as `_Fence` makes it in hard mode)."""

    unit: Unit = "ticks"

    def __init__(self, start: float) -> None:
        self.start = start
        self._memory = mmap.mmap(-1, 8)  # anonymous and shared: the child writes, the caller reads
        self.ticks = 0.0
        self.ctx: Context | None = None
        self.channel: Channel | None = None
        self.watcher: Watcher | None = None

    def now(self) -> float:
        return self.start + self.ticks

    def advance(self, n: float) -> None:
        self.ticks += n
        struct.pack_into("d", self._memory, 0, self.ticks)
        ctx = self.ctx
        if ctx is not None and self.channel is not None and late(self.ticks, ctx.allocation):
            looks = 0 if self.watcher is None else self.watcher.looks
            self.channel.send(("crossed", self.ticks, looks))
            while True:  # the caller answers and ends this process
                time.sleep(3600)

    def read(self) -> float:
        """The ticks reported so far (from the caller's side)."""
        return float(struct.unpack_from("d", self._memory, 0)[0])


class _SendingSlot(Slot):
    """The child's slot: every result kept is sent to the caller at once."""

    def __init__(self, channel: Channel, latest: bool) -> None:
        super().__init__(threaded=True, latest=latest)
        self.channel = channel

    def keep(self, result: Result) -> None:
        if self.closed:
            return
        try:
            self.channel.send(("result", result))
        except Exception as exc:  # pickling it failed: say which result could not travel
            raise TypeError(
                f"its result ({describe(result.value)}) cannot be sent from its process: {exc}"
            ) from exc
        super().keep(result)


class _SentLog:
    """A stopping policy's log in the child: each event goes to the caller's log."""

    def __init__(self, channel: Channel) -> None:
        self.channel = channel

    def record(self, time: float, kind: str, data: Mapping[str, Any]) -> None:
        self.channel.send(("log", time, kind, dict(data)))


def run_isolated(
    module: AnytimeModule,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    allocation: float,
    clock: Clock,
    caller_stop: threading.Event,
    watcher: Watcher | None,
    mode: Isolated,
) -> RunRecord:
    """`run` with the module in a child process (see the module docstring)."""
    watchdog = mode.watchdog
    ticks = _SharedTicks(clock.now()) if clock.unit != "seconds" else None
    start = clock.now()
    side = _CallerSide(module, allocation, caller_stop, watcher)
    child = partial(_child, module, args, kwargs, allocation, clock, ticks, watcher)
    began = time.monotonic()
    process = Child(child, mode.limits)
    try:
        while side.outcome is None:
            # Whether it had gone before this read: a child that has gone is crashed only once
            # everything it sent before it went is read (it may send its last results, and
            # even "done", after a read and before the next look).
            gone = process.gone
            wait = min(0.01, max(0.0, began + watchdog - time.monotonic()))
            if ticks is None:
                wait = min(wait, max(0.0, allocation - (clock.now() - start)))
            messages = process.receive(wait)
            if side.take(messages) is not None:
                break
            if gone and not messages:
                side.exit_code = process.exit_code
                side.outcome = Outcome(Status.CRASHED, died(side.exit_code))
            elif gone:
                continue  # read the rest of what it sent first
            elif caller_stop.is_set():
                side.outcome = Outcome(Status.INTERRUPTED)
            elif ticks is None and clock.now() - start >= allocation:
                side.outcome = _deadline(module, caller_stop)
            elif time.monotonic() - began >= watchdog:
                used = ticks.read() if ticks is not None else clock.now() - start
                side.outcome = Outcome(
                    Status.FAILED,
                    f"watchdog: no answer after {watchdog:g} s of wall time (it had used"
                    f" {used:.6g} of its {allocation:g} {clock.unit})",
                )
    except KeyboardInterrupt as exc:  # Ctrl-C while the caller waits: end the child, answer
        side.outcome = interrupted(exc)
    finally:
        used = clock.now() - start if ticks is None else ticks.read()  # the answer's time
        process.end()
    if ticks is not None:
        clock.advance(used)  # the caller's clock moves as if the module had run here
    return side.record(used)


def _child(
    module: AnytimeModule,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    allocation: float,
    clock: Clock,
    ticks: _SharedTicks | None,
    watcher: Watcher | None,
    channel: Channel,
) -> None:
    """(In the child.) The run, as soft mode runs it, sending what it keeps as it keeps it."""
    ctx = context(allocation, clock if ticks is None else ticks, threading.Event(), watcher)
    if ticks is not None:
        ticks.ctx, ticks.channel, ticks.watcher = ctx, channel, watcher
    if watcher is not None and getattr(watcher.observer, "log", None) is not None:
        watcher.observer.log = _SentLog(channel)  # type: ignore[attr-defined]
    slot = _SendingSlot(channel, keeps_latest(module))
    try:
        outcome = drive(module, ctx, args, kwargs, slot, watcher)
    except BaseException as exc:  # a result that could not be sent, or the like
        outcome = failure(exc)
    if outcome.interrupt is not None:  # no Ctrl-C reaches a process of its own: the module's
        outcome = failure(outcome.interrupt)
    looks = 0 if watcher is None else watcher.looks
    channel.send(("done", outcome.status, outcome.error, outcome.traceback, looks))


class _CallerSide:
    """What the caller has of an isolated run: the best of the results the child sent, its
    observer's looks and log, and how the run ended once it knows."""

    def __init__(
        self,
        module: AnytimeModule,
        allocation: float,
        caller_stop: threading.Event,
        watcher: Watcher | None,
    ) -> None:
        self.module, self.allocation, self.caller_stop = module, allocation, caller_stop
        self.watcher = watcher
        self.log = None if watcher is None else getattr(watcher.observer, "log", None)
        self.slot = Slot(threaded=False, latest=keeps_latest(module))
        self.looks = 0
        self.outcome: Outcome | None = None
        self.exit_code: int | None = None

    def take(self, messages: Sequence[Any]) -> Outcome | None:
        """The child's messages, in order: how the run ended, if one of them says."""
        for message in messages:
            kind = message[0]
            if kind == "result":
                self.slot.offer(message[1])
            elif kind == "log" and self.log is not None:
                self.log.record(*message[1:])
            elif kind == "crossed":
                self.outcome, self.looks = _deadline(self.module, self.caller_stop), message[2]
                if self.watcher is not None and not late(message[1], self.allocation):
                    self.outcome = Outcome(Status.STOPPED)  # its observer's stop time came
            elif kind == "done":
                status, error, trace, self.looks = message[1:]
                if status is Status.FAILED and (error or "").startswith("MemoryError"):
                    status = Status.CRASHED  # it ran out of the memory it may have
                self.outcome = Outcome(status, error, trace)
                break
        return self.outcome

    def record(self, used: float) -> RunRecord:
        outcome = self.outcome
        assert outcome is not None
        if self.watcher is not None:
            self.watcher.looks = self.looks
            if outcome.status is Status.INTERRUPTED and self.watcher.reached(used):
                outcome = Outcome(Status.STOPPED)
        best, count = self.slot.close()
        record = recorded(
            self.module, best, count, outcome, used, self.allocation, self.looks, self.exit_code
        )
        return answer(record, outcome)


def _deadline(module: AnytimeModule, caller_stop: threading.Event) -> Outcome:
    """How a run ends that the deadline ended (as hard mode says it)."""
    contract = module.kind == "contract" and not caller_stop.is_set()
    return Outcome(Status.CONTRACT_EXPIRED if contract else Status.INTERRUPTED)
