"""A compile result says, as fields, which allocator ran and why, whether the table is exact,
what is approximate and where a smaller total's split is kept; the note a person reads is
rendered from them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from toy_modules import toy_registry

from anytime import AnytimeLibrary, compile_file, load_schemas
from anytime.compiler import MESSAGES, Code, CompiledProgram, Note, compile_program
from anytime.dsl import parse_schemas
from anytime.library import RegistrySource

TIME = [0, 10, 20, 30, 40]


def toy(allocator: str) -> object:
    program = parse_schemas("(defschema p (x) (refine (sense x)))", "p.any")["p"]
    library = AnytimeLibrary([RegistrySource(toy_registry())])
    return compile_program(program, library, TIME, [0.0, 0.5, 1.0], allocator=allocator)


def test_dp_on_a_chain_of_monotone_modules_is_exact() -> None:
    compiled = toy("auto")
    assert (compiled.allocator, compiled.requested, compiled.dp_obstacle) == ("dp", "auto", None)
    assert (compiled.exact, compiled.approximations, compiled.kept_smaller) == (True, (), ())
    assert compiled.codes == (Code.DP_EXACT,)


@pytest.mark.parametrize(("allocator", "exact"), [("hill-climbing", False), ("exhaustive", True)])
def test_an_asked_allocator_is_exact_only_when_its_search_is(allocator: str, exact: bool) -> None:
    compiled = toy(allocator)
    assert (compiled.allocator, compiled.requested, compiled.exact) == (allocator, allocator, exact)


def test_the_shipped_navigate_schema_says_why_and_where_as_fields(navigation_any: Path) -> None:
    schemas = load_schemas(navigation_any)
    library = AnytimeLibrary.default()
    (navigate,) = compile_file(schemas, library, range(0, 1001, 250), schema="navigate")
    assert navigate.allocator == "exhaustive" and navigate.exact
    assert navigate.dp_obstacle == Note.of(Code.STOCHASTIC, module="get-domain-description")
    # The planner alone on the prior map does better with 250 ticks than with 500, but at 500
    # sensing first does better still: no total keeps a smaller one's allocation.
    assert navigate.kept_smaller == ()
    assert navigate.notes == (
        Note.of(Code.AUTO_FALLBACK, allocator="exhaustive", obstacle=navigate.dp_obstacle),
    )
    compiled = compile_file(schemas, library, range(0, 1001, 250), schema="navigate-two-planners")
    two = compiled[-1]
    # A DAG (one sensed map, two planners): its shared result is conditioned on, so every
    # cell's expectation is exact, and so is the table, found by the exhaustive search.
    assert (two.approximations, two.standard_error, two.exact_cells.all()) == ((), None, True)
    assert (two.allocator, two.exact) == ("exhaustive", True)


def test_the_navigation_demo_table_starts_at_zero_and_is_what_runs_are_given(
    navigation_any: Path,
) -> None:
    """The demo's table (0 to 3000 by 250): exactly 0 at T = 0, where nothing runs (it was
    0.010, a bin midpoint), and `allocation_at` gives the table's own split at every total
    (it rescaled 0, 250 at T = 500 to 0, 500)."""
    schemas = load_schemas(navigation_any)
    (navigate,) = compile_file(
        schemas, AnytimeLibrary.default(), range(0, 3001, 250), schema="navigate"
    )
    assert navigate.expected[0] == 0.0
    for j, total in enumerate(navigate.profile.time):
        np.testing.assert_array_equal(navigate.allocation_at([], total), navigate.allocation[j])


def test_the_message_table_renders_the_notes_as_the_reports_always_said_them() -> None:
    """The codes are what programs and tests compare; people read `MESSAGES`, whose sentences
    are those `anytime compile` printed before the codes (the docs' outputs show them)."""
    assert set(MESSAGES) == set(Code)
    stochastic = Note.of(Code.STOCHASTIC, module="measure")
    assert Note.of(Code.AUTO_FALLBACK, allocator="exhaustive", obstacle=stochastic).message == (
        "exhaustive, because dp would not be exact: module 'measure' has a stochastic profile;"
        " local compilation is exact only when every module's quality is a function of its"
        " input qualities and time"
    )
    assert Note.of(Code.DP_FALLBACK, obstacle=Note.of(Code.DAG)).message == (
        "dp was asked for but the program is a DAG (a result is used twice), and local"
        " compilation is exact only for chains and trees: fell back to hill-climbing"
    )
    assert Note.of(Code.DP_EXACT).message == (
        "dp: local compilation, exact for this tree of monotone modules"
    )
    assert Note.of(Code.NOT_INPUT_MONOTONE, module="m2", input=1).message == (
        "module 'm2' is not input-monotone: a better quality of input 1 lowers its output somewhere"
    )
    sampled = Note.of(Code.SAMPLED, draws=512, sampled=3, cells=9, error=0.01234)
    assert sampled.message == (
        "the shared results' joint outcomes were sampled (512 draws) at 3 of 9 cells of the"
        " table: their expected quality has a standard error of up to 0.012"
    )
    outside = Note.of(
        Code.OUTSIDE_INPUT_GRID,
        module="refine",
        input="x",
        low=0.0,
        high=1.0,
        measured_low=0.5,
        measured_high=1.0,
        share=0.25,
    )
    assert outside.message == (
        "module 'refine': input 'x' receives qualities 0 to 1, but its profile was measured on"
        " 0.5 to 1; outside that range (up to 25% of its inputs at some total) the profile is"
        " clamped to its nearest end, and the table may count on it: measure 'refine' on input"
        " qualities that cover 0 to 1 (its Measurement's input_grids), or compile with --strict"
        " to refuse such a table"
    )
    assert Note.of(Code.KEPT_SMALLER, totals=2).message.startswith(
        "at 2 of the table's totals a smaller total does better: there the program uses"
    )
    assert Note.from_dict(outside.to_dict()) == outside
    assert str(stochastic) == f"{stochastic}" == stochastic.message


def test_allocation_at_refuses_what_it_cannot_answer_and_warns_beyond_the_table() -> None:
    """One quality in [0, 1] per program input and a total >= 0, or a clear error; beyond the
    table's largest total, that total's split, with a warning that says so."""
    from anytime.compiler.model import CompileError
    from anytime.compiler.result import BeyondTableWarning

    compiled = toy("auto")
    assert isinstance(compiled, CompiledProgram)
    at = compiled.allocation_at
    np.testing.assert_array_equal(at([0.5], 40), compiled.allocation[1, -1])
    bad = [
        ((), 10, "p: allocation_at: expected 1 input quality in [0, 1] (one per"
         " quality-carrying input), got []"),
        ([1.5], 10, "p: allocation_at: expected 1 input quality in [0, 1] (one per"
         " quality-carrying input), got [1.5]"),
        ([0.5], -1, "p: allocation_at: expected a total time >= 0, got -1"),
        ([0.5], float("nan"), "p: allocation_at: expected a total time >= 0, got nan"),
        ([0.5], "ten", "p: allocation_at: expected a total time >= 0, got 'ten'"),
        ("q", 10, "p: allocation_at: expected 1 input quality, got 'q'"),
    ]  # fmt: skip
    for quality, total, message in bad:
        with pytest.raises(CompileError) as error:
            at(quality, total)
        assert str(error.value) == message
    with pytest.warns(BeyondTableWarning) as caught:
        beyond = at([0.5], 3000)
    assert str(caught[0].message) == (
        "p: a total of 3000 is beyond the compiled table's largest, 40: its split is used and"
        " the rest left unused (compile with a time grid up to the total to use it)"
    )
    np.testing.assert_array_equal(beyond, at([0.5], 40))
