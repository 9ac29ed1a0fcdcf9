"""`run`: one module under a contract or interruption, answering with a run record.

Interruption at any tick keeps the last result registered in time (hypothesis, soft and hard);
interruption from another thread; every way a module can misbehave (raise, yield a non-Result,
build a quality outside [0, 1], overrun its contract, register nothing, refuse to close) keeps
the best result it registered before, with a status and a message; elementary functions combine
their inputs' qualities; hard interruption cuts off a stuck module at the deadline, on the wall
clock within the issue's 50 ms and on the work clock by polling.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.clocks import WallClock, WorkClock
from anytime.modules import Context, Registry, Result, contract, elementary, interruptible
from anytime.runtime import Budget, Hard, RunRecord, Soft, Status, run

TOYS = Registry()
SETTINGS = settings(max_examples=80, deadline=None)


class Boom(Exception):
    """An exception of the test's own, to check that the error line names its class."""


# --- toy modules ------------------------------------------------------------------------------


@interruptible("script", inputs=[], registry=TOYS)
def script(ctx: Context, steps: Sequence[tuple[float, float]], tail: float = 0) -> Iterator[Result]:
    """For each (work, quality) step: report the work, then yield Result(i, quality); at the end
    report `tail` more work."""
    for i, (work, quality) in enumerate(steps):
        ctx.tick(work)
        yield Result(i, quality)
    ctx.tick(tail)


@interruptible("explode", inputs=[], registry=TOYS)
def explode(ctx: Context, k: int, error: Callable[[], BaseException]) -> Iterator[Result]:
    """Yields k results of increasing quality, then raises."""
    for i in range(k):
        ctx.tick(1)
        yield Result(i, (i + 1) / (k + 1))
    raise error()


@interruptible("emit", inputs=[], registry=TOYS)
def emit(ctx: Context, items: Sequence[Callable[[], Any]]) -> Iterator[Any]:
    """Yields what each factory makes (a Result, something else, or raising while making it)."""
    for make in items:
        ctx.tick(1)
        yield make()


@interruptible("nothing", inputs=[], registry=TOYS)
def nothing(ctx: Context, work: float) -> Iterator[Result]:
    """Works, then ends without registering anything."""
    ctx.tick(work)
    return
    yield


@interruptible("busy", inputs=[], registry=TOYS)
def busy(
    ctx: Context, k: int, reached: threading.Event, resume: threading.Event, cooperative: bool
) -> Iterator[Result]:
    """Yields results 0..k-1, then signals `reached` and computes until `resume` is set; a
    cooperative module then notices it was asked to stop and returns, another yields result k."""
    for i in range(k + 1):
        ctx.tick(1)
        if i == k:
            reached.set()
            resume.wait(30)
            if cooperative and ctx.expired:
                return
        yield Result(i, 1 - 1 / (i + 2))


@interruptible("stubborn", inputs=[], registry=TOYS)
def stubborn(ctx: Context, how: str) -> Iterator[Result]:
    """Improves forever, and misbehaves when it is closed."""
    i = 0
    try:
        while True:
            i += 1
            ctx.tick(1)
            yield Result(i, 1 - 1 / (i + 1))
    except GeneratorExit:
        if how == "raise":
            raise RuntimeError("cannot clean up") from None
        yield Result("after close", 1.0)  # "ignore": yields again instead of closing


@interruptible("hang", inputs=[], registry=TOYS)
def hang(ctx: Context, release: threading.Event, work: float = 0) -> Iterator[Result]:
    """Yields once, reports `work`, then is stuck (without looking at its context) until
    released or 2 s have passed."""
    yield Result("first", 0.3)
    ctx.tick(work)
    release.wait(2)
    yield Result("late", 0.9)


@contract("estimate", inputs=[], registry=TOYS)
def estimate(ctx: Context, work: float, quality: float) -> Result:
    """Reports `work` and answers with the allocation it was given."""
    ctx.tick(work)
    return Result(("estimate", ctx.allocation), quality)


