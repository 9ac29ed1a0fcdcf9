"""The multi-start allocator on random programs (hypothesis): never above the exhaustive
optimum, never below hill-climbing, the proportional split or the equal split, never worse
with more time; and the memory cap: chunked searches give what unchunked ones give, a table
that cannot fit is refused up front with the estimate, sizes are read with their units."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from compiler_strategies import QUALITY, TIME, RandomProgram, dag_programs, tree_programs
from conftest import Cli
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.compiler import CompiledProgram, CompileError, Evaluator, compile_program
from anytime.compiler.allocators import DynamicProgramming, Exhaustive, HillClimbing
from anytime.compiler.compile import memory_bytes
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary

SETTINGS = settings(max_examples=30, deadline=None)
#: Allocator results evaluated in other batches may differ by rounding.
ROUNDING = 1e-9


def compile_with(
    program: RandomProgram, allocator: str, library: AnytimeLibrary, **options: object
) -> CompiledProgram:
    schemas = parse_schemas(program.text, "random.any")
    return compile_program(schemas["p"], library, TIME, QUALITY, allocator=allocator, **options)  # type: ignore[arg-type]


def check_against_the_others(program: RandomProgram) -> None:
    library = program.library()
    search = compile_with(program, "multi-start", library)
    assert search.allocator == "multi-start"
    exhaustive = compile_with(program, "exhaustive", library)
    climbing = compile_with(program, "hill-climbing", library)
    proportional = compile_with(program, "proportional", library)
    assert (search.expected <= exhaustive.expected + ROUNDING).all()
    for other in (climbing, proportional):
        assert (search.expected >= other.expected - ROUNDING).all(), other.allocator
    assert (search.expected >= search.baselines["equal"] - ROUNDING).all()
    # Never worse with more time, and on the lattice, spending at most T.
    assert (np.diff(search.expected, axis=-1) >= -1e-12).all()
    units = search.allocation / 5.0
    np.testing.assert_array_equal(units, np.rint(units))
    spent = search.allocation.sum(axis=-1)
    assert (spent <= np.broadcast_to(TIME, spent.shape) + 1e-9).all()
    gap = float(np.max(exhaustive.expected - search.expected))
    assert search.exhaustive_gap == pytest.approx(max(gap, 0.0), abs=1e-12)


@SETTINGS
@given(tree_programs(min_modules=2, max_modules=4))
def test_multi_start_on_deterministic_trees(program: RandomProgram) -> None:
    check_against_the_others(program)


@SETTINGS
@given(tree_programs(min_modules=2, max_modules=4, stochastic=True))
def test_multi_start_on_stochastic_trees(program: RandomProgram) -> None:
    check_against_the_others(program)


@settings(max_examples=20, deadline=None)
@given(dag_programs())
def test_multi_start_on_dags(program: RandomProgram) -> None:
    check_against_the_others(program)


# --- chunks within the cap ------------------------------------------------------------------


@settings(max_examples=15, deadline=None)
@given(tree_programs(min_modules=2, max_modules=4))
def test_searches_in_small_chunks_find_what_they_find_at_once(program: RandomProgram) -> None:
    schemas = parse_schemas(program.text, "random.any")
    model = compile_program(schemas["p"], program.library(), TIME, QUALITY).model
    evaluator = Evaluator(model)
    m = len(model.quality_inputs)
    mesh = np.meshgrid(*([QUALITY] * m), indexing="ij")
    grid = np.stack(mesh, -1).reshape(-1, m) if m else np.zeros((1, 0))
    quality = np.repeat(grid, len(TIME), axis=0)
    units = np.tile(np.rint(TIME / 5).astype(np.int64), len(grid))
    for kind in (Exhaustive, HillClimbing, DynamicProgramming):
        least = kind().memory_needed(evaluator, units)
        whole, value = kind().allocate(evaluator, quality, units, 5.0)
        chunked, chunked_value = kind(least).allocate(evaluator, quality, units, 5.0)
        np.testing.assert_allclose(chunked_value, value, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(chunked, whole, kind.name)


# --- the memory cap: refusals and sizes -----------------------------------------------------

CHAIN = "(defschema p (x) (m2 (m1 x)))"


def chain_library() -> AnytimeLibrary:
    from compiler_strategies import library_of

    from anytime.modules import Context, Registry, Result, interruptible
    from anytime.profiles import tabulate

    def extra(registry: Registry) -> None:
        def run(ctx: Context, a: object) -> object:
            yield Result(None, 0.0)

        leaf = tabulate(lambda t: t / 40, TIME)
        curve = tabulate(lambda t, q: q * t / 40, TIME, input_grids=[[0.0, 1.0]], inputs=["a"])
        interruptible("m1", inputs=[], profile=leaf, registry=registry)(run)
        interruptible("m2", inputs=["a"], profile=curve, registry=registry)(run)

    return library_of((), extra)


@pytest.mark.parametrize(
    ("allocator", "message"),
    [
        (
            "dp",
            "schema 'p': the dp search needs about 9.62 kB of memory at the least, more than"
            " the cap of 1 kB: raise the cap (memory=, --memory), or use a coarser time grid,"
            " fewer input qualities or another allocator",
        ),
        (
            "exhaustive",
            "schema 'p': the exhaustive search needs about 864 B of memory at the least, more"
            " than the cap of 500 B: raise the cap (memory=, --memory), or use a coarser time"
            " grid, fewer input qualities or another allocator",
        ),
        (
            "multi-start",
            "schema 'p': the multi-start search needs about 444 kB of memory at the least,"
            " more than the cap of 1 kB: raise the cap (memory=, --memory), or use a coarser"
            " time grid, fewer input qualities or another allocator",
        ),
    ],
)
def test_a_search_over_the_cap_is_refused_with_its_estimate(allocator: str, message: str) -> None:
    schemas = parse_schemas(CHAIN, "p.any")
    with pytest.raises(CompileError) as raised:
        compile_program(
            schemas["p"],
            chain_library(),
            TIME,
            QUALITY,
            allocator=allocator,
            memory="500B" if allocator == "exhaustive" else "1kB",
            source=schemas.source,
        )
    assert str(raised.value) == message
    assert raised.value.where == "p.any"


def test_a_search_within_the_cap_compiles_as_without_one() -> None:
    schemas = parse_schemas(CHAIN, "p.any")
    free = compile_program(schemas["p"], chain_library(), TIME, QUALITY, allocator="exhaustive")
    capped = compile_program(
        schemas["p"], chain_library(), TIME, QUALITY, allocator="exhaustive", memory=20_000
    )
    np.testing.assert_array_equal(capped.allocation, free.allocation)


@pytest.mark.parametrize(
    ("text", "size"),
    [
        ("1GB", 10**9),
        ("1gb", 10**9),
        ("512 MB", 512 * 10**6),
        ("1.5GB", 1_500_000_000),
        ("2GiB", 2 * 2**30),
        ("64KiB", 65_536),
        ("800kB", 800_000),
        ("12345", 12_345),
        (" 3 B ", 3),
    ],
)
def test_memory_sizes_are_read_with_their_units(text: str, size: int) -> None:
    assert memory_bytes(text) == size


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("lots", "memory: expected a size such as 512MB, 1GB or 2GiB, got 'lots'"),
        ("1 parsec", "memory: expected a size such as 512MB, 1GB or 2GiB, got '1 parsec'"),
        ("-1GB", "memory: expected a size such as 512MB, 1GB or 2GiB, got '-1GB'"),
        ("0.1", "memory: expected at least one byte, got '0.1'"),
        (0, "memory: expected at least one byte, got 0"),
    ],
)
def test_a_memory_size_that_is_not_one_is_an_error(value: str | int, message: str) -> None:
    with pytest.raises(CompileError) as raised:
        memory_bytes(value)
    assert str(raised.value) == message


@given(st.integers(1, 10**15))
def test_a_number_of_bytes_is_itself(size: int) -> None:
    assert memory_bytes(size) == memory_bytes(str(size)) == size


def test_the_command_refuses_a_table_over_its_memory_cap(cli: Cli) -> None:
    schema = Path(__file__).resolve().parents[2] / "schemas" / "routing.any"
    code, out, err = cli("compile", str(schema), "--memory", "1kB")
    assert (code, out) == (1, "")
    assert err.startswith(f"{schema}: error: schema ")
    assert "search needs about " in err and "more than the cap of 1 kB: raise the cap" in err
    code, out, err = cli("compile", str(schema), "--memory", "lots")
    assert (code, out) == (2, "")
    assert err.endswith(
        "anytime compile: error: argument --memory: expected a size such as 512MB, 1GB or"
        " 2GiB, got 'lots'\n"
    )
