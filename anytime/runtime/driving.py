"""Driving a module on the thread that runs it: the one registration rule of the framework.

`drive` calls the module with its context, takes each result it registers in time (a contract's
return value, an interruptible module's yields), offers it to a `Slot` (the best so far), and
turns however the module ends into an `Outcome`. A `Watcher` is an observer's part in the run
(see `anytime.runtime.observe`): when it looks next, when the run stops, how many looks it took.
Every mode (`anytime.runtime.executor`, `threaded`, `isolated`) drives the module with these.
"""

from __future__ import annotations

import math
import threading
import traceback
from collections.abc import Generator, Mapping, Sequence
from contextlib import suppress
from typing import Any

from attrs import frozen

from anytime.clocks import Clock
from anytime.errors import interrupt_behind
from anytime.modules import AnytimeModule, Context, Result
from anytime.runtime.observe import Decision, Observer, PolicyError
from anytime.runtime.records import RunInterrupted, RunRecord, Status


class Slot:
    """The best result registered so far; written by the module's side, read by the caller's.

    The lock is only taken when the module runs on another thread (hard interruption)."""

    def __init__(self, threaded: bool, latest: bool = False) -> None:
        self.threaded = threaded
        self.latest = latest  # keep the latest result, not the highest self-reported
        self._lock = threading.Lock() if threaded else None
        self.best: Result | None = None
        self.count = 0
        self.closed = False  # once the caller has answered, late results are ignored

    def offer(self, result: Result) -> None:
        if self._lock is None:
            self.keep(result)
            return
        with self._lock:
            self.keep(result)

    def keep(self, result: Result) -> None:
        if self.closed:
            return
        self.count += 1
        best = self.best
        if self.latest or best is None or result.quality >= best.quality:
            self.best = result

    def close(self) -> tuple[Result | None, int]:
        if self._lock is None:
            self.closed = True
            return self.best, self.count
        with self._lock:
            self.closed = True
            return self.best, self.count


@frozen
class Outcome:
    """How the module's side ended (before the caller turns it into a record); `interrupt`, a
    KeyboardInterrupt the module's side caught, for the caller to raise once the record is kept."""

    status: Status
    error: str | None = None
    traceback: str | None = None
    interrupt: KeyboardInterrupt | None = None


def at_or_after(elapsed: float, time: float) -> bool:
    """Whether `elapsed` has reached `time`, within the rounding of a clock (never infinity)."""
    return time != math.inf and elapsed >= time - 1e-9 * max(1.0, abs(time))


def late(elapsed: float, allocation: float) -> bool:
    """Past the allocation, beyond the rounding of computing elapsed time on a clock."""
    return elapsed > allocation + 1e-9 * max(1.0, abs(allocation))