@contract("exact", inputs=[], registry=TOYS)
def exact(ctx: Context) -> Result:
    """Spends exactly its allocation."""
    ctx.tick(ctx.allocation)
    return Result(("exact", ctx.allocation), 1.0)


@contract("misfit", inputs=[], registry=TOYS)
def misfit(ctx: Context, make: Callable[[], Any]) -> Any:
    """Returns whatever `make` makes (or raises what it raises)."""
    ctx.tick(1)
    return make()


@contract("stuck", inputs=[], registry=TOYS)
def stuck(ctx: Context, release: threading.Event, work: float = 0) -> Result:
    """Reports `work`, then is stuck until released or 2 s have passed."""
    ctx.tick(work)
    release.wait(2)
    return Result("late", 1.0)


@elementary("pair", registry=TOYS)
def pair(a: Result, b: Result) -> Any:
    return (a.value, b.value)


@elementary("triple-max", combine=max, registry=TOYS)
def triple_max(a: Result, b: Result, c: Result) -> Any:
    return (a.value, b.value, c.value)


@elementary("triple-product", combine=math.prod, registry=TOYS)
def triple_product(a: Result, b: Result, c: Result) -> Any:
    return (a.value, b.value, c.value)


@elementary("product", combine=math.prod, registry=TOYS)
def product(a: Any, b: Any) -> Any:
    return 2


@elementary("label", inputs=["a"], registry=TOYS)
def label(a: Result, text: str) -> Any:
    return f"{text}: {a.value}"


@elementary("constant", inputs=[], registry=TOYS)
def constant(text: str) -> Any:
    return text


@elementary("scale", inputs=["a"], registry=TOYS)
def scale(a: Result, factor: int = 1) -> Any:
    return a.value * factor


@elementary("judged", registry=TOYS)
def judged(a: Result) -> Any:
    return Result(("judged", a.value), 0.25)


@elementary("faulty", registry=TOYS)
def faulty(a: Result) -> Any:
    raise Boom("no value")


@elementary("summed", combine=sum, registry=TOYS)
def summed(a: Result, b: Result) -> Any:
    return a.value + b.value


@pytest.fixture
def release() -> Iterator[threading.Event]:
    """Unsticks the stuck modules of a test when it ends (their threads then finish)."""
    event = threading.Event()
    yield event
    event.set()


def expected_run(
    steps: Sequence[tuple[float, float]], allocation: float
) -> tuple[Status, int | None, float, int]:
    """What the executor must answer for `script(steps)`: it stops the module at the first
    yield at or past the allocation, counting it only if it is not past. Returns the status, the
    index of the result (None for none), the time used and the number of results registered."""
    elapsed, last, count = 0.0, None, 0
    for i, (work, _) in enumerate(steps):
        elapsed += work
        if elapsed > allocation:
            return (Status.INTERRUPTED if count else Status.NO_RESULT), last, elapsed, count
        last, count = i, count + 1
        if elapsed >= allocation:
            return Status.INTERRUPTED, last, elapsed, count
    return (Status.COMPLETED if count else Status.NO_RESULT), last, elapsed, count


# --- interruption at any tick -----------------------------------------------------------------


def _with_increasing_qualities(steps: list[tuple[float, float]]) -> list[tuple[float, float]]:
    qualities = sorted(q for _, q in steps)
    return [(work, q) for (work, _), q in zip(steps, qualities, strict=True)]


#: (work before the yield, quality) per yield; qualities non-decreasing.
steps_strategy = st.lists(st.tuples(st.integers(0, 4).map(float), st.floats(0, 1)), max_size=8).map(
    _with_increasing_qualities
)


