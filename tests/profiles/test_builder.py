"""The profile builder: it recovers known profiles, measures time right, survives failing
modules, and gives the same profile whatever runs the trials."""

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.stats import norm

import anytime.problems
from anytime.measure import builder
from anytime.measure.builder import (
    BuildError,
    Instance,
    MissingExtraError,
    ProfileBuild,
    ProfileRequest,
    build_profile,
    dask_executor,
    profile_module,
    register_problems,
    registered_problems,
)
from anytime.modules import Context, Registry, Result, contract, elementary, interruptible
from anytime.profiles.io import save_profile
from anytime.runtime.modes import SOFT, Hard, Isolated, RunMode

# Toy modules live at the top level of this file: worker processes import them by reference.
TOYS = Registry()
RATE = 50.0  # quality = input quality * (1 - exp(-t / RATE)), plus noise
NOISE = 0.1
STEP = 5  # the interruptible toy yields every STEP ticks


def curve(t: Any, q: Any) -> Any:
    return np.asarray(q) * -np.expm1(-np.asarray(t, dtype=float) / RATE)


def clipped_mean(mu: Any, sigma: float = NOISE) -> Any:
    """E[clip(mu + sigma Z, 0, 1)] for a standard normal Z."""
    a, b = (0 - mu) / sigma, (1 - mu) / sigma
    inside = mu * (norm.cdf(b) - norm.cdf(a)) + sigma * (norm.pdf(a) - norm.pdf(b))
    return inside + norm.sf(b)


def noisy(mu: float, rng: np.random.Generator) -> float:
    return float(np.clip(mu + rng.normal(0, NOISE), 0, 1))


@interruptible("approach", inputs=["x"], registry=TOYS)
def approach(ctx: Context, x: Result, rng: np.random.Generator) -> Iterator[Result]:
    while not ctx.expired:
        ctx.tick(STEP)
        value = noisy(float(curve(ctx.elapsed, x.quality)), rng)
        yield Result(value, value)


@contract("estimate", inputs=["a", "b"], registry=TOYS)
def estimate(ctx: Context, a: Result, b: Result, rng: np.random.Generator) -> Result:
    ctx.tick(ctx.allocation)
    value = noisy(float(curve(ctx.allocation, min(a.quality, b.quality))), rng)
    return Result(value, value)


class NoisyProblems:
    """Instances are just a random stream; the output value is its own true quality."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        # Plain values for the quality-carrying inputs: the builder wraps them as Results.
        return Instance((*(f"input at {q}" for q in input_qualities), rng))

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


TIME = [0, 12, 25, 50, 100, 200]


def within_sampling_error(build: ProfileBuild, truth: Any) -> None:
    p = build.profile
    assert p.samples is not None and p.std is not None and p.mean is not None
    se = p.std / np.sqrt(p.samples)
    error = np.abs(p.mean - truth)
    assert np.all(error <= 4 * se + 1e-12), np.max(error / np.maximum(se, 1e-12))
    assert np.mean(error <= se + 1e-12) >= 0.5  # about 68% expected
    np.testing.assert_allclose(p.probability.sum(axis=-1), 1.0, atol=1e-12)
    assert np.all(p.samples == build.trials)


def test_an_interruptible_profile_recovers_the_analytic_curve() -> None:
    grid_q = [0.4, 0.7, 1.0]
    build = build_profile(
        approach, NoisyProblems(), time=TIME, input_grids=[grid_q], trials=300, seed=1
    )
    p = build.profile
    assert (p.module, p.kind, p.inputs, p.time_unit) == (
        "approach",
        "interruptible",
        ("x",),
        "ticks",
    )
    assert p.probability.shape == (3, len(TIME), 10)
    assert (build.runs, build.failures, build.overruns) == (900, 0, 0)
    # At grid time t the answer is the one yielded at the last multiple of STEP <= t, and
    # before the first yield there is no answer at all (quality 0, exactly).
    last_yield = np.floor(np.array(TIME) / STEP) * STEP
    q, t = np.meshgrid(grid_q, last_yield, indexing="ij")
    truth = np.where(t == 0, 0.0, clipped_mean(curve(t, q)))
    within_sampling_error(build, truth)
    assert np.all(p.mean[:, 0] == 0) and np.all(p.probability[:, 0, 0] == 1)


def test_a_contract_profile_recovers_the_analytic_curve_over_two_inputs() -> None:
    grid_a, grid_b = [0.5, 1.0], [0.3, 0.8, 1.0]
    build = build_profile(
        estimate,
        NoisyProblems(),
        time=TIME,
        input_grids=[grid_a, grid_b],
        trials=200,
        seed=2,
    )
    p = build.profile
    assert (p.kind, p.inputs, p.probability.shape) == ("contract", ("a", "b"), (2, 3, 6, 10))
    assert build.runs == 2 * 3 * 200 * len(TIME)
    a, b, t = np.meshgrid(grid_a, grid_b, TIME, indexing="ij")
    within_sampling_error(build, clipped_mean(curve(t, np.minimum(a, b))))


@interruptible("staircase", inputs=[], registry=TOYS)
def staircase(ctx: Context, fail: bool) -> Iterator[Result]:
    for ticks, quality in ((10, 0.3), (15, 0.6), (15, 0.9)):  # yields at 10, 25 and 40
        ctx.tick(ticks)
        yield Result(quality, quality)
        if fail and quality == 0.6:
            raise RuntimeError("lost the map")


class Staircase:
    """Every other instance fails after its second result."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance([bool(rng.integers(2))])

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


