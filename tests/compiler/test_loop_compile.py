"""Compiling loops: the run-time split of a loop's time among its calls (equal shares for
identical concave curves, the marginal-value rule otherwise) against an exhaustive search over
the calls, the loop's profile for each count, the program's table with a loop in it (dp exact,
checked against the exhaustive allocator), a stochastic call's mean distribution, the compile
errors of bad loops, and saving a compiled loop."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from choice_modules import library as choice_library
from hypothesis import given, settings
from hypothesis import strategies as st
from loop_modules import loop_library

from anytime.compiler import compile_file, compile_program
from anytime.compiler.allocators import compositions
from anytime.compiler.loops import best_splits, call_curves, loop_profiles, run_time_split
from anytime.compiler.model import LoopNode, ModuleNode
from anytime.compiler.storage import load_compiled, save_compiled
from anytime.dsl import parse_schemas
from anytime.errors import SchemaError
from anytime.profiles import tabulate

LOOPS = """
(defschema tours (depots) (map tour depots))
(defschema climbs (depots) (map climb depots :max 3))
(defschema triple (x) (repeat 3 (tour x)))
(defschema plan (sensor depots)
  (setf world (sense sensor))
  (best-of (map tour depots) world))
"""


def compiled(name: str, allocator: str = "auto", top: int = 40):
    schemas = parse_schemas(LOOPS)
    return compile_file(
        schemas,
        loop_library(),
        range(0, top + 1, 4),
        schema=name,
        allocator=allocator,
        resolution=1,
    )[-1]


def call_of(name: str) -> ModuleNode:
    loop = compiled(name).model.nodes[0]
    assert isinstance(loop, LoopNode)
    return loop.call


def best_by_exhaustive(call: ModuleNode, qualities: np.ndarray, total: int) -> float:
    """The best mean expected quality of the calls over every split of `total` units."""
    curves = call_curves(call, qualities[None], total, 1.0)[0]
    splits = compositions(total, len(qualities))
    return float(curves[np.arange(len(qualities)), splits].mean(axis=1).max())


@pytest.mark.parametrize("name", ["tours", "climbs"])
@pytest.mark.parametrize("k", [1, 2, 3, 4])
def test_the_run_time_split_is_within_half_a_percent_of_exhaustive(name: str, k: int) -> None:
    call = call_of(name)
    rng = np.random.default_rng(k)
    for _ in range(5):
        qualities = rng.uniform(0.2, 1.0, size=(k, 1))
        for total in (0, 3, 9, 16, 25, 40):
            shares = run_time_split(call, qualities, float(total), 1.0)
            assert shares.sum() == pytest.approx(total) or shares.sum() < total
            got = float(call.profile.expected(qualities, call.run_time(shares)).mean())
            best = best_by_exhaustive(call, qualities, total)
            assert got <= best + 1e-12
            assert got >= best * (1 - 0.005)


def test_identical_concave_calls_get_equal_shares() -> None:
    call = call_of("tours")
    np.testing.assert_array_equal(run_time_split(call, np.ones((3, 1)), 10.0, 1.0), [10 / 3] * 3)


def test_an_s_shaped_curve_concentrates_the_time() -> None:
    """Two climbs with 16 units: 8 units each give nothing; 16 to one gives it quality 1."""
    call = call_of("climbs")
    np.testing.assert_array_equal(run_time_split(call, np.ones((2, 1)), 16.0, 1.0), [16.0, 0.0])


def test_the_lower_quality_item_gets_less_of_a_concave_modules_time() -> None:
    shares = run_time_split(call_of("tours"), np.array([[1.0], [1.0], [0.5]]), 30.0, 1.0)
    np.testing.assert_array_equal(shares, [12.0, 12.0, 6.0])


def test_the_loops_profile_is_the_mean_of_its_calls_for_each_count() -> None:
    loop = compiled("tours").model.nodes[0]
    assert isinstance(loop, LoopNode)
    assert (loop.kind, loop.count, loop.most, loop.item_axes) == ("map", 4, 4, (0,))
    assert len(loop.profiles) == 5
    np.testing.assert_array_equal(loop.profiles[0].expected([[0.5]], [7.0]), [1.0])
    for count in (1, 2, 3, 4):
        q = np.full((count, 1), 0.5)
        shares = run_time_split(loop.call, q, 7.0, 1.0)
        expected = loop.call.profile.expected(q, shares).mean()
        assert loop.profiles[count].expected([[0.5]], [7.0])[0] == pytest.approx(expected)


def test_a_program_with_a_loop_has_its_table_from_the_loops_profile() -> None:
    tours = compiled("tours")
    assert tours.modules == ("map tour",)
    assert tours.allocator == "dp" and tours.exact
    # Planned for four items at quality 1: each gets a quarter of the total.
    np.testing.assert_allclose(tours.expected[-1], -np.expm1(-0.1 * np.arange(0, 41, 4) / 4))


@pytest.mark.parametrize("name", ["plan", "climbs", "triple"])
def test_dp_on_a_program_with_a_loop_equals_the_exhaustive_allocator(name: str) -> None:
    by_dp, by_search = compiled(name), compiled(name, "exhaustive")
    assert by_dp.allocator == "dp"
    np.testing.assert_allclose(by_dp.expected, by_search.expected, atol=1e-12)


def test_a_stochastic_calls_loop_has_the_distribution_of_their_mean() -> None:
    """Two gambles (excellent or useless after 2 units): their mean is 0.125, 0.5 or 0.875."""
    program = parse_schemas("(defschema two () (repeat 2 (gamble)))")["two"]
    result = compile_program(program, choice_library(), range(0, 11), resolution=1)
    profile = result.model.nodes[0].profile
    np.testing.assert_allclose(profile.distribution([], 4.0), [0.25, 0.0, 0.5, 0.25])
    assert profile.expected([], 4.0) == pytest.approx(0.5)
    assert result.allocator != "dp"  # a stochastic profile: dp would not be exact


@settings(max_examples=30, deadline=None)
@given(
    rises=st.lists(st.floats(0.0, 1.0), min_size=4, max_size=12),
    quality=st.sampled_from([0.0, 0.3, 1.0]),
    most=st.integers(1, 3),
)
def test_more_time_never_lowers_the_loops_compiled_expectation(
    rises: list[float], quality: float, most: int
) -> None:
    """Whatever the call's curve (non-decreasing, concave or not), the loop's expectation
    never falls as its time grows, for every count; and never beats an exhaustive split."""
    steps = np.cumsum(rises) / max(sum(rises), 1e-9)
    time = np.arange(len(steps), dtype=np.float64)
    profile = tabulate(
        lambda t, q: np.asarray(q) * np.interp(t, time, steps), time, input_grids=[[0.0, 1.0]]
    )
    call = ModuleNode(0, "f", (), profile, True, 0)
    lattice = np.arange(len(steps) + 4, dtype=np.float64)
    for count, loop in enumerate(loop_profiles(call, most, lattice, "loop")):
        curve = loop.expected(np.full((len(lattice), 1), quality), lattice)
        assert np.all(np.diff(curve) >= -1e-12)
        if count:
            q = np.full((count, 1), quality)
            best = best_by_exhaustive(call, q, len(lattice) - 1)
            assert curve[-1] <= best + 1e-9


def test_the_split_of_no_calls_is_empty() -> None:
    assert best_splits(np.zeros((2, 0, 5))).shape == (2, 5, 0)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "(defschema f (xs) (map count-items xs))",
            "map applies an anytime module, but 'count-items' is an elementary function (it "
            "takes no time): call it on the results instead",
        ),
        (
            "(defschema f (x) (repeat 2 (count-items x)))",
            "repeat applies an anytime module, but 'count-items' is an elementary function (it "
            "takes no time): call it on the results instead",
        ),
        ("(defschema f (xs) (map tuor xs))", "unknown function 'tuor'; did you mean 'tour'?"),
        ("(defschema f (xs w) (map tour xs w))", "function 'tour' takes 1 argument, got 2"),
    ],
)
def test_bad_loops_are_compile_errors_at_the_function(text: str, message: str) -> None:
    with pytest.raises(SchemaError) as raised:
        compile_file(parse_schemas(text, "f.any"), loop_library(), range(0, 9))
    (diagnostic,) = raised.value.diagnostics
    assert diagnostic.message == message
    assert diagnostic.column == text.index(message.split("'")[1]) + 1


def test_a_compiled_loop_is_saved_and_loaded_back(tmp_path: Path) -> None:
    tours = compiled("plan")
    save_compiled(tours, tmp_path / "plan.yaml")
    loaded = load_compiled(tmp_path / "plan.yaml", loop_library())
    np.testing.assert_array_equal(loaded.allocation, tours.allocation)
    (loop, old) = (
        next(n for n in c.model.nodes if isinstance(n, LoopNode)) for c in (loaded, tours)
    )
    np.testing.assert_allclose(loop.profile.mean, old.profile.mean)


@settings(max_examples=40, deadline=None)
@given(
    rises=st.lists(st.floats(0.0, 1.0), min_size=4, max_size=12),
    qualities=st.lists(st.floats(0.1, 1.0), min_size=1, max_size=4),
    total=st.integers(0, 15),
)
def test_the_run_time_split_of_any_curve_is_within_half_a_percent_of_exhaustive(
    rises: list[float], qualities: list[float], total: int
) -> None:
    steps = np.cumsum(rises) / max(sum(rises), 1e-9)
    time = np.arange(len(steps), dtype=np.float64)
    profile = tabulate(
        lambda t, q: np.asarray(q) * np.interp(t, time, steps), time, input_grids=[[0.0, 1.0]]
    )
    call = ModuleNode(0, "f", (), profile, True, 0)
    q = np.asarray(qualities).reshape(-1, 1)
    shares = run_time_split(call, q, float(total), 1.0)
    assert shares.sum() <= total + 1e-9
    got = float(call.profile.expected(q, call.run_time(shares)).mean())
    best = best_by_exhaustive(call, q, total)
    assert best * (1 - 0.005) - 1e-12 <= got <= best + 1e-12