@SETTINGS
@given(
    steps=steps_strategy,
    allocation=st.one_of(st.integers(0, 30).map(float), st.floats(0, 30)),
    already=st.integers(0, 1000),
)
def test_interrupting_at_any_tick_keeps_the_last_result_yielded_in_time(
    steps: list[tuple[float, float]], allocation: float, already: int
) -> None:
    clock = WorkClock()
    clock.advance(already)  # the run's time counts from its start, not from the clock's zero
    record = run(script, (steps,), budget=Budget(allocation, clock=clock))
    status, index, used, count = expected_run(steps, allocation)
    assert record.status == status
    if index is None:
        assert record.result is None and record.quality == 0.0
    else:
        assert record.result == Result(index, steps[index][1])
    assert record.time_used == used
    assert record.registered == count
    assert record.allocation == allocation
    assert (record.module, record.error, record.traceback) == ("script", None, None)


@SETTINGS
@given(
    steps=steps_strategy,
    allocation=st.integers(0, 30).flatmap(lambda n: st.sampled_from([float(n), n + 0.5])),
)
def test_hard_interruption_on_the_work_clock_answers_like_soft_interruption(
    steps: list[tuple[float, float]], allocation: float
) -> None:
    """On the tick lattice too (a result yielded exactly at the deadline): the work clock moves
    only when the module ticks, so the caller awaits it until it ticks past its allocation, and
    hard and soft interruption give the same record."""
    hard = run(script, (steps,), budget=allocation, mode=Hard(poll=0.0005))
    soft = run(script, (steps,), budget=allocation)
    assert hard == soft


@SETTINGS
@given(qualities=st.lists(st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0]), min_size=1, max_size=10))
def test_the_best_result_is_the_highest_quality_one_and_the_later_on_ties(
    qualities: list[float],
) -> None:
    steps = [(1.0, q) for q in qualities]
    record = run(script, (steps,))
    best = max(range(len(qualities)), key=lambda i: (qualities[i], i))
    assert record.status == Status.COMPLETED
    assert record.result == Result(best, qualities[best])
    assert record.registered == len(qualities)
    assert record.time_used == len(qualities)


def test_a_module_that_finishes_after_its_allocation_did_not_complete() -> None:
    """Its last result came in time, but the module went on working past the deadline before it
    ended: "completed" means it finished on its own within its time."""
    record = run(script, ([(1.0, 0.5), (1.0, 0.6)],), {"tail": 10.0}, budget=5)
    assert record.result == Result(1, 0.6)
    assert record.time_used == 12
    assert record.status == Status.INTERRUPTED


def test_a_module_that_finishes_within_its_allocation_completed() -> None:
    record = run(script, ([(1.0, 0.5), (1.0, 0.6)],), {"tail": 3.0}, budget=5)
    assert (record.status, record.result, record.time_used) == (
        Status.COMPLETED,
        Result(1, 0.6),
        5.0,
    )


# --- interruption from outside ----------------------------------------------------------------


@settings(max_examples=20, deadline=None)
@given(k=st.integers(0, 5), hard=st.booleans())
def test_a_stop_set_by_another_thread_interrupts_the_run(k: int, hard: bool) -> None:
    """The module is in the middle of computing result k when another thread sets `stop`: the
    answer is result k-1 (none for k = 0), and result k, yielded after the stop, does not count."""
    stop, reached, resume = threading.Event(), threading.Event(), threading.Event()

    def interrupter() -> None:
        reached.wait(30)
        stop.set()
        resume.set()

    other = threading.Thread(target=interrupter)
    other.start()
    record = run(
        busy, (k, reached, resume, False), budget=Budget(stop=stop), mode=Hard() if hard else Soft()
    )
    other.join()
    if k == 0:
        assert (record.status, record.result) == (Status.NO_RESULT, None)
    else:
        assert record.status == Status.INTERRUPTED
        assert record.result == Result(k - 1, 1 - 1 / (k + 1))
    assert record.registered == k


