"""Compiling and running `best-of` and `if`: the split against an exhaustive search, the output
distribution against Monte Carlo, preconditions at run time, the mixture of an if, Romanenko's
proportional split and discrete-variant modules."""

from __future__ import annotations

import numpy as np
import pytest
from choice_modules import BEST_OF, MID, TIME, compiled, gamble, library, steady

from anytime.compiler import (
    Code,
    Evaluator,
    compile_program,
)
from anytime.dsl import parse_schemas
from anytime.errors import SchemaError
from anytime.library import AnytimeLibrary, RegistrySource
from anytime.modules import Context, Registry, Result, contract, elementary
from anytime.profiles import DiscreteVariants
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.runtime import Status, run_program


def cdf(profile: ConditionalPerformanceProfile, t: float) -> np.ndarray:
    return np.cumsum(profile.distribution([], t))


def brute_force(total: int) -> tuple[float, int]:
    """max over t of E[max(Q_steady(t), Q_gamble(total - t))], from the CDF product."""
    values = []
    for t in range(total + 1):
        joint = cdf(steady(), t) * cdf(gamble(), total - t)
        values.append(float(MID @ np.diff(joint, prepend=0.0)))
    return max(values), int(np.argmax(values))


@pytest.mark.parametrize("allocator", ["auto", "exhaustive", "hill-climbing"])
def test_best_of_split_equals_an_exhaustive_search(allocator: str) -> None:
    result = compiled(BEST_OF, allocator=allocator)
    optimum = np.array([brute_force(int(t))[0] for t in TIME])
    if allocator == "hill-climbing":  # may stop at a local maximum: never above the optimum
        assert np.all(result.expected <= optimum + 1e-12)
    else:
        np.testing.assert_allclose(result.expected, optimum, atol=1e-12)
    assert result.modules == ("steady", "gamble")
    np.testing.assert_allclose(result.allocation.sum(axis=-1), TIME)


def test_best_of_output_is_the_distribution_of_the_maximum() -> None:
    result = compiled(BEST_OF)
    split = result.allocation[6]
    dist = Evaluator(result.model).evaluate(np.zeros((1, 0)), split[None])
    rng = np.random.default_rng(8)
    draws = 200_000
    a = rng.choice(MID, size=draws, p=steady().distribution([], split[0]))
    b = rng.choice(MID, size=draws, p=gamble().distribution([], split[1]))
    sampled = np.maximum(a, b)
    for value in MID:
        exact = dist.probs[0][np.isclose(dist.values[0], value)].sum()
        assert abs(np.mean(sampled == value) - exact) < 0.005
    assert abs(sampled.mean() - dist.expected()[0]) < 0.003
    assert result.expected[6] == pytest.approx(dist.expected()[0])


def test_diversifying_beats_giving_one_alternative_everything() -> None:
    result = compiled(BEST_OF)
    only = [
        max(float(MID @ steady().distribution([], t)), float(MID @ gamble().distribution([], t)))
        for t in TIME
    ]
    assert result.expected[6] > only[6] + 0.01


def test_run_returns_the_best_applicable_result_with_the_time_resplit() -> None:
    result = compiled(BEST_OF, lib=library(steady=0.6, gamble=0.9))
    both = run_program(result, ["left right"], 6).result
    assert both.quality == 0.9 and both.value[0] == "gamble"
    left = run_program(
        result, ["left"], 6
    ).result  # gamble is not applicable: steady gets the whole time
    assert left.value == ("steady", 6.0) and left.quality == 0.6
    right = run_program(result, ["right"], 6).result
    assert right.value == ("gamble", 6.0)


def test_no_applicable_alternative_is_a_clear_status() -> None:
    result = compiled(BEST_OF)
    record = run_program(result, ["nowhere"], 6)
    assert (record.status, record.result) == (Status.NO_RESULT, None)
    assert record.records[-1].error == (
        "schema 'choose': no alternative of best-of 't1' is applicable "
        "(all 2 preconditions are false)"
    )


