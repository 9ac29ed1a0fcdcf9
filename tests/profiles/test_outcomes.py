"""No result and bin means: what a measured profile knows beyond its histogram.

`no_result_table` (file key `no_result`): per cell, the probability that the module has no
result, an outcome of its own (downstream modules are not run on a missing input), counted as
quality 0 in the first bin. `bin_mean`: per bin of each cell, the mean quality of the trials
that fell in it, which the bins' representatives reproduce exactly.
"""

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
from conftest import Cli
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from anytime.errors import ProfileError
from anytime.measure.builder import Instance, build_profile
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.profiles import ConditionalPerformanceProfile, new_profile, tabulate
from anytime.profiles.io import load_profile, profile_from_dict, profile_to_dict, save_profile

Profile = ConditionalPerformanceProfile


# --- random measured-like profiles -----------------------------------------------------------


def unit() -> st.SearchStrategy[float]:
    return st.floats(0, 1, allow_subnormal=False)


def grid(low: float, high: float, min_size: int, max_size: int) -> st.SearchStrategy[list[float]]:
    values = st.floats(low, high, allow_subnormal=False)
    return st.lists(values, min_size=min_size, max_size=max_size, unique=True).map(sorted)


def bin_edges(bins: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The qualities each bin holds: the first reaches down to 0, the last up to 1."""
    return np.concatenate(([0.0], bins[1:-1])), np.concatenate((bins[1:-1], [1.0]))


@st.composite
def measured(draw: st.DrawFn, max_inputs: int = 2) -> Profile:
    """Profiles as the builder makes them: sparse rows, bin means anywhere in their bins (at an
    edge now and then), the mean they imply, and no result for part of the first bin's mass."""
    input_grids = draw(st.lists(grid(0, 1, 1, 3), max_size=max_inputs))
    time = draw(grid(0, 1000, 1, 4))
    bins = np.array(draw(grid(0, 1, 2, 5)))
    cells = (*map(len, input_grids), len(time))
    shape = (*cells, len(bins) - 1)
    weights = draw(arrays(np.float64, shape, elements=unit()))
    weights[..., 0] += 1e-3  # no all-zero rows; zeros elsewhere give sparse rows
    probability = weights / weights.sum(axis=-1, keepdims=True)
    lower, upper = bin_edges(bins)
    where = draw(arrays(np.float64, shape, elements=st.sampled_from([0.0, 1.0]) | unit()))
    bin_mean = np.clip(lower + where * (upper - lower), lower, upper)
    share = draw(arrays(np.float64, cells, elements=st.sampled_from([0.0, 1.0]) | unit()))
    mean = np.einsum("...k,...k->...", probability, bin_mean)
    return new_profile(
        input_grids=input_grids,
        time=time,
        bins=bins,
        probability=probability,
        mean=np.clip(mean, 0, 1) if draw(st.booleans()) else None,
        bin_mean=bin_mean,
        no_result_table=np.minimum(share * probability[..., 0], 1.0),
        module=draw(st.sampled_from(["", "plan"])),
    )


def points(profile: Profile, n: int = 8) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Batches of (q, t): grid points, and points reaching a little outside the grid."""
    q = arrays(np.float64, (n, profile.n_inputs), elements=st.floats(-0.25, 1.25))
    t = arrays(np.float64, (n,), elements=st.floats(-100, 1200))
    return st.tuples(q, t)


# --- bin means -------------------------------------------------------------------------------


@settings(deadline=None)
@given(st.data(), measured())
def test_interpolated_representatives_reproduce_the_interpolated_mean(
    data: st.DataObject, profile: Profile
) -> None:
    q, t = data.draw(points(profile))
    distribution = profile.distribution(q, t)
    values = profile.representatives(q, t)
    lower, upper = bin_edges(profile.bins)
    assert np.all((values >= lower - 1e-12) & (values <= upper + 1e-12))
    np.testing.assert_allclose(
        np.einsum("nk,nk->n", distribution, values), profile.expected(q, t), rtol=0, atol=1e-12
    )
    # Each bin stands for the mass-weighted mean of the interpolated cells' bin means.
    assert profile.bin_mean is not None
    moments = profile.interpolate(profile.probability * profile.bin_mean, q, t)
    held = distribution > 1e-9  # below, the quotient is rounding noise (and carries no mass)
    np.testing.assert_allclose(values[held], (moments / np.where(held, distribution, 1))[held])


@settings(deadline=None)
@given(st.data(), measured(max_inputs=1))
def test_at_grid_points_representatives_are_the_measured_bin_means(
    data: st.DataObject, profile: Profile
) -> None:
    mesh = np.meshgrid(*profile.input_grids, profile.time, indexing="ij")
    q = np.stack(mesh[:-1], axis=-1) if profile.n_inputs else np.zeros((*mesh[-1].shape, 0))
    values = profile.representatives(q, mesh[-1])
    assert profile.bin_mean is not None
    held = profile.probability > 0
    assert np.array_equal(values[held], profile.bin_mean[held])


@settings(deadline=None)
@given(st.data(), st.sampled_from([0.0, 1.0]), grid(0, 1, 2, 6), grid(0, 1000, 1, 4))
def test_point_masses_at_0_and_1_are_represented_exactly(
    data: st.DataObject, quality: float, edges: list[float], time: list[float]
) -> None:
    """Everywhere, between grid points too: the same bin in every cell, with the same mean."""
    bins = np.array(edges)
    k = 0 if quality == 0 else len(bins) - 2
    probability = np.zeros((len(time), len(bins) - 1))
    probability[:, k] = 1
    bin_mean = np.broadcast_to((bins[:-1] + bins[1:]) / 2, probability.shape).copy()
    bin_mean[:, k] = quality
    profile = new_profile(
        time=time,
        bins=bins,
        probability=probability,
        mean=np.full(len(time), quality),
        bin_mean=bin_mean,
    )
    t = data.draw(arrays(np.float64, (8,), elements=st.floats(-100, 1200)))
    q = np.zeros((8, 0))
    values = profile.representatives(q, t)
    assert np.all(values[:, k] == quality)
    assert np.all(np.einsum("nk,nk->n", profile.distribution(q, t), values) == quality)


def test_a_two_outcome_module_stands_for_exactly_its_two_qualities() -> None:
    """60% quality 1.0, 40% no result, in ten equal bins: {0, 1}, not {0.06, 0.96}; so the
    expected maximum of two independent ones (a best-of) is 1 - 0.4^2."""
    probability = np.zeros((1, 10))
    probability[0, [0, 9]] = [0.4, 0.6]
    midpoints = np.arange(10) / 10 + 0.05
    bin_mean = np.where(np.arange(10) == 9, 1.0, np.where(np.arange(10) == 0, 0.0, midpoints))
    two = dict(time=[4], bins=np.linspace(0, 1, 11), probability=probability, mean=[0.6])
    exact = new_profile(**two, bin_mean=[bin_mean], no_result_table=[0.4])
    values = exact.representatives(np.zeros((0,)), 4.0)
    assert (values[0], values[9]) == (0.0, 1.0)
    best_of = 1 - (1 - 0.6) ** 2
    assert 0.6 * 0.6 * values[9] + 2 * 0.6 * 0.4 * max(values[0], values[9]) == best_of
    # Without bin means the one common shift cannot hold both: exact in the mean only.
    shifted = new_profile(**two).representatives(np.zeros((0,)), 4.0)
    assert (round(shifted[0], 12), round(shifted[9], 12)) == (0.06, 0.96)
    assert float(probability[0] @ shifted) == pytest.approx(0.6, abs=1e-15)
    assert 0.36 * shifted[9] + 0.48 * max(shifted) + 0.16 * shifted[0] < best_of - 0.009


def test_without_a_mean_table_the_bin_means_give_the_expected_quality() -> None:
    profile = new_profile(
        time=[0, 10], bins=[0, 0.5, 1], probability=[[1, 0], [0.5, 0.5]],
        bin_mean=[[0, 0.75], [0.2, 0.9]],
    )  # fmt: skip
    assert profile.expected_at([0, 10, 5]).tolist() == [0.0, 0.55, 0.275]
    assert profile.representatives(np.zeros((0,)), 5.0).tolist() == [
        pytest.approx(0.2 * 0.25 / 0.75),
        0.9,
    ]


# --- no result -------------------------------------------------------------------------------


@settings(deadline=None, max_examples=50)
@given(measured())
def test_no_result_and_bin_means_round_trip_through_the_file(profile: Profile) -> None:
    data = profile_to_dict(profile)
    assert ("no_result" in data) == (profile.no_result_table is not None)
    assert "bin_mean" in data
    loaded = profile_from_dict(data, "plan.yaml")
    assert loaded == (profile if profile.module else attrs.evolve(profile, module="plan"))
    assert _same_or_both_none(loaded.no_result_table, profile.no_result_table)
    assert _same_or_both_none(loaded.bin_mean, profile.bin_mean)


def _same_or_both_none(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))


@settings(deadline=None)
@given(st.data(), measured())
def test_no_result_interpolates_within_0_and_1_and_within_the_first_bin(
    data: st.DataObject, profile: Profile
) -> None:
    q, t = data.draw(points(profile))
    missing = profile.no_result(q, t)
    assert missing.shape == t.shape
    assert np.all((missing >= 0) & (missing <= 1))
    assert np.all(missing <= profile.distribution(q, t)[:, 0] + 1e-12)
    table = profile.no_result_table
    expected = np.zeros(t.shape) if table is None else profile.interpolate(table, q, t)
    assert np.array_equal(missing, expected)


def test_a_profile_without_the_table_has_no_result_nowhere() -> None:
    profile = tabulate(lambda t: t / 10, time=[0, 10])
    assert profile.no_result_table is None
    assert profile.no_result(np.zeros((2, 3, 0)), np.full((2, 3), 5.0)).tolist() == [[0.0] * 3] * 2


def test_a_table_of_zeros_is_kept_as_none_and_not_written(tmp_path: Path) -> None:
    base = dict(time=[0, 10], bins=[0, 0.5, 1], probability=[[1, 0], [0, 1]])
    zeros = new_profile(**base, no_result_table=[0, 0])
    assert zeros.no_result_table is None and zeros == new_profile(**base)
    save_profile(zeros, tmp_path / "m.yaml")
    assert "no_result" not in (tmp_path / "m.yaml").read_text()
    some = new_profile(**base, no_result_table=[0.25, 0])
    save_profile(some, tmp_path / "m.yaml")
    assert "no_result: [0.25, 0]\n" in (tmp_path / "m.yaml").read_text()
    assert load_profile(tmp_path / "m.yaml") == attrs.evolve(some, module="m")


def test_library_show_says_where_a_module_may_have_no_result(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "profiles").mkdir()
    label = new_profile(
        time=[0, 4, 8], bins=[0, 0.5, 1], probability=[[1, 0], [0.4, 0.6], [0.4, 0.6]],
        mean=[0, 0.6, 0.6], bin_mean=[[0, 0.75], [0, 1], [0, 1]], no_result_table=[1, 0.4, 0.4],
        module="read-label",
    )  # fmt: skip
    save_profile(label, "profiles/read-label.yaml")
    save_profile(attrs.evolve(label, no_result_table=None, module="ok"), "profiles/ok.yaml")
    code, out, err = cli("library", "show", "read-label", "--no-plugins", "--profiles", "profiles")
    assert (code, err) == (0, "")
    assert (
        "  quality bins  0, 0.5, 1 (2 bins)\n  no result     in 3 of 3 cells, probability up to 1\n"
        in out
    )
    code, out, err = cli("library", "show", "ok", "--no-plugins", "--profiles", "profiles")
    assert (code, err) == (0, "") and "no result" not in out


def test_an_old_file_loads_without_either_table() -> None:
    profile = load_profile(Path(__file__).parent / "data" / "find-path.yaml")
    assert profile.no_result_table is None and profile.bin_mean is None
    assert profile.no_result([[0.9]], [100]).tolist() == [0.0]


def test_a_point_mass_profile_with_bin_means_keeps_the_probability_form(tmp_path: Path) -> None:
    """The `expected:` form cannot carry bin means; a measured deterministic module keeps them."""
    profile = new_profile(
        time=[0, 10], bins=[0, 0.5, 1], probability=[[1, 0], [0, 1]], mean=[0, 0.8],
        bin_mean=[[0, 0.75], [0.25, 0.8]], no_result_table=[1, 0], module="m",
    )  # fmt: skip
    save_profile(profile, tmp_path / "m.yaml")
    text = (tmp_path / "m.yaml").read_text()
    assert "expected:" not in text and "probability:" in text
    assert text.endswith(
        "mean: [0, 0.8]\nbin_mean:\n  - [0, 0.75]\n  - [0.25, 0.8]\nno_result: [1, 0]\n"
    )
    assert load_profile(tmp_path / "m.yaml") == profile


def test_no_result_goes_with_the_expected_form(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(
        "format: anytime-profile/1\ntime: [0, 10]\nquality_bins: [0, 0.5, 1]\n"
        "expected: [0, 0.9]\nno_result: [1, 0]\n"
    )
    profile = load_profile(path)
    assert profile.no_result_table is not None and profile.no_result_table.tolist() == [1, 0]
    save_profile(profile, path)
    assert path.read_text().endswith("expected: [0, 0.9]\nno_result: [1, 0]\n")


# --- the builder records both ----------------------------------------------------------------

TOYS = Registry()


@interruptible("late", inputs=[], registry=TOYS)
def late(ctx: Context, ready: int) -> Iterator[Result]:
    """No result before `ready` ticks, then quality exactly 1."""
    ctx.tick(ready)
    yield Result(1.0, 1.0)


@contract("late-contract", inputs=[], registry=TOYS)
def late_contract(ctx: Context, ready: int) -> Result | None:
    ctx.tick(min(ctx.allocation, ready))
    return Result(1.0, 1.0) if ctx.allocation >= ready else None


class Ready:
    def __init__(self, ready: int) -> None:
        self.ready = ready

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance([self.ready])

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


@settings(deadline=None, max_examples=25)
@given(
    st.sampled_from(["late", "late-contract"]),
    st.integers(1, 30),
    st.lists(st.integers(0, 40), min_size=1, max_size=6, unique=True).map(sorted),
    st.integers(2, 11).map(lambda k: np.linspace(0, 1, k)),
)
def test_a_module_with_no_result_then_quality_1_is_recorded_exactly(
    name: str, ready: int, time: list[int], bins: np.ndarray
) -> None:
    module = late if name == "late" else late_contract
    build = build_profile(module, Ready(ready), time=time, bins=bins, trials=3, progress=False)
    profile = build.profile
    before = np.array(time) < ready
    k = len(bins) - 2
    assert profile.bin_mean is not None and profile.mean is not None
    if before.any():
        assert profile.no_result_table is not None
        assert profile.no_result_table.tolist() == before.astype(float).tolist()
    else:  # a result at every grid time: kept as None, and not written to the file
        assert profile.no_result_table is None
        assert "no_result" not in profile_to_dict(profile)
    assert np.all(profile.bin_mean[before, 0] == 0.0)
    assert np.all(profile.bin_mean[~before, k] == 1.0)
    assert profile.mean.tolist() == (~before).astype(float).tolist()
    values = profile.representatives(np.zeros((len(time), 0)), time)
    assert np.all(values[before, 0] == 0.0) and np.all(values[~before, k] == 1.0)


def test_a_result_of_quality_0_is_a_result() -> None:
    """Quality 0 and no result share the first bin; only the second counts as no result."""

    @interruptible("zero-first", inputs=[], registry=Registry())
    def zero_first(ctx: Context, ready: int) -> Iterator[Result]:
        ctx.tick(2)
        yield Result(0.0, 0.0)
        ctx.tick(ready)
        yield Result(1.0, 1.0)

    profile = build_profile(zero_first, Ready(8), time=[0, 2, 10], trials=2).profile
    assert profile.probability[:, 0].tolist() == [1, 1, 0]
    assert profile.no_result_table is not None
    assert profile.no_result_table.tolist() == [1, 0, 0]


@contract("fails-late", inputs=[], registry=TOYS)
def fails_late(ctx: Context, ready: int) -> Result:
    ctx.tick(ctx.allocation)
    if ctx.allocation < ready:
        raise RuntimeError("not yet")
    return Result(0.5, 0.5)


def test_a_failed_contract_run_has_no_result() -> None:
    build = build_profile(fails_late, Ready(10), time=[0, 5, 10], trials=4)
    assert build.failures == 8
    assert build.profile.no_result_table is not None
    assert build.profile.no_result_table.tolist() == [1, 1, 0]
    assert build.profile.bin_mean is not None
    assert build.profile.bin_mean[:, 5].tolist() == [0.55, 0.55, 0.5]  # a midpoint where empty


def test_bin_means_of_a_noisy_module_agree_with_its_mean() -> None:
    @interruptible("noisy", inputs=[], registry=Registry())
    def noisy(ctx: Context, rng: np.random.Generator) -> Iterator[Result]:
        while True:
            ctx.tick(1)
            value = float(rng.random()) ** 2
            yield Result(value, value)

    class Stream:
        def instance(self, rng: np.random.Generator, qualities: tuple[float, ...]) -> Instance:
            return Instance([rng])

        def score(self, instance: Instance, value: Any) -> float:
            return float(value)

    profile = build_profile(noisy, Stream(), time=[0, 1, 3], trials=200).profile
    assert profile.bin_mean is not None and profile.mean is not None
    implied = np.einsum("tk,tk->t", profile.probability, profile.bin_mean)
    np.testing.assert_allclose(implied, profile.mean, rtol=0, atol=1e-15)
    lower, upper = bin_edges(profile.bins)
    assert np.all((profile.bin_mean >= lower) & (profile.bin_mean <= upper))


# --- validation ------------------------------------------------------------------------------

VALID: dict[str, Any] = {
    "input_grids": [[0.5, 1]],
    "time": [0, 10],
    "bins": [0, 0.5, 1],
    "probability": [[[1, 0], [0.5, 0.5]], [[1, 0], [0, 1]]],
}

INVALID = {
    "no-result-shape": (
        {"no_result_table": [0, 1]},
        "profile: no_result: expected shape [2, 2], got [2]",
    ),
    "no-result-above-1": (
        {"no_result_table": [[1, 0], [1.5, 0]]},
        "profile: no_result[1][0]: expected a probability in [0, 1], got 1.5",
    ),
    "no-result-negative": (
        {"no_result_table": [[1, -0.5], [0, 0]]},
        "profile: no_result[0][1]: expected a probability in [0, 1], got -0.5",
    ),
    "no-result-nan": (
        {"no_result_table": [[1, 0], [0, np.nan]]},
        "profile: no_result[1][1]: expected a probability in [0, 1], got nan",
    ),
    "no-result-beyond-the-first-bin": (
        {"no_result_table": [[1, 0.75], [0, 0]], "module": "plan"},
        "plan: no_result[0][1]: expected at most the first bin's probability,"
        " probability[0][1][0] = 0.5, which counts every trial without a result (within 1e-06),"
        " got 0.75",
    ),
    "bin-mean-shape": (
        {"bin_mean": [[0, 1], [0, 1]]},
        "profile: bin_mean: expected shape [2, 2, 2], got [2, 2]",
    ),
    "bin-mean-outside-its-bin": (
        {"bin_mean": [[[0, 0.75], [0.25, 0.75]], [[0.25, 0.75], [0.25, 0.4]]]},
        "profile: bin_mean[1][1][1]: expected a quality within bin 1, [0.5, 1], got 0.4",
    ),
    "bin-mean-above-1": (
        {"bin_mean": [[[0, 1.25], [0.25, 0.75]], [[0.25, 0.75], [0.25, 1]]]},
        "profile: bin_mean[0][0][1]: expected a quality within bin 1, [0.5, 1], got 1.25",
    ),
    "bin-mean-infinite": (
        {"bin_mean": [[[0, 0.75], [0.25, 0.75]], [[-np.inf, 0.75], [0.25, 1]]]},
        "profile: bin_mean[1][0][0]: expected a quality within bin 0, [0, 0.5], got -inf",
    ),
    "bin-mean-against-mean": (
        {
            "bin_mean": [[[0, 0.75], [0.25, 0.75]], [[0.25, 0.75], [0.25, 1]]],
            "mean": [[0, 0.5], [0.25, 0.9]],
        },
        "profile: bin_mean[1][1]: expected bin means whose mean over the bins is mean[1][1] ="
        " 0.9 (within 1e-06), got 1",
    ),
}


@pytest.mark.parametrize(("change", "message"), INVALID.values(), ids=INVALID.keys())
def test_invalid_tables_are_refused(change: dict[str, Any], message: str) -> None:
    with pytest.raises(ProfileError) as caught:
        Profile(**(VALID | change))
    assert str(caught.value) == message


def test_tables_within_the_tolerance_are_accepted() -> None:
    profile = Profile(
        **VALID,
        no_result_table=[[1, 0.5 + 1e-7], [0, 0]],
        bin_mean=[[[0, 0.75], [0.25, 0.75]], [[0.25, 0.75], [0.25, 1]]],
        mean=[[0, 0.5 + 1e-7], [0.25, 1 - 1e-7]],
    )
    assert profile.no_result_table is not None


def test_the_first_and_last_bins_reach_0_and_1_when_the_edges_do_not() -> None:
    """As `point_mass` and the builder place them: below the first edge is the first bin."""
    profile = new_profile(
        time=[0], bins=[0.2, 0.5, 0.8], probability=[[0.5, 0.5]], bin_mean=[[0.0, 1.0]],
        mean=[0.5], no_result_table=[0.5],
    )  # fmt: skip
    assert profile.representatives(np.zeros((0,)), 0.0).tolist() == [0.0, 1.0]


FILE = (
    "format: anytime-profile/1\ntime: [0, 10]\nquality_bins: [0, 0.5, 1]\n"
    "probability: [[1, 0], [0.5, 0.5]]\n"
)

MALFORMED = {
    "no-result-not-a-list": (
        FILE + "no_result: 0.5\n",
        ": no_result: expected a list of 2 numbers (one per time), got 0.5",
    ),
    "no-result-string": (
        FILE + "no_result: [0, '1e-3']\n",
        ": no_result[1]: expected a number, got '1e-3' (YAML reads it as a string: write a dot"
        " and a signed exponent, as in 1.0e+3)",
    ),
    "no-result-negative": (
        FILE + "no_result: [0, -0.25]\n",
        ": no_result[1]: expected a number >= 0, got -0.25",
    ),
    "no-result-above-1": (
        FILE + "no_result: [1.5, 0]\n",
        ": no_result[0]: expected a probability in [0, 1], got 1.5",
    ),
    "no-result-beyond-the-first-bin": (
        FILE + "no_result: [1, 0.75]\n",
        ": no_result[1]: expected at most the first bin's probability, probability[1][0] = 0.5,"
        " which counts every trial without a result (within 1e-06), got 0.75",
    ),
    "bin-mean-row": (
        FILE + "bin_mean: [[0, 0.75], [0.25]]\n",
        ": bin_mean[1]: expected a list of 2 numbers (one per quality bin), got a list of 1",
    ),
    "bin-mean-outside-its-bin": (
        FILE + "bin_mean: [[0, 0.75], [0.625, 0.75]]\n",
        ": bin_mean[1][0]: expected a quality within bin 0, [0, 0.5], got 0.625",
    ),
    "bin-mean-against-mean": (
        FILE + "mean: [0, 0.5]\nbin_mean: [[0, 0.75], [0.25, 0.875]]\n",
        ": bin_mean[1]: expected bin means whose mean over the bins is mean[1] = 0.5 (within"
        " 1e-06), got 0.5625",
    ),
    "bin-mean-with-expected": (
        FILE.replace("probability: [[1, 0], [0.5, 0.5]]", "expected: [0, 0.5]")
        + "bin_mean: [[0, 0.75], [0.25, 0.75]]\n",
        ": bin_mean: not allowed next to expected, whose point masses stand for their quality"
        " (expected bin_mean only with probability, got both)",
    ),
}


@pytest.mark.parametrize(("text", "message"), MALFORMED.values(), ids=MALFORMED.keys())
def test_malformed_tables_in_a_file_name_the_file_and_the_cell(
    tmp_path: Path, text: str, message: str
) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    with pytest.raises(ProfileError) as caught:
        load_profile(path)
    assert str(caught.value) == f"{path}{message}"