def test_a_cooperative_module_stopped_from_outside_was_interrupted() -> None:
    """The module sees `ctx.expired` turn true because another thread set `stop`, and returns:
    it was stopped from outside, so the run was interrupted, not completed. (Soft mode only: in
    hard mode the answer depends on whether the caller sees the stop before the module ends.)"""
    stop, reached, resume = threading.Event(), threading.Event(), threading.Event()

    def interrupter() -> None:
        reached.wait(30)
        stop.set()
        resume.set()

    other = threading.Thread(target=interrupter)
    other.start()
    record = run(busy, (3, reached, resume, True), budget=Budget(stop=stop))
    other.join()
    assert record.result == Result(2, 0.75)
    assert record.status == Status.INTERRUPTED


def test_a_run_whose_stop_is_already_set_registers_nothing() -> None:
    stop = threading.Event()
    stop.set()
    record = run(script, ([(0.0, 0.5)],), budget=Budget(stop=stop))
    assert (record.status, record.result, record.registered) == (Status.NO_RESULT, None, 0)


# --- failures keep the best result ------------------------------------------------------------


ERRORS: list[tuple[Callable[[], BaseException], str]] = [
    (lambda: ValueError("bad input"), "ValueError: bad input"),
    (lambda: KeyError("x"), "KeyError: 'x'"),
    (lambda: ZeroDivisionError("division by zero"), "ZeroDivisionError: division by zero"),
    (lambda: Boom("stuck at 3"), f"{Boom.__module__}.Boom: stuck at 3"),
    (lambda: RuntimeError(), "RuntimeError"),
]


@SETTINGS
@given(k=st.integers(0, 6), error=st.sampled_from(ERRORS), hard=st.booleans())
def test_a_module_that_raises_after_k_yields_keeps_result_k(
    k: int, error: tuple[Callable[[], BaseException], str], hard: bool
) -> None:
    make, headline = error
    record = run(explode, (k, make), mode=Hard() if hard else Soft())
    assert record.status == Status.FAILED
    assert record.result == (Result(k - 1, k / (k + 1)) if k else None)
    assert record.registered == k
    assert record.time_used == k
    assert record.error == headline
    assert record.traceback is not None
    lines = record.traceback.rstrip().splitlines()
    assert lines[0] == "Traceback (most recent call last):"
    assert lines[-1] == headline
    assert ", in explode" in record.traceback  # the frame that raised


def test_a_syntax_error_is_reported_by_its_last_line() -> None:
    def make() -> BaseException:
        try:
            compile("1 +", "<plan>", "exec")
        except SyntaxError as error:
            return error
        raise AssertionError("compiled")

    record = run(explode, (1, make))
    assert record.error == "SyntaxError: invalid syntax"
    assert record.result == Result(0, 0.5)


def _multiline() -> BaseException:
    return ValueError("the map is\ninconsistent")


def _noted() -> BaseException:
    error = ValueError("the map is inconsistent")
    error.add_note("while reading sensor 3")
    return error


@pytest.mark.parametrize("make", [_multiline, _noted], ids=["multi-line message", "with a note"])
def test_the_error_line_names_the_exception(make: Callable[[], BaseException]) -> None:
    record = run(explode, (2, make))
    assert record.status == Status.FAILED and record.result == Result(1, 2 / 3)
    assert record.error is not None
    assert record.error.startswith("ValueError: the map is")
    assert "\n" not in record.error


@pytest.mark.parametrize("hard", [False, True], ids=["soft", "hard"])
def test_a_module_that_cannot_be_called_fails_without_a_result(hard: bool) -> None:
    record = run(script, (), mode=Hard() if hard else Soft())
    assert (record.status, record.result, record.registered) == (Status.FAILED, None, 0)
    assert record.error == "TypeError: script() missing 1 required positional argument: 'steps'"
    assert record.traceback is not None and record.traceback.startswith("Traceback")


