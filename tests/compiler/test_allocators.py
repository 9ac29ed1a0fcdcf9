"""The allocators on random programs (hypothesis): dp is exact where it applies, hill-climbing
never beats the exhaustive reference and reports its gap, and the compiler falls back from dp,
saying why, on stochastic profiles and DAGs. Also the lattice helpers `compositions` and
`equal_split`, and the baselines every report carries."""

from __future__ import annotations

from collections.abc import Iterator
from math import comb
from typing import Any

import numpy as np
import pytest
from compiler_strategies import (
    QUALITY,
    TIME,
    RandomProgram,
    dag_programs,
    library_of,
    tree_programs,
)
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.compiler import Code, CompiledProgram, Note, compile_program, dp_obstacle
from anytime.compiler.allocators import Exhaustive, compositions, equal_split
from anytime.compiler.compile import AUTO_EXHAUSTIVE_PER_CELL
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, elementary, interruptible
from anytime.profiles import tabulate

SETTINGS = settings(max_examples=40, deadline=None)

DAG_REASON = Note.of(Code.DAG)


def auto_fallback(compiled: CompiledProgram) -> str:
    """What "auto" uses when dp would not be exact: the exact search when it is cheap (no more
    allocations per cell than the multi-start search evaluates), else multi-start."""
    n = len(compiled.model.anytime_nodes)
    units = np.rint(compiled.profile.time / compiled.resolution).astype(np.int64)
    cheap = Exhaustive.rows(units, n) <= AUTO_EXHAUSTIVE_PER_CELL * len(units)
    return "exhaustive" if cheap else "multi-start"


def compile_with(
    program: RandomProgram, allocator: str, library: AnytimeLibrary | None = None
) -> CompiledProgram:
    schemas = parse_schemas(program.text, "random.any")
    return compile_program(
        schemas["p"],
        library if library is not None else program.library(),
        TIME,
        QUALITY,
        allocator=allocator,
    )


def check_table(compiled: CompiledProgram, program: RandomProgram) -> None:
    """What every compiled table of a random program satisfies, whichever allocator made it."""
    m = len(program.quality_inputs)
    assert compiled.modules == tuple(s.name for s in program.modules)
    assert compiled.model.quality_inputs == program.quality_inputs
    assert compiled.model.graph.shape == program.shape
    assert compiled.expected.shape == (len(QUALITY),) * m + (len(TIME),)
    assert compiled.allocation.shape == compiled.expected.shape + (program.n,)
    # Whole multiples of the lattice step, summing to at most T: less only where a smaller
    # total's split is kept because it does better, so the quality never falls as T grows.
    units = compiled.allocation / 5.0
    np.testing.assert_array_equal(units, np.rint(units))
    assert (compiled.allocation >= 0).all()
    spent = compiled.allocation.sum(axis=-1)
    assert (spent <= np.broadcast_to(TIME, spent.shape) + 1e-9).all()
    assert (np.diff(compiled.expected, axis=-1) >= -1e-12).all()


def without_idle(compiled: CompiledProgram) -> tuple[Note, ...]:
    """The notes, less the one saying that some totals keep a smaller total's split."""
    return tuple(note for note in compiled.notes if note.code != Code.KEPT_SMALLER)


def fallback(compiled: CompiledProgram, obstacle: Note) -> tuple[Note, ...]:
    """The notes of a compilation where dp would not be exact: why, and what ran instead."""
    if compiled.requested == "dp":
        return (Note.of(Code.DP_FALLBACK, obstacle=obstacle),)
    return (Note.of(Code.AUTO_FALLBACK, allocator=compiled.allocator, obstacle=obstacle),)


# --- (a) deterministic monotone profiles: dp is exact ---------------------------------------


