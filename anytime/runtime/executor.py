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
it next looks at its context or finishes, and its late results are ignored. On a work clock the
deadline is the tick that takes the module past its allocation: the run ends at that tick, and
the abandoned module's later ticks go nowhere, so a hard run's record (and the time of what runs
next on the same clock) is the same however busy the machine is and however many runs share it.

An interruptible module may run under a stopping policy (`anytime.runtime.policies`): the policy
is asked before the run and at the first result registered at or after each time it asks to
look, and ends the run at its word or at the time it names (status `stopped`), which the module's
context shows as its allocation.
"""

from __future__ import annotations

import math
import mmap
import struct
import threading
import time
import traceback
from collections.abc import Generator, Mapping, Sequence
from contextlib import suppress
from enum import StrEnum
from typing import Any

from attrs import frozen

from anytime.clocks import Clock, Unit, WorkClock
from anytime.isolation import (
    ISOLATIONS,
    WATCHDOG,
    Channel,
    Child,
    Isolation,
    IsolationError,
    Limits,
    died,
)
from anytime.modules import AnytimeModule, Context, Result
from anytime.runtime.monitor import EventLog
from anytime.runtime.policies import Decision, PolicyError, StoppingPolicy


class Status(StrEnum):
    """How a run ended."""

    COMPLETED = "completed"  # the module finished on its own, within its time
    INTERRUPTED = "interrupted"  # its allocation ran out, or it was stopped from outside
    CONTRACT_EXPIRED = "contract-expired"  # a contract module used more than its allocation
    FAILED = "failed"  # it raised, or broke the protocol (see `error`)
    NO_RESULT = "no-result"  # it ended without registering any result
    STOPPED = "stopped"  # its stopping policy stopped it (with its best result, if any)
    CRASHED = "crashed"  # its process died (isolation="process"): a signal, an exit, no memory


@frozen
class RunRecord:
    """What a run gives back.

    Attributes:
        module: the module's name.
        status: how the run ended.
        result: the best `Result` registered in time (highest quality, the later one on ties;
            the latest for an interruptible module that does not report its true quality),
            or None when there is none.
        time_used: time on the run's clock from start to the answer.
        allocation: the time the run was given.
        registered: how many results the module registered in time.
        error: for a failure, what went wrong, in one line.
        traceback: for a failure raised by the module, its traceback.
        looks: how many times a stopping policy looked at the run.
        exit_code: for a crashed isolated run, how its process ended: its exit code, or the
            negated number of the signal that killed it (as `subprocess` reports it); None
            when it did not exit (it ran out of memory, or was not isolated).
    """

    module: str
    status: Status
    result: Result | None
    time_used: float
    allocation: float
    registered: int = 0
    error: str | None = None
    traceback: str | None = None
    looks: int = 0
    exit_code: int | None = None

    @property
    def quality(self) -> float:
        """The quality of the answer (0 when there is none)."""
        return self.result.quality if self.result is not None else 0.0


class _Slot:
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
            self._keep(result)
            return
        with self._lock:
            self._keep(result)

    def _keep(self, result: Result) -> None:
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
class _Outcome:
    """How the module's side ended (before the caller turns it into a record); `interrupt`, a
    KeyboardInterrupt the module's side caught, for the caller to raise once the record is kept."""

    status: Status
    error: str | None = None
    traceback: str | None = None
    interrupt: KeyboardInterrupt | None = None


