"""Issue 37, items 1 and 9: what a module raises that is not an `Exception` (`SystemExit`, its
own `KeyboardInterrupt`, any other `BaseException`) is a failed trial or run under every runner
(the builder with 1 and 2 workers, isolated, soft and hard, on Dask; the catalogue, isolated and
soft; `run` isolated), every other trial kept; and a module stuck in `anytime check` costs one
watchdog, not one per run. The user's own Ctrl-C is tests/cli/test_cli_interrupt.py's."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import Cli

from anytime.measure.builder import build_profile, dask_executor, register_problems
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.problems import BuildError, Instance
from anytime.profiles.io import load_profile
from anytime.runtime import Budget, Hard, Isolated, Status, run
from anytime.runtime.modes import SOFT, RunMode
from anytime.testing import check_module, check_seed

MODULES = Registry()


class Escape(BaseException):
    """Neither an Exception nor an interrupt nor an exit."""


RAISED: dict[str, BaseException] = {
    "exit": SystemExit(3),
    "keyboard-interrupt": KeyboardInterrupt(),
    "base-exception": Escape("out"),
}
HEADLINES = {
    "exit": "SystemExit: 3",
    "keyboard-interrupt": "KeyboardInterrupt",
    "base-exception": f"{Escape.__module__}.Escape: out",
}


@interruptible("raises-after-two", registry=MODULES, inputs=())
def raises_after_two(ctx: Context, how: str) -> Iterator[Result]:
    for quality in (0.1, 0.2):
        ctx.tick(1)
        yield Result(quality, quality)
    if how in RAISED:
        raise RAISED[how]
    ctx.tick(1)
    yield Result(0.9, 0.9)


@contract("raises-contract", registry=MODULES, inputs=())
def raises_contract(ctx: Context, how: str) -> Result:
    ctx.tick(1)
    if how in RAISED:
        raise RAISED[how]
    return Result(0.9, 0.9)


@interruptible("stuck", registry=MODULES, inputs=())
def stuck(ctx: Context) -> Iterator[Result]:
    ctx.tick(1)
    yield Result(0.1, 0.1)
    time.sleep(60)  # neither ticks nor yields: only the watchdog ends it
    yield Result(0.2, 0.2)


BAD = 37  # the trial (of 60) that raises


def _draw(seed: int, trial: int) -> int:
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0, trial)))
    return int(rng.integers(1_000_000))


class OneBad:
    """The instance whose draw is `target` raises `how`; the others are well behaved."""

    def __init__(self, how: str, target: int) -> None:
        self.how, self.target = how, target

    def instance(self, rng: np.random.Generator, qualities: tuple[float, ...]) -> Instance:
        return Instance((self.how if int(rng.integers(1_000_000)) == self.target else "none",))

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


class Stuck:
    def instance(self, rng: np.random.Generator, qualities: tuple[float, ...]) -> Instance:
        return Instance(())

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


MODES: dict[str, RunMode] = {"isolated": Isolated(30.0), "soft": SOFT, "hard": Hard()}


@pytest.mark.parametrize("kind", ["interruptible", "contract"])
@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize("mode", list(MODES))
@pytest.mark.parametrize("how", list(RAISED))
def test_the_builder_counts_a_trial_that_raises_what_is_no_exception(
    how: str, mode: str, workers: int, kind: str
) -> None:
    name = "raises-after-two" if kind == "interruptible" else "raises-contract"
    module = MODULES.get(name)
    assert module is not None
    problems = OneBad(how, _draw(0, BAD))
    build = build_profile(
        module, problems, time=[1, 2, 3], trials=60, workers=workers, mode=MODES[mode]
    )
    runs = 1 if kind == "interruptible" else 3  # a contract trial: one run per grid time
    assert (build.failures, dict(build.reasons)) == (runs, {HEADLINES[how]: runs})
    assert build.first_failure is not None
    assert build.first_failure.startswith(f"{HEADLINES[how]} (trial {BAD} at input qualities [])")
    mean = build.profile.mean
    assert mean is not None
    kept = 0.2 if kind == "interruptible" else 0.0  # what the failed trial had registered
    assert mean[-1] == pytest.approx((59 * 0.9 + kept) / 60)


@pytest.mark.parametrize("how", list(RAISED))
def test_the_builder_on_dask_counts_it_too(how: str) -> None:
    from distributed import LocalCluster

    module = MODULES.get("raises-after-two")
    assert module is not None
    with (
        LocalCluster(
            processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None
        ) as cluster,
        dask_executor(cluster.scheduler_address) as executor,
    ):
        for mode in (Isolated(30.0), SOFT):
            build = build_profile(
                module, OneBad(how, _draw(0, BAD)), time=[1, 2, 3], trials=60,
                executor=executor, mode=mode,
            )  # fmt: skip
            assert (build.failures, dict(build.reasons)) == (1, {HEADLINES[how]: 1})


@pytest.mark.parametrize("mode", ["isolated", "soft"])
@pytest.mark.parametrize("how", list(RAISED))
def test_the_catalogue_counts_a_run_that_raises_what_is_no_exception(how: str, mode: str) -> None:
    module = MODULES.get("raises-after-two")
    assert module is not None
    problems = OneBad(how, _draw(check_seed(0), 2))
    report = check_module(module, problems, trials=5, time=[1, 2, 3], mode=MODES[mode])
    assert not report["errors"].passed
    assert report["errors"].message == (
        f"{HEADLINES[how]} (allocation 3, trial 2); 1 of 20 runs raised"
    )
    assert report["quality"].passed


@pytest.mark.parametrize("how", list(RAISED))
def test_an_isolated_run_of_a_module_that_raises_it_fails(how: str) -> None:
    """In a process of its own no Ctrl-C of the user's reaches the module: its interrupt is
    its own, a failed run with the best result it sent."""
    module = MODULES.get("raises-after-two")
    assert module is not None
    record = run(module, (how,), budget=Budget(10), mode=Isolated(30.0))
    assert (record.status, record.quality, record.error) == (Status.FAILED, 0.2, HEADLINES[how])


# --- a stuck module in the catalogue: one watchdog ---------------------------------------------


def test_a_stuck_module_costs_the_catalogue_one_watchdog() -> None:
    module = MODULES.get("stuck")
    assert module is not None
    started = time.monotonic()
    report = check_module(module, Stuck(), trials=5, time=[1, 2, 3], mode=Isolated(0.5))
    # 40 runs and a profile at 0.5 s each would take 20 s and more; one watchdog takes 0.5 s.
    assert time.monotonic() - started < 15  # a generous bound only the old behaviour reaches
    # At allocation 1 its first result ends the run; at 2 it hangs.
    stuck_at = "watchdog: no answer after 0.5 s of wall time, allocation 2, trial 0"
    assert report["errors"].message == (
        "watchdog: no answer after 0.5 s of wall time (allocation 2, trial 0); 1 of 2 runs"
        " failed; the other 18 runs were skipped: a module whose run hits the watchdog is taken"
        " to be stuck (each further run would wait the watchdog again)"
    )
    assert report["deadline"].passed and not report["deadline"].skipped  # allocation 1's run
    for name in ("interruption", "profile"):
        assert report[name].skipped
        assert report[name].message == f"skipped: the module is stuck ({stuck_at})"
    assert not report.passed


# --- the commands -------------------------------------------------------------------------------


@pytest.fixture
def raising(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """`raises-after-two` in the process-wide registry; `exit-profile` and `exit-check` raise
    SystemExit in one trial, `interrupt-profile` and `interrupt-check` KeyboardInterrupt."""
    fresh = Registry()
    monkeypatch.setattr("anytime.library.REGISTRY", fresh)
    monkeypatch.setattr("anytime.problems._MEASUREMENTS", {})
    for module in MODULES:
        fresh.add(module)
    yield


@pytest.mark.parametrize("isolation", ["process", "none"])
@pytest.mark.parametrize("workers", ["1", "2"])
@pytest.mark.parametrize("how", ["exit", "keyboard-interrupt"])
def test_anytime_profile_writes_its_file_when_a_module_exits_or_interrupts(
    cli: Cli, raising: None, tmp_path: Path, how: str, workers: str, isolation: str
) -> None:
    register_problems("raises-after-two", OneBad(how, _draw(0, BAD)), time=[1, 2, 3])
    out = tmp_path / "out.yaml"
    code, stdout, stderr = cli(
        "profile", "raises-after-two", "--trials", "60", "--quiet", "--no-plugins", "-o",
        str(out), "--workers", workers, "--isolation", isolation,
    )  # fmt: skip
    assert (code, stderr) == (0, "")
    assert f"1 of 60 runs failed; first: {HEADLINES[how]} (trial {BAD}" in stdout
    assert f"  1 x {HEADLINES[how]}\n" in stdout
    profile = load_profile(out)
    assert profile.mean is not None and profile.mean[-1] == pytest.approx((59 * 0.9 + 0.2) / 60)


@pytest.mark.parametrize("isolation", ["process", "none"])
@pytest.mark.parametrize("how", ["exit", "keyboard-interrupt"])
def test_anytime_check_reports_a_module_that_exits_or_interrupts(
    cli: Cli, raising: None, how: str, isolation: str
) -> None:
    register_problems("raises-after-two", OneBad(how, _draw(check_seed(0), 2)), time=[1, 2, 3])
    code, stdout, stderr = cli(
        "check", "raises-after-two", "--trials", "5", "--quiet", "--no-plugins",
        "--isolation", isolation,
    )  # fmt: skip
    assert (code, stderr) == (
        1,
        "anytime: error: module 'raises-after-two' fails 1 of 6 checks: errors\n",
    )
    assert f"{HEADLINES[how]} (allocation 3, trial 2); 1 of 20 runs raised" in stdout


def test_anytime_check_of_a_stuck_module_says_what_it_skipped(cli: Cli, raising: None) -> None:
    register_problems("stuck", Stuck(), time=[1, 2, 3])
    code, stdout, stderr = cli(
        "check", "stuck", "--trials", "5", "--quiet", "--no-plugins", "--watchdog", "0.5"
    )
    assert (code, stderr) == (1, "anytime: error: module 'stuck' fails 1 of 6 checks: errors\n")
    assert "; the other 18 runs were skipped: a module whose run hits the watchdog" in stdout


# --- a problem set that exits --------------------------------------------------------------------


class ExitingProblems:
    """A problem set whose `instance` raises what is no Exception: the plugin's fault (its own
    KeyboardInterrupt too: no Ctrl-C was pressed), a BuildError that names it."""

    def __init__(self, raised: BaseException) -> None:
        self.raised = raised

    def instance(self, rng: np.random.Generator, qualities: tuple[float, ...]) -> Instance:
        raise self.raised

    def score(self, instance: Instance, value: Any) -> float:
        return 0.5


@pytest.mark.parametrize("mode", list(MODES))
@pytest.mark.parametrize("how", ["exit", "keyboard-interrupt"])
def test_a_problem_set_that_exits_is_a_build_error_naming_it(how: str, mode: str) -> None:
    module = MODULES.get("raises-after-two")
    assert module is not None
    problems = ExitingProblems(SystemExit(4) if how == "exit" else KeyboardInterrupt())
    with pytest.raises(BuildError) as caught:
        build_profile(module, problems, time=[1, 2], trials=2, mode=MODES[mode])
    raised = "SystemExit: 4" if how == "exit" else "KeyboardInterrupt"
    assert str(caught.value) == (
        f"ExitingProblems.instance failed (trial 0 at input qualities []): {raised}"
    )
