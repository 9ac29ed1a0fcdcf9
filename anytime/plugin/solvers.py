"""External solvers as anytime modules, opt-in: `from anytime.plugin.solvers import ...`.

Two shapes cover most solvers a module wraps:

- **resumable**: the solver runs for a limit of its own work (iterations, validity checks,
  nodes) and can be called again to go on where it stopped (OMPL's `solve` with a termination
  condition, a search with a node limit). Give it the `Resumable` methods and write the module
  as `yield from resume(ctx, solver, step=...)`.
- **call-back**: the solver runs in one blocking call and calls back on each improvement or
  iteration (`scipy.optimize`'s `callback`, OR-Tools CP-SAT's solution callback, most MIP
  solvers). Write the module as `yield from on_improvement(ctx, solve)`, where `solve(report)`
  runs the solver with a callback that calls `report(result)` and stops the solver when it
  answers True.

Either way the module's work clock counts the solver's own unit (what `advance` says it spent;
for a call-back solver one unit per callback, or what a `work` function counts, such as the
objective's evaluations), so its profile is as deterministic as the solver, and an interrupted
module (its allocation spent, or `ctx.stop` set) stops the solver at its next slice or callback.
Both yield only results of strictly higher quality than the last they yielded: the framework's
answer is the module's last registered result, and a solver whose best gets worse (or repeats
itself) must not replace a better answer.
"""

from __future__ import annotations

import math
import numbers
import queue
import threading
from collections.abc import Callable, Generator
from typing import Any, Protocol

from anytime.errors import first_in_chain
from anytime.modules import Context, Result

__all__ = ["Report", "Resumable", "on_improvement", "resume"]


class Resumable(Protocol):
    """A solver that runs for a limit of its own work units and resumes where it stopped.

    Its unit is whatever it counts deterministically (iterations, validity checks, expanded
    nodes): the module's ticks are these units, so its profile is measured in them.
    """

    def advance(self, limit: float) -> float:
        """Run the solver for at most `limit` of its own work units; return the units actually
        spent; 0 means it can do no more (finished)."""
        ...

    def best(self) -> Result | None:
        """The best result found so far (value and self-estimated quality), or None."""
        ...