class RunInterrupted(KeyboardInterrupt):
    """A KeyboardInterrupt (Ctrl-C, or SIGTERM in the `anytime` command) during a run, raised
    to the caller once the run's record is kept: `record` has the best result registered
    before it, status `interrupted`. The interrupt that came is its `__cause__`."""

    def __init__(self, record: RunRecord) -> None:
        super().__init__(f"run of '{record.module}' interrupted")
        self.record = record


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
    policy: StoppingPolicy | None = None,
    log: EventLog | None = None,
    isolation: Isolation = "none",
    watchdog: float = WATCHDOG,
    limits: Limits | None = None,
) -> RunRecord:
    """Run `module(ctx, *args, **kwargs)` with `allocation` time on `clock` (a fresh
    `WorkClock` by default) and answer with its best registered result.

    Args:
        stop: set from another thread to interrupt the run.
        hard: run the module in a worker thread and return at the deadline even if the
            module does not yield (see the module docstring).
        poll: with `hard` on a clock that is not the wall clock, how often (seconds) the caller
            looks at the clock.
        policy: a stopping policy for an interruptible module: consulted before the run and at
            the first result registered at or after each time it asks to look, with the quality
            of the run's answer then; it may stop the run (status `stopped`).
        log: where the policy's decisions are recorded (kind "stopping").
        isolation: "process" runs the module in a child process of its own (see
            `anytime.isolation`), which answers at the deadline as `hard` does and
            survives whatever the module does: a process that dies gives status `crashed`
            with the best result it had sent, and nothing it started outlives the run.
        watchdog: with process isolation, the wall-clock seconds after which a run that has
            not answered fails (status `failed`) and its process is ended, whatever its clock
            says: on the work clock, a module that never ticks cannot hang the caller.
        limits: with process isolation, the run's memory and CPU limits.
    """
    if isolation not in ISOLATIONS:
        raise IsolationError(
            f"run: isolation: expected one of {', '.join(map(repr, ISOLATIONS))}, got {isolation!r}"
        )
    if not watchdog > 0:  # NaN too
        raise IsolationError(
            f"run: watchdog: expected a positive number of seconds, got {watchdog!r}"
        )
    if limits is not None and isolation != "process":
        raise IsolationError('run: limits need isolation="process"')
    clock = clock if clock is not None else WorkClock()
    caller_stop = stop if stop is not None else threading.Event()
    police = None
    if policy is not None:
        police = _Police(_checked_policy(module, policy), log, float(allocation))
        if police.stopped:  # stopped before it started
            return RunRecord(module.name, Status.STOPPED, None, 0.0, float(allocation))
    if isolation == "process":
        return _isolated(
            module,
            args,
            kwargs or {},
            float(allocation),
            clock,
            caller_stop,
            police,
            watchdog,
            limits,
        )
    if not hard:
        ctx = _context(allocation, clock, caller_stop, police)
        slot = _Slot(threaded=False, latest=_keeps_latest(module))
        outcome = _drive(module, ctx, args, kwargs or {}, slot, police)
        return _answer(_record(module, ctx, slot, outcome, police), outcome)
    # At the deadline the module's `ctx.expired` turns true by itself (its clock has reached
    # the allocation), so the caller's stop event is never set here: one run's deadline must
    # not stop what the caller runs next.
    slot = _Slot(threaded=True, latest=_keeps_latest(module))
    finished = threading.Event()  # the module's side ended, or its tick ended the run
    fence = _Fence(clock, slot, finished)
    ctx = _context(allocation, fence, caller_stop, police)
    fence.ctx = ctx
    box: list[_Outcome] = []

    def work() -> None:
        try:
            box.append(_drive(module, ctx, args, kwargs or {}, slot, police))
        except BaseException as exc:  # anything else the module's side let through
            box.append(_failure(exc))
        finally:
            finished.set()

    worker = threading.Thread(target=work, name=f"anytime:{module.name}", daemon=True)
    worker.start()
    try:
        _wait(finished, ctx, caller_stop, poll, police)
    except KeyboardInterrupt as exc:  # Ctrl-C while the caller waits: stop the module, answer
        caller_stop.set()
        fence.close()
        outcome = _interrupted(exc)
        return _answer(_record(module, ctx, slot, outcome, police), outcome)
    if fence.crossed or not box:  # the deadline came first: answer now; the module sees expired
        fence.close()
        status = Status.CONTRACT_EXPIRED if module.kind == "contract" else Status.INTERRUPTED
        if caller_stop.is_set() and module.kind == "contract":
            status = Status.INTERRUPTED
        if police is not None and not caller_stop.is_set() and police.reached(ctx.elapsed):
            status = Status.STOPPED
        return _record(module, ctx, slot, _Outcome(status), police)
    return _answer(_record(module, ctx, slot, box[0], police), box[0])


