"""In-process runs of modules that exit, are interrupted, or report impossible work: each run
ends with a record keeping the best result registered before, in soft and in hard mode, on the
work and the wall clock; a KeyboardInterrupt then reaches the caller, as the user asked."""

from __future__ import annotations

import math
import sys
from collections.abc import Iterator
from typing import Any

import pytest

from anytime.clocks import WallClock, WorkClock
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.runtime import Budget, Hard, RunInterrupted, Soft, Status, run

MODULES = Registry()


def _after_one_result(ctx: Context, then: BaseException | float) -> Iterator[Result]:
    ctx.tick(1)
    yield Result("first", 0.4)
    if isinstance(then, BaseException):
        raise then
    ctx.tick(then)
    yield Result("second", 0.9)


@interruptible("exits", registry=MODULES)
def exits(ctx: Context) -> Iterator[Result]:
    yield from _after_one_result(ctx, SystemExit(3))


@interruptible("presses-ctrl-c", registry=MODULES)
def presses_ctrl_c(ctx: Context) -> Iterator[Result]:
    yield from _after_one_result(ctx, KeyboardInterrupt())


def _reported_by_compiled_code() -> SystemError:
    """What a Ctrl-C during a numba function's call usually surfaces as: the signal is handled
    when the call, boxing an array it returns, calls back into Python."""
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as interrupt:
        error = SystemError("CPUDispatcher(<function f>) returned a result with an exception set")
        error.__cause__ = interrupt
        return error


@interruptible("ctrl-c-in-compiled-code", registry=MODULES)
def ctrl_c_in_compiled_code(ctx: Context) -> Iterator[Result]:
    yield from _after_one_result(ctx, _reported_by_compiled_code())


@interruptible("ticks", registry=MODULES)
def ticks(ctx: Context, work: float) -> Iterator[Result]:
    yield from _after_one_result(ctx, work)


class Escape(BaseException):
    """A BaseException of the module's own (neither an Exception nor SystemExit)."""


@interruptible("escapes", registry=MODULES)
def escapes(ctx: Context) -> Iterator[Result]:
    yield from _after_one_result(ctx, Escape("out"))


@contract("contract-escapes", registry=MODULES)
def contract_escapes(ctx: Context) -> Result:
    ctx.tick(1)
    raise Escape("out")


@contract("contract-exits", registry=MODULES)
def contract_exits(ctx: Context) -> Result:
    ctx.tick(1)
    sys.exit("bye")


@contract("contract-presses-ctrl-c", registry=MODULES)
def contract_presses_ctrl_c(ctx: Context) -> Result:
    ctx.tick(1)
    raise KeyboardInterrupt


MODES = [
    pytest.param(hard, clock, id=f"{'hard' if hard else 'soft'}-{clock.__name__}")
    for hard in (False, True)
    for clock in (WorkClock, WallClock)
]


def _run(name: str, hard: bool, clock: type, *args: Any) -> Any:
    allocation = 10.0 if clock is WorkClock else 5.0
    module = MODULES.get(name)
    assert module is not None
    return run(
        module, args, budget=Budget(allocation, clock=clock()), mode=Hard() if hard else Soft()
    )


@pytest.mark.parametrize(("hard", "clock"), MODES)
def test_sys_exit_in_a_module_is_a_failed_run_with_its_best_result(hard: bool, clock: type) -> None:
    record = _run("exits", hard, clock)
    assert (record.status, record.result, record.error) == (
        Status.FAILED, Result("first", 0.4), "SystemExit: 3",
    )  # fmt: skip
    assert record.traceback is not None and "SystemExit: 3" in record.traceback
    record = _run("contract-exits", hard, clock)
    assert (record.status, record.result, record.error) == (Status.FAILED, None, "SystemExit: bye")


@pytest.mark.parametrize(("hard", "clock"), MODES)
def test_any_other_base_exception_is_a_failed_run_with_its_best_result(
    hard: bool, clock: type
) -> None:
    """Neither the caller's Ctrl-C nor an exit: the module's own failure, its best result kept,
    the caller untouched."""
    record = _run("escapes", hard, clock)
    error = f"{__name__}.Escape: out"
    assert (record.status, record.result, record.error) == (
        Status.FAILED, Result("first", 0.4), error,
    )  # fmt: skip
    record = _run("contract-escapes", hard, clock)
    assert (record.status, record.result, record.error) == (Status.FAILED, None, error)


@pytest.mark.parametrize(("hard", "clock"), MODES)
def test_a_keyboard_interrupt_keeps_the_record_then_reaches_the_caller(
    hard: bool, clock: type
) -> None:
    with pytest.raises(RunInterrupted) as raised:
        _run("presses-ctrl-c", hard, clock)
    record = raised.value.record
    assert (record.module, record.status, record.result, record.error) == (
        "presses-ctrl-c", Status.INTERRUPTED, Result("first", 0.4), "KeyboardInterrupt",
    )  # fmt: skip
    assert isinstance(raised.value, KeyboardInterrupt)
    assert type(raised.value.__cause__) is KeyboardInterrupt
    with pytest.raises(RunInterrupted) as raised:
        _run("contract-presses-ctrl-c", hard, clock)
    assert (raised.value.record.status, raised.value.record.result) == (Status.INTERRUPTED, None)


@pytest.mark.parametrize(("hard", "clock"), MODES)
def test_a_ctrl_c_compiled_code_reported_as_an_error_is_an_interrupt(
    hard: bool, clock: type
) -> None:
    """Not a failed run the caller goes on from: the Ctrl-C reaches the caller, the best result
    kept (`anytime.errors.interrupt_behind`)."""
    with pytest.raises(RunInterrupted) as raised:
        _run("ctrl-c-in-compiled-code", hard, clock)
    record = raised.value.record
    assert (record.status, record.result, record.error) == (
        Status.INTERRUPTED, Result("first", 0.4), "KeyboardInterrupt",
    )  # fmt: skip


@pytest.mark.parametrize(("hard", "clock"), MODES)
@pytest.mark.parametrize("work", [math.nan, -1.0, math.inf, -math.inf])
def test_impossible_work_is_refused_and_the_best_result_kept(
    hard: bool, clock: type, work: float
) -> None:
    record = _run("ticks", hard, clock, work)
    assert (record.status, record.result) == (Status.FAILED, Result("first", 0.4))
    assert record.error == (
        f"ValueError: ctx.tick({work!r}): work must be a finite number of units, 0 or more"
    )
    assert math.isfinite(record.time_used)


def test_zero_work_is_allowed() -> None:
    record = _run("ticks", False, WorkClock, 0.0)
    assert (record.status, record.result, record.time_used) == (
        Status.COMPLETED, Result("second", 0.9), 1.0,
    )  # fmt: skip
