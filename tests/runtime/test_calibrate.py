"""Calibration (`anytime.measure.calibrate`, `anytime calibrate`): a module's ticks per second,
and profiles converted between ticks and seconds. No test asserts a timing."""

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
from conftest import Cli
from hypothesis import given, settings
from hypothesis import strategies as st

import anytime.library
import anytime.problems
from anytime.errors import ProfileError
from anytime.measure.builder import Instance, Measurement
from anytime.measure.calibrate import Calibration, CalibrationError, calibrate, convert_profile
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.problems import Grid
from anytime.profiles import tabulate
from anytime.profiles.io import load_profile, save_profile

MODULES = Registry()
TIME = [0, 50, 100]


@interruptible("calibrate-sum", inputs=[], registry=MODULES)
def summing(ctx: Context, numbers: list[int]) -> Iterator[Result]:
    """Real work: one tick per number added."""
    total = 0
    for i, number in enumerate(numbers, 1):
        total += sum(range(number))
        ctx.tick()
        yield Result(total, i / len(numbers))


@contract("calibrate-contract", inputs=[], registry=MODULES)
def summing_contract(ctx: Context, numbers: list[int]) -> Result:
    """`summing` as a contract: adds as many numbers as its allocation affords."""
    done = min(len(numbers), int(ctx.allocation))
    for number in numbers[:done]:
        sum(range(number))
        ctx.tick()
    return Result(done, done / len(numbers))


@interruptible("calibrate-idle", inputs=[], registry=MODULES)
def idle(ctx: Context, numbers: list[int]) -> Iterator[Result]:
    """Answers at once and never says it worked."""
    yield Result(0, 1.0)


@interruptible("calibrate-endless", inputs=[], registry=MODULES)
def endless(ctx: Context, numbers: list[int]) -> Iterator[Result]:
    """Never finishes on its own within its (huge) allocation."""
    while True:
        ctx.tick()
        yield Result(None, 0.5)


@interruptible("calibrate-broken", inputs=[], registry=MODULES)
def broken(ctx: Context, numbers: list[int]) -> Iterator[Result]:
    ctx.tick()
    raise RuntimeError("out of numbers")
    yield Result(None, 0.0)


class Numbers:
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance(args=([int(n) for n in rng.integers(50, 150, size=100)],))

    def score(self, instance: Instance, value: Any) -> float:
        return 1.0


MEASUREMENTS = {
    module.name: Measurement(Numbers(), Grid([0, 1e12] if module is endless else TIME))
    for module in MODULES
}