def _work(value: Any, what: str) -> float:
    """`value` as units of work: a finite number >= 0 (else a ValueError naming `what`)."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        units = float(value)
        if units >= 0 and math.isfinite(units):
            return units
    raise ValueError(f"{what} gave {value!r}: expected units of work, a finite number >= 0")


def _candidate(value: Any, what: str) -> Result | None:
    if value is None or isinstance(value, Result):
        return value
    raise TypeError(f"{what} gave {type(value).__name__} {value!r:.60}: expected a Result or None")


def _better(candidate: Result | None, best: Result | None) -> bool:
    """Whether `candidate` is a new result of strictly higher quality than `best`."""
    if candidate is None or candidate is best:
        return False
    return best is None or candidate.quality > best.quality


def resume(ctx: Context, solver: Resumable, *, step: float) -> Generator[Result, None, None]:
    """Drive `solver` in slices of at most `step` units (fewer when ctx.remaining is smaller),
    ticking ctx with what each slice spent; yield solver.best() whenever it is a new, better
    result; stop when ctx.expired or the solver finishes.

    Written as the whole body of an interruptible module::

        @interruptible("plan", inputs=[], reports="estimate", step=100)
        def plan(ctx, problem):
            yield from resume(ctx, MySolver(problem), step=100)

    - What a slice spent is ticked as the solver reports it, even when that is more than its
      limit (it is the truth): the run then overshoots its allocation by that excess, and a
      result found in that slice is registered late (the runtime decides what is late). Each
      slice is limited to what remains and the module stops as soon as its context expires, so
      a run goes past its allocation by at most the solver's largest excess over a limit: that
      is the module's `step` to declare (0 for a solver that keeps to its limits), whatever
      `step` the slices are. Between slices nothing runs, so `ctx.stop` set from another
      thread stops the solver before its next slice.
    - `best()` is asked after every slice (the one that spent 0 too: a solver may finish with
      its best). It is yielded only when it is a new object of strictly higher quality than the
      last one yielded: the runtime keeps the module's last registered result as its answer, so
      a best that repeats itself, keeps its quality or gets worse is not registered.
    - A slice that spends 0 ends the module (the solver is finished); with an infinite
      allocation the solver runs until then. A solver whose unit is whole (checks, nodes) and is
      given a limit below one unit should spend one unit (an excess, ticked), not 0.
    - On a wall clock (`ctx.clock.unit` is "seconds") the solver's units are not the clock's:
      every slice is `step` units, the ticks move no clock, and the module stops at the first
      slice that ends past its allocation in seconds.

    Raises:
        ValueError: `step` is not a finite number > 0 (when the generator starts), or
            `advance` returned something other than a finite number >= 0.
        TypeError: `best()` returned something other than a `Result` or None.
    """
    if not (
        isinstance(step, numbers.Real)
        and not isinstance(step, bool)
        and math.isfinite(step)
        and step > 0
    ):
        raise ValueError(f"resume: step: expected a finite number of units > 0, got {step!r}")
    name = type(solver).__name__
    work_clock = ctx.clock.unit == "ticks"  # the solver's units are the clock's
    best: Result | None = None
    while not ctx.expired:
        limit = min(float(step), ctx.remaining) if work_clock else float(step)
        spent = _work(solver.advance(limit), f"{name}.advance({limit:g})")
        ctx.tick(spent)
        found = _candidate(solver.best(), f"{name}.best()")
        if _better(found, best):
            best = found
            assert found is not None
            yield found
        if spent == 0:  # finished
            return


class _Stopped(Exception):
    """Raised by `Report.check` in the solver's thread, to stop a solver that stops only when
    its callback raises; `on_improvement` catches it."""


_REPORT, _RETURNED, _RAISED = "report", "returned", "raised"


class Report:
    """What `on_improvement` hands to `solve`: the solver's callback calls it at each
    improvement (or each iteration) of the solver.

    `report(result)` (or `report()` at an iteration with nothing new) counts the solver's work
    so far, hands `result` to the module (which registers it if its quality is strictly higher
    than the last registered), and answers whether the solver must stop now: True once the
    module's allocation is spent, `ctx.stop` is set, or the module was closed. Stop the solver
    the way it provides when it answers True (scipy: raise `StopIteration`; CP-SAT: call
    `StopSearch()`; a callback whose return value stops the solver: return it).

    For a solver that stops only when its callback raises, call `report.check(result)`
    instead: it raises an exception of the adapter's own (which `on_improvement` catches)
    where `report(result)` would answer True.

    Once told to stop, a solver that calls back again is answered True again at once (its
    stop may take effect later: CP-SAT's `stop_search` is asynchronous), and `check` raises
    again; the callback is never made to raise otherwise, since an exception raised into a
    compiled solver's callback may end more than the search. A solver that ignores the answer
    runs to its end (its further callbacks counted as work when it returns): the module waits
    for it, so stop it as it provides.
    """

    def __init__(self) -> None:
        self._to_module: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._to_solver: queue.SimpleQueue[bool] = queue.SimpleQueue()
        self._lock = threading.Lock()  # one callback at a time (a solver's own threads)
        self._module_thread: int | None = None
        self._told_to_stop = False
        self._ended = False
        self._late = 0  # reports answered at once, after the answer to stop

    def __call__(self, result: Result | None = None) -> bool:
        """Report the solver's work so far and, if any, a result; whether to stop now."""
        if threading.get_ident() == self._module_thread:
            raise RuntimeError(
                "report(...) is for the solver's callback, while on_improvement runs `solve`"
            )
        with self._lock:
            if self._told_to_stop or self._ended:  # told to stop, it goes on for now
                self._late += 1
                return True
            self._to_module.put((_REPORT, result))
            stop = self._to_solver.get()  # the module's thread runs meanwhile, not this one
            self._told_to_stop = stop
            return stop

    def check(self, result: Result | None = None) -> None:
        """As `report(result)`, but raises (an exception `on_improvement` catches) where that
        answers True: for a solver that stops only when its callback raises."""
        if self(result):
            raise _Stopped

    def _run(self, solve: Callable[[Report], object]) -> None:
        """The solver's thread: `solve`, and how it ended, for the module's thread."""
        try:
            value = solve(self)
        except _Stopped:
            self._end(_RETURNED, None)
        except BaseException as exc:  # handed to the module's thread, which raises it
            self._end(_RAISED, exc)
        else:
            self._end(_RETURNED, value)

    def _end(self, kind: str, payload: Any) -> None:
        with self._lock:
            self._ended = True
        self._to_module.put((kind, payload))

    def _stopped_by_us(self, exc: BaseException) -> bool:
        """Whether an exception out of `solve` is the stop the adapter asked for: ours, wrapped
        by the solver (it is in the chain), or a `StopIteration` raised after an answer of
        True (the callback's way to stop a solver that lets it through)."""
        if first_in_chain(exc, _Stopped) is not None:
            return True
        return self._told_to_stop and isinstance(exc, StopIteration)


def on_improvement(
    ctx: Context,
    solve: Callable[[Report], object],
    *,
    work: Callable[[], float] | None = None,
) -> Generator[Result, None, None]:
    """Run a solver that calls back on each improvement (or iteration) as an interruptible
    module: `solve(report)` runs it, its callback calls `report(result)` and stops the solver
    when that answers True. Each result of strictly higher quality than the last is yielded as
    it comes; a `Result` that `solve` returns is the last candidate (anything else it returns
    is ignored).

    Written as the whole body of an interruptible module::

        @interruptible("fit", inputs=[], reports="estimate", step=1)
        def fit(ctx, x0):
            def solve(report):
                def callback(intermediate_result):  # scipy passes the OptimizeResult so named
                    if report(Result(intermediate_result.x, quality(intermediate_result.fun))):
                        raise StopIteration  # how a scipy callback stops minimize
                minimize(f, x0, method="BFGS", callback=callback)
            yield from on_improvement(ctx, solve)

    Args:
        ctx: the module's context.
        solve: runs the solver to its end (or until told to stop) with a callback that calls
            its argument, a `Report`.
        work: the solver's work so far, in its own unit (for example the objective's
            evaluations, counted by a wrapped objective): each report, and the solver's end,
            ticks ctx with its growth since the last. Default: each report is one unit (an
            iteration, or a solution found). The work is ticked at the callbacks, so a run
            goes past its allocation by at most the work between two callbacks (from the
            start to the first, from the last to the solver's return): the module's `step`.

    Why a thread: the runtime keeps only what a module's generator yields, when it yields
    (and in hard mode the tick that crosses the deadline ends the run there), so a result
    must be yielded from the module's generator while the solver is still inside its
    blocking call. `solve` therefore runs in a thread of its own, and the two threads hand
    over strictly: at a callback the solver's thread waits while the module's thread counts
    the work, yields the result and decides whether to stop; otherwise the module's thread
    waits. Only the module's thread touches `ctx` (its ticks, and the observers' looks they
    may take), and the work count is what the solver counts, so a run is as deterministic as
    the solver. A module that is closed (its run ended: the deadline, an interruption, an
    observer's stop) or that raises tells the solver to stop at its next callback and waits
    for its thread to end: no solver thread outlives its module, though a solver that never
    calls back again nor returns keeps it waiting. An exception the solver raises is raised
    in the module's thread (the run fails with it), except the stop the adapter asked for.

    Raises:
        ValueError: `work()` gave something other than a finite number, or went back.
        TypeError: a report or `solve`'s result is not a `Result` (or None).
    """
    report = Report()
    report._module_thread = threading.get_ident()
    solver = threading.Thread(target=report._run, args=(solve,), name="anytime:solver")
    solver.daemon = True  # a solver stuck in its call does not keep the interpreter alive
    best: Result | None = None
    counted = 0.0  # the units of `work` ticked so far
    waiting = False  # the solver's thread waits for an answer
    ended = False  # the solver's thread has ended (or is about to)
    solver.start()
    try:
        while True:
            kind, payload = report._to_module.get()
            waiting, ended = kind == _REPORT, kind != _REPORT
            if work is None:  # one unit a report (the late ones counted at the end)
                units = 1.0 if kind == _REPORT else float(report._late)
            else:
                total = _work(work(), "on_improvement: work()")
                if total < counted:
                    raise ValueError(
                        f"on_improvement: work() went back from {counted:g} to {total:g}"
                    )
                units, counted = total - counted, total
            ctx.tick(units)
            if kind == _RAISED:
                if report._stopped_by_us(payload):
                    return
                if isinstance(payload, StopIteration):  # a generator may not raise it as is
                    raise RuntimeError(
                        "the solver let a StopIteration through before it was told to stop"
                    ) from payload
                raise payload
            if kind == _REPORT:
                found = _candidate(payload, "report(...)")
            else:
                found = payload if isinstance(payload, Result) else None
            if _better(found, best):
                best = found
                assert found is not None
                yield found
            if ended:
                return
            waiting = False
            report._to_solver.put(ctx.expired)
    finally:
        if not ended:  # closed or failed with the solver running: stop it, await its end
            if waiting:
                report._to_solver.put(True)
            while True:
                kind, _ = report._to_module.get()
                if kind != _REPORT:
                    break
                report._to_solver.put(True)
        solver.join()
