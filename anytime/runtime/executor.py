"""Running one anytime module under a contract or interruption, and keeping its best result.

"Interruptible algorithms produce results of the quality advertised by their performance
profiles even when interrupted unexpectedly; contract algorithms must be given a particular time
allocation in advance" (Zilberstein & Russell). `run` does both and answers with a `RunRecord`,
never with an exception for running out of time: the best `Result` registered so far, a status,
the time used, and for a failure the error with its traceback. Whatever the module does — raise
midway, yield something that is not a `Result`, build a `Result` of quality outside [0, 1]
(which `Result` itself refuses), overrun its contract, or hang — the best result it registered
before is kept.

How the module is driven is the run's mode (`anytime.runtime.modes`): `Soft()` in the caller's
thread, checking the deadline each time the module yields; `Hard()` in a worker thread that
the caller leaves at the deadline (`anytime.runtime.threaded`); `Isolated()` in a child process
(`anytime.runtime.isolated`). On a work clock the deadline is the tick that takes the module
past its allocation, in every mode, so a record is the same however busy the machine is.

An observer (`anytime.runtime.observe`) watches the run: it sees each result kept, looks at the
times it asks for on the run's clock, may stop the run (status `stopped`, with the best result
so far), and sees the record. A stopping policy is one (`Stopping`).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from typing import Any

from anytime.modules import AnytimeModule
from anytime.runtime.driving import Slot, Watcher, answer, context, drive, keeps_latest, record_of
from anytime.runtime.isolated import run_isolated
from anytime.runtime.modes import SOFT, Budget, Hard, Isolated, RunMode, Soft, budget_of
from anytime.runtime.observe import Observer
from anytime.runtime.records import RunInterrupted, RunRecord, Status
from anytime.runtime.threaded import run_threaded

__all__ = ["RunInterrupted", "RunRecord", "Status", "run"]


def run(
    module: AnytimeModule,
    args: Sequence[Any] = (),
    kwargs: Mapping[str, Any] | None = None,
    *,
    budget: Budget | float = math.inf,
    mode: RunMode = SOFT,
    observer: Observer | None = None,
) -> RunRecord:
    """Run `module(ctx, *args, **kwargs)` within `budget` (its allocation on its clock, a fresh
    `WorkClock` by default, and the caller's stop event; a number: the allocation) and answer
    with its best registered result.

    Args:
        mode: `Soft()`, `Hard(poll=...)` or `Isolated(watchdog=..., limits=...)`; see
            `anytime.runtime.modes`. Under `Isolated` a process that dies gives status
            `crashed` with the best result it had sent, and nothing it started outlives the
            run; one that does not answer within its watchdog fails.
        observer: watches the run (see `anytime.runtime.observe`); a stopping policy is
            `Stopping(policy, log)`.
    """
    if not isinstance(mode, Soft | Hard | Isolated):
        raise TypeError(f"run: mode: expected Soft(), Hard() or Isolated(), got {mode!r}")
    given = budget_of(budget)
    allocation, clock = given.allocation, given.clock
    caller_stop = given.stop if given.stop is not None else threading.Event()
    watcher = None
    if observer is not None:
        watcher = Watcher(observer, module, args, allocation)
    try:
        record = _run(module, args, kwargs or {}, allocation, clock, caller_stop, mode, watcher)
    except RunInterrupted as exc:
        if observer is not None:
            observer.ended(exc.record)
        raise
    if observer is not None:
        observer.ended(record)
    return record


def _run(
    module: AnytimeModule,
    args: Sequence[Any],
    kwargs: Mapping[str, Any],
    allocation: float,
    clock: Any,
    caller_stop: threading.Event,
    mode: RunMode,
    watcher: Watcher | None,
) -> RunRecord:
    if watcher is not None and watcher.stopped:  # stopped before it started
        return RunRecord(module.name, Status.STOPPED, None, 0.0, allocation)
    if isinstance(mode, Isolated):
        return run_isolated(module, args, kwargs, allocation, clock, caller_stop, watcher, mode)
    if isinstance(mode, Hard):
        return run_threaded(module, args, kwargs, allocation, clock, caller_stop, watcher, mode)
    ctx = context(allocation, clock, caller_stop, watcher)
    slot = Slot(threaded=False, latest=keeps_latest(module))
    outcome = drive(module, ctx, args, kwargs, slot, watcher)
    return answer(record_of(module, ctx, slot, outcome, watcher), outcome)