class _Fence:
    """A hard-mode run's view of its clock. On a work clock, the tick that takes the module
    past its allocation ends the run at that tick, not whenever the caller next looks (so the
    record is the same however busy the machine is, or how many runs share it); once the run
    is answered, the abandoned module's further ticks go nowhere (its record's time, and the
    time of what the caller runs next on the same clock, do not depend on how long it takes
    to notice). A wall clock passes through: its deadline comes by itself."""

    def __init__(self, clock: Clock, slot: _Slot, ended: threading.Event) -> None:
        self.clock, self.slot, self.ended = clock, slot, ended
        self.unit = clock.unit
        self._work = clock.unit != "seconds"
        self.ctx: Context | None = None
        self._allocation = self._limit = math.nan  # the ctx's allocation; past it, late
        self.crossed = False  # a tick of the module took it past its allocation
        self._frozen: float | None = None  # the time at which the run was answered
        self._lock = threading.Lock()

    def now(self) -> float:
        frozen = self._frozen
        return self.clock.now() if frozen is None else frozen

    def advance(self, n: float) -> None:
        with self._lock:
            if self._frozen is not None:
                return
            clock, ctx = self.clock, self.ctx
            clock.advance(n)
            if not self._work or ctx is None:
                return
            if ctx.allocation != self._allocation:  # a stopping policy moved it
                self._allocation = ctx.allocation
                self._limit = self._allocation + 1e-9 * max(1.0, abs(self._allocation))
            if clock.now() - ctx.start > self._limit:  # as `_late`: past it beyond rounding
                self.crossed = True
                self._freeze()
                self.ended.set()

    def close(self) -> None:
        """The caller answers: the time stops here for this run."""
        with self._lock:
            if self._frozen is None:
                self._freeze()

    def _freeze(self) -> None:
        self.slot.close()  # results registered from now on are late
        if self.unit != "seconds":
            self._frozen = self.clock.now()


def _answer(record: RunRecord, outcome: _Outcome) -> RunRecord:
    """The record, or, when the run was ended by a KeyboardInterrupt, `RunInterrupted` raised
    with it: the user asked the caller to stop too."""
    if outcome.interrupt is not None:
        raise RunInterrupted(record) from outcome.interrupt
    return record


def _context(
    allocation: float, clock: Clock, stop: threading.Event, police: _Police | None
) -> Context:
    """The module's context; with a policy, its allocation is the policy's stop time."""
    ctx = Context(allocation=allocation, clock=clock, stop=stop)
    if police is not None:
        police.watch(ctx)
    return ctx


def _checked_policy(module: AnytimeModule, policy: StoppingPolicy) -> StoppingPolicy:
    """The policy, if it can watch this module."""
    if module.kind != "interruptible":
        raise PolicyError(
            f"run: a stopping policy needs an interruptible module; '{module.name}' is a"
            f" {module.kind} module (make_interruptible turns a contract into one)"
        )
    if policy.observed is not None and policy.observed != module.reports:
        raise PolicyError(
            f"run: policy '{policy.name}' reads {_REPORTS[policy.observed]}, but module"
            f" '{module.name}' reports {_REPORTS[module.reports]}"
        )
    return policy


_REPORTS = {
    "true": "the true quality",
    "estimate": "an estimate of the quality",
    "none": "nothing of the quality",
}


def _at_or_after(elapsed: float, time: float) -> bool:
    """Whether `elapsed` has reached `time`, within the rounding of a clock (never infinity)."""
    return time != math.inf and elapsed >= time - 1e-9 * max(1.0, abs(time))


def _never(time: float) -> float | None:
    """A time for the log: None for never (JSON has no infinity)."""
    return None if time == math.inf else time


class _Police:
    """A stopping policy's part in one run: when it looks next, when the run stops, how many
    looks it took, and its decisions in the log.

    The module's context is given the policy's stop time as its allocation, so that a module
    that watches its time (or a contract made interruptible, which starts no contract that
    cannot end in time) ends there by itself."""

    def __init__(self, policy: StoppingPolicy, log: EventLog | None, allocation: float) -> None:
        self.policy, self.log, self.allocation = policy, log, allocation
        self.ctx: Context | None = None
        self.looks = 0
        self.stopped = False
        self.look_at = self.stop_at = math.inf
        self.follow(0.0, None, policy.start(allocation))

    def watch(self, ctx: Context) -> None:
        self.ctx = ctx
        ctx.allocation = min(self.allocation, self.stop_at)

    def follow(self, time: float, quality: float | None, decision: Decision) -> None:
        if not isinstance(decision, Decision):
            raise PolicyError(
                f"policy '{self.policy.name}' answered with {_describe(decision)}, not a Decision"
            )
        self.stopped = decision.stop
        self.look_at = decision.look_at
        # Stopping at the allocation is the allocation running out, not the policy's doing.
        self.stop_at = decision.stop_at if decision.stop_at < self.allocation else math.inf
        if self.ctx is not None:
            self.ctx.allocation = min(self.allocation, self.stop_at)
        if self.log is not None:
            self.log.record(
                time,
                "stopping",
                {
                    "policy": self.policy.name,
                    "quality": quality,
                    "decision": "stop" if decision.stop else "continue",
                    "look_at": None if decision.stop else _never(decision.look_at),
                    "stop_at": None
                    if decision.stop
                    else _never(min(decision.stop_at, self.allocation)),
                    "reason": decision.reason,
                },
            )

    def consult(self, elapsed: float, quality: float | None) -> bool:
        """After a result kept at `elapsed`: look if a look is due; whether the run stops."""
        if _at_or_after(elapsed, self.look_at):
            self.looks += 1
            self.follow(elapsed, quality, self.policy.observe(elapsed, quality))
        return self.stopped or self.reached(elapsed)

    def reached(self, elapsed: float) -> bool:
        """Whether the time the policy said to stop at has come."""
        return _at_or_after(elapsed, self.stop_at)

    def late(self, elapsed: float) -> bool:
        """Whether a result at `elapsed` comes after the time the policy said to stop at."""
        return self.stop_at != math.inf and elapsed > self.stop_at + 1e-9 * max(
            1.0, abs(self.stop_at)
        )


