"""`anytime profile MODULE`: measure a module and write its profile file."""

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import Cli

import anytime.library
from anytime.measure import builder
from anytime.measure.builder import Instance, register_problems
from anytime.modules import Context, Registry, Result, interruptible
from anytime.profiles import Exponential, tabulate
from anytime.profiles.io import load_profile, save_profile
from anytime.runtime.modes import SOFT, Isolated, RunMode

MODULES = Registry()


@interruptible("halving", inputs=["guess"], registry=MODULES)
def halving(ctx: Context, guess: Result, target: float) -> Iterator[Result]:
    """Halve the error of a guess each step; the quality is one minus the error."""
    error = 1.0
    while not ctx.expired:
        ctx.tick(10)
        error /= 2
        yield Result(target + error, guess.quality * (1 - error))


class HalvingProblems:
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance(args=(None, float(rng.random())), reference=input_qualities[0])

    def score(self, instance: Instance, value: Any) -> float:
        return float(instance.reference) * (1 - abs(value - instance.args[1]))


register_problems(halving, HalvingProblems(), time=[0, 10, 20, 40], input_grids=[[0.5, 1.0]])


@pytest.fixture(autouse=True)
def only_these_modules(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(anytime.library, "REGISTRY", MODULES)


def test_profile_writes_the_measured_profile(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "halving.yaml"
    code, out, err = cli(
        "profile", "Halving", "--trials", "5", "--no-plugins", "--quiet", "-o", str(path)
    )
    assert (code, err) == (0, "")
    assert out.startswith("halving: 5 trials per cell over 2x4 cells, 10 runs in ")
    assert out.endswith(f"wrote {path}\n")
    profile = load_profile(path)
    assert profile.module == "halving" and profile.inputs == ("guess",)
    assert profile.samples is not None and profile.samples.tolist() == [[5.0] * 4] * 2
    assert profile.mean is not None
    np.testing.assert_allclose(profile.mean, [[0, 0.25, 0.375, 0.46875], [0, 0.5, 0.75, 0.9375]])


def test_same_seed_same_file_whatever_the_workers(cli: Cli, tmp_path: Path) -> None:
    one, two = tmp_path / "one.yaml", tmp_path / "two.yaml"
    base = ["profile", "halving", "--trials", "8", "--seed", "3", "--no-plugins", "--quiet"]
    assert cli(*base, "-o", str(one))[0] == 0
    assert cli(*base, "--workers", "2", "-o", str(two), "--json")[0] == 0
    assert one.read_bytes() == two.read_bytes()


def test_unknown_module(cli: Cli) -> None:
    code, out, err = cli("profile", "halfing", "--no-plugins")
    assert (code, out) == (1, "")
    assert err == "anytime: error: no module named 'halfing'; did you mean 'halving'?\n"


def test_a_profile_only_module_has_nothing_to_run(cli: Cli, tmp_path: Path) -> None:
    save_profile(tabulate(Exponential(0.1), [0, 10], module="sensor"), tmp_path / "sensor.yaml")
    code, _, err = cli("profile", "sensor", "--no-plugins", "--profiles", str(tmp_path))
    assert code == 1
    assert err == (
        "anytime: error: module 'sensor' has no code to run: it is only a profile "
        f"(profile file {tmp_path / 'sensor.yaml'})\n"
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--trials", "0"], "argument --trials: expected a whole number from 1 to 100000, got 0"),
        (["--workers", "two"], "argument --workers: expected a whole number, got 'two'"),
        (["--workers", "2", "--scheduler", "tcp://x:1"], "not allowed with argument"),
    ],
    ids=["zero-trials", "workers-not-a-number", "workers-and-scheduler"],
)
def test_usage_errors(cli: Cli, argv: list[str], message: str) -> None:
    code, _, err = cli("profile", "halving", *argv)
    assert code == 2
    assert message in err


@pytest.mark.parametrize(
    ("options", "mode"),
    [
        ([], Isolated()),
        (["--watchdog", "5"], Isolated(watchdog=5.0)),
        (["--isolation", "none"], SOFT),
    ],
    ids=["default", "watchdog", "none"],
)
def test_isolation_and_watchdog_are_the_builder_s_run_mode(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, options: list[str], mode: RunMode
) -> None:
    seen: list[RunMode] = []
    measure = builder.build_profile

    def spy(*args: Any, **kwargs: Any) -> builder.ProfileBuild:
        seen.append(kwargs["mode"])
        return measure(*args, **kwargs)

    monkeypatch.setattr(builder, "build_profile", spy)
    path = tmp_path / "halving.yaml"
    argv = ["profile", "halving", "--trials", "2", "--no-plugins", "--quiet", "-o", str(path)]
    code, _, err = cli(*argv, *options)
    assert (code, err, seen) == (0, "", [mode])