def good(i: int, quality: float) -> Callable[[], Result]:
    return lambda: Result(i, quality)


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (lambda: 0.7, "yielded float 0.7, not a Result"),
        (lambda: None, "yielded NoneType None, not a Result"),
        (lambda: ("plan", 0.9), "yielded tuple ('plan', 0.9), not a Result"),
        (lambda: "x" * 100, "yielded str '" + "x" * 59 + "..., not a Result"),
    ],
    ids=["float", "None", "tuple", "long"],
)
@pytest.mark.parametrize("hard", [False, True], ids=["soft", "hard"])
def test_yielding_something_else_than_a_result_fails_and_keeps_the_best(
    bad: Callable[[], Any], message: str, hard: bool
) -> None:
    items = [good(0, 0.4), good(1, 0.6), bad, good(3, 0.9)]
    record = run(emit, (items,), mode=Hard() if hard else Soft())
    assert record.status == Status.FAILED
    assert record.error == message
    assert record.traceback is None
    assert record.result == Result(1, 0.6)
    assert record.registered == 2
    assert record.time_used == 3


@pytest.mark.parametrize(
    ("quality", "shown"), [(1.5, "1.5"), (-0.1, "-0.1"), (math.nan, "nan")], ids=str
)
def test_a_result_of_quality_outside_the_unit_interval_fails_and_keeps_the_best(
    quality: float, shown: str
) -> None:
    items = [good(0, 0.4), good(1, 0.6), good(2, quality)]
    record = run(emit, (items,))
    assert record.status == Status.FAILED
    assert record.error == f"ValueError: a Result's quality must be in [0, 1], got {shown}"
    assert record.traceback is not None and ", in emit" in record.traceback
    assert record.result == Result(1, 0.6)


@pytest.mark.parametrize("work", [0.0, 4.0], ids=["at once", "after working"])
def test_a_module_that_registers_nothing_has_no_result(work: float) -> None:
    record = run(nothing, (work,), budget=10)
    assert record == RunRecord(
        module="nothing",
        status=Status.NO_RESULT,
        result=None,
        time_used=work,
        allocation=10.0,
        registered=0,
    )


@pytest.mark.parametrize("how", ["raise", "ignore"])
def test_a_module_that_misbehaves_when_closed_changes_nothing(how: str) -> None:
    record = run(stubborn, (how,), budget=3)
    assert record.status == Status.INTERRUPTED
    assert record.result == Result(3, 0.75)
    assert (record.registered, record.time_used, record.error) == (3, 3.0, None)


# --- contracts --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("work", "hard"),
    [(0.0, False), (7.0, False), (10.0, False), (0.0, True), (7.0, True), (10.0, True)],
    ids=["idle", "within", "exactly", "idle-hard", "within-hard", "exactly-hard"],
)
def test_a_contract_within_its_allocation_completes(work: float, hard: bool) -> None:
    record = run(estimate, (work, 0.8), budget=10, mode=Hard() if hard else Soft())
    assert record.status == Status.COMPLETED
    assert record.result == Result(("estimate", 10.0), 0.8)
    assert (record.time_used, record.registered) == (work, 1)


@pytest.mark.parametrize("allocation", [0.0, 10.0])
def test_hard_mode_awaits_a_contract_on_the_work_clock_every_time(allocation: float) -> None:
    """A contract that spends exactly its allocation (0 included) answers in every run: the
    caller does not race the module's start (it answered 1 run in 100 at 0 ticks)."""
    records = [run(estimate, (allocation, 0.8), budget=allocation, mode=Hard()) for _ in range(200)]
    assert {r.status for r in records} == {Status.COMPLETED}
    assert {r.result for r in records} == {Result(("estimate", allocation), 0.8)}


def test_a_contract_that_overruns_expires_and_keeps_its_result() -> None:
    record = run(estimate, (15.0, 0.8), budget=10)
    assert record.status == Status.CONTRACT_EXPIRED
    assert str(record.status) == "contract-expired"
    assert record.result == Result(("estimate", 10.0), 0.8)
    assert (record.time_used, record.allocation, record.registered) == (15.0, 10.0, 1)