def _wait(
    finished: threading.Event,
    ctx: Context,
    caller_stop: threading.Event,
    poll: float,
    police: _Police | None = None,
) -> None:
    """Until the module finishes, its allocation is spent, or the caller stops it.

    On the wall clock the deadline comes by itself. On the work clock time moves only when the
    module ticks, so the deadline has come only once it has ticked *past* its allocation: a
    module that reaches it exactly is still registering its answer there, and is awaited as
    soft mode awaits it (otherwise a contract given 0 ticks would race its own start)."""
    wall = ctx.clock.unit == "seconds"
    while not finished.is_set():
        spent = ctx.elapsed >= ctx.allocation if wall else _late(ctx.elapsed, ctx.allocation)
        if caller_stop.is_set() or spent:
            return
        remaining = ctx.allocation - ctx.elapsed
        finished.wait(min(remaining, 0.01) if wall else min(remaining, poll))


def _drive(
    module: AnytimeModule,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    slot: _Slot,
    police: _Police | None = None,
) -> _Outcome:
    """Run the module on this thread, offering each result registered in time to `slot`."""
    if module.kind == "interruptible":
        return _interruptible(module, ctx, args, kwargs, slot, police)
    try:
        if module.kind == "elementary":
            value = module(*args, **kwargs)
            if not isinstance(value, Result):  # its quality combines its inputs' (min default)
                positions = sorted(module.parameters.index(name) for name in module.inputs)
                qualities = [_quality_of(args[i]) for i in positions if i < len(args)]
                value = Result(value, module.combine(qualities))
            slot.offer(value)
            return _Outcome(Status.COMPLETED)
        value = module(ctx, *args, **kwargs)
    except (Exception, SystemExit) as exc:
        return _failure(exc)
    except KeyboardInterrupt as exc:
        return _interrupted(exc)
    if value is None:  # a contract's way of saying it has no result
        late = _late(ctx.elapsed, ctx.allocation)
        return _Outcome(Status.CONTRACT_EXPIRED if late else Status.COMPLETED)
    if not isinstance(value, Result):
        return _Outcome(Status.FAILED, f"returned {_describe(value)}, not a Result")
    if ctx.stop.is_set() and ctx.elapsed < ctx.allocation:
        return _Outcome(Status.INTERRUPTED)  # answered after the caller gave up on it
    slot.offer(value)
    if _late(ctx.elapsed, ctx.allocation):
        return _Outcome(Status.CONTRACT_EXPIRED)
    return _Outcome(Status.COMPLETED)


def _late(elapsed: float, allocation: float) -> bool:
    """Past the allocation, beyond the rounding of computing elapsed time on a clock."""
    return elapsed > allocation + 1e-9 * max(1.0, abs(allocation))