@SETTINGS
@given(tree_programs())
def test_dp_equals_exhaustive_and_hill_climbing_never_beats_it(program: RandomProgram) -> None:
    library = program.library()
    dp = compile_with(program, "dp", library)
    exhaustive = compile_with(program, "exhaustive", library)
    climbing = compile_with(program, "hill-climbing", library)
    for compiled in (dp, exhaustive, climbing):
        check_table(compiled, program)
    assert (dp.allocator, exhaustive.allocator, climbing.allocator) == (
        "dp",
        "exhaustive",
        "hill-climbing",
    )
    np.testing.assert_allclose(dp.expected, exhaustive.expected, rtol=0, atol=1e-9)
    assert dp.exhaustive_gap is not None and dp.exhaustive_gap <= 1e-9
    assert exhaustive.exhaustive_gap == 0.0
    assert (climbing.expected <= exhaustive.expected + 1e-12).all()
    gap = float(np.max(exhaustive.expected - climbing.expected))
    assert climbing.exhaustive_gap == pytest.approx(max(gap, 0.0), abs=1e-12)


@SETTINGS
@given(tree_programs())
def test_auto_uses_dp_on_deterministic_monotone_trees(program: RandomProgram) -> None:
    compiled = compile_with(program, "auto")
    assert compiled.allocator == "dp"
    assert compiled.codes == (Code.DP_EXACT,)
    assert dp_obstacle(compiled.model) is None


def _single_module_library(name: str, curve: Any) -> AnytimeLibrary:
    profile = tabulate(curve, TIME, input_grids=[[0.0, 1.0]], inputs=["a"])

    def extra(registry: Registry) -> None:
        def run(ctx: Context, a: Any) -> Iterator[Result]:
            yield Result(None, 0.0)

        interruptible(name, inputs=["a"], profile=profile, registry=registry)(run)

    return library_of((), extra)


def test_dp_gives_no_time_to_a_call_that_takes_none() -> None:
    """`lo` of two program inputs takes no time, so all of T goes to m2. Where every split
    gives the same quality (min(x, y) = 0), dp must still spend exactly T."""
    library = _single_module_library("m2", lambda t, q: q * t / 40)
    schemas = parse_schemas("(defschema p (x y) (m2 (lo x y)))", "lo.any")
    for allocator in ("dp", "exhaustive"):
        compiled = compile_program(schemas["p"], library, TIME, QUALITY, allocator=allocator)
        assert compiled.allocator == allocator
        np.testing.assert_array_equal(
            compiled.allocation[..., 0], np.broadcast_to(TIME, (3, 3, len(TIME))), allocator
        )


