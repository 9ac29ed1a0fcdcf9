"""`anytime.explain`: each module's share and the marginal expected quality of its time, exact
on an analytic chain, never a gaining move where the split is optimal, and clear errors."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import anytime
from anytime.compiler import Code, CompiledProgram, CompileError, compile_program
from anytime.compiler.explain import explanation_to_dict
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary, RegistrySource
from anytime.modules import Context, Registry, Result, interruptible
from anytime.profiles import tabulate

TIME = np.arange(0, 41, 5.0)
CHAIN = "(defschema p (x) (m2 (m1 x)))"


def _one(ctx: Context, a: Any) -> Iterator[Result]:
    yield Result(None, 0.0)


def _none(ctx: Context) -> Iterator[Result]:
    yield Result(None, 0.0)


def chain(a: float, b: float, *, input_grid: bool = False) -> AnytimeLibrary:
    """m1: 1 - exp(-a t) (of x's quality when `input_grid`); m2: q (1 - exp(-b t)), linear in
    its input quality, so its interpolation is exact."""
    registry = Registry()
    if input_grid:
        first = tabulate(
            lambda t, q: q * -np.expm1(-a * t), TIME, input_grids=[[0.5, 1.0]], inputs=["a"]
        )
    else:
        first = tabulate(lambda t: -np.expm1(-a * t), TIME)
    second = tabulate(
        lambda t, q: q * -np.expm1(-b * t), TIME, input_grids=[[0.0, 1.0]], inputs=["a"]
    )
    interruptible("m1", inputs=("a",) if input_grid else (), profile=first, registry=registry)(_one)
    interruptible("m2", inputs=("a",), profile=second, registry=registry)(_one)
    return AnytimeLibrary([RegistrySource(registry)])


def compiled(a: float, b: float, time: Any = TIME, **options: Any) -> CompiledProgram:
    program = parse_schemas(CHAIN, "p.any")["p"]
    input_grid = options.pop("input_grid", False)
    return compile_program(program, chain(a, b, input_grid=input_grid), time, **options)


def value(a: float, b: float, t1: float, t2: float, q: float = 1.0) -> float:
    """The chain's expected quality, clamped at the profiles' last time like the profiles."""
    t1, t2 = min(t1, TIME[-1]), min(t2, TIME[-1])
    return float(q * -np.expm1(-a * t1) * -np.expm1(-b * t2))


def test_the_margins_are_the_analytic_differences() -> None:
    a, b = 0.1, 0.05
    (explanation,) = anytime.explain(compiled(a, b), [20])
    t1, t2 = (m.share for m in explanation.modules)
    assert t1 + t2 == 20
    assert explanation.total == 20 and explanation.unit == 5
    assert explanation.expected == pytest.approx(value(a, b, t1, t2), abs=1e-12)
    first, second = explanation.modules
    assert (first.module, second.module) == ("m1", "m2")
    assert first.gain == pytest.approx(value(a, b, t1 + 5, t2) - value(a, b, t1, t2), abs=1e-12)
    assert second.gain == pytest.approx(value(a, b, t1, t2 + 5) - value(a, b, t1, t2), abs=1e-12)
    assert first.loss == pytest.approx(value(a, b, t1, t2) - value(a, b, t1 - 5, t2), abs=1e-12)
    assert second.loss == pytest.approx(value(a, b, t1, t2) - value(a, b, t1, t2 - 5), abs=1e-12)
    move = explanation.best_move
    assert move is not None
    moved = {("m1", "m2"): value(a, b, t1 - 5, t2 + 5), ("m2", "m1"): value(a, b, t1 + 5, t2 - 5)}
    best = max(moved, key=lambda k: moved[k])
    assert (move.source, move.target) == best
    assert move.change == pytest.approx(moved[best] - value(a, b, t1, t2), abs=1e-12)


def test_a_module_without_time_has_no_loss_and_at_its_ceiling_says_so() -> None:
    program = compiled(0.1, 0.05, np.arange(0, 101, 5.0))
    (nothing,) = anytime.explain(program, [0])
    assert [(m.share, m.loss) for m in nothing.modules] == [(0, None), (0, None)]
    assert nothing.best_move is None  # no time to move
    (everything,) = anytime.explain(program, [100])
    assert [m.share for m in everything.modules] == [60, 40]  # both past their profiles' 40
    assert [m.at_ceiling for m in everything.modules] == [True, True]
    assert [m.gain for m in everything.modules] == [0, 0]
    assert everything.modules[0].code == Code.AT_CEILING


def test_notes_for_zero_and_negative_margins() -> None:
    margin = anytime.ModuleMargin("m", share=5, gain=0.0, loss=0.1, at_ceiling=False)
    assert margin.code == Code.ZERO_MARGINAL
    falling = anytime.ModuleMargin("m", share=5, gain=-0.01, loss=0.1, at_ceiling=False)
    assert falling.code == Code.MORE_TIME_LOWERS
    rising = anytime.ModuleMargin("m", share=5, gain=0.01, loss=0.1, at_ceiling=False)
    assert (rising.code, rising.note) == (None, "")


@settings(max_examples=20, deadline=None)
@given(st.floats(0.01, 0.5), st.floats(0.01, 0.5), st.sampled_from(["dp", "exhaustive"]))
def test_no_move_of_one_unit_gains_where_the_split_is_optimal(
    a: float, b: float, allocator: str
) -> None:
    program = compiled(a, b, allocator=allocator)
    for explanation in anytime.explain(program, TIME.tolist()):
        assert explanation.best_move is None or explanation.best_move.change <= 1e-12
        for margin in explanation.modules:  # more time never hurts a monotone chain
            assert margin.gain >= -1e-12
            assert margin.loss is None or margin.loss >= -1e-12


def test_default_totals_are_a_quarter_half_and_all_of_the_grid() -> None:
    explanations = anytime.explain(compiled(0.1, 0.05))
    assert [e.total for e in explanations] == [10, 20, 40]


def test_input_qualities_default_to_the_best_and_may_be_chosen() -> None:
    program = compiled(0.1, 0.05, input_quality=[0.5, 1.0], input_grid=True)
    (best,) = anytime.explain(program, [20])
    (half,) = anytime.explain(program, [20], [0.5])
    assert (best.input_quality, half.input_quality) == ((1.0,), (0.5,))
    assert half.expected == pytest.approx(best.expected / 2, abs=1e-12)


def test_a_total_off_the_grid_is_refused() -> None:
    with pytest.raises(CompileError) as caught:
        anytime.explain(compiled(0.1, 0.05), [12])
    assert str(caught.value) == (
        "explain: expected a total of the table's time grid (0, 5, 10, 15, 20, 25, ... ticks;"
        " 9 totals up to 40), got 12"
    )


def test_input_qualities_off_the_grid_are_refused() -> None:
    program = compiled(0.1, 0.05, input_quality=[0.5, 1.0], input_grid=True)
    with pytest.raises(CompileError) as caught:
        anytime.explain(program, [20], [0.7])
    assert str(caught.value) == (
        "explain: expected 1 input qualities of the table's grid (0.5, 1), one per quality"
        " input of 'p', got [0.7]"
    )
    with pytest.raises(CompileError) as caught:
        anytime.explain(compiled(0.1, 0.05), [20], [0.5])
    assert str(caught.value) == (
        "explain: 'p' has no quality input: expected no input qualities, got [0.5]"
    )


def test_an_explanation_as_data() -> None:
    (explanation,) = anytime.explain(compiled(0.1, 0.05), [20])
    data = explanation_to_dict(explanation)
    assert list(data) == [
        "total",
        "input_quality",
        "unit",
        "expected_quality",
        "unused",
        "modules",
        "best_move",
    ]
    assert list(data["modules"][0]) == ["module", "share", "gain", "loss", "at_ceiling", "note"]
    assert list(data["best_move"]) == ["from", "to", "change"]


def test_explain_is_public_for_users_and_plugins() -> None:
    assert {"explain", "Explanation", "ModuleMargin", "Move"} <= set(anytime.__all__)


def test_a_kept_smaller_split_leaves_time_unused_and_says_so() -> None:
    """A module whose quality falls after 20 ticks: from then on the table keeps the split of
    20 and leaves the rest unused, and more time to either module loses."""
    registry = Registry()
    rises_then_falls = tabulate(lambda t: np.where(t <= 20, t / 20, 1 - (t - 20) / 40), TIME)
    interruptible("m", inputs=(), profile=rises_then_falls, registry=registry)(_none)
    program = parse_schemas("(defschema p () (m))", "p.any")["p"]
    compiled = compile_program(program, AnytimeLibrary([RegistrySource(registry)]), TIME)
    (explanation,) = anytime.explain(compiled, [30])
    assert explanation.unused == 10
    (margin,) = explanation.modules
    assert (margin.share, margin.code) == (20, Code.MORE_TIME_LOWERS)
    assert margin.gain == pytest.approx(-5 / 40, abs=1e-12)
    text = anytime.compiler.explain.format_explanations(compiled, [explanation])
    assert (
        "  T = 30 ticks: expected quality 1.00000 (10 ticks unused: a smaller total's split" in text
    )
