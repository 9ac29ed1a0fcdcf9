"""Hard mode on the work clock is deterministic: the tick that takes a module past its
allocation ends its run there (not whenever the caller next looks), and the abandoned module's
later ticks go nowhere. So a run's record, and the time of what runs next on the same clock,
are the same alone and with other runs on other threads at once."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.clocks import WorkClock
from anytime.compiler import CompiledProgram, compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, contract, elementary, interruptible
from anytime.profiles import tabulate
from anytime.runtime import Budget, Hard, ProgramRecord, Status, run, run_program

TIME = np.arange(0, 21, 5, dtype=np.float64)
LINEAR = [[0.0, 1.0]]
MODULES = Registry()


def curve(t: Any, q: Any) -> Any:
    return np.asarray(q) * -np.expm1(-0.1 * np.asarray(t, dtype=np.float64))


def _busy() -> None:
    """Some work between ticks, longer than the caller's poll when threads compete."""
    sum(range(20_000))


@interruptible(
    "ticks-then-yields",
    inputs=["x"],
    profile=tabulate(curve, TIME, input_grids=LINEAR, inputs=["x"]),
    registry=MODULES,
)
def ticks_then_yields(ctx: Context, x: Result) -> Iterator[Result]:
    n = 0
    while True:
        ctx.tick(0.5)
        _busy()
        ctx.tick(0.5)
        n += 1
        yield Result(("first", n), float(curve(n, x.quality)))


@contract(
    "overruns",
    inputs=["x"],
    profile=tabulate(curve, TIME, input_grids=LINEAR, inputs=["x"], kind="contract"),
    registry=MODULES,
)
def overruns(ctx: Context, x: Result, by: int = 3) -> Result:
    for _ in range(int(ctx.allocation) + by):  # never looks at its time
        ctx.tick(1)
        _busy()
    return Result("overran", float(curve(ctx.allocation, x.quality)))


@elementary("pair", registry=MODULES)
def pair(a: Result, b: Result) -> Any:
    return (a.value, b.value)


def test_the_tick_past_the_allocation_ends_a_hard_run_there() -> None:
    clock = WorkClock()
    module = MODULES.get("overruns")
    assert module is not None
    for _ in range(20):
        start = clock.now()
        record = run(module, [Result("map", 1.0)], budget=Budget(4, clock=clock), mode=Hard())
        assert (record.status, record.result, record.time_used, record.registered) == (
            Status.CONTRACT_EXPIRED, None, 5.0, 0,
        )  # fmt: skip
        assert clock.now() - start == 5.0  # its later ticks did not move the caller's clock


@settings(max_examples=25, deadline=None)
@given(
    allocation=st.integers(0, 6).map(float),
    by=st.integers(1, 4),
    quality=st.floats(0, 1),
)
def test_a_hard_run_that_overruns_gets_the_same_record_every_time(
    allocation: float, by: int, quality: float
) -> None:
    module = MODULES.get("overruns")
    assert module is not None
    records = {
        run(module, [Result("map", quality)], {"by": by}, budget=allocation, mode=Hard())
        for _ in range(3)
    }
    assert records == {
        run(module, [Result("map", quality)], {"by": by}, budget=allocation, mode=Hard())
    }
    (record,) = records
    assert (record.status, record.result, record.time_used) == (
        Status.CONTRACT_EXPIRED, None, allocation + 1,
    )  # fmt: skip


def test_an_interruptible_hard_run_ends_at_the_half_tick_past_its_allocation() -> None:
    module = MODULES.get("ticks-then-yields")
    assert module is not None
    for _ in range(20):
        record = run(module, [Result("map", 1.0)], budget=2.2, mode=Hard())
        assert (record.status, record.result, record.time_used, record.registered) == (
            Status.INTERRUPTED, Result(("first", 2), float(curve(2, 1.0))), 2.5, 2,
        )  # fmt: skip


def _program() -> CompiledProgram:
    text = "(defschema p (x) (ticks-then-yields (pair (ticks-then-yields x) (overruns x))))"
    program = next(iter(parse_schemas(text, "p.any").programs))
    library = AnytimeLibrary.default(registry=MODULES, plugins=False)
    return compile_program(program, library, TIME, [0.0, 0.5, 1.0])


def _key(record: ProgramRecord) -> tuple[Any, ...]:
    calls = tuple((r.module, r.status, r.result, r.time_used) for r in record.records)
    return (record.status, record.result, record.time_used, calls)


def test_hard_programs_on_several_threads_answer_as_each_alone() -> None:
    compiled = _program()
    cases = [(q, float(total)) for q in (0.0, 0.5, 1.0) for total in range(0, 21, 2)]

    def once(case: tuple[float, float]) -> tuple[Any, ...]:
        quality, total = case
        return _key(run_program(compiled, {"x": Result("map", quality)}, total, mode=Hard()))

    alone = {case: once(case) for case in cases}
    soft = {
        case: _key(run_program(compiled, {"x": Result("map", case[0])}, case[1])) for case in cases
    }
    # The overrunning contract leaves the program no answer; its calls' records are compared.
    assert sum(alone[c][3][0][2] is not None for c in cases) >= len(cases) // 2
    assert {alone[c][3][1][1] for c in cases} == {Status.CONTRACT_EXPIRED}
    differ: list[tuple[float, float]] = []

    def worker() -> None:
        for case in cases:
            if once(case) != alone[case]:
                differ.append(case)

    threads = [threading.Thread(target=worker) for _ in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert differ == []
    # Soft mode awaits an overrunning contract and keeps its late answer; hard mode ends the run
    # at the tick past its allocation: the first call has the same status and result.
    assert [c for c in cases if alone[c][3][0][:3] != soft[c][3][0][:3]] == []