def _interruptible(
    module: AnytimeModule,
    ctx: Context,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    slot: _Slot,
    police: _Police | None,
) -> _Outcome:
    try:
        generator: Generator[Any, None, None] = module(ctx, *args, **kwargs)
    except (Exception, SystemExit) as exc:
        return _failure(exc)
    except KeyboardInterrupt as exc:
        return _interrupted(exc)
    # Read once: this loop runs once per registered result and should cost little. In soft
    # mode the best result is kept in locals and handed to the slot when the run ends; in hard
    # mode every result is published at once, for the caller to take at the deadline.
    clock, start, stop = ctx.clock, ctx.start, ctx.stop
    allocation = ctx.allocation if police is None else police.allocation  # the run's own
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
                if stop.is_set():
                    return _Outcome(Status.INTERRUPTED)  # it noticed the stop and returned
                if clock.now() - start > limit:
                    return _Outcome(Status.INTERRUPTED)  # it finished after its deadline
                return _Outcome(Status.COMPLETED)
            except (Exception, SystemExit) as exc:
                return _failure(exc)
            except KeyboardInterrupt as exc:
                return _interrupted(exc)
            if stop.is_set():
                return _Outcome(Status.INTERRUPTED)
            elapsed = clock.now() - start
            if elapsed > limit:  # registered too late to count
                return _Outcome(Status.INTERRUPTED)
            if type(item) is not Result and not isinstance(item, Result):
                return _Outcome(Status.FAILED, f"yielded {_describe(item)}, not a Result")
            if police is not None and police.late(elapsed):  # after the policy's stop time
                return _Outcome(Status.STOPPED)
            if publish is not None:
                publish(item)
            else:
                count += 1
                if latest or best is None or item.quality >= best.quality:
                    best = item
            if police is not None:
                answer = best if publish is None else slot.best
                try:
                    stops = police.consult(elapsed, None if answer is None else answer.quality)
                except Exception as exc:
                    return _failure(exc, "stopping policy: ")
                if stops:
                    return _Outcome(Status.STOPPED)
            if elapsed >= allocation:
                return _Outcome(Status.INTERRUPTED)
    finally:
        if publish is None:
            slot.best, slot.count = best, count
        # The outcome is decided; a module that fails while being closed changes nothing.
        with suppress(Exception, SystemExit):
            generator.close()


def _keeps_latest(module: AnytimeModule) -> bool:
    """An interruptible module whose self-reports are not its true quality: its latest result
    is its best as far as its profile knows (the quality of an anytime algorithm's answer
    grows with time), whatever it says of itself."""
    return module.kind == "interruptible" and module.reports != "true"


def _quality_of(arg: Any) -> float:
    return arg.quality if isinstance(arg, Result) else 1.0


def _failure(exc: BaseException, where: str = "") -> _Outcome:
    trace = "".join(traceback.format_exception(exc))
    return _Outcome(Status.FAILED, where + _headline(exc), trace)


def _interrupted(exc: KeyboardInterrupt) -> _Outcome:
    return _Outcome(Status.INTERRUPTED, _headline(exc), interrupt=exc)


def _headline(exc: BaseException) -> str:
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


def _describe(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text[:60]}{'...' if len(text) > 60 else ''}"


def _record(
    module: AnytimeModule,
    ctx: Context,
    slot: _Slot,
    outcome: _Outcome,
    police: _Police | None = None,
) -> RunRecord:
    best, count = slot.close()
    allocation = ctx.allocation if police is None else police.allocation
    looks = 0 if police is None else police.looks
    return _recorded(module, best, count, outcome, ctx.elapsed, allocation, looks)