@SETTINGS
@given(already=st.floats(0, 100), allocation=st.floats(0, 40))
def test_a_contract_that_spends_exactly_its_allocation_completes(
    already: float, allocation: float
) -> None:
    """Wherever the run starts on the clock (in a program, modules start at fractional times,
    and the clock's sum then rounds)."""
    clock = WorkClock()
    clock.advance(already)
    record = run(exact, budget=Budget(allocation, clock=clock))
    assert record.result == Result(("exact", allocation), 1.0)
    assert record.status == Status.COMPLETED


@pytest.mark.parametrize("hard", [False, True], ids=["soft", "hard"])
@pytest.mark.parametrize(
    ("make", "error"),
    [
        (lambda: Boom("no estimate"), f"{Boom.__module__}.Boom: no estimate"),
        (lambda: Result("x", 1.5), "ValueError: a Result's quality must be in [0, 1], got 1.5"),
    ],
    ids=["raises", "bad quality"],
)
def test_a_contract_that_raises_fails_without_a_result(
    make: Callable[[], Any], error: str, hard: bool
) -> None:
    def raising() -> Any:
        made = make()
        if isinstance(made, BaseException):
            raise made
        return made

    record = run(misfit, (raising,), budget=10, mode=Hard() if hard else Soft())
    assert (record.status, record.result, record.registered) == (Status.FAILED, None, 0)
    assert record.error == error
    assert record.traceback is not None and ", in misfit" in record.traceback


@pytest.mark.parametrize(
    ("value", "message"),
    [(3, "returned int 3, not a Result"), ({"a": 1}, "returned dict {'a': 1}, not a Result")],
    ids=["int", "dict"],
)
def test_a_contract_that_returns_something_else_fails(value: Any, message: str) -> None:
    record = run(misfit, (lambda: value,), budget=10)
    assert (record.status, record.result, record.error, record.traceback) == (
        Status.FAILED,
        None,
        message,
        None,
    )


# --- elementary functions ---------------------------------------------------------------------


qualities3 = st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1))


@SETTINGS
@given(q=qualities3)
def test_an_elementary_function_combines_its_inputs_qualities(
    q: tuple[float, float, float],
) -> None:
    a, b, c = (Result(name, quality) for name, quality in zip("abc", q, strict=True))
    lowest = run(pair, (a, b))
    assert lowest == RunRecord(
        module="pair",
        status=Status.COMPLETED,
        result=Result(("a", "b"), min(q[0], q[1])),
        time_used=0.0,
        allocation=math.inf,
        registered=1,
    )
    assert run(triple_max, (a, b, c)).result == Result(("a", "b", "c"), max(q))
    assert run(triple_product, (a, b, c)).result == Result(("a", "b", "c"), math.prod(q))


def test_only_quality_carrying_inputs_count_and_plain_values_have_quality_one() -> None:
    assert run(label, (Result("map", 0.4), "plan")).result == Result("plan: map", 0.4)
    assert run(product, (Result("map", 0.4), "raw")).result == Result(2, 0.4)
    assert run(product, ("raw", "raw")).result == Result(2, 1.0)
    assert run(constant, ("hello",)).result == Result("hello", 1.0)


def test_an_elementary_function_gets_its_keyword_arguments() -> None:
    record = run(scale, (Result(2, 0.5),), {"factor": 3})
    assert record.result == Result(6, 0.5)


def test_an_elementary_function_that_returns_a_result_keeps_its_quality() -> None:
    record = run(judged, (Result("map", 0.9),))
    assert (record.status, record.result) == (Status.COMPLETED, Result(("judged", "map"), 0.25))


