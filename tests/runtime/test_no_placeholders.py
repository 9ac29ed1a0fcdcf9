"""No placeholders: a call whose input has no result is not made (its step has no result and
says why), unless its module accepts a missing input (it then gets `MISSING`); a best-of's
precondition is never called with a missing value, and a contract that returns None has no
result. Each through `run_program` and `CompiledProgram.run` alike."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from anytime.compiler import compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import (
    MISSING,
    Context,
    Registry,
    Result,
    contract,
    elementary,
    interruptible,
)
from anytime.profiles import tabulate
from anytime.runtime import Status, run, run_program

TIME = np.arange(0.0, 41.0, 10.0)
MODULES = Registry()
CALLED: list[tuple[str, Any]] = []  # (module, argument) of every call, to see who was called


def _rising(t: Any, q: Any) -> Any:
    return np.asarray(q) * np.minimum(1.0, np.asarray(t, dtype=np.float64) / 20)


PROFILE = tabulate(_rising, TIME, input_grids=[[0.0, 1.0]], inputs=["m"])
SOURCE = tabulate(lambda t: np.minimum(1.0, np.asarray(t) / 20), TIME, kind="contract")


@contract("source", inputs=[], profile=SOURCE, registry=MODULES)
def source(ctx: Context, x: Any) -> Result | None:
    """No result when told so (None), else its input."""
    ctx.tick(ctx.allocation)
    return None if x == "nothing" else Result(x, min(1.0, ctx.allocation / 20))


@interruptible("after", inputs=["m"], profile=PROFILE, registry=MODULES)
def after(ctx: Context, m: Result) -> Iterator[Result]:
    CALLED.append(("after", m))
    yield Result(("after", m.value), m.quality * min(1.0, ctx.allocation / 20))


@interruptible("tolerant", inputs=["m"], profile=PROFILE, registry=MODULES, accepts_missing=True)
def tolerant(ctx: Context, m: Result) -> Iterator[Result]:
    CALLED.append(("tolerant", m))
    yield Result("fallback" if m is MISSING else m.value, 0.25 if m is MISSING else m.quality)


@elementary("usable?", registry=MODULES)
def usable(m: Result) -> bool:
    CALLED.append(("usable?", m))
    return True


@interruptible(
    "plan-b", inputs=[], profile=tabulate(lambda t: np.full_like(t, 0.5), TIME), registry=MODULES
)
def plan_b(ctx: Context, x: Any) -> Iterator[Result]:
    yield Result("plan b", 0.5)


@elementary("always?", registry=MODULES)
def always(x: Any) -> bool:
    return True


def compiled(text: str) -> Any:
    program = next(iter(parse_schemas(text, "p.any").programs))
    return compile_program(program, AnytimeLibrary.default(registry=MODULES, plugins=False), TIME)


@pytest.fixture(autouse=True)
def forget_calls() -> Iterator[None]:
    CALLED.clear()
    yield


def test_a_contract_that_returns_none_has_no_result() -> None:
    record = run(source, ("nothing",), budget=10)
    assert (record.status, record.result, record.time_used) == (Status.NO_RESULT, None, 10.0)


def test_a_call_whose_input_has_no_result_is_not_made() -> None:
    """It was called with a placeholder `Result(None, 0.0)`; now its step has no result."""
    program = compiled("(defschema p (x) (after (source x)))")
    record = run_program(program, {"x": "nothing"}, 40)
    assert [r.status for r in record.records] == [Status.NO_RESULT, Status.NO_RESULT]
    assert record.records[1].error == "not run: its input from 'source' has no result"
    assert (record.status, record.result, CALLED) == (Status.NO_RESULT, None, [])
    assert CALLED == []


def test_a_module_that_accepts_a_missing_input_gets_missing() -> None:
    program = compiled("(defschema p (x) (tolerant (source x)))")
    record = run_program(program, {"x": "nothing"}, 40)
    assert record.result == Result("fallback", 0.25)
    assert CALLED == [("tolerant", MISSING)]


def test_a_precondition_is_never_called_with_a_missing_value() -> None:
    """Its alternative is inapplicable; the other one answers."""
    program = compiled(
        "(defschema p (x)"
        " (setf m (source x))"
        " (best-of (when (usable? m) (after m)) (when (always? x) (plan-b x))))"
    )
    record = run_program(program, {"x": "nothing"}, 40)
    assert record.result == Result("plan b", 0.5)
    assert ("usable?", MISSING) not in CALLED and not [c for c in CALLED if c[0] == "usable?"]
    # With a result, the precondition runs and both alternatives are candidates.
    record = run_program(program, {"x": "data"}, 40)
    assert record.result is not None and [c[0] for c in CALLED][:1] == ["usable?"]


def test_an_alternative_without_when_is_always_a_candidate() -> None:
    program = compiled(
        "(defschema p (x) (setf m (source x)) (best-of (when (usable? m) (after m)) (plan-b x)))"
    )
    assert run_program(program, {"x": "nothing"}, 40).result == Result("plan b", 0.5)
    best = run_program(program, {"x": "data"}, 40).result
    assert best is not None and best.value == ("after", "data") and best.quality == 1.0