def test_a_precondition_must_be_elementary() -> None:
    text = "(defschema c (w)\n  (best-of (when (slow-test w) (steady))))"
    with pytest.raises(SchemaError) as raised:
        compiled(text)
    assert str(raised.value).splitlines()[0] == (
        "<string>:2:19: error: the precondition 'slow-test' must be an elementary function "
        "(it takes no time), but it is an interruptible module"
    )


def expected(profile: ConditionalPerformanceProfile) -> np.ndarray:
    return np.array([float(MID @ profile.distribution([], t)) for t in TIME])


@pytest.mark.parametrize(
    ("text", "p"),
    [
        ("(defschema c (w) (if (cloudy? w) (steady) (gamble) :p 0.25))", 0.25),
        ("(defschema c (w) (if (sunny? w) (steady) (gamble)))", 0.7),
    ],
    ids=["literal-p", "declared-p"],
)
def test_if_compiles_to_the_probability_weighted_mixture(text: str, p: float) -> None:
    result = compiled(text)
    mixture = p * expected(steady()) + (1 - p) * expected(gamble())
    np.testing.assert_allclose(result.expected, mixture, atol=1e-12)
    dist = Evaluator(result.model).evaluate(np.zeros((1, 0)), [[8.0]])
    np.testing.assert_allclose(dist.probs.sum(), 1.0)


def test_if_runs_the_branch_its_condition_selects() -> None:
    result = compiled(
        "(defschema c (w) (if (sunny? w) (steady) (gamble)))", library(steady=0.6, gamble=0.9)
    )
    assert run_program(result, ["sun"], 5).result.value == ("steady", 5.0)
    assert run_program(result, ["rain"], 5).result.value == ("gamble", 5.0)


def test_if_without_a_probability_is_a_compile_error() -> None:
    text = "(defschema c (w)\n  (if (cloudy? w) (steady) (gamble)))"
    with pytest.raises(SchemaError) as raised:
        compiled(text)
    assert str(raised.value).splitlines()[0] == (
        "<string>:2:4: error: the probability of the condition of 'if' is unknown: 'cloudy?' "
        "declares no probability; give it as (if CONDITION THEN ELSE :p P)"
    )


def test_proportional_is_romanenkos_rule() -> None:
    result = compiled(BEST_OF, allocator="proportional")
    # T* = least time with positive expected quality: steady 1, gamble 2 -> shares 1/3, 2/3.
    np.testing.assert_allclose(result.allocation[9], [3.0, 6.0])
    assert result.codes == (Code.PROPORTIONAL, Code.DEPENDENCE)
    optimum = compiled(BEST_OF).expected
    assert np.all(result.expected <= optimum + 1e-12)


def variants_library() -> AnytimeLibrary:
    registry = Registry()

    @elementary("always", inputs=[], registry=registry)
    def always() -> bool:
        return True

    shapes = {
        "quick": DiscreteVariants([(1.5, 0.3), (4, 0.5), (9, 0.6)]),
        "thorough": DiscreteVariants([(3, 0.2), (6.2, 0.9)]),
    }
    for name, family in shapes.items():

        def run(ctx: Context, family: DiscreteVariants = family) -> Result:
            return Result(None, float(family.snapped(1.0)(ctx.allocation)))

        run.__name__ = run.__qualname__ = name
        contract(name, inputs=[], profile=family.profile(1.0, 10), registry=registry)(run)
    return AnytimeLibrary([RegistrySource(registry)])


@pytest.mark.parametrize("allocator", ["auto", "exhaustive"])
def test_discrete_variants_are_optimised_exactly(allocator: str) -> None:
    text = "(defschema c () (best-of (when (always) (quick)) (when (always) (thorough))))"
    lib = variants_library()
    result = compile_program(parse_schemas(text).programs[0], lib, TIME, allocator=allocator)
    quick = DiscreteVariants([(2, 0.3), (4, 0.5), (9, 0.6)])
    thorough = DiscreteVariants([(3, 0.2), (7, 0.9)])
    for total in TIME:
        t = np.arange(total + 1)
        best = np.max(np.maximum(quick(t), thorough(total - t)))
        assert result.expected[int(total)] == pytest.approx(best, abs=1e-12)
