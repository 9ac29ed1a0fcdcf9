"""Profiles: invariants over random tables (hypothesis), the analytic families, validation."""

import tempfile
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from anytime.errors import ProfileError
from anytime.profiles import (
    ConditionalPerformanceProfile,
    Constant,
    Exponential,
    PerformanceProfile,
    Step,
    VisionHyperbola,
    new_profile,
    point_mass,
    tabulate,
)
from anytime.profiles.io import load_profile, profile_from_dict, save_profile

# --- random valid profiles ---------------------------------------------------------------------

Profile = ConditionalPerformanceProfile
TOLERANCE = 1e-9


def unit(**kwargs: Any) -> st.SearchStrategy[float]:
    return st.floats(0, 1, allow_subnormal=False, **kwargs)


def grid(low: float, high: float, min_size: int, max_size: int) -> st.SearchStrategy[list[float]]:
    """Increasing grids of distinct values in [low, high]."""
    values = st.floats(low, high, allow_subnormal=False)
    return st.lists(values, min_size=min_size, max_size=max_size, unique=True).map(sorted)


@st.composite
def profiles(draw: st.DrawFn, max_inputs: int = 2) -> Profile:
    """Profiles with 0..max_inputs inputs, small grids and random (Dirichlet-like) rows."""
    input_grids = draw(st.lists(grid(0, 1, 1, 3), max_size=max_inputs))
    time = draw(grid(0, 1000, 1, 4))
    bins = draw(grid(0, 1, 2, 5))
    cells = (*map(len, input_grids), len(time))
    weights = draw(arrays(np.float64, (*cells, len(bins) - 1), elements=unit()))
    weights[..., 0] += 1e-3  # no all-zero rows; zeros elsewhere give sparse rows and point masses
    optional = st.none() | st.just(True)

    def table(elements: st.SearchStrategy[float]) -> np.ndarray | None:
        return draw(arrays(np.float64, cells, elements=elements)) if draw(optional) else None

    return Profile(
        input_grids=input_grids,
        inputs=[f"in{i}" for i in range(len(input_grids))] if draw(st.booleans()) else [],
        time=time,
        bins=bins,
        probability=weights / weights.sum(axis=-1, keepdims=True),
        mean=table(unit()),
        std=table(st.floats(0, 0.5)),
        samples=table(st.integers(0, 100).map(float)),
        module=draw(st.sampled_from(["", "plan"])),
        kind=draw(st.sampled_from(["interruptible", "contract"])),
        time_unit=draw(st.sampled_from(["ticks", "seconds"])),
    )


