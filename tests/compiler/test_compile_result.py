"""A compile result says, as fields, which allocator ran and why, whether the table is exact,
what is approximate and where a smaller total's split is kept; the note a person reads is
rendered from them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from toy_modules import toy_registry

from anytime import AnytimeLibrary, compile_file, load_schemas
from anytime.compiler import compile_program
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
    assert compiled.note == "dp: local compilation, exact for this tree of monotone modules"


@pytest.mark.parametrize(("allocator", "exact"), [("hill-climbing", False), ("exhaustive", True)])
def test_an_asked_allocator_is_exact_only_when_its_search_is(allocator: str, exact: bool) -> None:
    compiled = toy(allocator)
    assert (compiled.allocator, compiled.requested, compiled.exact) == (allocator, allocator, exact)


def test_the_shipped_navigate_schema_says_why_and_where_as_fields(navigation_any: Path) -> None:
    schemas = load_schemas(navigation_any)
    library = AnytimeLibrary.default()
    (navigate,) = compile_file(schemas, library, range(0, 1001, 250), schema="navigate")
    assert navigate.allocator == "exhaustive" and navigate.exact
    assert navigate.dp_obstacle is not None
    assert navigate.dp_obstacle.startswith("module 'get-domain-description' has a stochastic")
    # The planner alone on the prior map does better with 250 ticks than with 500, but at 500
    # sensing first does better still: no total keeps a smaller one's allocation.
    assert navigate.kept_smaller == ()
    assert navigate.note.startswith(
        f"exhaustive, because dp would not be exact: {navigate.dp_obstacle}"
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