def test_a_result_counts_from_the_tick_it_was_yielded_at() -> None:
    time = [0, 9, 10, 24, 25, 39, 40, 100]
    build = build_profile(staircase, Staircase(), time=time, trials=1, seed=0)
    failed = build.failures == 1
    expected = [0, 0, 0.3, 0.3, 0.6, 0.6, 0.6 if failed else 0.9, 0.6 if failed else 0.9]
    assert build.profile.mean is not None
    assert build.profile.mean.tolist() == expected


def test_failures_are_counted_and_keep_the_result_registered_before_them() -> None:
    build = build_profile(staircase, Staircase(), time=[10, 25, 40], trials=200, seed=3)
    p = build.profile
    assert p.mean is not None
    failed_fraction = build.failures / 200
    assert 0.3 < failed_fraction < 0.7
    # Failed runs keep 0.6 after the failure; the others reach 0.9.
    assert p.mean[0] == pytest.approx(0.3)
    assert p.mean[1] == pytest.approx(0.6)
    assert p.mean[2] == pytest.approx(0.6 * failed_fraction + 0.9 * (1 - failed_fraction))
    assert build.first_failure is not None
    assert build.first_failure.startswith("RuntimeError: lost the map (trial ")
    assert "Traceback (most recent call last)" in build.first_failure
    assert f"{build.failures} of 200 runs failed; first: RuntimeError" in build.summary()


@contract("brittle", inputs=[], registry=TOYS)
def brittle(ctx: Context, mode: str) -> Any:
    ctx.tick(ctx.allocation * (2 if mode == "overrun" else 1))
    if mode == "raise":
        raise ValueError("no answer")
    if mode == "garbage":
        return 0.5  # not a Result
    return Result(1.0, 1.0)


class Modes:
    def __init__(self, mode: str) -> None:
        self.mode = mode

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance([self.mode])

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


@pytest.mark.parametrize(
    ("mode", "mean", "failures", "overruns", "first"),
    [
        ("raise", 0.0, 6, 0, "ValueError: no answer (trial 0 at input qualities [])"),
        ("garbage", 0.0, 6, 0, "returned float 0.5, not a Result (trial 0 at input qualities [])"),
        ("overrun", 1.0, 0, 4, None),  # allocation 0 cannot be overrun
    ],
    ids=["raises", "returns-garbage", "overruns"],
)
def test_a_failing_contract_run_scores_zero_and_is_counted(
    mode: str, mean: float, failures: int, overruns: int, first: str | None
) -> None:
    build = build_profile(brittle, Modes(mode), time=[0, 10, 20], trials=2, seed=0)
    assert build.profile.mean is not None
    assert build.profile.mean[1:].tolist() == [mean, mean]
    assert (build.runs, build.failures, build.overruns) == (6, failures, overruns)
    assert build.first_failure == first or (build.first_failure or "").startswith(str(first))