def points(profile: Profile, n: int = 8) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Batches of (q, t), reaching a little outside the grid on every axis."""
    q = arrays(np.float64, (n, profile.n_inputs), elements=st.floats(-0.25, 1.25))
    t = arrays(np.float64, (n,), elements=st.floats(-100, 1200))
    return st.tuples(q, t)


def distributions(k: int, batch: int = 3) -> st.SearchStrategy[np.ndarray]:
    weights = arrays(np.float64, (batch, k), elements=unit())
    return weights.map(lambda w: (w + 1e-3) / (w + 1e-3).sum(axis=-1, keepdims=True))


def grid_points(profile: Profile) -> tuple[np.ndarray, np.ndarray]:
    """Every grid point, shaped like the cells: q (*cells, m) and t (*cells)."""
    mesh = np.meshgrid(*profile.input_grids, profile.time, indexing="ij")
    q = np.stack(mesh[:-1], axis=-1) if profile.n_inputs else np.zeros((*mesh[-1].shape, 0))
    return q, mesh[-1]


def expected_table(profile: Profile) -> np.ndarray:
    return profile.mean if profile.mean is not None else profile.probability @ profile.values


# --- properties ------------------------------------------------------------------------------


@settings(deadline=None)
@given(st.data(), profiles())
def test_rows_sum_to_one_after_interpolation(data: st.DataObject, profile: Profile) -> None:
    q, t = data.draw(points(profile))
    distribution = profile.distribution(q, t)
    assert distribution.shape == (len(t), profile.n_bins)
    assert np.all(distribution >= 0)
    np.testing.assert_allclose(distribution.sum(axis=-1), 1, rtol=0, atol=TOLERANCE)


@settings(deadline=None)
@given(st.data(), profiles())
def test_rows_sum_to_one_after_propagation(data: st.DataObject, profile: Profile) -> None:
    own = [data.draw(distributions(profile.n_bins)) for _ in range(profile.n_inputs)]
    t = data.draw(arrays(np.float64, (3,), elements=st.floats(-100, 1200)))
    out = profile.propagate(own, t)
    assert out.shape == (3, profile.n_bins)
    assert np.all(out >= 0)
    np.testing.assert_allclose(out.sum(axis=-1), 1, rtol=0, atol=TOLERANCE)
    # Inputs whose bins are another profile's: any number of bins, any representative values.
    values = [data.draw(grid(0, 1, 1, 6)) for _ in range(profile.n_inputs)]
    other = [data.draw(distributions(len(v))) for v in values]
    out = profile.propagate(other, t, input_values=values)
    np.testing.assert_allclose(out.sum(axis=-1), 1, rtol=0, atol=TOLERANCE)


@settings(deadline=None)
@given(st.data(), profiles())
def test_representatives_stay_in_their_bins_and_give_the_profiles_mean(
    data: st.DataObject, profile: Profile
) -> None:
    """Where the mean table is one the bins can hold (between the means of the distribution's
    lower and upper bin edges), the bins' representatives reproduce it exactly; never a bin
    midpoint where the profile knows better."""
    q, t = data.draw(points(profile))
    distribution = profile.distribution(q, t)
    values = profile.representatives(q, t)
    assert values.shape == distribution.shape
    lower, upper = profile.bins[:-1], profile.bins[1:]
    assert np.all((values >= lower - 1e-12) & (values <= upper + 1e-12))
    mean = profile.expected(q, t)
    holdable = (distribution @ lower <= mean) & (mean <= distribution @ upper)
    np.testing.assert_allclose(
        np.einsum("nk,nk->n", distribution, values)[holdable], mean[holdable], atol=1e-9
    )
    if profile.mean is None:
        np.testing.assert_array_equal(values, np.broadcast_to(profile.values, values.shape))


@settings(deadline=None)
@given(profiles())
def test_interpolation_at_grid_points_returns_the_table(profile: Profile) -> None:
    q, t = grid_points(profile)
    assert np.array_equal(profile.distribution(q, t), profile.probability)
    assert np.array_equal(profile.expected(q, t), expected_table(profile))


@settings(deadline=None)
@given(st.data(), profiles())
def test_expected_quality_is_within_0_and_1(data: st.DataObject, profile: Profile) -> None:
    q, t = data.draw(points(profile))
    expected = profile.expected(q, t)
    assert np.all((expected >= 0) & (expected <= 1))


@settings(deadline=None)
@given(st.data(), profiles())
def test_outside_the_grid_is_the_value_at_the_nearest_end(
    data: st.DataObject, profile: Profile
) -> None:
    q, t = data.draw(points(profile))
    axes = [*profile.input_grids, profile.time]
    coords = np.concatenate([q, t[:, None]], axis=1)
    # Push some coordinates well beyond either end of their grid.
    beyond = data.draw(arrays(np.int8, coords.shape, elements=st.sampled_from([-1, 0, 1])))
    spans = np.array([max(g[-1] - g[0], 1.0) for g in axes])
    lows, highs = np.array([g[0] for g in axes]), np.array([g[-1] for g in axes])
    coords = np.where(beyond < 0, lows - spans, np.where(beyond > 0, highs + spans, coords))
    ends = np.clip(coords, lows, highs)
    for method in (profile.distribution, profile.expected):
        assert np.array_equal(
            method(coords[:, :-1], coords[:, -1]), method(ends[:, :-1], ends[:, -1])
        )


@settings(deadline=None)
@given(st.data(), profiles(max_inputs=1))
def test_point_mass_profile_is_the_deterministic_curve(
    data: st.DataObject, profile: Profile
) -> None:
    low, high = profile.bins[0], profile.bins[-1]  # a file's `expected:` must lie in the bins
    curve = data.draw(arrays(np.float64, profile.cell_shape, elements=st.floats(low, high)))
    tabulated = tabulate(
        lambda t, *q: curve,
        profile.time,
        bins=profile.bins,
        input_grids=profile.input_grids,
        module="curve",
    )
    from_file = profile_from_dict(
        {
            "format": "anytime-profile/1",
            "inputs": [f"in{i}" for i in range(profile.n_inputs)],
            "input_quality": [g.tolist() for g in profile.input_grids],
            "time": profile.time.tolist(),
            "quality_bins": profile.bins.tolist(),
            "expected": curve.tolist(),
        },
        "curve.yaml",
    )
    q_grid, t_grid = grid_points(profile)
    q, t = data.draw(points(profile))
    for point_mass_profile in (tabulated, from_file):
        # At the grid points: the curve itself, and all the mass in the bin that holds it.
        assert np.array_equal(point_mass_profile.expected(q_grid, t_grid), curve)
        assert np.array_equal(
            point_mass_profile.distribution(q_grid, t_grid), point_mass(curve, profile.bins)
        )
        # Between them: the curve's linear interpolation (time first, then the input).
        rows = curve.reshape(-1, len(profile.time))  # one row per input grid value
        along_time = np.stack([np.interp(t, profile.time, row) for row in rows])
        if profile.n_inputs:
            grid_q = profile.input_grids[0]
            reference = np.array(
                [np.interp(q[i, 0], grid_q, along_time[:, i]) for i in range(len(t))]
            )
        else:
            reference = along_time[0]
        np.testing.assert_allclose(
            point_mass_profile.expected(q, t), reference, rtol=1e-12, atol=1e-12
        )
    assert from_file.mean is not None and np.array_equal(from_file.mean, tabulated.mean)
    assert np.array_equal(from_file.probability, tabulated.probability)


@settings(deadline=None)
@given(st.floats(-100, 1200), profiles())
def test_transition_rows_sum_to_one(t: float, profile: Profile) -> None:
    transition = profile.transition(t)
    assert transition.shape == (profile.n_bins,) * (profile.n_inputs + 1)
    np.testing.assert_allclose(transition.sum(axis=-1), 1, rtol=0, atol=TOLERANCE)


@settings(deadline=None)
@given(st.data(), profiles())
def test_propagating_a_certain_input_is_the_distribution_at_its_bin(
    data: st.DataObject, profile: Profile
) -> None:
    t = data.draw(st.floats(-100, 1200))
    bins = [data.draw(st.integers(0, profile.n_bins - 1)) for _ in range(profile.n_inputs)]
    one_hot = [np.eye(profile.n_bins)[k] for k in bins]
    representative = profile.values[bins]
    np.testing.assert_allclose(
        profile.propagate(one_hot, t),
        profile.distribution(representative, t),
        rtol=0,
        atol=1e-15,
    )
    assert np.array_equal(
        profile.transition(t)[tuple(bins)], profile.distribution(representative, t)
    )


@settings(deadline=None, max_examples=50)
@given(profiles())
def test_the_file_format_keeps_every_profile_exactly(profile: Profile) -> None:
    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / "plan.yaml"
        save_profile(profile, path)
        loaded = load_profile(path)
    # A profile without input axes comes back as a PerformanceProfile with the same fields.
    expected = new_profile(**attrs.asdict(profile, recurse=False))
    assert loaded == (expected if profile.module else attrs.evolve(expected, module="plan"))


# --- analytic families -----------------------------------------------------------------------

TIMES = np.linspace(-5, 50, 221)


def _non_decreasing(values: np.ndarray) -> bool:
    return bool(np.all(np.diff(values) >= 0))


def test_constant_is_flat() -> None:
    assert Constant(0.7)(TIMES).tolist() == [0.7] * len(TIMES)
    assert Constant(0.0)(3.0) == 0.0


def test_exponential_starts_at_0_and_rises_to_q_max() -> None:
    curve = Exponential(0.1, q_max=0.8)
    assert curve(0) == 0.0
    assert curve(-3) == 0.0  # no negative time
    assert curve(10) == pytest.approx(0.8 * (1 - np.exp(-1)), rel=1e-15)
    assert curve(1e4) == 0.8
    assert _non_decreasing(curve(TIMES))
    assert np.all(np.diff(curve(TIMES[TIMES >= 0])) > 0)


def test_step_takes_the_best_variant_that_fits() -> None:
    curve = Step([(10, 0.5), (5, 0.2), (20, 0.4)])  # any order; a slower, worse variant
    assert curve.variants == ((5.0, 0.2), (10.0, 0.5), (20.0, 0.4))
    assert curve([0, 4.99, 5, 9.99, 10, 20, 100]).tolist() == [0, 0, 0.2, 0.2, 0.5, 0.5, 0.5]
    assert _non_decreasing(curve(TIMES))


def test_vision_hyperbola_nothing_before_t_a_then_q_a_rising_to_1_at_t_b() -> None:
    for q_a in (0.0, 0.3, 0.7, 1.0):
        curve = VisionHyperbola(t_a=2, q_a=q_a, t_b=9)
        assert curve([-1, 0, 1.999]).tolist() == [0, 0, 0]
        assert curve(2) == q_a
        assert curve(9) == 1.0
        assert curve([9.5, 100]).tolist() == [1, 1]
        assert _non_decreasing(curve(TIMES))
        between = curve(np.linspace(2, 9, 50))
        assert np.all(np.diff(between, 2) <= 1e-12)  # concave: fast early gains


def test_tabulated_family_is_a_point_mass_per_cell() -> None:
    curve = VisionHyperbola(t_a=2, q_a=0.3, t_b=9)
    profile = tabulate(curve, [0, 2, 5, 9], bins=[0, 0.25, 0.5, 0.75, 1], module="vision")
    assert profile.mean is not None and np.array_equal(profile.mean, curve([0, 2, 5, 9]))
    assert profile.probability.argmax(axis=-1).tolist() == [0, 1, 3, 3]


FAMILY_ERRORS = {
    "constant-above-1": (lambda: Constant(1.5), "constant: quality must be in [0, 1], got 1.5"),
    "exponential-rate-0": (lambda: Exponential(0), "exponential: rate must be > 0, got 0"),
    "exponential-q-max-0": (
        lambda: Exponential(1, q_max=0),
        "exponential: q_max must be in (0, 1], got 0",
    ),
    "step-empty": (lambda: Step([]), "step: needs at least one (time, quality) variant"),
    "step-quality-above-1": (
        lambda: Step([(1, 2)]),
        "step: variant (1.0, 2.0) outside time >= 0, [0, 1]",
    ),
    "vision-t-b-before-t-a": (
        lambda: VisionHyperbola(t_a=5, q_a=0.3, t_b=5),
        "vision: need 0 <= t_a < t_b, got 5, 5",
    ),
    "vision-flat-curvature": (
        lambda: VisionHyperbola(t_a=1, q_a=0.3, t_b=5, k=0),
        "vision: curvature k must be > 0, got 0",
    ),
    "tabulate-outside-0-1": (
        lambda: tabulate(lambda t: t, [0, 2], module="m"),
        "m: the curve gives qualities outside [0, 1]",
    ),
}


@pytest.mark.parametrize(("make", "message"), FAMILY_ERRORS.values(), ids=FAMILY_ERRORS.keys())
def test_family_errors(make: Any, message: str) -> None:
    with pytest.raises(ProfileError) as caught:
        make()
    assert str(caught.value) == message


# --- validation of the class -----------------------------------------------------------------

VALID: dict[str, Any] = {
    "input_grids": [[0.5, 1]],
    "time": [0, 10],
    "bins": [0, 0.5, 1],
    "probability": [[[1, 0], [0.5, 0.5]], [[1, 0], [0, 1]]],
}

INVALID = {
    "probability-shape": (
        {"probability": [[1, 0], [0.5, 0.5]]},
        "profile: probability: expected shape [2, 2, 2], got [2, 2]",
    ),
    "probability-negative": (
        {"probability": [[[1, 0], [1.5, -0.5]], [[1, 0], [0, 1]]]},
        "profile: probability: expected finite numbers >= 0, got -0.5",
    ),
    "probability-nan": (
        {"probability": [[[1, 0], [np.nan, 1]], [[1, 0], [0, 1]]]},
        "profile: probability: expected finite numbers >= 0, got nan",
    ),
    "row-sum": (
        {"probability": [[[1, 0], [0.5, 0.5]], [[1, 0], [0, 0.9]]]},
        "profile: probability[1][1]: expected a row summing to 1 (within 1e-06), got 0.9",
    ),
    "time-decreasing": (
        {"time": [10, 0]},
        "profile: time: expected increasing values, got 10 then 0",
    ),
    "time-negative": ({"time": [-1, 10]}, "profile: time: expected numbers >= 0, got -1"),
    "time-infinite": (
        {"time": [0, np.inf]},
        "profile: time: expected finite numbers, got NaN or infinity",
    ),
    "one-bin-edge": (
        {"bins": [0], "probability": np.ones((2, 2, 0))},
        "profile: quality_bins: expected a list of at least 2 number(s), got shape [1]",
    ),
    "bins-above-1": (
        {"bins": [0, 0.5, 1.5]},
        "profile: quality_bins: expected qualities in [0, 1], got 1.5",
    ),
    "input-grid-not-1d": (
        {"input_grids": [[[0.5, 1]]]},
        "profile: input_quality[0]: expected a list of at least 1 number(s), got shape [1, 2]",
    ),
    "inputs-count": (
        {"inputs": ["map", "goal"], "module": "plan"},
        "plan: inputs: expected one name per input grid (1), got 2",
    ),
    "mean-shape": ({"mean": [0.5, 1]}, "profile: mean: expected shape [2, 2], got [2]"),
    "mean-above-1": (
        {"mean": [[0, 0.5], [0, 1.5]]},
        "profile: mean: expected qualities in [0, 1], got 1.5",
    ),
    "samples-negative": (
        {"samples": [[1, 1], [1, -1]]},
        "profile: samples: expected finite numbers >= 0, got -1",
    ),
    "kind": (
        {"kind": "sometimes"},
        "profile: kind: expected 'interruptible' or 'contract', got 'sometimes'",
    ),
    "time-unit": (
        {"time_unit": "ms"},
        "profile: time_unit: expected 'ticks' or 'seconds', got 'ms'",
    ),
}


@pytest.mark.parametrize(("change", "message"), INVALID.values(), ids=INVALID.keys())
def test_invalid_profile_is_refused(change: dict[str, Any], message: str) -> None:
    with pytest.raises(ProfileError) as caught:
        Profile(**(VALID | change))
    assert str(caught.value) == message


def test_valid_profile_is_frozen_hashable_and_compares_by_value() -> None:
    a, b = Profile(**VALID), Profile(**VALID)
    assert a == b and hash(a) == hash(b)
    assert not a.probability.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        a.probability[0, 0, 0] = 0.5


def test_performance_profile_reads_by_time() -> None:
    profile = PerformanceProfile(time=[0, 10], bins=[0, 0.5, 1], probability=[[1, 0], [0, 1]])
    assert profile.at(5).tolist() == [0.5, 0.5]
    assert profile.expected_at([0, 5, 10]).tolist() == [0.25, 0.5, 0.75]


def test_propagate_names_a_wrong_number_of_inputs() -> None:
    with pytest.raises(ProfileError) as caught:
        Profile(**VALID, module="plan").propagate([], 5)
    assert str(caught.value) == "plan: expected 1 input distributions, got 0"


def test_standard_error_of_a_measured_profile() -> None:
    profile = Profile(**VALID, samples=[[4, 4], [4, 100]], std=[[0, 0.2], [0, 0.5]])
    assert profile.standard_error([[1.0], [0.5]], [10, 10]).tolist() == [0.05, 0.1]
    assert Profile(**VALID).standard_error([[1.0]], [10]).tolist() == [0.0]