def test_dp_matches_exhaustive_when_quality_drops_after_a_peak() -> None:
    """A module whose quality peaks at t = 20 and then drops (input-monotone, not time-
    monotone: local compilation needs only the former). Spending all of T would give 0.3 from
    T = 25 on (x = y = 1); the compiled program keeps the split of T = 20 and leaves the rest
    unused, so its quality stays 1, and dp and exhaustive agree on it."""
    library = _single_module_library(
        "mp", lambda t, q: (0.5 + 0.5 * q) * np.where(t <= 20, t / 20, 0.3)
    )
    schemas = parse_schemas("(defschema p (x y) (mp (lo x y)))", "peak.any")
    dp = compile_program(schemas["p"], library, TIME, QUALITY, allocator="dp")
    exhaustive = compile_program(schemas["p"], library, TIME, QUALITY, allocator="exhaustive")
    np.testing.assert_allclose(exhaustive.expected[-1, -1], [0, 0.25, 0.5, 0.75, 1] + [1.0] * 4)
    np.testing.assert_allclose(exhaustive.allocation[-1, -1, :, 0], [0, 5, 10, 15, 20] + [20] * 4)
    np.testing.assert_allclose(dp.expected, exhaustive.expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(dp.allocation.sum(axis=-1), exhaustive.allocation.sum(axis=-1))
    assert Code.KEPT_SMALLER in exhaustive.codes  # the notes say so


# --- (e) the compiled profile is at least every baseline ------------------------------------


@SETTINGS
@given(tree_programs())
def test_compiled_quality_is_at_least_every_baseline(program: RandomProgram) -> None:
    library = program.library()
    for allocator in ("dp", "exhaustive"):
        compiled = compile_with(program, allocator, library)
        assert set(compiled.baselines) == {"equal", "min", "max"}
        for name, baseline in compiled.baselines.items():
            assert baseline.shape == compiled.expected.shape, name
            worse = compiled.expected < baseline - 1e-12
            assert not worse.any(), (allocator, name, np.argwhere(worse))


# --- (b) stochastic monotone profiles: hill-climbing, and why -------------------------------


@SETTINGS
@given(tree_programs(stochastic=True))
def test_stochastic_profiles_fall_back_to_exhaustive_or_hill_climbing(
    program: RandomProgram,
) -> None:
    """Auto picks the exact search when it is cheap, else multi-start; dp asked for falls back
    to hill-climbing; both say why."""
    first = next(s.name for s in program.modules if s.stochastic)
    reason = Note.of(Code.STOCHASTIC, module=first)
    library = program.library()
    auto = compile_with(program, "auto", library)
    if auto.allocator == "exhaustive":
        assert auto.notes == fallback(auto, reason)
        assert auto.exhaustive_gap == 0.0
    else:
        assert auto.allocator == "multi-start"
        assert without_idle(auto) == fallback(auto, reason)
    asked = compile_with(program, "dp", library)
    assert asked.allocator == "hill-climbing"
    assert without_idle(asked) == fallback(asked, reason)
    exhaustive = compile_with(program, "exhaustive", library)
    assert (asked.expected <= exhaustive.expected + 1e-12).all()
    for compiled in (auto, exhaustive):
        check_table(compiled, program)
    assert (auto.expected <= exhaustive.expected + 1e-12).all()
    gap = float(np.max(exhaustive.expected - auto.expected))
    assert auto.exhaustive_gap == pytest.approx(max(gap, 0.0), abs=1e-12)


# --- (c) DAGs: approximate evaluation, said so ----------------------------------------------


@settings(max_examples=25, deadline=None)
@given(dag_programs())
def test_dags_fall_back_and_say_evaluation_is_approximate(program: RandomProgram) -> None:
    library = program.library()
    # Point masses stay point masses, so with deterministic modules a DAG is evaluated exactly:
    # no note says the table is approximate.
    auto = compile_with(program, "auto", library)
    assert auto.allocator == auto_fallback(auto)
    assert without_idle(auto) == fallback(auto, DAG_REASON)
    asked = compile_with(program, "dp", library)
    assert asked.allocator == "hill-climbing"
    assert without_idle(asked) == fallback(asked, DAG_REASON)
    exhaustive = compile_with(program, "exhaustive", library)
    assert without_idle(exhaustive) == (Note.of(Code.EXHAUSTIVE),)
    for compiled in (auto, exhaustive):
        check_table(compiled, program)
    assert (auto.expected <= exhaustive.expected + 1e-12).all()


def test_an_elementary_function_of_unknown_monotonicity_keeps_dp_away() -> None:
    curve = tabulate(lambda t, q: q * t / 40, TIME, input_grids=[QUALITY], inputs=["a"])
    leaf = tabulate(lambda t: t / 40, TIME)

    def extra(registry: Registry) -> None:
        def first(ctx: Context, a: Any) -> Iterator[Result]:
            yield Result(None, 0.0)

        def second(ctx: Context, a: Any) -> Iterator[Result]:
            yield Result(None, 0.0)

        def join(a: Any, b: Any) -> Any:
            return (a, b)

        interruptible("m1", inputs=[], profile=leaf, registry=registry)(first)
        interruptible("m2", inputs=["a"], profile=curve, registry=registry)(second)
        elementary("prod", combine=lambda qs: qs[0] * qs[1], registry=registry)(join)

    schemas = parse_schemas("(defschema p (x) (m2 (prod (m1 x) (m1 x))))", "prod.any")
    compiled = compile_program(schemas["p"], library_of((), extra), TIME, QUALITY, allocator="auto")
    assert compiled.allocator == auto_fallback(compiled)
    assert compiled.notes == fallback(compiled, Note.of(Code.UNKNOWN_MONOTONICITY, function="prod"))
    exhaustive = compile_program(
        schemas["p"], library_of((), extra), TIME, QUALITY, allocator="exhaustive"
    )
    assert (compiled.expected <= exhaustive.expected + 1e-12).all()


def test_a_module_that_is_not_input_monotone_keeps_dp_away() -> None:
    """A deterministic module whose output drops when its input gets better: dp could miss
    the optimum (a worse subtree might serve the parent better), so the compiler falls back."""
    peaked = tabulate(
        lambda t, q: (1 - np.abs(q - 0.5)) * t / 40, TIME, input_grids=[QUALITY], inputs=["a"]
    )
    leaf = tabulate(lambda t: t / 40, TIME)

    def extra(registry: Registry) -> None:
        def first(ctx: Context, a: Any) -> Iterator[Result]:
            yield Result(None, 0.0)

        interruptible("m1", inputs=[], profile=leaf, registry=registry)(first)
        interruptible("m2", inputs=["a"], profile=peaked, registry=registry)(first)

    schemas = parse_schemas("(defschema p (x) (m2 (m1 x)))", "peak.any")
    reason = Note.of(Code.NOT_INPUT_MONOTONE, module="m2", input=1)
    auto = compile_program(schemas["p"], library_of((), extra), TIME, QUALITY)
    assert auto.allocator == auto_fallback(auto)
    assert without_idle(auto) == fallback(auto, reason)
    asked = compile_program(schemas["p"], library_of((), extra), TIME, QUALITY, allocator="dp")
    assert without_idle(asked) == fallback(asked, reason)
    exhaustive = compile_program(
        schemas["p"], library_of((), extra), TIME, QUALITY, allocator="exhaustive"
    )
    assert (auto.expected <= exhaustive.expected + 1e-12).all()
    for j, total in enumerate(TIME):
        first = np.arange(0, total + 1, 5)
        value = (1 - np.abs(first / 40 - 0.5)) * (total - first) / 40
        assert exhaustive.expected[j] == pytest.approx(value.max(), abs=1e-12)


# --- (d) the lattice: compositions and equal shares -----------------------------------------


@pytest.mark.parametrize("parts", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("total", [0, 1, 2, 7, 12])
def test_compositions_are_every_split_once(total: int, parts: int) -> None:
    rows = compositions(total, parts)
    assert rows.shape == (comb(total + parts - 1, parts - 1), parts)
    assert np.issubdtype(rows.dtype, np.integer)
    assert (rows >= 0).all()
    assert (rows.sum(axis=1) == total).all()
    assert len({tuple(r) for r in rows.tolist()}) == len(rows)


def test_compositions_of_nothing() -> None:
    assert compositions(0, 0).shape == (1, 0)
    assert compositions(3, 0).shape == (0, 0)
    np.testing.assert_array_equal(compositions(4, 1), [[4]])
    np.testing.assert_array_equal(compositions(0, 3), [[0, 0, 0]])
    np.testing.assert_array_equal(sorted(compositions(2, 2).tolist()), [[0, 2], [1, 1], [2, 0]])


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(0, 1000), min_size=1, max_size=20), st.integers(1, 9))
def test_equal_split_shares_the_lattice_fairly(units: list[int], n: int) -> None:
    split = equal_split(np.array(units, dtype=np.int64), n)
    assert split.shape == (len(units), n)
    assert np.issubdtype(split.dtype, np.integer)
    np.testing.assert_array_equal(split.sum(axis=1), units)
    assert (split.max(axis=1) - split.min(axis=1) <= 1).all()
    # The remainder goes one unit each to the first modules.
    assert (np.diff(split, axis=1) <= 0).all()
    np.testing.assert_array_equal(split[:, -1], np.array(units) // n)


def test_equal_split_examples() -> None:
    np.testing.assert_array_equal(
        equal_split(np.array([0, 5, 7, 9]), 3),
        [
            [0, 0, 0],
            [2, 2, 1],
            [3, 2, 2],
            [3, 3, 3],
        ],
    )
    np.testing.assert_array_equal(equal_split(np.array([4]), 1), [[4]])
