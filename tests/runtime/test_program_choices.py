"""The runtime's `run_program` runs best-of and if like `CompiledProgram.run`, with a run record
per call: the best applicable alternative with the time re-split, no applicable alternative as
a status (not an exception), the branch an if's condition selects; adaptive runs re-allocate
only among the modules that will run."""

from __future__ import annotations

import pytest
from choice_modules import BEST_OF, compiled, library

from anytime.runtime import Status, run_program


def test_best_of_runs_the_applicable_alternatives_and_keeps_the_best() -> None:
    program = compiled(BEST_OF, lib=library(steady=0.6, gamble=0.9))
    both = run_program(program, ["left right"], 6)
    assert both.status == Status.COMPLETED
    assert both.result is not None and both.result.value[0] == "gamble"
    assert both.quality == 0.9
    assert [r.module for r in both.records] == [
        "left-clear?",
        "right-clear?",
        "steady",
        "gamble",
        "best-of",
    ]
    assert sum(r.allocation for r in both.records if r.module in ("steady", "gamble")) == 6
    left = run_program(program, ["left"], 6)  # gamble is not applicable: steady gets it all
    assert left.result is not None and left.result.value == ("steady", 6.0)
    assert [r.module for r in left.records] == ["left-clear?", "right-clear?", "steady", "best-of"]


def test_no_applicable_alternative_is_a_status_with_the_reason() -> None:
    record = run_program(compiled(BEST_OF), ["nowhere"], 6)
    assert (record.status, record.result) == (Status.NO_RESULT, None)
    (choice,) = [r for r in record.records if r.module == "best-of"]
    assert choice.status == Status.NO_RESULT
    assert choice.error == (
        "schema 'choose': no alternative of best-of 't1' is applicable "
        "(all 2 preconditions are false)"
    )


def test_if_runs_the_branch_its_condition_selects_with_the_ifs_time() -> None:
    program = compiled(
        "(defschema c (w) (if (sunny? w) (steady) (gamble)))", library(steady=0.6, gamble=0.9)
    )
    sunny = run_program(program, ["sun"], 5)
    assert sunny.status == Status.COMPLETED
    assert sunny.result is not None and sunny.result.value == ("steady", 5.0)
    modules = [r.module for r in sunny.records]
    assert modules[0] == "sunny?" and modules[1].startswith("if -> ") and "steady" in modules
    rainy = run_program(program, ["rain"], 5)
    assert rainy.result is not None and rainy.result.value == ("gamble", 5.0)


@pytest.mark.parametrize("applicable", ["left", "right", "left right"])
def test_adaptive_runs_give_the_time_of_alternatives_that_will_not_run_to_those_that_will(
    applicable: str,
) -> None:
    program = compiled(BEST_OF, lib=library(steady=0.6, gamble=0.9))
    plain = run_program(program, [applicable], 6)
    adaptive = run_program(program, [applicable], 6, adaptive=True)
    assert adaptive.status == Status.COMPLETED
    assert adaptive.result is not None and plain.result is not None
    assert adaptive.result.value[0] == plain.result.value[0]
    ran = [r for r in adaptive.records if r.module in ("steady", "gamble")]
    assert [r.module for r in ran] == [
        name for name, side in (("steady", "left"), ("gamble", "right")) if side in applicable
    ]
    assert sum(r.allocation for r in ran) == 6  # nothing left to an alternative that won't run


def test_adaptive_runs_run_the_branch_of_an_if() -> None:
    program = compiled(
        "(defschema c (w) (if (sunny? w) (steady) (gamble)))", library(steady=0.6, gamble=0.9)
    )
    record = run_program(program, ["rain"], 5, adaptive=True)
    assert record.result is not None and record.result.value == ("gamble", 5.0)
