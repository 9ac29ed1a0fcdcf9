"""Anytime vision: the prior below T_a, reproducible and nested errors, the error rate, time."""

import math

import numpy as np
import pytest
from anytime_navigation.task.vision import (
    error_draws,
    fraction_correct,
    prior_map,
    sense,
    sense_progressively,
)
from anytime_navigation.world import World, random_world

from anytime.modules import Context
from anytime.profiles.families import VisionHyperbola

PROFILE = {"t_a": 10.0, "q_a": 0.6, "t_b": 100.0}
CURVE = VisionHyperbola(**PROFILE)


@pytest.fixture(scope="module")
def world() -> World:
    return random_world(128, seed=3, density=0.2)


def sensed(world: World, t: float, seed: int = 7) -> tuple[np.ndarray, float]:
    result = sense(Context(t), world, seed=seed, **PROFILE)
    return result.value, result.quality


def test_same_seed_same_map_other_seed_other_map(world: World) -> None:
    first, _ = sensed(world, 40)
    again, _ = sensed(world, 40)
    other, _ = sensed(world, 40, seed=8)
    assert np.array_equal(first, again)
    assert not np.array_equal(first, other)


def test_errors_are_nested_as_time_grows(world: World) -> None:
    truth = world.blocked
    wrong = [sensed(world, t)[0] != truth for t in (10, 20, 40, 70, 99)]
    for earlier, later in zip(wrong, wrong[1:], strict=False):
        assert not np.any(later & ~earlier)  # a cell correct at t stays correct after
    assert wrong[0].sum() > wrong[-1].sum() > 0


@pytest.mark.parametrize("t", [10.0, 30.0, 60.0, 100.0, 500.0], ids=lambda t: f"t={t:g}")
def test_realised_fraction_within_sampling_error_of_the_model(world: World, t: float) -> None:
    seen, quality = sensed(world, t)
    assert quality == pytest.approx(float(CURVE(t)))
    cells = seen.size
    sigma = math.sqrt(quality * (1 - quality) / cells)
    assert abs(fraction_correct(seen, world) - quality) <= 4 * sigma + 1e-12


@pytest.mark.parametrize("t", [0.0, 5.0, 9.99], ids=lambda t: f"t={t:g}")
def test_below_t_a_the_prior_all_free(world: World, t: float) -> None:
    seen, quality = sensed(world, t)
    assert not seen.any()
    assert quality == pytest.approx(1 - world.blocked.mean())
    assert not seen.flags.writeable


def test_accepts_a_bare_grid(world: World) -> None:
    from_grid = sense(Context(40), np.array(world.blocked), seed=7, **PROFILE)
    assert np.array_equal(from_grid.value, sensed(world, 40)[0])


@pytest.mark.parametrize("allocation", [0.0, 5.0, 10.0, 37.5, 250.0], ids=str)
def test_contract_spends_exactly_its_allocation(world: World, allocation: float) -> None:
    ctx = Context(allocation)
    sense(ctx, world, seed=7, **PROFILE)
    assert ctx.ticks == allocation
    assert ctx.elapsed == pytest.approx(allocation)


def test_unbounded_contract_spends_t_b_for_a_perfect_map(world: World) -> None:
    ctx = Context()
    result = sense(ctx, world, seed=7, **PROFILE)
    assert ctx.ticks == PROFILE["t_b"]
    assert result.quality == 1.0
    assert np.array_equal(result.value, world.blocked)


def test_progressive_yields_better_maps_matching_the_contract(world: World) -> None:
    ctx = Context()
    results = list(sense_progressively(ctx, world, seed=7, steps=8, **PROFILE))
    qualities = [r.quality for r in results]
    assert qualities == sorted(set(qualities))  # strictly increasing
    assert not results[0].value.any()  # the prior comes first
    assert qualities[-1] == 1.0
    assert np.array_equal(results[-1].value, world.blocked)
    assert ctx.ticks == pytest.approx(PROFILE["t_b"])
    # the map at T_a (q_a = 0.6 is below the prior's 0.8) is kept back; a later one is the
    # contract's map for the same time
    assert PROFILE["q_a"] < qualities[0] and PROFILE["q_a"] not in qualities
    times = np.linspace(PROFILE["t_a"], PROFILE["t_b"], 9)[1:]
    by_quality = {float(CURVE(t)): t for t in times}
    for result in results[1:]:
        assert np.array_equal(result.value, sensed(world, by_quality[result.quality])[0])


def test_progressive_below_t_a_keeps_the_prior_and_never_overruns(world: World) -> None:
    ctx = Context(7)
    results = list(sense_progressively(ctx, world, seed=7, **PROFILE))
    assert len(results) == 1 and not results[0].value.any()
    assert ctx.ticks == 7


def test_progressive_with_a_good_first_reading_yields_it_at_t_a() -> None:
    blocked = np.zeros((16, 16), dtype=bool)
    blocked[:8] = True  # the prior is half wrong, so q_a = 0.6 already beats it
    ctx = Context(10)
    results = list(sense_progressively(ctx, blocked, seed=1, **PROFILE))
    assert [r.quality for r in results] == [0.5, pytest.approx(0.6)]
    assert ctx.ticks == 10


def test_prior_and_draws_are_fixed_shapes(world: World) -> None:
    assert prior_map(world).shape == world.blocked.shape
    assert np.array_equal(error_draws((4, 4), 2), error_draws((4, 4), 2))


def test_fraction_correct_rejects_a_map_of_another_shape(world: World) -> None:
    with pytest.raises(ValueError, match=r"the map has shape \(4, 4\), the world \(128, 128\)"):
        fraction_correct(np.zeros((4, 4), dtype=bool), world)
