"""Running one anytime module under a contract or interruption, and keeping its best result.

"Interruptible algorithms produce results of the quality advertised by their performance
profiles even when interrupted unexpectedly; contract algorithms must be given a particular time
allocation in advance" (Zilberstein & Russell). `run` does both and answers with a `RunRecord`,
never with an exception for running out of time: the best `Result` registered so far, a status,
the time used, and for a failure the error with its traceback. Whatever the module does — raise
midway, yield something that is not a `Result`, build a `Result` of quality outside [0, 1]
(which `Result` itself refuses), overrun its contract, or hang — the best result it registered
before is kept.

Soft interruption runs the module in the caller's thread and checks the deadline each time it
yields. Hard interruption (`hard=True`) runs it in a worker thread that publishes every result to
a slot; at the deadline the caller takes the slot's best result, asks the module to stop (its
`ctx.expired` turns true) and returns at once, so a module stuck in a long computation cannot
make the caller late. Python cannot kill a thread: a stuck module keeps its (daemon) thread until
it next looks at its context or finishes, and its late results are ignored.
"""

from __future__ import annotations

import math
import threading
import traceback
from collections.abc import Generator, Mapping, Sequence
from contextlib import suppress
from enum import StrEnum
from typing import Any

from attrs import frozen

from anytime.clocks import Clock, WorkClock
from anytime.modules import AnytimeModule, Context, Result


class Status(StrEnum):
    """How a run ended."""

    COMPLETED = "completed"  # the module finished on its own, within its time
    INTERRUPTED = "interrupted"  # its allocation ran out, or it was stopped from outside
    CONTRACT_EXPIRED = "contract-expired"  # a contract module used more than its allocation
    FAILED = "failed"  # it raised, or broke the protocol (see `error`)
    NO_RESULT = "no-result"  # it ended without registering any result


@frozen
class RunRecord:
    """What a run gives back.

    Attributes:
        module: the module's name.
        status: how the run ended.
        result: the best `Result` registered in time (highest quality; the later one on ties),
            or None when there is none.
        time_used: time on the run's clock from start to the answer.
        allocation: the time the run was given.
        registered: how many results the module registered in time.
        error: for a failure, what went wrong, in one line.
        traceback: for a failure raised by the module, its traceback.
    """

    module: str
    status: Status
    result: Result | None
    time_used: float
    allocation: float
    registered: int = 0
    error: str | None = None
    traceback: str | None = None

    @property
    def quality(self) -> float:
        """The quality of the answer (0 when there is none)."""
        return self.result.quality if self.result is not None else 0.0


class _Slot:
    """The best result registered so far; written by the module's side, read by the caller's."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.best: Result | None = None
        self.count = 0
        self.closed = False  # once the caller has answered, late results are ignored

    def offer(self, result: Result) -> None:
        with self._lock:
            if self.closed:
                return
            self.count += 1
            if self.best is None or result.quality >= self.best.quality:
                self.best = result

    def close(self) -> tuple[Result | None, int]:
        with self._lock:
            self.closed = True
            return self.best, self.count


@frozen
class _Outcome:
    """How the module's side ended (before the caller turns it into a record)."""

    status: Status
    error: str | None = None
    traceback: str | None = None


def run(
    module: AnytimeModule,
    args: Sequence[Any] = (),
    kwargs: Mapping[str, Any] | None = None,
    *,
    allocation: float = math.inf,
    clock: Clock | None = None,
    stop: threading.Event | None = None,
    hard: bool = False,
    poll: float = 0.001,
) -> RunRecord:
    """Run `module(ctx, *args, **kwargs)` with `allocation` time on `clock` (a fresh
    `WorkClock` by default) and answer with its best registered result.

    Args:
        stop: set from another thread to interrupt the run.
        hard: run the module in a worker thread and return at the deadline even if the
            module does not yield (see the module docstring).
        poll: with `hard` on a clock that is not the wall clock, how often (seconds) the caller
            looks at the clock.
    """
    clock = clock if clock is not None else WorkClock()
    stop = stop if stop is not None else threading.Event()
    ctx = Context(allocation=allocation, clock=clock, stop=stop)
    slot = _Slot()
    if not hard:
        outcome = _drive(module, ctx, args, kwargs or {}, slot)
        return _record(module, ctx, slot, outcome)
    finished = threading.Event()
    box: list[_Outcome] = []

    def work() -> None:
        try:
            box.append(_drive(module, ctx, args, kwargs or {}, slot))
        finally:
            finished.set()

    worker = threading.Thread(target=work, name=f"anytime:{module.name}", daemon=True)
    worker.start()
    _wait(finished, ctx, poll)
    if not finished.is_set():  # the deadline came first: answer now, tell the module to stop
        stop.set()
        status = Status.CONTRACT_EXPIRED if module.kind == "contract" else Status.INTERRUPTED
        return _record(module, ctx, slot, _Outcome(status))
    return _record(module, ctx, slot, box[0])