class Watcher:
    """An observer's part in one run: when it looks next, when the run stops, how many looks
    it took, and an error one of its looks raised (the run then fails).

    The module's context is given the observer's stop time as its allocation, so that a module
    that watches its time (or a contract made interruptible, which starts no contract that
    cannot end in time) ends there by itself."""

    def __init__(
        self, observer: Observer, module: AnytimeModule, args: Sequence[Any], allocation: float
    ) -> None:
        self.observer, self.allocation = observer, allocation
        self.ctx: Context | None = None
        self.best: Result | None = None  # the run's answer so far, kept by the driver
        self.looks = 0
        self.stopped = False
        self.look_at = self.stop_at = math.inf
        self.error: BaseException | None = None
        self.pending: float | None = None  # a look came due at this time, at a report of work
        self.follow(observer.started(module, args, allocation))

    def watch(self, ctx: Context) -> None:
        self.ctx = ctx
        ctx.allocation = min(self.allocation, self.stop_at)

    def clock(self, clock: Clock) -> Clock:
        """`clock` as the module sees it: each report of work may be a look."""
        return _Looking(clock, self)

    def follow(self, decision: Decision | None, elapsed: float = 0.0) -> None:
        if decision is None:
            return
        if not isinstance(decision, Decision):
            raise PolicyError(
                f"{self.observer.label} answered with {describe(decision)}, not a Decision"
            )
        self.stopped = decision.stop
        self.look_at = math.inf if decision.stop else decision.look_at
        # Stopping at the allocation is the allocation running out, not the observer's doing.
        stop_at = elapsed if decision.stop else decision.stop_at
        self.stop_at = stop_at if stop_at < self.allocation else math.inf
        if self.ctx is not None:
            self.ctx.allocation = min(self.allocation, self.stop_at)

    def registered(self, elapsed: float, result: Result, best: Result | None) -> bool:
        """After a result kept at `elapsed`: tell the observer, look if a look is due; whether
        the run stops."""
        self.best, self.pending = best, None
        self.follow(self.observer.registered(elapsed, result), elapsed)
        if not self.stopped:
            self.look(elapsed)
        return self.stopped or self.reached(elapsed)

    def look(self, elapsed: float) -> None:
        # A look at the time the run ends anyway (the observer's stop time, or the deadline)
        # could not change its answer: it is not taken, as `replay` does not take it.
        if at_or_after(elapsed, self.look_at) and not at_or_after(
            elapsed, min(self.stop_at, self.allocation)
        ):
            self.looks += 1
            self.follow(self.observer.look(elapsed, self.best), elapsed)

    def before_work(self) -> None:
        """Before a report of work: a look that came due at the report before is taken now,
        at the time it came due (the module registered nothing since, so the answer then is
        the answer now). It runs inside the module's `ctx.tick`, so what it raises is kept for
        the driver, and ends the run; a stop there is the module's allocation."""
        pending, self.pending = self.pending, None
        if pending is None or self.error is not None or self.stopped:
            return
        try:
            self.look(pending)
        except Exception as exc:
            self.error = exc
            self.stopped = True
        if self.stopped and self.ctx is not None:
            self.ctx.allocation = min(self.ctx.allocation, pending)

    def after_work(self, elapsed: float) -> None:
        """After a report of work: a look due now waits for the module's next move (a result
        it registers at this time is part of the answer then). Before the run has an answer
        there is nothing to look at: a look due then is taken at the first result."""
        if self.best is None or self.error is not None or self.stopped:
            return
        if at_or_after(elapsed, self.look_at):
            self.pending = elapsed

    def reached(self, elapsed: float) -> bool:
        """Whether the time the observer said to stop at has come."""
        return at_or_after(elapsed, self.stop_at)

    def late(self, elapsed: float) -> bool:
        """Whether a result at `elapsed` comes after the time the observer said to stop at."""
        return self.stop_at != math.inf and elapsed > self.stop_at + 1e-9 * max(
            1.0, abs(self.stop_at)
        )

    def failure(self, exc: BaseException) -> Outcome:
        return failure(exc, f"{self.observer.label}: ")


class _Looking:
    """A clock that gives the watcher a look at each report of work it is due at."""

    def __init__(self, clock: Clock, watcher: Watcher) -> None:
        self.clock, self.watcher = clock, watcher
        self.unit = clock.unit

    def now(self) -> float:
        return self.clock.now()

    def advance(self, n: float) -> None:
        watcher, clock = self.watcher, self.clock
        ctx = watcher.ctx
        if ctx is None or (watcher.look_at == math.inf and watcher.pending is None):
            clock.advance(n)
            return
        watcher.before_work()
        clock.advance(n)
        watcher.after_work(clock.now() - ctx.start)


def context(
    allocation: float, clock: Clock, stop: threading.Event, watcher: Watcher | None
) -> Context:
    """The module's context; with an observer, its clock gives looks and its allocation is the
    observer's stop time."""
    if watcher is None:
        return Context(allocation=allocation, clock=clock, stop=stop)
    ctx = Context(allocation=allocation, clock=watcher.clock(clock), stop=stop)
    watcher.watch(ctx)
    return ctx