@pytest.mark.parametrize(
    ("mode", "mean", "step"),
    [(SOFT, 1.0, 20.0), (Isolated(), 1.0, 20.0), (Hard(), 0.0, 20.0)],
    ids=["soft", "isolated", "hard"],
)
def test_an_overrunning_contract_run_answers_as_its_mode_answers(
    mode: RunMode, mean: float, step: float
) -> None:
    # Soft (and soft in an isolated trial's process) the run keeps the result it returned
    # late; hard, it answered at the tick that passed its allocation, with none.
    build = build_profile(brittle, Modes("overrun"), time=[0, 10, 20], trials=2, mode=mode)
    assert build.profile.mean is not None
    assert build.profile.mean[1:].tolist() == [mean, mean]
    assert (build.failures, build.overruns, build.profile.step) == (0, 4, step)


def test_the_mode_is_a_run_mode() -> None:
    with pytest.raises(BuildError) as caught:
        build_profile(brittle, Modes(""), time=[0, 10], mode="none")  # type: ignore[arg-type]
    assert str(caught.value) == "mode: expected Soft(), Hard() or Isolated(), got 'none'"


@interruptible("mumbler", inputs=[], registry=TOYS)
def mumbler(ctx: Context, mode: str) -> Iterator[Any]:
    ctx.tick(5)
    yield Result(0.5, 0.5)
    ctx.tick(5)
    yield "not a result"


def test_a_yield_that_is_not_a_result_fails_the_run_and_keeps_the_last_result() -> None:
    build = build_profile(mumbler, Modes(""), time=[5, 10], trials=3, seed=0)
    assert build.failures == 3
    assert build.profile.mean is not None and build.profile.mean.tolist() == [0.5, 0.5]
    assert build.first_failure == (
        "yielded str 'not a result', not a Result (trial 0 at input qualities [])"
    )


def profiles_equal(a: ProfileBuild, b: ProfileBuild) -> bool:
    return a.profile == b.profile and all(
        np.array_equal(getattr(a.profile, name), getattr(b.profile, name))
        for name in ("time", "bins", "probability", "mean", "std", "samples")
    )


def saved(build: ProfileBuild, path: Path) -> bytes:
    save_profile(build.profile, path)
    return path.read_bytes()


def test_one_and_two_workers_and_any_chunk_size_give_the_same_file(tmp_path: Path) -> None:
    kwargs: dict[str, Any] = dict(time=TIME, input_grids=[[0.4, 1.0]], trials=60, seed=7)
    one = build_profile(approach, NoisyProblems(), workers=1, **kwargs)
    two = build_profile(approach, NoisyProblems(), workers=2, chunk_size=7, **kwargs)
    tiny = build_profile(approach, NoisyProblems(), workers=1, chunk_size=1, **kwargs)
    assert profiles_equal(one, two) and profiles_equal(one, tiny)
    assert saved(one, tmp_path / "one.yaml") == saved(two, tmp_path / "two.yaml")
    other_seed = build_profile(approach, NoisyProblems(), **{**kwargs, "seed": 8})
    assert not profiles_equal(one, other_seed)


def test_a_fresh_seed_is_reported_and_reproduces_the_profile() -> None:
    first = build_profile(
        estimate, NoisyProblems(), time=[0, 50], input_grids=[[1], [1]], trials=20, seed=None
    )
    again = build_profile(
        estimate, NoisyProblems(), time=[0, 50], input_grids=[[1], [1]], trials=20, seed=first.seed
    )
    assert first.seed >= 2**32 and profiles_equal(first, again)


def test_a_dask_cluster_gives_the_same_profile(tmp_path: Path) -> None:
    from distributed import LocalCluster

    kwargs: dict[str, Any] = dict(time=TIME, input_grids=[[0.5], [0.3, 1.0]], trials=40, seed=5)
    local = build_profile(estimate, NoisyProblems(), **kwargs)
    with LocalCluster(
        processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None
    ) as cluster:
        with dask_executor(cluster.scheduler_address) as executor:
            on_dask = build_profile(estimate, NoisyProblems(), executor=executor, **kwargs)
        measurement = builder.Measurement(NoisyProblems(), builder.Grid(TIME, [[0.5], [0.3, 1.0]]))
        request = ProfileRequest(trials=40, seed=5, scheduler=cluster.scheduler_address)
        requested = profile_module(estimate, request, measurement=measurement)
    assert profiles_equal(local, on_dask) and profiles_equal(local, requested)
    assert saved(local, tmp_path / "local.yaml") == saved(on_dask, tmp_path / "dask.yaml")