def _wait(finished: threading.Event, ctx: Context, poll: float) -> None:
    """Until the module finishes, its allocation is spent, or it is stopped from outside."""
    wall = ctx.clock.unit == "seconds"
    while not finished.is_set():
        if ctx.stop.is_set() or ctx.elapsed >= ctx.allocation:
            return
        remaining = ctx.allocation - ctx.elapsed
        finished.wait(min(remaining, poll) if not wall else min(remaining, 0.05))


def _drive(
    module: AnytimeModule,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    slot: _Slot,
) -> _Outcome:
    """Run the module on this thread, offering each result registered in time to `slot`."""
    if module.kind == "interruptible":
        return _interruptible(module, ctx, args, kwargs, slot)
    try:
        value = module(ctx, *args, **kwargs) if module.kind == "contract" else module(*args)
    except Exception as exc:
        return _failure(exc)
    if module.kind == "elementary":
        if not isinstance(value, Result):  # its quality combines its inputs' (min by default)
            positions = sorted(module.parameters.index(name) for name in module.inputs)
            qualities = [_quality_of(args[i]) for i in positions if i < len(args)]
            value = Result(value, module.combine(qualities))
        slot.offer(value)
        return _Outcome(Status.COMPLETED)
    if not isinstance(value, Result):
        return _Outcome(Status.FAILED, f"returned {_describe(value)}, not a Result")
    if ctx.stop.is_set() and ctx.elapsed < ctx.allocation:
        return _Outcome(Status.INTERRUPTED)  # answered after the caller gave up on it
    slot.offer(value)
    if ctx.elapsed > ctx.allocation:
        return _Outcome(Status.CONTRACT_EXPIRED)
    return _Outcome(Status.COMPLETED)


def _interruptible(
    module: AnytimeModule,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    slot: _Slot,
) -> _Outcome:
    try:
        generator: Generator[Any, None, None] = module(ctx, *args, **kwargs)
    except Exception as exc:
        return _failure(exc)
    try:
        while True:
            try:
                item = next(generator)
            except StopIteration:
                return _Outcome(Status.COMPLETED)
            except Exception as exc:
                return _failure(exc)
            if ctx.stop.is_set():
                return _Outcome(Status.INTERRUPTED)
            if ctx.elapsed > ctx.allocation:  # registered too late to count
                return _Outcome(Status.INTERRUPTED)
            if not isinstance(item, Result):
                return _Outcome(Status.FAILED, f"yielded {_describe(item)}, not a Result")
            slot.offer(item)
            if ctx.expired:
                return _Outcome(Status.INTERRUPTED)
    finally:
        # The outcome is decided; a module that fails while being closed changes nothing.
        with suppress(Exception):
            generator.close()


def _quality_of(arg: Any) -> float:
    return arg.quality if isinstance(arg, Result) else 1.0


def _failure(exc: BaseException) -> _Outcome:
    headline = "".join(traceback.format_exception_only(exc)).strip().splitlines()[-1]
    return _Outcome(Status.FAILED, headline, "".join(traceback.format_exception(exc)))


def _describe(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text[:60]}{'...' if len(text) > 60 else ''}"


def _record(module: AnytimeModule, ctx: Context, slot: _Slot, outcome: _Outcome) -> RunRecord:
    best, count = slot.close()
    status = outcome.status
    if best is None and status in (Status.COMPLETED, Status.INTERRUPTED):
        status = Status.NO_RESULT
    return RunRecord(
        module=module.name,
        status=status,
        result=best,
        time_used=ctx.elapsed,
        allocation=ctx.allocation,
        registered=count,
        error=outcome.error,
        traceback=outcome.traceback,
    )
