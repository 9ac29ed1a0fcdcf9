"""The adapters for external solvers (anytime.plugin.solvers): `resume` for a solver that runs
for a limit of its own work and resumes, `on_improvement` for one that calls back on each
improvement; both with toy solvers, and scipy.optimize.minimize run as an interruptible module
under allocations, interruption and failure."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize, rosen

from anytime import (
    Budget,
    Decision,
    Hard,
    Isolated,
    Observer,
    Result,
    Soft,
    Status,
    WallClock,
    WorkClock,
    interruptible,
    run,
)
from anytime.plugin import Context
from anytime.plugin.solvers import Report, Resumable, on_improvement, resume


def solver_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "anytime:solver"]


@pytest.fixture(autouse=True)
def no_solver_thread_outlives_its_test() -> Iterator[None]:
    yield
    # A hard run answers at its deadline and leaves its module to notice: the module's thread
    # (and the solver's, which it stops and awaits) ends a moment later.
    for thread in solver_threads():
        thread.join(5)
    assert solver_threads() == []


# --- resume ----------------------------------------------------------------------------------


class Scripted:
    """A resumable solver that follows a script: at each slice it spends the next amount and,
    when the script gives a quality, its best becomes a new result of that quality; after the
    script, it is finished (spends 0)."""

    def __init__(self, script: Sequence[tuple[float, float | None]]) -> None:
        self.script = list(script)
        self.limits: list[float] = []
        self.current: Result | None = None

    def advance(self, limit: float) -> float:
        self.limits.append(limit)
        if not self.script:
            return 0
        spent, quality = self.script.pop(0)
        if quality is not None:
            self.current = Result(len(self.limits), quality)
        return spent

    def best(self) -> Result | None:
        return self.current


def drain(generator: Iterator[Result]) -> list[float]:
    return [result.quality for result in generator]


def test_resume_slices_the_allocation_and_ticks_what_each_slice_spent() -> None:
    solver = Scripted([(100, 0.2), (100, 0.5), (50, 0.7), (100, 0.9)])
    ctx = Context(allocation=250)
    assert drain(resume(ctx, solver, step=100)) == [0.2, 0.5, 0.7]
    assert solver.limits == [100, 100, 50]  # the last slice is what remained
    assert ctx.ticks == 250 and ctx.expired


def test_a_slice_that_spends_more_than_its_limit_is_ticked_as_spent() -> None:
    solver = Scripted([(100, 0.2), (180, 0.6), (100, 0.9)])
    ctx = Context(allocation=150)
    assert drain(resume(ctx, solver, step=100)) == [0.2, 0.6]
    assert solver.limits == [100, 50]
    assert ctx.ticks == 280  # the truth: 130 past the allocation, the second slice's excess


def test_a_solver_that_spends_nothing_at_first_is_finished() -> None:
    solver = Scripted([(0, 0.4)])  # finished at once, with a result (found for free)
    ctx = Context(allocation=1000)
    assert drain(resume(ctx, solver, step=100)) == [0.4]
    assert solver.limits == [100] and ctx.ticks == 0
    empty = Scripted([])
    assert drain(resume(Context(allocation=1000), empty, step=100)) == []
    assert empty.limits == [100]


def test_a_best_that_repeats_keeps_its_quality_or_gets_worse_is_not_yielded() -> None:
    solver = Scripted([(10, 0.5), (10, None), (10, 0.5), (10, 0.3), (10, 0.6), (10, 0.6)])
    assert drain(resume(Context(), solver, step=10)) == [0.5, 0.6]
    assert solver.limits == [10] * 7  # ran to the end: it finished at the seventh slice


def test_with_an_infinite_allocation_the_solver_runs_until_it_finishes() -> None:
    solver = Scripted([(7, 0.1)] * 5)
    ctx = Context()
    assert len(drain(resume(ctx, solver, step=1e6))) == 1
    assert solver.limits == [1e6] * 6 and ctx.ticks == 35


def test_an_expired_context_runs_no_slice() -> None:
    solver = Scripted([(10, 0.5)])
    assert drain(resume(Context(allocation=0), solver, step=10)) == []
    assert solver.limits == []


def test_a_stop_set_from_another_thread_ends_it_before_the_next_slice() -> None:
    ctx = Context()
    reached, stopped = threading.Event(), threading.Event()

    class Stopped(Scripted):
        def advance(self, limit: float) -> float:
            if len(self.limits) == 2:
                reached.set()  # the third slice: the other thread stops the module now
                assert stopped.wait(5)
            return super().advance(limit)

    def stopper() -> None:
        assert reached.wait(5)
        ctx.stop.set()
        stopped.set()

    other = threading.Thread(target=stopper)
    other.start()
    solver = Stopped([(10, 0.1 * i) for i in range(1, 9)])
    assert drain(resume(ctx, solver, step=10)) == [0.1, 0.2, pytest.approx(0.3)]
    other.join()
    assert len(solver.limits) == 3 and ctx.ticks == 30


@pytest.mark.parametrize("step", [0, -1, math.nan, math.inf, -math.inf, True, "10", None])
def test_a_step_that_is_not_a_finite_positive_number_is_refused(step: Any) -> None:
    with pytest.raises(ValueError, match=r"resume: step: expected a finite number of units > 0"):
        next(resume(Context(), Scripted([(1, 0.5)]), step=step))


@pytest.mark.parametrize("spent", [-1, math.nan, math.inf, None, "3"])
def test_a_solver_that_reports_impossible_work_is_named(spent: Any) -> None:
    with pytest.raises(ValueError, match=r"Scripted\.advance\(10\) gave .*: expected units"):
        next(resume(Context(), Scripted([(spent, 0.5)]), step=10))


def test_a_best_that_is_not_a_result_is_named() -> None:
    class Wrong(Scripted):
        def best(self) -> Any:
            return 0.5

    with pytest.raises(TypeError, match=r"Wrong\.best\(\) gave float 0\.5: expected a Result"):
        next(resume(Context(), Wrong([(1, 0.5)]), step=10))


def test_the_protocol_is_what_a_resumable_solver_has() -> None:
    solver: Resumable = Scripted([])  # mypy checks that it fits
    assert solver.best() is None


@interruptible("scripted", inputs=[], reports="estimate", step=100)
def scripted(ctx: Context, script: list[tuple[float, float | None]]) -> Iterator[Result]:
    yield from resume(ctx, Scripted(script), step=100)


@pytest.mark.parametrize(
    ("allocation", "status", "quality", "used"),
    [
        (50, Status.INTERRUPTED, 0.1, 50),
        (250, Status.INTERRUPTED, 0.5, 250),
        (math.inf, Status.COMPLETED, 0.9, 400),
    ],
)
def test_resume_as_a_module_run_under_an_allocation(
    allocation: float, status: Status, quality: float, used: float
) -> None:
    script: list[tuple[float, float | None]] = [(50, 0.1), (50, 0.2), (50, 0.3)]
    script += [(100, 0.5), (150, 0.9)]
    record = run(scripted, [script], budget=allocation)
    assert (record.status, record.quality, record.time_used) == (status, quality, used)


reports = st.lists(
    st.tuples(
        st.floats(min_value=0, max_value=300, allow_nan=False),
        st.none() | st.floats(min_value=0, max_value=1),
    ),
    max_size=30,
)


@settings(max_examples=200, deadline=None)
@given(
    script=reports,
    allocation=st.floats(min_value=0, max_value=2000) | st.just(math.inf),
    step=st.floats(min_value=0.5, max_value=200),
)
def test_resume_yields_better_results_ticks_what_was_spent_and_overruns_by_one_excess(
    script: list[tuple[float, float | None]], allocation: float, step: float
) -> None:
    solver = Scripted(script)
    ctx = Context(allocation=allocation)
    qualities = drain(resume(ctx, solver, step=step))
    assert all(a < b for a, b in zip(qualities, qualities[1:], strict=False))
    slices = len(solver.limits)
    spent = [s for s, _ in script[:slices]]
    assert ctx.ticks == pytest.approx(sum(spent))
    # It stops at the first slice that spends 0 or after which the context has expired.
    for i, limit in enumerate(solver.limits):
        assert 0 < limit <= step
        if i < len(spent):
            assert spent[i] > 0 or i == slices - 1
    excess = max(0.0, spent[-1] - solver.limits[-1]) if spent else 0.0
    assert ctx.ticks <= allocation + excess + 1e-6 * max(1.0, allocation)
    if not ctx.expired:  # it stopped before its allocation: the solver finished
        assert slices > len(script) or spent[-1] == 0
    # What it yielded is the best of what the solver had after each slice, never a worse one.
    seen = [q for _, q in script[:slices] if q is not None]
    assert qualities[-1:] == ([max(seen)] if seen else [])


# --- on_improvement: toy solvers -------------------------------------------------------------


def climbing(qualities: Sequence[float], *, log: list[str] | None = None) -> Callable[..., Any]:
    """A solve function: a solver that reports each quality in turn (one per iteration) and
    stops when told to; `log` gets its stops and ends."""

    def solve(report: Report) -> str:
        for i, quality in enumerate(qualities):
            if report(Result(i, quality)):
                if log is not None:
                    log.append(f"stopped at {i}")
                return "stopped"
        if log is not None:
            log.append("finished")
        return "finished"

    return solve


def test_on_improvement_yields_each_better_result_as_it_comes() -> None:
    ctx = Context()
    log: list[str] = []
    generator = on_improvement(ctx, climbing([0.1, 0.1, 0.05, 0.3, 0.2, 0.8], log=log))
    first = next(generator)
    assert first == Result(0, 0.1) and ctx.ticks == 1
    assert [r.quality for r in generator] == [0.3, 0.8]
    assert ctx.ticks == 6 and log == ["finished"]


def test_the_allocation_stops_the_solver_at_its_callback() -> None:
    ctx = Context(allocation=3)
    log: list[str] = []
    assert drain(on_improvement(ctx, climbing([0.1, 0.2, 0.3, 0.4, 0.5], log=log))) == [
        0.1,
        0.2,
        0.3,
    ]
    assert log == ["stopped at 2"] and ctx.ticks == 3


def test_a_module_closed_early_stops_its_solver_and_waits_for_it() -> None:
    log: list[str] = []
    generator = on_improvement(Context(), climbing([0.1 * i for i in range(10)], log=log))
    next(generator)
    next(generator)
    assert len(solver_threads()) == 1  # waiting in its callback
    generator.close()
    assert log == ["stopped at 1"] and solver_threads() == []


def test_a_module_that_is_never_started_starts_no_solver() -> None:
    called: list[str] = []
    generator = on_improvement(Context(), lambda report: called.append("solved"))
    generator.close()
    assert called == [] and solver_threads() == []


def test_work_counts_the_solvers_own_unit() -> None:
    evaluations = 0

    def solve(report: Report) -> Result:
        nonlocal evaluations
        for i in range(1, 6):
            evaluations += 10 * i  # the work of an iteration, counted by the solver
            report(Result(i, i / 10))
        evaluations += 7  # work after the last callback, before it returns
        return Result("final", 0.9)

    ctx = Context()
    assert drain(on_improvement(ctx, solve, work=lambda: evaluations)) == [
        0.1,
        0.2,
        0.3,
        0.4,
        0.5,
        0.9,
    ]
    assert ctx.ticks == 157


def test_what_solve_returns_is_the_last_candidate_if_it_is_a_result() -> None:
    assert drain(on_improvement(Context(), lambda report: Result("x", 0.4))) == [0.4]
    worse = drain(on_improvement(Context(), lambda report: report(Result(1, 0.5)) and None))
    assert worse == [0.5]

    def returns_worse(report: Report) -> Result:
        report(Result(1, 0.5))
        return Result(2, 0.5)

    assert drain(on_improvement(Context(), returns_worse)) == [0.5]
    assert drain(on_improvement(Context(), lambda report: "not a result")) == []


def test_work_that_goes_back_or_is_not_a_number_is_an_error() -> None:
    counts = iter([5.0, 3.0])
    with pytest.raises(ValueError, match=r"work\(\) went back from 5 to 3"):
        drain(on_improvement(Context(), climbing([0.1, 0.2, 0.3]), work=lambda: next(counts)))
    with pytest.raises(ValueError, match=r"work\(\) gave nan"):
        drain(on_improvement(Context(), climbing([0.1]), work=lambda: math.nan))


def test_a_report_that_is_not_a_result_is_an_error() -> None:
    def solve(report: Report) -> None:
        report(0.5)  # type: ignore[arg-type]

    with pytest.raises(TypeError, match=r"report\(\.\.\.\) gave float 0\.5: expected a Result"):
        drain(on_improvement(Context(), solve))


def test_check_stops_a_solver_that_stops_only_when_its_callback_raises() -> None:
    log: list[str] = []

    def solve(report: Report) -> None:
        for i in range(100):
            try:
                report.check(Result(i, i / 100))
            except Exception:
                log.append(f"raised at {i}")
                raise

    ctx = Context(allocation=4)
    assert drain(on_improvement(ctx, solve)) == [0, 0.01, 0.02, 0.03]
    assert log == ["raised at 3"] and ctx.ticks == 4


def test_a_solver_told_to_stop_that_calls_back_again_is_answered_at_once() -> None:
    answers: list[bool] = []

    def deaf(report: Report) -> None:
        for i in range(10):
            answers.append(report(Result(i, i / 100)))  # its answer ignored

    ctx = Context(allocation=2)
    assert drain(on_improvement(ctx, deaf)) == [0, 0.01]  # nothing after the stop
    assert answers == [False] + [True] * 9
    assert ctx.ticks == 10  # its callbacks after the stop, counted when it returned
    closed = on_improvement(Context(), deaf)
    next(closed)
    closed.close()  # answered to stop, it runs to its end: the close waits for it
    assert answers[10:] == [True] * 10 and solver_threads() == []


def test_a_stop_wrapped_by_the_solver_or_a_stop_iteration_after_a_stop_is_a_stop() -> None:
    def wrapping(report: Report) -> None:
        try:
            report.check(Result(1, 0.5))
        except Exception as exc:
            raise RuntimeError("the solver's own error") from exc

    assert drain(on_improvement(Context(allocation=1), wrapping)) == [0.5]

    def stop_iteration(report: Report) -> None:
        if report(Result(1, 0.5)):
            raise StopIteration  # a solver that lets the callback's StopIteration through

    assert drain(on_improvement(Context(allocation=1), stop_iteration)) == [0.5]


def test_a_stop_iteration_before_any_stop_is_an_error_that_says_so() -> None:
    def early(report: Report) -> None:
        report(Result(1, 0.5))
        raise StopIteration

    generator = on_improvement(Context(), early)
    assert next(generator) == Result(1, 0.5)
    with pytest.raises(RuntimeError, match="let a StopIteration through before it was told"):
        next(generator)


class SolverError(Exception):
    pass


def test_an_error_of_the_solver_is_raised_in_the_module() -> None:
    def failing(report: Report) -> None:
        report(Result(1, 0.5))
        raise SolverError("singular matrix")

    generator = on_improvement(Context(), failing)
    assert next(generator) == Result(1, 0.5)
    with pytest.raises(SolverError, match="singular matrix"):
        next(generator)


def test_only_the_modules_thread_touches_the_context() -> None:
    threads: set[int] = set()

    class Recording(WorkClock):
        def advance(self, n: float) -> None:
            threads.add(threading.get_ident())
            super().advance(n)

    ctx = Context(clock=Recording())
    assert len(drain(on_improvement(ctx, climbing([0.1, 0.2, 0.3])))) == 3
    assert threads == {threading.get_ident()}


def test_report_outside_the_solvers_call_is_refused() -> None:
    kept: list[Report] = []

    def solve(report: Report) -> None:
        kept.append(report)
        report(Result(1, 0.5))

    generator = on_improvement(Context(), solve)
    next(generator)
    with pytest.raises(RuntimeError, match=r"report\(\.\.\.\) is for the solver's callback"):
        kept[0](Result(2, 0.6))
    generator.close()


@interruptible("climb", inputs=[], reports="estimate", step=1)
def climb(ctx: Context, n: int) -> Iterator[Result]:
    yield from on_improvement(ctx, climbing([i / n for i in range(1, n + 1)]))


@interruptible("climb-and-fail", inputs=[], reports="estimate", step=1)
def climb_and_fail(ctx: Context) -> Iterator[Result]:
    def solve(report: Report) -> None:
        report(Result("first", 0.3))
        raise SolverError("the solver gave up")

    yield from on_improvement(ctx, solve)


@pytest.mark.parametrize("mode", [Soft(), Hard(), Isolated()], ids=["soft", "hard", "isolated"])
def test_on_improvement_as_a_module_run_under_an_allocation(mode: Soft | Hard | Isolated) -> None:
    record = run(climb, [100], budget=10, mode=mode)
    assert (record.status, record.quality, record.time_used) == (Status.INTERRUPTED, 0.1, 10)
    done = run(climb, [100], budget=1000, mode=mode)
    assert (done.status, done.quality, done.time_used) == (Status.COMPLETED, 1.0, 100)
    assert done.registered == 100


class StopsAtHalf(Observer):
    """Looks at every tick (from the module's thread: the context's clock is where looks are
    taken) and stops the run once its answer is of quality 0.5."""

    def __init__(self) -> None:
        self.looks: list[float] = []
        self.threads: set[int] = set()

    def started(self, module: Any, args: Any, allocation: float) -> Decision:
        return Decision.later(1, math.inf, "look at every tick")

    def look(self, elapsed: float, best: Result | None) -> Decision:
        self.looks.append(elapsed)
        self.threads.add(threading.get_ident())
        if best is not None and best.quality >= 0.5:
            return Decision.now("good enough")
        return Decision.later(elapsed + 1, math.inf, "look at the next tick")


@pytest.mark.parametrize("mode", [Soft(), Hard()], ids=["soft", "hard"])
def test_an_observer_that_stops_the_run_stops_the_solver(mode: Soft | Hard) -> None:
    observer = StopsAtHalf()
    record = run(climb, [10], budget=100, mode=mode, observer=observer)
    assert record.status is Status.STOPPED and record.quality == 0.5
    assert observer.looks == [1, 2, 3, 4, 5] and record.time_used == 5
    # Looks are taken on the module's thread (this one in soft mode, the worker in hard mode),
    # never on the solver's.
    assert len(observer.threads) == 1
    assert (observer.threads == {threading.get_ident()}) == isinstance(mode, Soft)


def test_an_error_of_the_solver_is_the_modules_failure() -> None:
    record = run(climb_and_fail)
    assert record.status is Status.FAILED
    assert record.result == Result("first", 0.3)  # the best before it failed, kept
    assert record.error == "test_solvers.SolverError: the solver gave up"
    assert record.traceback is not None and "in solve" in record.traceback


# --- scipy.optimize.minimize with a callback -------------------------------------------------


def rosenbrock_quality(value: float) -> float:
    return 1 / (1 + value)


@interruptible("minimize-rosenbrock", inputs=[], reports="estimate")
def minimize_rosenbrock(ctx: Context, x0: list[float], slow: float = 0.0) -> Iterator[Result]:
    """Rosenbrock's function minimized by BFGS; the work clock counts its evaluations."""
    evaluations = 0

    def objective(x: np.ndarray) -> float:
        nonlocal evaluations
        evaluations += 1
        if slow:
            time.sleep(slow)
        return float(rosen(x))

    def solve(report: Report) -> None:
        def callback(intermediate_result: Any) -> None:
            found = Result(intermediate_result.x, rosenbrock_quality(intermediate_result.fun))
            if report(found):
                raise StopIteration  # how a callback stops minimize

        minimize(objective, np.asarray(x0), method="BFGS", callback=callback)

    yield from on_improvement(ctx, solve, work=lambda: evaluations)


