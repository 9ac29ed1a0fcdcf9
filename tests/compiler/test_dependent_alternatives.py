"""A best-of's alternatives run on one problem: the table takes them independent given their
inputs, and `CompiledProgram.dependence` bounds what any dependence between them delivers --
checked against every joint distribution of given marginals (hypothesis), against runs whose
modules sample from their profiles with one shared draw (the worst case, reached) or opposite
draws (the best), and through a called schema, storage and the reports."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from choice_modules import BEST_OF, MID, TIME, compiled, gamble, library, steady
from conftest import Cli
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.compiler import Code, compile_file, compile_program, load_compiled, save_compiled
from anytime.compiler.dist import NO_RESULT, Dist
from anytime.compiler.evaluate import Evaluator, _coupled_maximum
from anytime.compiler.model import ChoiceNode
from anytime.compiler.report import compiled_to_dict, format_report
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary, RegistrySource
from anytime.modules import Context, Registry, Result, contract
from anytime.plugin import Instance
from anytime.verification import format_verification, verification_to_dict, verify

VALUES = np.array([NO_RESULT, 0.0, 0.3, 0.7, 1.0])


@st.composite
def joints(draw: st.DrawFn) -> np.ndarray:
    """A joint distribution of 2 or 3 alternatives over `VALUES`, any dependence."""
    n = draw(st.integers(2, 3))
    cells = len(VALUES) ** n
    weights = np.array(draw(st.lists(st.integers(0, 9), min_size=cells, max_size=cells)))
    if weights.sum() == 0:
        weights[0] = 1
    joint: np.ndarray = (weights / weights.sum()).reshape((len(VALUES),) * n)
    return joint


def marginals(joint: np.ndarray) -> list[Dist]:
    n = joint.ndim
    return [
        Dist(VALUES[None, :], joint.sum(axis=tuple(a for a in range(n) if a != i))[None, :])
        for i in range(n)
    ]


@settings(max_examples=200, deadline=None)
@given(joints())
def test_the_bounds_hold_for_every_joint_distribution_of_the_marginals(joint: np.ndarray) -> None:
    grids = np.meshgrid(*([VALUES] * joint.ndim), indexing="ij")
    maximum = float((np.maximum(np.maximum.reduce(grids), 0.0) * joint).sum())  # none: 0
    least, most = (_coupled_maximum(marginals(joint), c) for c in ("least", "most"))
    assert least.probs.sum() == pytest.approx(1.0) and most.probs.sum() == pytest.approx(1.0)
    assert least.expected()[0] - 1e-12 <= maximum <= most.expected()[0] + 1e-12


@settings(max_examples=100, deadline=None)
@given(joints())
def test_one_shared_draw_reaches_the_least_and_opposite_draws_the_most(joint: np.ndarray) -> None:
    dists = marginals(joint)
    u = (np.arange(20_000) + 0.5) / 20_000
    cdfs = [np.cumsum(d.probs[0]) for d in dists]

    def quantile(cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
        return VALUES[np.minimum(np.searchsorted(cdf, u), len(VALUES) - 1)]

    shared = np.maximum(np.maximum.reduce([quantile(c, u) for c in cdfs]), 0.0).mean()
    assert shared == pytest.approx(_coupled_maximum(dists, "least").expected()[0], abs=1e-3)
    if len(dists) == 2:  # countermonotone: sharp for two alternatives
        opposite = np.maximum.reduce([quantile(cdfs[0], u), quantile(cdfs[1], 1 - u), 0 * u]).mean()
        most = _coupled_maximum(dists, "most").expected()[0]
        assert opposite == pytest.approx(most, abs=1e-3)


def test_runs_that_sample_one_draw_for_both_alternatives_deliver_the_least() -> None:
    result = compiled(BEST_OF)
    assert result.dependence is not None and result.dependence.shape == (2, len(TIME))
    least, most = result.dependence
    assert np.all(least <= result.expected + 1e-12) and np.all(result.expected <= most + 1e-12)
    rng = np.random.default_rng(3)
    u = rng.random(100_000)
    for j, split in enumerate(result.allocation):
        cdfs = [
            np.cumsum(p.distribution([], t))
            for p, t in ((steady(), split[0]), (gamble(), split[1]))
        ]
        a, b = (MID[np.minimum(np.searchsorted(c, u * c[-1]), len(MID) - 1)] for c in cdfs)
        same = np.maximum(a, b)  # one draw: a hard problem for one is hard for both
        se = same.std() / np.sqrt(len(u))
        assert abs(same.mean() - least[j]) <= 4 * se + 1e-9, j
        assert least[j] <= np.maximum(a, rng.permutation(b)).mean() + 4 * se


def test_the_note_and_the_reports_say_by_how_much() -> None:
    result = compiled(BEST_OF)
    assert result.dependence is not None
    below = float(np.max(result.expected - result.dependence[0]))
    above = float(np.max(result.dependence[1] - result.expected))
    (note,) = [n for n in result.notes if n.code is Code.DEPENDENCE]
    assert note.message == (
        "a best-of's alternatives are taken as independent given their inputs' qualities, or"
        " as dependent as its :dependence says; if they depend on each other otherwise (a"
        " problem hard for one is hard for all), the expected quality is up to"
        f" {below:.3f} lower or {above:.3f} higher than the table's (the bounds over every"
        " dependence: dependence)"
    )
    assert "if dependent" in format_report(result).splitlines()[1]
    row = compiled_to_dict(result)["budgets"][6]
    assert row["expected_quality_if_dependent"] == [
        result.dependence[0, 6],
        result.dependence[1, 6],
    ]


def test_a_program_without_a_best_of_has_no_bounds() -> None:
    result = compiled("(defschema one () (steady))")
    assert result.dependence is None
    assert Code.DEPENDENCE not in result.codes


FILE = """(defschema pick (w)
  (best-of (when (left-clear? w) (steady)) (when (right-clear? w) (gamble))))

