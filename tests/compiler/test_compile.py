"""`compile_program` and `compile_file`: an analytic optimum, hierarchical schemas, running a
compiled program as a contract algorithm, the compiled profile and its file, and the errors."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
import yaml
from compiler_strategies import (
    QUALITY,
    TIME,
    Curve,
    RandomProgram,
    curves,
    tree_programs,
)
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar
from toy_modules import toy_registry

import anytime.compiler.allocators.exhaustive as exhaustive_search
from anytime.clocks import WorkClock
from anytime.compiler import (
    CompiledProgram,
    CompileError,
    Evaluator,
    compile_file,
    compile_program,
    save_compiled,
)
from anytime.compiler.model import ModuleNode
from anytime.dsl import parse_schemas
from anytime.dsl.source import Source
from anytime.errors import SchemaError
from anytime.library import AnytimeLibrary, LibraryEntry, RegistrySource
from anytime.modules import Context, Registry, Result, contract, elementary, interruptible
from anytime.profiles import ConditionalPerformanceProfile, tabulate
from anytime.profiles.io import load_profile
from anytime.runtime import Budget, ExecutionError, program_module, run_program


def _one(ctx: Context, a: Any) -> Iterator[Result]:
    yield Result(None, 0.0)


def _pair(a: Any, b: Any) -> Any:
    return (a, b)


def library(**profiles: ConditionalPerformanceProfile) -> AnytimeLibrary:
    """A fresh library of one-argument interruptible modules with these profiles (their
    quality inputs are the profiles' axes, named 'a'), and `hi`, the maximum."""
    registry = Registry()
    for name, profile in profiles.items():
        inputs = ("a",) if profile.n_inputs else ()
        interruptible(name, inputs=inputs, profile=profile, registry=registry)(_one)
    elementary("hi", combine=max, registry=registry)(_pair)
    return AnytimeLibrary([RegistrySource(registry)])


def program(text: str, name: str = "p", filename: str = "p.any") -> Any:
    return parse_schemas(text, filename)[name]


def source(text: str, filename: str = "p.any") -> Source:
    return parse_schemas(text, filename).source


# --- (a) an analytic optimum ---------------------------------------------------------------


def exponential_chain(a: float, b: float) -> AnytimeLibrary:
    """m1: 1 - exp(-a t); m2: q (1 - exp(-b t)), tabulated on the lattice. m2 is linear in its
    input quality, so interpolating it between input grid points is exact."""
    return library(
        m1=tabulate(lambda t: -np.expm1(-a * t), TIME),
        m2=tabulate(
            lambda t, q: q * -np.expm1(-b * t), TIME, input_grids=[[0.0, 1.0]], inputs=["a"]
        ),
    )


CHAIN = "(defschema p (x) (m2 (m1 x)))"


@pytest.mark.parametrize("allocator", ["dp", "exhaustive", "auto"])
@pytest.mark.parametrize("rate", [0.02, 0.1, 0.3])
def test_two_equal_exponentials_split_the_time_in_half(rate: float, allocator: str) -> None:
    compiled = compile_program(
        program(CHAIN), exponential_chain(rate, rate), TIME, QUALITY, allocator=allocator
    )
    assert compiled.model.quality_inputs == ()
    assert compiled.expected.shape == (len(TIME),)
    for j, total in enumerate(TIME):
        if total % 10 == 0:  # T/2 on the lattice of 5
            optimum = (-math.expm1(-rate * total / 2)) ** 2
            assert compiled.expected[j] == pytest.approx(optimum, abs=1e-12)
            assert compiled.allocation[j].tolist() == [total / 2, total / 2]


def chain_value(a: float, b: float, t1: Any, total: float) -> Any:
    return -np.expm1(-a * np.asarray(t1)) * -np.expm1(-b * (total - np.asarray(t1)))


@settings(max_examples=15, deadline=None)
@given(st.floats(0.01, 0.5), st.floats(0.01, 0.5))
def test_two_exponentials_match_the_continuous_optimum(a: float, b: float) -> None:
    """f(t1) = (1 - e^{-a t1})(1 - e^{-b (T - t1)}) is 0 at both ends, so its maximum t* is
    interior with f'(t*) = 0, and |f''| <= a^2 + 2ab + b^2 = (a + b)^2 everywhere. The nearest
    lattice point is within dt/2 of t*, so the lattice optimum is below the continuous one by
    at most (a + b)^2 (dt/2)^2 / 2 = (a + b)^2 dt^2 / 8, and never above it."""
    dt = 5.0
    compiled = compile_program(program(CHAIN), exponential_chain(a, b), TIME, QUALITY)
    assert compiled.allocator == "dp"
    for j, total in enumerate(TIME):
        lattice = np.arange(0, total + dt / 2, dt)
        assert compiled.expected[j] == pytest.approx(
            float(np.max(chain_value(a, b, lattice, total))), abs=1e-12
        )
        np.testing.assert_allclose(
            chain_value(a, b, compiled.allocation[j][0], total), compiled.expected[j], atol=1e-12
        )
        if total == 0:
            assert compiled.expected[j] == 0
            continue
        best = minimize_scalar(
            lambda t1, total=total: -chain_value(a, b, t1, total),
            bounds=(0, total),
            method="bounded",
            options={"xatol": 1e-10},
        )
        continuous = -float(best.fun)
        assert compiled.expected[j] <= continuous + 1e-12
        assert compiled.expected[j] >= continuous - (a + b) ** 2 * dt**2 / 8 - 1e-12


def test_the_baselines_of_the_papers() -> None:
    """Equal split (the odd unit to the first module); MIN: the first module gets the first
    profiled time its quality is above 0 (here 5); MAX: the time it reaches its maximum (here
    40, the end of its profile), capped by T; the rest goes to the second module."""
    rate = 0.1
    compiled = compile_program(program(CHAIN), exponential_chain(rate, rate), TIME, QUALITY)

    def value(first: Any) -> Any:
        return chain_value(rate, rate, first, TIME)

    equal = np.ceil(TIME / 10) * 5
    np.testing.assert_allclose(compiled.baselines["equal"], value(equal), rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        compiled.baselines["min"], value(np.minimum(5, TIME)), rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(compiled.baselines["max"], value(TIME), rtol=0, atol=1e-12)


# --- (b) hierarchical schemas ---------------------------------------------------------------


HIERARCHY = """\
(defschema sub (x) (m2 (m1 x)))
(defschema top (x) (m3 (sub x)))
"""
FLAT = "(defschema flat (x) (m3 (m2 (m1 x))))"


@settings(max_examples=15, deadline=None)
@given(
    st.booleans(),
    curves(0),
    curves(1),
    curves(1),
    curves(1),
    st.sampled_from([[0.0, 0.5, 1.0], [0.0, 0.3, 0.6, 1.0]]),
)
def test_a_hierarchical_schema_compiles_like_its_flattened_program(
    conditioned: bool, free: Curve, c1: Curve, c2: Curve, c3: Curve, quality: list[float]
) -> None:
    grid = [0.0, 0.25, 0.5, 1.0]
    first = (
        tabulate(c1, TIME, input_grids=[grid], inputs=["a"])
        if conditioned
        else tabulate(free, TIME)
    )
    profiles = {
        "m1": first,
        "m2": tabulate(c2, TIME, input_grids=[grid], inputs=["a"]),
        "m3": tabulate(c3, [0.0, 10.0, 25.0, 40.0], input_grids=[grid], inputs=["a"]),
    }
    schemas = parse_schemas(HIERARCHY, "h.any")
    lib = library(**profiles)
    coarse = TIME[::2]  # 0, 10, ..., 40: the callee is compiled on the lattice of 5 below it
    sub, top = compile_file(
        schemas, lib, coarse, quality, schema="top", allocator="dp", resolution=5.0
    )
    assert (sub.name, top.name) == ("sub", "top")
    np.testing.assert_array_equal(sub.profile.time, TIME)
    (call,) = [n for n in top.model.anytime_nodes if n.name == "sub"]
    assert isinstance(call, ModuleNode) and call.callee is sub and call.profile is sub.profile
    assert "sub" not in lib  # compiling a file leaves the library as it was
    assert top.allocator == "dp" and top.modules == ("sub", "m3")
    flat = compile_program(
        program(FLAT, "flat"), library(**profiles), coarse, quality, allocator="dp", resolution=5.0
    )
    assert top.model.quality_inputs == flat.model.quality_inputs == (("x",) if conditioned else ())
    np.testing.assert_allclose(top.expected, flat.expected, rtol=0, atol=1e-12)
    # The callee's share is what the flattened program gives its two modules.
    np.testing.assert_allclose(
        top.allocation.sum(axis=-1), flat.allocation.sum(axis=-1), rtol=0, atol=1e-9
    )


# --- (c) running a compiled program ---------------------------------------------------------


def toy_library() -> AnytimeLibrary:
    """The shared toy modules (tests/toy_modules.py), whose quality follows their profiles."""
    return AnytimeLibrary([RegistrySource(toy_registry())])


TOY = "(defschema p (x) (refine (both (sense x) (guess x))))"


@pytest.fixture(scope="module")
def toy() -> CompiledProgram:
    return compile_program(program(TOY), toy_library(), TIME, QUALITY)


def test_a_compiled_program_runs_to_its_expected_quality(toy: CompiledProgram) -> None:
    assert toy.allocator == "dp" and toy.modules == ("sense", "guess", "refine")
    for i, q in enumerate(QUALITY):
        for j, total in enumerate(TIME):
            clock = WorkClock()
            result = run_program(toy, {"x": Result("map", q)}, Budget(total, clock=clock)).result
            assert result.quality == pytest.approx(toy.expected[i, j], abs=1e-12), (q, total)
            assert result.value[0] == "plan"
            assert clock.now() == total  # the modules spent exactly the contract's time
            positional = run_program(toy, [Result("map", q)], total).result
            assert positional.quality == result.quality


def test_a_compiled_program_runs_as_a_contract_module(toy: CompiledProgram) -> None:
    module = program_module(toy)
    assert (module.name, module.kind, module.parameters, module.inputs) == (
        "p",
        "contract",
        ("x",),
        ("x",),
    )
    assert module.profile_source is toy.profile
    result = module(Context(allocation=30.0), Result("map", 1.0))
    assert result.quality == pytest.approx(toy.expected[-1, 6], abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(q=st.floats(0.0, 1.0), total=st.floats(0.0, 60.0))
def test_the_allocation_at_any_point_spends_no_more_than_the_total(
    toy: CompiledProgram, q: float, total: float
) -> None:
    allocation = toy.allocation_at([q], total)
    assert allocation.shape == (3,)
    assert (allocation >= 0).all()
    assert allocation.sum() <= total + 1e-9


def test_allocation_at_keeps_a_smaller_totals_split() -> None:
    """Where more time would not help, the table keeps a smaller total's split and leaves the
    rest unused; running it must not spend that rest (it once rescaled the split to the
    total: the shipped navigate schema's table said 0, 250 at T = 500 and the run used 0, 500).
    """
    schemas = parse_schemas("(defschema p (x) (sense x))", "k.any")
    library = AnytimeLibrary()

    def worse(t: Any) -> Any:  # a contract that does worse when given more than 20 ticks
        return np.where(np.asarray(t) < 20, 0.0, np.where(np.asarray(t) < 30, 1.0, 0.5))

    profile = tabulate(worse, time=[0, 20, 30, 40], module="sense", kind="contract")

    @contract("sense", inputs=[], profile=profile, registry=Registry())
    def sense(ctx: Context, x: Any) -> Result:
        ctx.tick(ctx.allocation)
        return Result(x, float(worse(ctx.allocation)))

    library.add(LibraryEntry.of_module(sense))
    program = compile_program(schemas["p"], library, [0, 20, 40, 60])
    np.testing.assert_array_equal(program.allocation[..., 0], [0.0, 20.0, 20.0, 20.0])
    for total in (20.0, 30.0, 40.0, 50.0, 60.0, 90.0):
        np.testing.assert_array_equal(program.allocation_at([], total), [20.0])
    clock = WorkClock()
    assert run_program(program, {"x": "data"}, Budget(60.0, clock=clock)).result.quality == 1.0
    assert clock.now() == 20.0


def test_a_hierarchical_program_runs_to_its_expected_quality() -> None:
    """The callee runs as the contract module its compilation registered, on the same clock."""
    schemas = parse_schemas(
        "(defschema sub (x) (both (sense x) (guess x)))\n(defschema top (x) (refine (sub x)))",
        "h.any",
    )
    sub, top = compile_file(schemas, toy_library(), TIME, QUALITY, schema="top")
    assert (sub.allocator, top.allocator, top.modules) == ("dp", "dp", ("sub", "refine"))
    for i, q in enumerate(QUALITY):
        for j, total in enumerate(TIME):
            clock = WorkClock()
            result = run_program(top, {"x": Result("map", q)}, Budget(total, clock=clock)).result
            assert result.quality == pytest.approx(top.expected[i, j], abs=1e-12), (q, total)
            assert clock.now() == total


def test_allocation_at_grid_points_is_the_table(toy: CompiledProgram) -> None:
    for i, q in enumerate(QUALITY):
        for j, total in enumerate(TIME):
            np.testing.assert_array_equal(toy.allocation_at([q], total), toy.allocation[i, j])


def test_running_needs_every_input_and_code_for_every_module(toy: CompiledProgram) -> None:
    with pytest.raises(ExecutionError, match=r"^schema 'p': missing inputs: x$"):
        run_program(toy, {"y": Result("map", 1.0)}, 10)
    with pytest.raises(ExecutionError, match=r"^schema 'p' takes 1 input \(x\), got 2$"):
        run_program(toy, [Result("map", 1.0), Result("map", 1.0)], 10)
    lib = AnytimeLibrary()
    chain = exponential_chain(0.1, 0.1)
    for name in ("m1", "m2"):
        profile = attrs.evolve(chain.profile(name), module=name)
        lib.add(LibraryEntry.of_profile(profile, Path(f"profiles/{name}.yaml")))
    profile_only = compile_program(program(CHAIN), lib, TIME)
    with pytest.raises(ExecutionError) as raised:
        run_program(profile_only, [Result("map", 1.0)], 10)
    assert str(raised.value) == ("schema 'p': 'm1' is known only by its profile (no code to run)")


# --- (d) the compiled profile ---------------------------------------------------------------


def cells(compiled: CompiledProgram) -> tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]:
    """(program input qualities, allocation) of every cell of the table, as rows."""
    profile = compiled.profile
    m = profile.n_inputs
    mesh = np.meshgrid(*profile.input_grids, profile.time, indexing="ij")
    q = np.stack(mesh[:-1], axis=-1).reshape(-1, m) if m else np.zeros((mesh[-1].size, 0))
    return q, compiled.allocation.reshape(-1, len(compiled.modules))


@settings(max_examples=25, deadline=None)
@given(st.booleans().flatmap(lambda s: tree_programs(stochastic=s)))
def test_the_compiled_profile_is_a_contract_profile_of_the_table(program_: RandomProgram) -> None:
    compiled = compile_program(program(program_.text), program_.library(), TIME, QUALITY)
    profile = compiled.profile
    assert (profile.module, profile.kind, profile.time_unit) == ("p", "contract", "ticks")
    assert profile.inputs == program_.quality_inputs
    np.testing.assert_array_equal(profile.time, TIME)
    for grid in profile.input_grids:
        np.testing.assert_array_equal(grid, QUALITY)
    np.testing.assert_allclose(profile.probability.sum(axis=-1), 1.0, rtol=0, atol=1e-12)
    q, allocation = cells(compiled)
    expected = Evaluator(compiled.model).expected(q, allocation)
    np.testing.assert_allclose(compiled.expected.reshape(-1), expected, rtol=0, atol=1e-12)
    # The bins' midpoints give the expected quality to within half a bin.
    binned = profile.probability @ profile.values
    assert np.all(np.abs(binned - compiled.expected) <= np.max(np.diff(profile.bins)) / 2 + 1e-12)


# --- (e) the compiled profile's file --------------------------------------------------------


def stochastic_tree() -> tuple[str, AnytimeLibrary]:
    bins = np.linspace(0, 1, 5)
    probability = np.array([[1, 0, 0, 0], [0.5, 0.5, 0, 0], [0.2, 0.3, 0.3, 0.2]], dtype=float)
    noisy = ConditionalPerformanceProfile(
        input_grids=(), time=[0, 20, 40], bins=bins, probability=probability
    )
    return "(defschema p (x) (m3 (hi (m1 x) (m2 x))))", library(
        m1=noisy,
        m2=tabulate(lambda t: t / 40, TIME),
        m3=tabulate(lambda t, q: q * t / 40, TIME, input_grids=[[0.0, 1.0]], inputs=["a"]),
    )


def deterministic_chain() -> tuple[str, AnytimeLibrary]:
    return CHAIN, exponential_chain(0.05, 0.1)


@pytest.mark.parametrize("make", [deterministic_chain, stochastic_tree], ids=["chain", "noisy"])
def test_save_writes_a_profile_file_with_the_allocation(make: Any, tmp_path: Path) -> None:
    text, lib = make()
    compiled = compile_program(program(text), lib, TIME, QUALITY)
    path = tmp_path / "p.yaml"
    save_compiled(compiled, path)
    assert load_profile(path) == compiled.profile
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert data["modules"] == list(compiled.modules)
    np.testing.assert_array_equal(np.array(data["allocation"], dtype=float), compiled.allocation)


# --- (f) errors ------------------------------------------------------------------------------


def compile_error(
    text: str, lib: AnytimeLibrary, time: Any = TIME, quality: Any = QUALITY, **options: Any
) -> str:
    with pytest.raises((SchemaError, CompileError)) as raised:
        compile_program(program(text), lib, time, quality, source=source(text), **options)
    return str(raised.value)


def test_an_unknown_function_is_named_with_a_suggestion_where_it_is_called() -> None:
    lib = exponential_chain(0.1, 0.1)
    text = "(defschema p (x)\n  (m2 (mm1 x)))"
    with pytest.raises(SchemaError) as raised:
        compile_program(program(text), lib, TIME, source=source(text))
    assert (raised.value.filename, raised.value.line, raised.value.column) == ("p.any", 2, 8)
    assert str(raised.value) == (
        "p.any:2:8: error: unknown function 'mm1'; did you mean 'm1'?\n"
        "    (m2 (mm1 x)))\n"
        "         ^~~"
    )


def test_an_unknown_function_far_from_any_known_one_lists_the_library() -> None:
    message = compile_error("(defschema p (x) (m2 (zzz x)))", exponential_chain(0.1, 0.1))
    assert message.splitlines()[0] == (
        "p.any:1:23: error: unknown function 'zzz' (known: hi, m1, m2)"
    )


def test_a_module_without_a_profile_cannot_be_compiled() -> None:
    registry = Registry()
    interruptible("m1", inputs=[], registry=registry)(_one)
    lib = AnytimeLibrary([RegistrySource(registry)])
    message = compile_error("(defschema p (x) (m1 x))", lib)
    assert message.splitlines()[0] == (
        "p.any:1:19: error: module 'm1' has no performance profile (python module "
        f"{__name__}): the compiler cannot allocate time to it"
    )


def test_every_bad_call_is_reported_at_once() -> None:
    registry = Registry()
    interruptible("m1", inputs=[], registry=registry)(_one)
    lib = AnytimeLibrary([RegistrySource(registry)])
    text = "(defschema p (x)\n  (setf a (m1 x))\n  (mm2 a))"
    with pytest.raises(SchemaError) as raised:
        compile_program(program(text), lib, TIME, source=source(text))
    assert [(d.line, d.column) for d in raised.value.diagnostics] == [(2, 12), (3, 4)]


MERGE = tabulate(
    lambda t, a, b: a * b * t / 40,
    TIME,
    input_grids=[[0.0, 1.0], [0.0, 1.0]],
    inputs=["left", "right"],
    module="merge",
)


def profile_only_library() -> AnytimeLibrary:
    lib = exponential_chain(0.1, 0.1)
    lib.add(LibraryEntry.of_profile(MERGE, Path("profiles/merge.yaml")))
    return lib


def test_a_profile_only_module_whose_inputs_cannot_be_matched() -> None:
    message = compile_error("(defschema p (x y) (merge x y))", profile_only_library())
    assert message.splitlines()[0] == (
        "p.any:1:21: error: cannot tell which arguments of 'merge' carry the quality of its "
        "inputs (left, right): it is known only by its profile; name the arguments like its "
        "inputs"
    )


def test_a_profile_only_module_is_matched_by_argument_names_or_computed_arguments() -> None:
    by_name = compile_program(
        program("(defschema p (right left) (merge right left))"),
        profile_only_library(),
        TIME,
        [0.0, 0.5, 1.0],
    )
    # Quality inputs in the program's order; the slots follow the profile's axis order.
    assert by_name.model.quality_inputs == ("right", "left")
    assert [s.index for s in by_name.model.nodes[0].slots] == [1, 0]
    computed = compile_program(
        program("(defschema p (x) (merge (m1 x) (m1 x)))"), profile_only_library(), TIME
    )
    assert computed.modules == ("m1", "m1", "merge")


def test_a_module_called_with_too_few_arguments_for_its_quality_inputs() -> None:
    registry = Registry()

    def two(ctx: Context, a: Any, b: Any) -> Iterator[Result]:
        yield Result(None, 0.0)

    interruptible(
        "m2",
        inputs=["b"],
        profile=tabulate(lambda t, q: q, TIME, input_grids=[[0.0, 1.0]], inputs=["b"]),
        registry=registry,
    )(two)
    message = compile_error("(defschema p (x) (m2 x))", AnytimeLibrary([RegistrySource(registry)]))
    assert message.splitlines()[0] == "p.any:1:19: error: function 'm2' takes 2 arguments, got 1"


def grid_error(time: Any = TIME, quality: Any = QUALITY, **options: Any) -> tuple[str | None, str]:
    """(where, message) of the CompileError a bad grid makes: the message names no file, and
    `where` names the one compiled (the command line prints `WHERE: error: MESSAGE`)."""
    with pytest.raises(CompileError) as raised:
        compile_program(program(CHAIN), exponential_chain(0.1, 0.1), time, quality, **options)
    return raised.value.where, str(raised.value)


@pytest.mark.parametrize(
    ("time", "message"),
    [
        ([], "time grid: expected at least one total time, got none"),
        ([-5, 0, 5], "time grid: expected times >= 0, got -5"),
        ([0, 5, float("nan")], "time grid: expected times >= 0, got nan"),
        ([0, 10, 5], "time grid: expected increasing times"),
        ([0, 10, 10], "time grid: expected increasing times"),
        (
            [0, 5, 12],
            "time grid: every total must be a multiple of the resolution 5 "
            "(allocations are "
            "whole multiples of it), got 12",
        ),
    ],
    ids=["empty", "negative", "nan", "decreasing", "repeated", "off-the-lattice"],
)
def test_bad_time_grids(time: list[float], message: str) -> None:
    assert grid_error(time=time) == ("<schema>", message)


def test_a_time_grid_off_the_given_resolution() -> None:
    assert grid_error(resolution=3.0) == (
        "<schema>",
        "time grid: every total must be a multiple of the resolution 3 "
        "(allocations are whole "
        "multiples of it), got 5",
    )
    assert grid_error(resolution=0.0) == (
        "<schema>",
        "time resolution: expected a number > 0, got 0",
    )


@pytest.mark.parametrize(
    ("quality", "message"),
    [
        ([0.0, 1.5], "input quality: expected qualities in [0, 1], got 1.5"),
        ([-0.1, 1.0], "input quality: expected qualities in [0, 1], got -0.1"),
        ([], "input quality: expected at least one quality, got none"),
        ([0.5, 0.2], "input quality: expected increasing qualities"),
    ],
    ids=["above-one", "negative", "empty", "decreasing"],
)
def test_bad_input_quality_grids(quality: list[float], message: str) -> None:
    assert grid_error(quality=quality) == ("<schema>", message)


def test_an_unknown_allocator() -> None:
    assert compile_error(CHAIN, exponential_chain(0.1, 0.1), allocator="greedy") == (
        "unknown allocator 'greedy' (expected one of auto, hill-climbing, exhaustive, dp, "
        "proportional, multi-start)"
    )


def test_profiles_in_different_time_units() -> None:
    lib = library(
        m1=tabulate(lambda t: t / 40, TIME),
        m2=tabulate(
            lambda t, q: q * t / 40, TIME, input_grids=[[0, 1]], inputs=["a"], time_unit="seconds"
        ),
    )
    with pytest.raises(CompileError) as raised:
        compile_program(program(CHAIN), lib, TIME, source=source(CHAIN))
    assert raised.value.where == "p.any"
    assert str(raised.value) == (
        "schema 'p': its modules' profiles are in different time units (m1: ticks, "
        "m2: seconds); measure them with one clock"
    )


def test_exhaustive_beyond_its_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(exhaustive_search, "EXHAUSTIVE_LIMIT", 20)
    # Two modules, no quality input: T/dt + 1 allocations for each total 0, 5, ..., 40.
    assert compile_error(CHAIN, exponential_chain(0.1, 0.1), allocator="exhaustive") == (
        "exhaustive search would evaluate 45 allocations (more than 20); use dp or "
        "hill-climbing, or a coarser time grid"
    )


def test_exhaustive_beyond_its_limit_leaves_the_gap_uncomputed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The limit the exhaustive allocator enforces is the one the gap computation respects:
    dp still compiles, and reports the gap as unknown."""
    monkeypatch.setattr(exhaustive_search, "EXHAUSTIVE_LIMIT", 20)
    compiled = compile_program(program(CHAIN), exponential_chain(0.1, 0.1), TIME, allocator="dp")
    assert compiled.exhaustive_gap is None


def test_a_large_table_is_compiled_without_the_exhaustive_gap() -> None:
    """Four modules, 61 totals and 11 input qualities: about 7.1 million allocations, more than
    the exhaustive search may evaluate; dp compiles the table and no gap is claimed."""
    time = np.arange(0, 301, 5.0)
    grid = [0.0, 0.5, 1.0]
    lib = library(
        m1=tabulate(lambda t, q: q * -np.expm1(-0.02 * t), time, input_grids=[grid], inputs=["a"]),
        m2=tabulate(lambda t, q: q * -np.expm1(-0.03 * t), time, input_grids=[grid], inputs=["a"]),
        m3=tabulate(lambda t, q: q * -np.expm1(-0.01 * t), time, input_grids=[grid], inputs=["a"]),
        m4=tabulate(lambda t, q: q * -np.expm1(-0.05 * t), time, input_grids=[grid], inputs=["a"]),
    )
    chain = "(defschema p (x) (m4 (m3 (m2 (m1 x)))))"
    quality = np.round(np.linspace(0, 1, 11), 12)
    compiled = compile_program(program(chain), lib, time, quality)
    assert compiled.allocator == "dp" and compiled.exhaustive_gap is None
    with pytest.raises(CompileError, match=r"^exhaustive search would evaluate 6,989,136 "):
        compile_program(program(chain), lib, time, quality, allocator="exhaustive")