X0 = [-1.2, 1.0, -0.5, 0.8]


def test_scipy_minimize_under_more_time_is_never_worse_and_deterministic() -> None:
    allocations = [10, 25, 50, 100, 150, 400, math.inf]  # it converges after 190 evaluations
    records = [run(minimize_rosenbrock, [X0], budget=a) for a in allocations]
    qualities = [r.quality for r in records]
    assert all(a <= b for a, b in zip(qualities, qualities[1:], strict=False))
    assert qualities[-1] > 0.999 and qualities[0] < 0.5
    assert [r.status for r in records[-2:]] == [Status.COMPLETED] * 2
    assert records[-1].time_used == 190
    assert all(r.status is Status.INTERRUPTED for r in records[:-2])
    again = [run(minimize_rosenbrock, [X0], budget=a) for a in allocations]
    assert [(r.time_used, r.quality, r.registered) for r in again] == [
        (r.time_used, r.quality, r.registered) for r in records
    ]
    # The evaluations are ticked at each callback, an iteration's at once (BFGS evaluates the
    # objective a few times an iteration): the run goes past its allocation by at most one
    # iteration's evaluations (its step), at the tick that crosses it, in either mode.
    for allocation, record in zip(allocations[:-2], records[:-2], strict=True):
        assert allocation <= record.time_used <= allocation + 30
        hard = run(minimize_rosenbrock, [X0], budget=allocation, mode=Hard())
        assert (hard.time_used, hard.quality) == (record.time_used, record.quality)