(defschema outer (w)
  (pick w))
"""


def test_a_caller_carries_its_callees_bounds_and_storage_keeps_them(tmp_path: Path) -> None:
    lib = library()
    pick, outer = compile_file(parse_schemas(FILE, "f.any"), lib, TIME, schema="outer")[-2:]
    assert outer.dependence is not None and pick.dependence is not None
    # the caller runs the callee's table: its bounds are the callee's at the totals it gives
    np.testing.assert_allclose(outer.expected, pick.expected)
    np.testing.assert_allclose(outer.dependence, pick.dependence)
    path = tmp_path / "outer.yaml"
    save_compiled(outer, path)
    loaded = load_compiled(path, lib)
    assert loaded.dependence is not None
    np.testing.assert_array_equal(loaded.dependence, outer.dependence)
    assert loaded.note == outer.note


def test_the_bounds_are_checked_when_a_saved_program_is_loaded(tmp_path: Path) -> None:
    import yaml

    lib = library()
    path = tmp_path / "pick.yaml"
    save_compiled(compile_file(parse_schemas(FILE, "f.any"), lib, TIME, schema="pick")[-1], path)
    document = yaml.safe_load(path.read_text())
    document["compiled"]["dependence"][0][3] = 1.5
    path.write_text(yaml.safe_dump(document))
    with pytest.raises(Exception, match=r"dependence.*a quality in \[0, 1\]"):
        load_compiled(path, lib)


def test_the_compiled_plot_draws_the_band_between_the_bounds() -> None:
    pytest.importorskip("matplotlib")
    from anytime.plot import draw_compiled, new_figure

    result = compiled(BEST_OF)
    assert result.dependence is not None
    ax = new_figure(7, 5).subplots()
    draw_compiled(ax, result.profile, result.baselines, dependence=result.dependence)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0] == "compiled, if the best-of's alternatives depend on each other"
    (band,) = ax.collections
    path = band.get_paths()[0].vertices  # the lower edge, then the upper one back
    assert np.min(path[:, 1]) == pytest.approx(np.min(result.dependence[0]))
    assert np.max(path[:, 1]) == pytest.approx(np.max(result.dependence[1]))


def test_plotting_a_saved_program_draws_the_baselines_and_the_band_it_holds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, cli: Cli
) -> None:
    """`anytime plot` of a file written by `compile -o` draws what plotting the schema draws:
    the baselines and the dependence band are read off the file, checked as loading checks
    them, without the library."""
    pytest.importorskip("matplotlib")
    import yaml

    import anytime.cli.plot as plot_command

    pick = compile_file(parse_schemas(FILE, "f.any"), library(), TIME, schema="pick")[-1]
    assert pick.dependence is not None
    path = tmp_path / "pick.yaml"
    save_compiled(pick, path)
    drawn: dict[str, object] = {}
    monkeypatch.setattr(plot_command, "plot_allocation", lambda *a, **k: drawn.update(k))
    assert cli("plot", str(path), "-o", str(tmp_path / "pick.png"))[0] == 0
    baselines = drawn["baselines"]
    assert isinstance(baselines, dict) and baselines.keys() == pick.baselines.keys()
    for name, table in pick.baselines.items():
        np.testing.assert_array_equal(baselines[name], table)
    np.testing.assert_array_equal(drawn["dependence"], pick.dependence)

    document = yaml.safe_load(path.read_text())
    document["compiled"]["dependence"][1][3] = -0.5  # (least and most, time): no input
    path.write_text(yaml.safe_dump(document))
    assert cli("plot", str(path), "-o", str(tmp_path / "pick.png")) == (
        1,
        "",
        f"{path}: error: compiled.dependence[1][3]: expected a quality in [0, 1], got -0.5\n",
    )


def _declared(dependence: float) -> str:
    return BEST_OF[:-2] + f"\n           :dependence {dependence}))"


def test_a_declared_dependence_mixes_independent_and_one_draw_deciding_all() -> None:
    """At any allocation, `:dependence D` gives (1 - D) x the independent expectation + D x
    the comonotone bound's, and the table is optimised for it."""
    free, half = compiled(BEST_OF), compiled(_declared(0.5))
    for allocation in (half.allocation, free.allocation):
        split = allocation.reshape(len(TIME), -1)
        independent = Evaluator(free.model).expected([], split)
        least = Evaluator(free.model, "least").expected([], split)
        declared = Evaluator(half.model).expected([], split)
        np.testing.assert_allclose(declared, 0.5 * independent + 0.5 * least, atol=1e-12)
    np.testing.assert_allclose(
        half.expected, Evaluator(half.model).expected([], half.allocation), atol=1e-12
    )
    assert np.all(half.expected <= free.expected + 1e-12)
    assert np.any(half.expected < free.expected - 0.01)  # a gamble loses most when shared
    assert half.dependence is not None
    assert np.all(half.dependence[0] <= half.expected + 1e-12)
    assert np.all(half.expected <= half.dependence[1] + 1e-12)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.0, 1.0))