def drive(
    module: AnytimeModule,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    slot: Slot,
    watcher: Watcher | None = None,
) -> Outcome:
    """Run the module on this thread, offering each result registered in time to `slot`."""
    if module.kind == "interruptible":
        return _interruptible(module, ctx, args, kwargs, slot, watcher)
    try:
        if module.kind == "elementary":
            value = module(*args, **kwargs)
            if not isinstance(value, Result):  # its quality combines its inputs' (min default)
                positions = sorted(module.parameters.index(name) for name in module.inputs)
                qualities = [_quality_of(args[i]) for i in positions if i < len(args)]
                value = Result(value, module.combine(qualities))
            return _returned(value, ctx, slot, watcher, elementary=True)
        value = module(ctx, *args, **kwargs)
    except (Exception, SystemExit) as exc:
        return raised(exc)
    except KeyboardInterrupt as exc:
        return interrupted(exc)
    except BaseException as exc:  # any other the module raised: a failed run
        return failure(exc)
    if watcher is not None and watcher.error is not None:
        return watcher.failure(watcher.error)
    if value is None:  # a contract's way of saying it has no result
        return Outcome(
            Status.CONTRACT_EXPIRED if late(ctx.elapsed, ctx.allocation) else Status.COMPLETED
        )
    if not isinstance(value, Result):
        return Outcome(Status.FAILED, f"returned {describe(value)}, not a Result")
    if ctx.stop.is_set() and ctx.elapsed < ctx.allocation:
        return Outcome(Status.INTERRUPTED)  # answered after the caller gave up on it
    return _returned(value, ctx, slot, watcher)


def _returned(
    value: Result, ctx: Context, slot: Slot, watcher: Watcher | None, elementary: bool = False
) -> Outcome:
    """A contract's (or an elementary function's) result, kept."""
    slot.offer(value)
    if watcher is not None:
        try:
            watcher.registered(ctx.elapsed, value, slot.best)
        except Exception as exc:
            return watcher.failure(exc)
    if not elementary and late(ctx.elapsed, ctx.allocation):
        return Outcome(Status.CONTRACT_EXPIRED)
    return Outcome(Status.COMPLETED)


def _interruptible(
    module: AnytimeModule,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    slot: Slot,
    watcher: Watcher | None,
) -> Outcome:
    try:
        generator: Generator[Any, None, None] = module(ctx, *args, **kwargs)
    except (Exception, SystemExit) as exc:
        return raised(exc)
    except KeyboardInterrupt as exc:
        return interrupted(exc)
    except BaseException as exc:  # any other the module raised: a failed run
        return failure(exc)
    # Read once: this loop runs once per registered result and should cost little. In soft
    # mode the best result is kept in locals and handed to the slot when the run ends; in hard
    # mode every result is published at once, for the caller to take at the deadline.
    clock, start, stop = ctx.clock, ctx.start, ctx.stop
    allocation = ctx.allocation if watcher is None else watcher.allocation  # the run's own
    limit = allocation + 1e-9 * max(1.0, abs(allocation))  # past it, a result is late
    publish = slot.offer if slot.threaded else None
    latest = slot.latest
    best: Result | None = None
    count = 0
    try:
        while True:
            try:
                item = next(generator)
            except StopIteration:
                if watcher is not None and watcher.error is not None:
                    return watcher.failure(watcher.error)
                if watcher is not None and watcher.stopped:
                    return Outcome(Status.STOPPED)  # a look at a report of work stopped it
                if stop.is_set():
                    return Outcome(Status.INTERRUPTED)  # it noticed the stop and returned
                if clock.now() - start > limit:
                    return Outcome(Status.INTERRUPTED)  # it finished after its deadline
                return Outcome(Status.COMPLETED)
            except (Exception, SystemExit) as exc:
                return raised(exc)
            except KeyboardInterrupt as exc:
                return interrupted(exc)
            except BaseException as exc:  # any other the module raised: a failed run
                return failure(exc)
            if stop.is_set():
                return Outcome(Status.INTERRUPTED)
            elapsed = clock.now() - start
            if elapsed > limit:  # registered too late to count
                return Outcome(Status.INTERRUPTED)
            if type(item) is not Result and not isinstance(item, Result):
                return Outcome(Status.FAILED, f"yielded {describe(item)}, not a Result")
            if watcher is not None:
                if watcher.error is not None:
                    return watcher.failure(watcher.error)
                if watcher.late(elapsed):  # after the observer's stop time
                    return Outcome(Status.STOPPED)
            if publish is not None:
                publish(item)
            else:
                count += 1
                if latest or best is None or item.quality >= best.quality:
                    best = item
            if watcher is not None:
                try:
                    stops = watcher.registered(
                        elapsed, item, best if publish is None else slot.best
                    )
                except Exception as exc:
                    return watcher.failure(exc)
                if stops:
                    return Outcome(Status.STOPPED)
            if elapsed >= allocation:
                return Outcome(Status.INTERRUPTED)
    finally:
        if publish is None:
            slot.best, slot.count = best, count
        # The outcome is decided; a module that fails while being closed changes nothing.
        with suppress(Exception, SystemExit):
            generator.close()