@pytest.fixture(autouse=True)
def only_these_modules(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(anytime.library, "REGISTRY", MODULES)
    monkeypatch.setattr(anytime.problems, "_MEASUREMENTS", dict(MEASUREMENTS))


# --- convert_profile ---------------------------------------------------------------------------

GRID = [0, 1, 2, 3, 7, 25, 50, 100, 150, 1000, 12345, 98765.4321]
PROFILE = tabulate(
    lambda t, q: q * (1 - np.exp(-t / 300)),
    GRID,
    input_grids=[[0.5, 1.0]],
    inputs=["data"],
    module="calibrate-sum",
)


@pytest.mark.parametrize(
    "rate", [1.0, 3.0, 1000.0, 0.7467473617355628, 448412.73519, 1e9 / 7, 2.5e-4]
)
def test_ticks_to_seconds_and_back_is_exact(rate: float) -> None:
    seconds = convert_profile(PROFILE, rate)
    assert seconds.time_unit == "seconds"
    np.testing.assert_allclose(seconds.time, np.array(GRID) / rate, rtol=1e-15)
    assert attrs.evolve(seconds, time=PROFILE.time, time_unit="ticks") == PROFILE  # nothing else
    back = convert_profile(seconds, rate, to="ticks")
    assert back == PROFILE
    assert back.time.tolist() == GRID


@settings(max_examples=150, deadline=None)
@given(
    rate=st.floats(1e-6, 1e12),
    grid=st.lists(st.integers(0, 10**9), min_size=1, max_size=8, unique=True).map(sorted),
    unit=st.sampled_from(["ticks", "seconds"]),
)
def test_round_trip_is_exact_for_any_rate(rate: float, grid: list[int], unit: str) -> None:
    times = [t / 1000 for t in grid] if unit == "seconds" else grid  # seconds: ms steps
    profile = tabulate(lambda t: np.ones_like(t), times, time_unit=unit)  # type: ignore[arg-type]
    there = "ticks" if unit == "seconds" else "seconds"
    back = convert_profile(convert_profile(profile, rate, to=there), rate, to=unit)  # type: ignore[arg-type]
    assert back.time.tolist() == profile.time.tolist()


def test_conversion_errors() -> None:
    seconds = convert_profile(PROFILE, 10.0)
    with pytest.raises(ProfileError) as raised:
        convert_profile(seconds, 10.0, to="seconds")
    assert str(raised.value) == "calibrate-sum: time_unit: the profile is already in seconds"
    with pytest.raises(CalibrationError) as bad_rate:
        convert_profile(PROFILE, 0.0)
    assert str(bad_rate.value) == "ticks_per_second: expected a positive number, got 0.0"
    assert isinstance(bad_rate.value, ValueError)  # still what it resembles
    with pytest.raises(CalibrationError) as bad_unit:
        convert_profile(PROFILE, 1.0, to="minutes")  # type: ignore[arg-type]
    assert str(bad_unit.value) == "to: expected 'seconds' or 'ticks', got 'minutes'"


# --- calibrate ---------------------------------------------------------------------------------


@pytest.mark.parametrize("module", [summing, summing_contract], ids=["interruptible", "contract"])
def test_a_module_doing_real_work_has_a_positive_rate_with_a_spread(module: Any) -> None:
    calibration = calibrate(module, 0.1, max_runs=50)
    assert isinstance(calibration, Calibration) and calibration.module == module.name
    assert calibration.runs >= 1 and len(calibration.rates) == calibration.runs
    assert 0 < calibration.ticks <= 100 * calibration.runs  # at most 100 numbers a run
    low, high = calibration.interval
    assert 0 < calibration.low <= low <= calibration.ticks_per_second <= high <= calibration.high
    assert calibration.to_dict()["ticks_per_second"] == calibration.ticks_per_second
    assert calibration.summary().startswith(f"{module.name}: ")


def test_the_interval_of_the_median_from_order_statistics() -> None:
    rates = tuple(float(r) for r in range(1, 101))
    calibration = Calibration("m", rates, 100, 0.0, 1.0)
    assert calibration.ticks_per_second == 50.5
    assert calibration.interval == (40.0, 61.0)
    assert Calibration("m", (3.0,), 1, 0.0, 1.0).interval == (3.0, 3.0)


def test_the_budget_stops_a_run_that_would_go_on() -> None:
    calibration = calibrate(endless, 0.02)
    assert calibration.runs == 1 and calibration.ticks > 0


def test_calibration_errors() -> None:
    with pytest.raises(CalibrationError) as idle_error:
        calibrate(idle, 0.01)
    assert str(idle_error.value) == (
        "module 'calibrate-idle' reported no ticks while being calibrated: it must report its"
        " work with ctx.tick(n)"
    )
    with pytest.raises(CalibrationError) as broken_error:
        calibrate(broken, 0.01)
    assert str(broken_error.value) == (
        "module 'calibrate-broken' failed while being calibrated (trial 0): RuntimeError: out of"
        " numbers"
    )
    with pytest.raises(CalibrationError) as no_budget:
        calibrate(idle, 0.0)
    assert str(no_budget.value) == "seconds: expected a positive budget, got 0.0"


# --- `anytime calibrate MODULE` ------------------------------------------------------------------


def test_calibrate_prints_the_rate(cli: Cli) -> None:
    code, out, err = cli("calibrate", "calibrate-sum", "--seconds", "0.05", "--no-plugins")
    assert (code, err) == (0, "")
    assert out.startswith("calibrate-sum: ") and " ticks/s (median of " in out
    assert out.count("\n") == 1


def test_calibrate_converts_a_profile(cli: Cli, tmp_path: Path) -> None:
    source, target = tmp_path / "sum.yaml", tmp_path / "sum-seconds.yaml"
    save_profile(PROFILE, source)
    code, out, err = cli(
        "calibrate", "calibrate-sum", "--seconds", "0.05", "--profile", str(source),
        "-o", str(target), "--json", "--no-plugins",
    )  # fmt: skip
    assert (code, err) == (0, "")
    report = json.loads(out)
    assert report["file"] == str(target) and report["module"] == "calibrate-sum"
    converted = load_profile(target)
    assert converted == convert_profile(PROFILE, report["ticks_per_second"])
    code, _, err = cli(
        "calibrate", "calibrate-sum", "--seconds", "0.05", "--profile", str(target),
        "--to", "ticks", "-o", str(tmp_path / "back.yaml"), "--no-plugins",
    )  # fmt: skip
    assert (code, err) == (0, "")
    assert load_profile(tmp_path / "back.yaml").time_unit == "ticks"


def test_no_problem_set(cli: Cli, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(anytime.problems, "_MEASUREMENTS", {})
    code, out, err = cli("calibrate", "calibrate-sum", "--no-plugins")
    assert (code, out) == (1, "")
    assert err == (
        "anytime: error: no problem set is registered for module 'calibrate-sum'"
        " (registered: none)\n"
    )


def test_a_module_that_reports_no_ticks(cli: Cli) -> None:
    code, out, err = cli("calibrate", "calibrate-idle", "--seconds", "0.01", "--no-plugins")
    assert (code, out) == (1, "")
    assert err == (
        "anytime: error: module 'calibrate-idle' reported no ticks while being calibrated: it"
        " must report its work with ctx.tick(n)\n"
    )


def test_a_profile_already_in_the_target_unit(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "sum.yaml"
    save_profile(convert_profile(PROFILE, 1000.0), path)
    code, out, err = cli(
        "calibrate", "calibrate-sum", "--profile", str(path), "-o", str(tmp_path / "out.yaml"),
        "--no-plugins",
    )  # fmt: skip
    assert (code, out) == (1, "")
    assert err == (
        f"anytime: error: {path}: time_unit: the profile is already in seconds (give --to ticks"
        " to convert it to ticks)\n"
    )
    assert not (tmp_path / "out.yaml").exists()


def test_a_profile_of_another_module(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "other.yaml"
    save_profile(attrs.evolve(PROFILE, module="someone-else"), path)
    code, _, err = cli(
        "calibrate", "calibrate-sum", "--profile", str(path), "-o", str(tmp_path / "out.yaml"),
        "--no-plugins",
    )  # fmt: skip
    assert code == 1
    assert err == (
        f"anytime: error: {path}: module: expected 'calibrate-sum' (the module calibrated), got"
        " 'someone-else'\n"
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["-o", "out.yaml"], "error: --profile FILE and -o OUT go together"),
        (["--seconds", "0"], "argument --seconds: expected a number > 0 and <= 3600, got 0"),
        (["--to", "minutes"], "argument --to: invalid choice: 'minutes'"),
    ],
    ids=["output-without-profile", "zero-seconds", "unknown-unit"],
)
def test_usage_errors(cli: Cli, argv: list[str], message: str) -> None:
    code, _, err = cli("calibrate", "calibrate-sum", "--no-plugins", *argv)
    assert code == 2
    assert message in err


@pytest.mark.parametrize("rate", [4.0, 1e9 / 7])
def test_a_measured_step_converts_with_the_time_axis(rate: float) -> None:
    """The step is a time like the grid's: it was left in ticks in a profile in seconds."""
    stepped = attrs.evolve(PROFILE, step=12.0)
    seconds = convert_profile(stepped, rate)
    assert seconds.step == pytest.approx(12.0 / rate, rel=1e-15)
    assert convert_profile(seconds, rate, to="ticks").step == 12.0
    assert convert_profile(PROFILE, rate).step is None
