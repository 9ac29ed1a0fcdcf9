"""Hard mode: the module runs in a worker thread that publishes every result to a slot; at the
deadline the caller takes the slot's best result, asks the module to stop (its `ctx.expired`
turns true) and returns at once, so a module stuck in a long computation cannot make the caller
late. Python cannot kill a thread: a stuck module keeps its (daemon) thread until it next looks
at its context or finishes, and its late results are ignored. On a work clock the deadline is
the tick that takes the module past its allocation: the run ends at that tick, and the abandoned
module's later ticks go nowhere, so a hard run's record (and the time of what runs next on the
same clock) is the same however busy the machine is and however many runs share it.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from typing import Any

from anytime.clocks import Clock
from anytime.modules import AnytimeModule, Context
from anytime.runtime.driving import (
    Outcome,
    Slot,
    Watcher,
    answer,
    context,
    drive,
    failure,
    interrupted,
    keeps_latest,
    late,
    record_of,
)
from anytime.runtime.modes import Hard
from anytime.runtime.records import RunRecord, Status


def run_threaded(
    module: AnytimeModule,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    allocation: float,
    clock: Clock,
    caller_stop: threading.Event,
    watcher: Watcher | None,
    mode: Hard,
) -> RunRecord:
    """`run` in hard mode (see the module docstring)."""
    # At the deadline the module's `ctx.expired` turns true by itself (its clock has reached
    # the allocation), so the caller's stop event is never set here: one run's deadline must
    # not stop what the caller runs next.
    slot = Slot(threaded=True, latest=keeps_latest(module))
    finished = threading.Event()  # the module's side ended, or its tick ended the run
    fence = _Fence(clock, slot, finished)
    ctx = context(allocation, fence, caller_stop, watcher)
    fence.ctx = ctx
    ended: list[Outcome] = []  # the module's side's outcome, when it has one

    def work() -> None:
        try:
            ended.append(drive(module, ctx, args, kwargs, slot, watcher))
        except BaseException as exc:  # anything else the module's side let through
            ended.append(failure(exc))
        finally:
            finished.set()

    worker = threading.Thread(target=work, name=f"anytime:{module.name}", daemon=True)
    worker.start()
    try:
        _wait(finished, ctx, caller_stop, mode.poll)
    except KeyboardInterrupt as exc:  # Ctrl-C while the caller waits: stop the module, answer
        caller_stop.set()
        fence.close()
        outcome = interrupted(exc)
        return answer(record_of(module, ctx, slot, outcome, watcher), outcome)
    if fence.crossed or not ended:  # the deadline came first: answer now; the module sees expired
        fence.close()
        status = Status.CONTRACT_EXPIRED if module.kind == "contract" else Status.INTERRUPTED
        if caller_stop.is_set() and module.kind == "contract":
            status = Status.INTERRUPTED
        if watcher is not None and not caller_stop.is_set() and watcher.reached(ctx.elapsed):
            status = Status.STOPPED
        return record_of(module, ctx, slot, Outcome(status), watcher)
    return answer(record_of(module, ctx, slot, ended[0], watcher), ended[0])


class _Fence:
    """A hard-mode run's view of its clock. On a work clock, the tick that takes the module
    past its allocation ends the run at that tick, not whenever the caller next looks (so the
    record is the same however busy the machine is, or how many runs share it); once the run
    is answered, the abandoned module's further ticks go nowhere (its record's time, and the
    time of what the caller runs next on the same clock, do not depend on how long it takes
    to notice). A wall clock passes through: its deadline comes by itself."""

    def __init__(self, clock: Clock, slot: Slot, ended: threading.Event) -> None:
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


def _wait(
    finished: threading.Event,
    ctx: Context,
    caller_stop: threading.Event,
    poll: float,
    watcher: Watcher | None = None,
) -> None:
    """Until the module finishes, its allocation is spent, or the caller stops it.

    On the wall clock the deadline comes by itself. On the work clock time moves only when the
    module ticks, so the deadline has come only once it has ticked *past* its allocation: a
    module that reaches it exactly is still registering its answer there, and is awaited as
    soft mode awaits it (otherwise a contract given 0 ticks would race its own start)."""
    wall = ctx.clock.unit == "seconds"
    while not finished.is_set():
        spent = ctx.elapsed >= ctx.allocation if wall else late(ctx.elapsed, ctx.allocation)
        if caller_stop.is_set() or spent:
            return
        remaining = ctx.allocation - ctx.elapsed
        finished.wait(min(remaining, 0.01) if wall else min(remaining, poll))