def test_scipy_minimize_is_interrupted_promptly_from_another_thread() -> None:
    stop = threading.Event()
    timer = threading.Timer(0.3, stop.set)
    timer.start()
    began = time.perf_counter()
    # 10 ms an evaluation: about 0.1 s an iteration, 2 s to converge (190 evaluations).
    record = run(minimize_rosenbrock, [X0, 0.01], budget=Budget(math.inf, stop=stop))
    took = time.perf_counter() - began
    timer.join()
    assert record.status is Status.INTERRUPTED and record.result is not None
    assert 0.3 <= took < 1.0 and record.time_used < 150


def test_an_error_in_the_objective_is_the_modules_failure() -> None:
    @interruptible("minimize-failing", inputs=[], reports="estimate")
    def failing(ctx: Context) -> Iterator[Result]:
        def objective(x: np.ndarray) -> float:
            if x[0] > -1.0:
                raise SolverError("the model is undefined there")
            return float(rosen(x))

        def solve(report: Report) -> None:
            def callback(intermediate_result: Any) -> None:
                if report(Result(intermediate_result.x, 0.5)):
                    raise StopIteration

            minimize(objective, np.array([-1.2, 1.0]), method="Nelder-Mead", callback=callback)

        yield from on_improvement(ctx, solve)

    record = run(failing)
    assert record.status is Status.FAILED
    assert record.error == "test_solvers.SolverError: the model is undefined there"


def test_on_a_wall_clock_the_slices_are_whole_steps_until_the_time_is_up() -> None:
    class Slow(Scripted):
        def advance(self, limit: float) -> float:
            time.sleep(0.01)
            return super().advance(limit)

    solver = Slow([(100, i / 100) for i in range(100)])
    ctx = Context(allocation=0.05, clock=WallClock())
    assert len(drain(resume(ctx, solver, step=100))) == len(solver.limits)
    assert set(solver.limits) == {100}
    assert 1 <= len(solver.limits) <= 6  # each takes 10 ms or more; it stops past 50 ms
    assert ctx.ticks == 100 * len(solver.limits)