def test_an_elementary_function_that_raises_fails() -> None:
    record = run(faulty, (Result("map", 0.9),))
    assert (record.status, record.result) == (Status.FAILED, None)
    assert record.error == f"{Boom.__module__}.Boom: no value"


def test_a_combination_outside_the_unit_interval_is_a_failure_not_an_exception() -> None:
    """`combine=sum` of 0.5 and 0.75 gives 1.25: the run answers with a record saying so."""
    record = run(summed, (Result(1, 0.5), Result(2, 0.75)))
    assert (record.status, record.result) == (Status.FAILED, None)
    assert record.error == "ValueError: a Result's quality must be in [0, 1], got 1.25"


# --- hard interruption ------------------------------------------------------------------------


def test_hard_interruption_cuts_off_a_stuck_module_at_the_wall_clock_deadline(
    release: threading.Event,
) -> None:
    """A module yields once, then sleeps 2 s without looking at its context. With 0.1 s on the
    wall clock the caller answers within 50 ms of the deadline (the issue's bound), five times
    in a row, with the first result."""
    for _ in range(5):
        began = time.perf_counter()
        record = run(hang, (release,), budget=Budget(0.1, clock=WallClock()), mode=Hard())
        waited = time.perf_counter() - began
        assert record.status == Status.INTERRUPTED
        assert record.result == Result("first", 0.3)
        assert record.registered == 1
        assert 0.1 <= record.time_used < 0.15
        assert waited < 0.15


def test_a_stuck_module_is_asked_to_stop_and_ends_at_its_next_yield(
    release: threading.Event,
) -> None:
    before = set(threading.enumerate())
    record = run(hang, (release,), budget=Budget(0.05, clock=WallClock()), mode=Hard())
    workers = [t for t in threading.enumerate() if t not in before and t.name == "anytime:hang"]
    assert len(workers) == 1
    assert workers[0].is_alive()  # still stuck: the caller did not wait for it
    release.set()
    workers[0].join(5)
    assert not workers[0].is_alive()  # its late yield saw the stop and ended it
    assert record.result == Result("first", 0.3)


def test_hard_interruption_cuts_off_a_stuck_contract_at_the_wall_clock_deadline(
    release: threading.Event,
) -> None:
    for _ in range(5):
        began = time.perf_counter()
        record = run(stuck, (release,), budget=Budget(0.1, clock=WallClock()), mode=Hard())
        waited = time.perf_counter() - began
        assert (record.status, record.result, record.registered) == (
            Status.CONTRACT_EXPIRED,
            None,
            0,
        )
        assert 0.1 <= record.time_used < 0.15
        assert waited < 0.15


def test_hard_interruption_on_the_work_clock_polls_the_clock(release: threading.Event) -> None:
    """The module reports work past its allocation and is then stuck: the caller, polling the
    work clock, answers while the module is still stuck."""
    record = run(hang, (release, 10.0), budget=5, mode=Hard())
    assert not release.is_set()
    assert record.status == Status.INTERRUPTED
    assert record.result == Result("first", 0.3)
    assert (record.time_used, record.registered) == (10.0, 1)
    contract_record = run(stuck, (release, 12.0), budget=5, mode=Hard())
    assert not release.is_set()
    assert (contract_record.status, contract_record.result, contract_record.time_used) == (
        Status.CONTRACT_EXPIRED,
        None,
        12.0,
    )


def test_hard_interruption_on_the_work_clock_by_a_stop_from_outside(
    release: threading.Event,
) -> None:
    """Stuck without reporting work, the module never reaches its deadline on the work clock;
    a stop from another thread still gets its first result back."""
    stop = threading.Event()
    timer = threading.Timer(0.05, stop.set)
    timer.start()
    record = run(hang, (release,), budget=Budget(100, stop=stop), mode=Hard())
    timer.join()
    assert not release.is_set()
    assert (record.status, record.result, record.time_used) == (
        Status.INTERRUPTED,
        Result("first", 0.3),
        0.0,
    )