def _recorded(
    module: AnytimeModule,
    best: Result | None,
    count: int,
    outcome: _Outcome,
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


# Process isolation: the module runs in a `Child` (anytime.isolation) as it would run
# in soft mode, sending each result it keeps as it keeps it; the caller keeps the best of them
# and answers at the deadline (or on the watchdog, or when the child dies) as hard mode does.


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

    def now(self) -> float:
        return self.start + self.ticks

    def advance(self, n: float) -> None:
        self.ticks += n
        struct.pack_into("d", self._memory, 0, self.ticks)
        ctx = self.ctx
        if ctx is not None and self.channel is not None and _late(self.ticks, ctx.allocation):
            self.channel.send(("crossed", self.ticks))
            while True:  # the caller answers and ends this process
                time.sleep(3600)

    def read(self) -> float:
        """The ticks reported so far (from the caller's side)."""
        return float(struct.unpack_from("d", self._memory, 0)[0])


class _SendingSlot(_Slot):
    """The child's slot: every result kept is sent to the caller at once."""

    def __init__(self, channel: Channel, latest: bool) -> None:
        super().__init__(threaded=True, latest=latest)
        self.channel = channel

    def _keep(self, result: Result) -> None:
        if self.closed:
            return
        try:
            self.channel.send(("result", result))
        except Exception as exc:  # pickling it failed: say which result could not travel
            raise TypeError(
                f"its result ({_describe(result.value)}) cannot be sent from its process: {exc}"
            ) from exc
        super()._keep(result)


class _SentLog:
    """A stopping policy's log in the child: each event goes to the caller's log."""

    def __init__(self, channel: Channel) -> None:
        self.channel = channel

    def record(self, time: float, kind: str, data: Mapping[str, Any]) -> None:
        self.channel.send(("log", time, kind, dict(data)))


def _isolated(
    module: AnytimeModule,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    allocation: float,
    clock: Clock,
    caller_stop: threading.Event,
    police: _Police | None,
    watchdog: float,
    limits: Limits | None,
) -> RunRecord:
    """`run` with the module in a child process (see `run`'s `isolation`)."""
    ticks = _SharedTicks(clock.now()) if clock.unit != "seconds" else None
    start = clock.now()
    log = None if police is None else police.log

    def child(channel: Channel) -> None:
        child_clock: Clock = clock if ticks is None else ticks
        ctx = _context(allocation, child_clock, threading.Event(), police)
        if ticks is not None:
            ticks.ctx, ticks.channel = ctx, channel
        if police is not None and police.log is not None:
            police.log = _SentLog(channel)  # type: ignore[assignment]
        slot = _SendingSlot(channel, _keeps_latest(module))
        try:
            outcome = _drive(module, ctx, args, kwargs, slot, police)
        except BaseException as exc:  # a result that could not be sent, or the like
            outcome = _failure(exc)
        looks = 0 if police is None else police.looks
        channel.send(("done", outcome.status, outcome.error, outcome.traceback, looks))

    slot = _Slot(threaded=False, latest=_keeps_latest(module))
    looks = 0
    outcome: _Outcome | None = None
    exit_code: int | None = None
    began = time.monotonic()
    process = Child(child, limits)
    try:
        while outcome is None:
            # Whether it had gone before this read: a child that has gone is crashed only once
            # everything it sent before it went is read (it may send its last results, and
            # even "done", after a read and before the next look).
            gone = process.gone
            wait = min(0.01, max(0.0, began + watchdog - time.monotonic()))
            if ticks is None:
                wait = min(wait, max(0.0, allocation - (clock.now() - start)))
            messages = process.receive(wait)
            for message in messages:
                kind = message[0]
                if kind == "result":
                    slot.offer(message[1])
                elif kind == "log" and log is not None:
                    log.record(*message[1:])
                elif kind == "crossed":
                    outcome = _deadline(module, caller_stop)
                elif kind == "done":
                    status, error, trace, looks = message[1:]
                    if status is Status.FAILED and (error or "").startswith("MemoryError"):
                        status = Status.CRASHED  # it ran out of the memory it may have
                    outcome = _Outcome(status, error, trace)
                    break
            if outcome is not None:
                break
            if gone and not messages:
                exit_code = process.exit_code
                outcome = _Outcome(Status.CRASHED, died(exit_code))
            elif gone:
                continue  # read the rest of what it sent first
            elif caller_stop.is_set():
                outcome = _Outcome(Status.INTERRUPTED)
            elif ticks is None and clock.now() - start >= allocation:
                outcome = _deadline(module, caller_stop)
            elif time.monotonic() - began >= watchdog:
                used = ticks.read() if ticks is not None else clock.now() - start
                outcome = _Outcome(
                    Status.FAILED,
                    f"watchdog: no answer after {watchdog:g} s of wall time (it had used"
                    f" {used:.6g} of its {allocation:g} {clock.unit})",
                )
    except KeyboardInterrupt as exc:  # Ctrl-C while the caller waits: end the child, answer
        outcome = _interrupted(exc)
    finally:
        used = clock.now() - start if ticks is None else ticks.read()  # the answer's time
        process.end()
    if ticks is not None:
        clock.advance(used)  # the caller's clock moves as if the module had run here
    if police is not None:
        police.looks = looks
        if outcome.status is Status.INTERRUPTED and police.reached(used):
            outcome = _Outcome(Status.STOPPED)
    best, count = slot.close()
    record = _recorded(module, best, count, outcome, used, allocation, looks, exit_code)
    return _answer(record, outcome)


def _deadline(module: AnytimeModule, caller_stop: threading.Event) -> _Outcome:
    """How a run ends that the deadline ended (as hard mode says it)."""
    contract = module.kind == "contract" and not caller_stop.is_set()
    return _Outcome(Status.CONTRACT_EXPIRED if contract else Status.INTERRUPTED)