def test_runs_whose_draws_are_shared_with_that_probability_deliver_it(dependence: float) -> None:
    """Sampled from the profiles: with probability D one uniform decides both alternatives,
    else each its own; the mean of the better is the compiled promise within 4 se."""
    result = compiled(_declared(round(dependence, 3)))
    rng = np.random.default_rng(5)
    n = 40_000
    shared = rng.random(n) < round(dependence, 3)
    u = rng.random(n)
    v = np.where(shared, u, rng.random(n))
    for j, split in enumerate(result.allocation):
        cdfs = [
            np.cumsum(p.distribution([], t))
            for p, t in ((steady(), split[0]), (gamble(), split[1]))
        ]
        a, b = (
            MID[np.minimum(np.searchsorted(c, w * c[-1]), len(MID) - 1)]
            for c, w in zip(cdfs, (u, v), strict=True)
        )
        better = np.maximum(a, b)
        se = better.std() / np.sqrt(n)
        assert abs(better.mean() - result.expected[j]) <= 4 * se + 1e-9, j


SHARING = 0.6  # the runs' true dependence


def sampling_library() -> AnytimeLibrary:
    """`steady` and `gamble` drawing their quality from their profiles, each with the uniform
    the problem gives it: a best-of's run sees them as dependent as the problem draws them."""
    registry = Registry()
    for index, (name, profile) in enumerate((("steady", steady()), ("gamble", gamble()))):

        def run(ctx: Context, w: Any, profile: Any = profile, index: int = index) -> Result:
            ctx.tick(ctx.allocation)
            cdf = np.cumsum(profile.distribution([], ctx.allocation))
            quality = float(MID[min(np.searchsorted(cdf, w[index] * cdf[-1]), len(MID) - 1)])
            return Result(quality, quality)

        run.__name__ = run.__qualname__ = name
        contract(name, inputs=[], profile=profile, registry=registry)(run)
    return AnytimeLibrary([RegistrySource(registry)])