def test_without_dask_the_error_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    request = ProfileRequest(scheduler="tcp://127.0.0.1:8786")
    measurement = builder.Measurement(NoisyProblems(), builder.Grid([0]))
    with pytest.raises(MissingExtraError, match=r"pip install 'anytime-compose\[dask\]'"):
        profile_module(estimate, request, measurement=measurement)


def test_a_bad_scheduler_address_is_named() -> None:
    with pytest.raises(BuildError) as caught, dask_executor("nonsense://here"):
        pass
    assert str(caught.value).startswith(
        "cannot connect to the Dask scheduler at nonsense://here: unknown address scheme"
    )


def test_the_wall_clock_measures_in_seconds() -> None:
    build = build_profile(
        approach, NoisyProblems(), time=[0, 0.001], input_grids=[[1.0]], trials=3, clock="wall"
    )
    assert build.profile.time_unit == "seconds"
    np.testing.assert_allclose(build.profile.probability.sum(axis=-1), 1.0)


@elementary("join", registry=TOYS)
def join(a: Any, b: Any) -> Any:
    return (a, b)


@pytest.mark.parametrize(
    ("module", "kwargs", "message"),
    [
        (
            join,
            {},
            "profile of module 'join': only interruptible and contract modules have"
            " a profile to measure (this one is elementary)",
        ),
        (
            approach,
            {"input_grids": []},
            "profile of module 'approach': expected 1 input-quality"
            " grid(s) (one per quality-carrying input: x), got 0",
        ),
        (
            approach,
            {"trials": 0},
            "profile of module 'approach': trials: expected an integer >= 1, got 0",
        ),
        (
            approach,
            {"seed": -1},
            "profile of module 'approach': seed: expected an integer >= 0, got -1",
        ),
        (
            approach,
            {"clock": "sundial"},
            "profile of module 'approach': clock: expected 'work' or 'wall', got 'sundial'",
        ),
        (
            approach,
            {"time": [0, 10, 5]},
            "profile of module 'approach': time: expected increasing values, got 10 then 5",
        ),
        (
            approach,
            {"input_grids": [[0.5, 1.5]]},
            "profile of module 'approach': input_quality[0]: expected qualities in [0, 1], got 1.5",
        ),
    ],
    ids=["elementary", "grid-count", "trials", "seed", "clock", "time", "input-grid"],
)
def test_a_bad_request_is_refused_with_its_reason(
    module: Any, kwargs: dict[str, Any], message: str
) -> None:
    arguments: dict[str, Any] = {"time": [0, 10], "input_grids": [[1.0]], **kwargs}
    with pytest.raises(BuildError) as caught:
        build_profile(module, NoisyProblems(), **arguments)
    assert str(caught.value) == message


class WrongQuality(NoisyProblems):
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance([Result("map", 0.5), rng])


class TooMany(NoisyProblems):
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance(["map", rng, "extra"])


class OverScored(NoisyProblems):
    def score(self, instance: Instance, value: Any) -> float:
        return 1.5


@pytest.mark.parametrize(
    ("problems", "message"),
    [
        (
            WrongQuality(),
            "WrongQuality.instance: input 'x' was asked at quality 1, got a Result of quality 0.5",
        ),
        (
            TooMany(),
            "TooMany.instance: 3 argument(s) do not fit module 'approach' (parameters"
            " after ctx: x, rng): too many positional arguments",
        ),
        (
            OverScored(),
            "OverScored.score (trial 0 at input qualities [1.0]): expected a quality"
            " in [0, 1], got 1.5",
        ),
    ],
    ids=["input-quality", "arity", "score"],
)
def test_a_problem_set_that_breaks_its_contract_stops_the_build(
    problems: Any, message: str
) -> None:
    with pytest.raises(BuildError) as caught:
        build_profile(approach, problems, time=[0, 10], input_grids=[[1.0]], trials=2)
    assert str(caught.value) == message


def test_registered_problems_are_found_by_module_name(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(anytime.problems, "_MEASUREMENTS", {})
    register_problems(approach, NoisyProblems(), time=[0, 50], input_grids=[[1.0]])
    assert registered_problems("APPROACH").grid.time.tolist() == [0, 50]
    build = profile_module(approach, ProfileRequest(trials=4, quiet=True))
    assert build.profile.cell_shape == (1, 2) and build.trials == 4
    with pytest.raises(BuildError) as caught:
        registered_problems("aproach")
    assert str(caught.value) == (
        "no problem set is registered for module 'aproach' (registered: approach);"
        " did you mean 'approach'?"
    )