def keeps_latest(module: AnytimeModule) -> bool:
    """An interruptible module whose self-reports are not its true quality: its latest result
    is its best as far as its profile knows (the quality of an anytime algorithm's answer
    grows with time), whatever it says of itself."""
    return module.kind == "interruptible" and module.reports != "true"


def _quality_of(arg: Any) -> float:
    return arg.quality if isinstance(arg, Result) else 1.0


def failure(exc: BaseException, where: str = "") -> Outcome:
    trace = "".join(traceback.format_exception(exc))
    return Outcome(Status.FAILED, where + headline(exc), trace)


def raised(exc: BaseException) -> Outcome:
    """How a run ends that the module ended with `exc` (not a KeyboardInterrupt): failed, unless
    it stands for a Ctrl-C that compiled code reported as an error (`interrupt_behind`), which
    ends it as the interrupt does."""
    behind = interrupt_behind(exc)
    return failure(exc) if behind is None else interrupted(behind)


def interrupted(exc: KeyboardInterrupt) -> Outcome:
    return Outcome(Status.INTERRUPTED, headline(exc), interrupt=exc)


def headline(exc: BaseException) -> str:
    """The exception's own line, as Python prints it (module-qualified name and the first line
    of the message), without a SyntaxError's source lines or any notes."""
    kind = type(exc)
    name = kind.__qualname__
    if kind.__module__ not in ("builtins", "__main__"):
        name = f"{kind.__module__}.{name}"
    for part in traceback.format_exception_only(exc):
        if part.startswith(name):
            return part.strip().splitlines()[0]
    return name


def describe(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text[:60]}{'...' if len(text) > 60 else ''}"


def answer(record: RunRecord, outcome: Outcome) -> RunRecord:
    """The record, or, when the run was ended by a KeyboardInterrupt, `RunInterrupted` raised
    with it: the user asked the caller to stop too."""
    if outcome.interrupt is not None:
        raise RunInterrupted(record) from outcome.interrupt
    return record


def record_of(
    module: AnytimeModule,
    ctx: Context,
    slot: Slot,
    outcome: Outcome,
    watcher: Watcher | None = None,
) -> RunRecord:
    best, count = slot.close()
    allocation = ctx.allocation if watcher is None else watcher.allocation
    looks = 0 if watcher is None else watcher.looks
    return recorded(module, best, count, outcome, ctx.elapsed, allocation, looks)


def recorded(
    module: AnytimeModule,
    best: Result | None,
    count: int,
    outcome: Outcome,
    time_used: float,
    allocation: float,
    looks: int,
    exit_code: int | None = None,
) -> RunRecord:
    status = outcome.status
    no_answer = status is Status.COMPLETED or (
        status is Status.INTERRUPTED and outcome.interrupt is None
    )
    if best is None and no_answer:
        status = Status.NO_RESULT
    return RunRecord(
        module=module.name,
        status=status,
        result=best,
        time_used=time_used,
        allocation=allocation,
        registered=count,
        error=outcome.error,
        traceback=outcome.traceback,
        looks=looks,
        exit_code=exit_code,
    )