class SharedDraws:
    """A problem: with probability `SHARING` one uniform for both alternatives, else two."""

    def instance(self, rng: np.random.Generator) -> Instance:
        u = float(rng.random())
        return Instance(((u, u if rng.random() < SHARING else float(rng.random())),))


def test_verify_fits_the_dependence_the_runs_show_and_its_promise_holds() -> None:
    text = "(defschema pick (w) (best-of (steady w) (gamble w){}))"
    lib = sampling_library()
    free = compile_program(parse_schemas(text.format(""))["pick"], lib, TIME)
    checked = verify(free, SharedDraws(), runs=600, seed=1)
    fit = checked.dependence_fit
    assert fit is not None and fit.declared == 0.0
    assert abs(fit.estimate - SHARING) <= 3 * fit.se and fit.se < 0.1
    assert not checked.passed  # independent alternatives promise too much
    written = round(fit.estimate, 2)
    declared = compile_program(
        parse_schemas(text.format(f" :dependence {written}"))["pick"], lib, TIME
    )
    again = verify(declared, SharedDraws(), runs=600, seed=3)  # other problems than the fit's
    assert again.passed, format_verification(again)
    assert again.dependence_fit is not None and again.dependence_fit.declared == written
    assert abs(again.dependence_fit.estimate - SHARING) <= 3 * again.dependence_fit.se
    text_out = format_verification(again)
    assert f"the runs fit :dependence {again.dependence_fit.estimate:.2f} ± " in text_out
    assert verification_to_dict(again)["dependence_fit"] == {
        "declared": written,
        "estimate": again.dependence_fit.estimate,
        "se": again.dependence_fit.se,
    }


def test_no_fit_without_exactly_one_best_of() -> None:
    lib = sampling_library()
    one = compile_program(parse_schemas("(defschema one (w) (steady w))")["one"], lib, TIME)
    assert verify(one, SharedDraws(), runs=5).dependence_fit is None
    text = "(defschema two (w) (best-of (steady w) (best-of (gamble w) (steady w))))"
    two = compile_program(parse_schemas(text)["two"], lib, TIME)
    assert two.dependence is not None
    assert verify(two, SharedDraws(), runs=5, budgets=[4]).dependence_fit is None


def test_storage_keeps_a_declared_dependence(tmp_path: Path) -> None:
    half = compiled(_declared(0.5))
    path = tmp_path / "half.yaml"
    save_compiled(half, path)
    loaded = load_compiled(path, library())
    (choice,) = [node for node in loaded.model.nodes if isinstance(node, ChoiceNode)]
    assert choice.dependence == 0.5
    np.testing.assert_array_equal(loaded.expected, half.expected)
