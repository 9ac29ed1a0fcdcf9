"""Expected qualities are exact where the profile knows them: a measured profile's bins stand
for their measured means, not their midpoints, so no result counts as exactly 0 and a module
that always reaches 1.0 as exactly 1.0, through a program as well as alone; checked against
runs, not against the compiler itself."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import attrs
import numpy as np
import pytest

from anytime.clocks import WorkClock
from anytime.compiler import Code, CompileError, compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.measure.builder import build_profile
from anytime.modules import AnytimeModule, Context, Registry, Result, interruptible
from anytime.problems import Instance
from anytime.runtime import Budget, run_program

MODULES = Registry()
TIME = [0.0, 5.0, 10.0, 20.0]


@interruptible("exact", inputs=[], registry=MODULES)
def exact(ctx: Context, delay: int) -> Iterator[Result]:
    """Nothing for `delay` ticks (5 or 10, by the problem), then the exact answer: a stochastic
    profile, with no result at T = 0 and always quality 1.0 from T = 10."""
    ctx.tick(delay)
    yield Result("answer", 1.0)


@interruptible("refine", inputs=["x"], registry=MODULES)
def refine(ctx: Context, x: Result) -> Iterator[Result]:
    """At once as good as its input; never better."""
    yield Result(x.value, x.quality)


class Problems:
    """An answer's true quality is the quality of what it was made from (1.0 for `exact`)."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        if input_qualities:
            return Instance((Result("answer", input_qualities[0]),), input_qualities[0])
        return Instance((int(rng.choice([5, 10])),), 1.0)

    def score(self, instance: Instance, value: Any) -> float:
        return float(instance.reference) if value == "answer" else 0.0


def measured(module: AnytimeModule, **grid: Any) -> LibraryEntry:
    """The module with the profile the builder measures for it."""
    profile = build_profile(module, Problems(), time=TIME, trials=8, **grid).profile
    return LibraryEntry.of_module(attrs.evolve(module, profile_source=profile))


@pytest.fixture(scope="module")
def library() -> AnytimeLibrary:
    return _library()


def test_a_measured_module_that_always_reaches_one_compiles_to_exactly_one(
    library: AnytimeLibrary,
) -> None:
    """With the default ten bins it compiled to 0.950 (the last bin's midpoint), and to 0.050
    at T = 0 where nothing runs. Its measured step (10 ticks: a run may go that long without a
    result) is kept back from its share, so that it answers within it: it runs 10 ticks at
    T = 20, where it always has its answer, and nothing can be promised below."""
    program = parse_schemas("(defschema p (delay) (exact delay))", "p.any")["p"]
    compiled = compile_program(program, library, TIME)
    assert library["exact"].step == 10.0
    np.testing.assert_array_equal(compiled.expected, [0.0, 0.0, 0.0, 1.0])
    for total, expected in zip(TIME, compiled.expected, strict=True):
        for delay in (5, 10):
            record = run_program(compiled, {"delay": delay}, Budget(total, clock=WorkClock()))
            assert (record.quality, record.time_used <= total) == (expected, True)


def test_a_chain_fed_no_result_or_a_perfect_result_expects_exactly_what_runs_give(
    library: AnytimeLibrary,
) -> None:
    """No result upstream is exactly 0 downstream; a perfect one exactly 1.0, which is what
    every run gives."""
    program = parse_schemas("(defschema p (delay) (refine (exact delay)))", "p.any")["p"]
    compiled = compile_program(program, library, [0.0, 10.0, 15.0, 20.0], resolution=5.0)
    # `exact` keeps back its step of 10 ticks: with 15 it runs 5, enough for the delay of 5.
    np.testing.assert_array_equal(compiled.expected, [0.0, 0.0, 0.5, 1.0])
    for total, delay, quality in [(10.0, 5, 0.0), (15.0, 5, 1.0), (15.0, 10, 0.0), (20.0, 10, 1.0)]:
        record = run_program(compiled, {"delay": delay}, Budget(total, clock=WorkClock()))
        assert (record.quality, record.time_used <= total) == (quality, True), (total, delay)


def test_qualities_outside_a_profiles_input_grid_are_a_warning() -> None:
    """A downstream profile measured on input qualities 0.5..1 is clamped below 0.5: the
    allocator could give the upstream module nothing and count on the clamped value. The
    compile result says so, as a field (and in the JSON report)."""
    narrow = build_profile(
        refine, Problems(), time=TIME, input_grids=[[0.5, 1.0]], trials=4
    ).profile
    library = AnytimeLibrary()
    library.add(measured(exact))
    library.add(LibraryEntry.of_module(attrs.evolve(refine, profile_source=narrow)))
    # The program's input carries any quality of the default grid, 0 to 1.
    program = parse_schemas("(defschema p (x) (refine x))", "p.any")["p"]
    compiled = compile_program(program, library, TIME)
    (warning,) = compiled.warnings
    assert warning.code == Code.OUTSIDE_INPUT_GRID
    assert (warning["module"], warning["input"], warning["low"], warning["high"]) == (
        "refine",
        "x",
        0.0,
        1.0,
    )
    assert (warning["measured_low"], warning["measured_high"]) == (0.5, 1.0)
    assert warning["share"] == pytest.approx(1.0)
    with pytest.raises(CompileError) as refused:
        compile_program(program, library, TIME, strict=True)
    assert str(refused.value) == f"schema 'p' (--strict): {warning.message}"
    within = compile_program(program, _library(), TIME)
    assert within.warnings == ()
    # What has no result upstream is no quality: `refine` is not called on it, so a chain
    # whose upstream answers 1.0 or nothing feeds it only 1.0.
    chain = parse_schemas("(defschema p (delay) (refine (exact delay)))", "p.any")["p"]
    assert compile_program(chain, library, TIME).warnings == ()


def _library() -> AnytimeLibrary:
    library = AnytimeLibrary()
    library.add(measured(exact))
    library.add(measured(refine, input_grids=[[0.0, 0.5, 1.0]]))
    return library
