"""The fault matrix: misbehaving modules under every runner.

Each misbehaviour comes after two results (qualities 0.1 and 0.2): raising, yielding what is
not a Result, building a Result of quality NaN, looping or sleeping without ticking,
`sys.exit`, its own `KeyboardInterrupt` or another `BaseException`, `os._exit`, a segmentation
fault, `abort()`, a SIGTERM to itself, forking a child that would outlive it, growing its memory
under a limit, closing its standard output, mutating its arguments. Under
`isolation="process"` on the work and the wall clock (interruptible and contract modules, and a
contract made interruptible) every case ends with a record that keeps the best result sent
(0.2, or the last for a module that goes on), the caller survives, and no process of the run is
left. The profile builder (1 and 2 workers), the catalogue, and
`anytime profile` and `anytime check` run one misbehaving trial among many: it fails alone, the
rest are measured, the file is written, and the reason is reported. (A compiled program's
isolated runs are in test_program.py; the time isolation takes to answer is measured by
benchmarks/bench_isolation.py, not asserted here.)

In-process runs (soft and hard) survive the cases that do not end the interpreter; the others
(`os._exit`, a segfault, `abort()`, a signal) are what isolation is for, and are not run here
in-process (they would end the test run).
"""

from __future__ import annotations

import ctypes
import faulthandler
import io
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import Cli

from anytime.clocks import WallClock, WorkClock
from anytime.isolation import Limits, processes
from anytime.measure.builder import build_profile, register_problems
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.problems import Instance
from anytime.profiles.io import load_profile
from anytime.runtime import Budget, Hard, Isolated, Soft, Status, run
from anytime.runtime.conversion import make_interruptible
from anytime.testing import check_module, check_seed

MODULES = Registry()
COMMANDS = Registry()  # the modules of the command tests, put in the library's registry there
RELEASE = threading.Event()  # lets an in-process loop that never ticks end after its test


def _session_processes() -> set[int]:
    """The live (not zombie) children of this process, and the orphans of its session (what a
    process a run forks becomes once the run's process is gone)."""
    me, session = os.getpid(), os.getsid(0)
    return {
        p.pid
        for p in processes()
        if p.state not in ("Z", "X")
        and (p.parent == me or (p.parent == 1 and p.session == session))
    }


class Escape(BaseException):
    """Neither an Exception, nor an exit, nor an interrupt."""


def _misbehave(ctx: Context, how: str, args: list[Any]) -> None:
    """What the module does after its second result."""
    match how:
        case "raise":
            raise RuntimeError("broken")
        case "exit":
            sys.exit(3)
        case "keyboard-interrupt":  # its own: no Ctrl-C was pressed
            raise KeyboardInterrupt
        case "base-exception":
            raise Escape("out")
        case "os-exit":
            os._exit(3)
        case "segfault":
            faulthandler.disable()  # pytest's would print the dying process's stack
            ctypes.string_at(0)
        case "abort":
            faulthandler.disable()
            os.abort()
        case "sigterm":
            os.kill(os.getpid(), signal.SIGTERM)
        case "loop":
            while not RELEASE.is_set():
                pass
        case "sleep":
            RELEASE.wait(30)
        case "fork":
            if os.fork() == 0:  # a child that would sleep on long after the run
                time.sleep(30)
                os._exit(0)
        case "memory":
            hoard = []
            while True:
                hoard.append(bytearray(16 << 20))
        case "close-stdout":
            sys.stdout.close()
        case "mutate":
            args.append("changed")
        case "nan-quality":
            Result("bad", math.nan)


@interruptible("misbehaving", registry=MODULES, inputs=())
def misbehaving(ctx: Context, how: str, args: list[Any]) -> Iterator[Result]:
    yield from _two_results_then(ctx, how, args)


@interruptible("faulty-count", registry=COMMANDS, inputs=())
def faulty_count_module(ctx: Context, how: str, args: list[Any]) -> Iterator[Result]:
    yield from _two_results_then(ctx, how, args)


@interruptible("faulty-check", registry=COMMANDS, inputs=())
def faulty_check_module(ctx: Context, how: str, args: list[Any]) -> Iterator[Result]:
    yield from _two_results_then(ctx, how, args)


def _two_results_then(ctx: Context, how: str, args: list[Any]) -> Iterator[Result]:
    for quality in (0.1, 0.2):
        ctx.tick(1)
        yield Result(quality, quality)
    if how == "garbage":
        yield "not a result"  # type: ignore[misc]
    _misbehave(ctx, how, args)
    ctx.tick(1)
    yield Result(0.9, 0.9)


@contract("misbehaving-contract", registry=MODULES, inputs=())
def misbehaving_contract(ctx: Context, how: str, args: list[Any]) -> Result:
    ctx.tick(1)
    _misbehave(ctx, how, args)
    return Result(0.9, 0.9)


#: misbehaviour -> (status, quality of the best result, error or how it ended) under isolation
ISOLATED = {
    "raise": (Status.FAILED, 0.2, "RuntimeError: broken"),
    "garbage": (Status.FAILED, 0.2, "yielded str 'not a result', not a Result"),
    "nan-quality": (
        Status.FAILED,
        0.2,
        "ValueError: a Result's quality must be in [0, 1], got nan",
    ),
    "exit": (Status.FAILED, 0.2, "SystemExit: 3"),
    "keyboard-interrupt": (Status.FAILED, 0.2, "KeyboardInterrupt"),
    "base-exception": (Status.FAILED, 0.2, f"{Escape.__module__}.Escape: out"),
    "os-exit": (Status.CRASHED, 0.2, 3),
    "segfault": (Status.CRASHED, 0.2, -signal.SIGSEGV),
    "abort": (Status.CRASHED, 0.2, -signal.SIGABRT),
    "sigterm": (Status.CRASHED, 0.2, -signal.SIGTERM),
    "loop": (Status.FAILED, 0.2, "watchdog"),
    "sleep": (Status.FAILED, 0.2, "watchdog"),
    "fork": (Status.COMPLETED, 0.9, None),
    "memory": (Status.CRASHED, 0.2, "MemoryError"),
    "close-stdout": (Status.COMPLETED, 0.9, None),
    "mutate": (Status.COMPLETED, 0.9, None),
}

WATCHDOG = 0.5
#: The watchdog of the cases that end by themselves: one they never meet, however loaded the
#: machine (growing 256 MB under a limit from a large forked test process took over 0.5 s once
#: in a full CI run). Only the hanging cases need the short one.
SLACK = 30.0
HANGING = ("loop", "sleep")


@pytest.fixture(autouse=True)
def released() -> Iterator[None]:
    RELEASE.clear()
    yield
    RELEASE.set()


def _isolated(how: str, clock: type, kind: str = "interruptible") -> tuple[Any, list[Any]]:
    module = MODULES.get("misbehaving" if kind == "interruptible" else "misbehaving-contract")
    assert module is not None
    args: list[Any] = ["original"]
    limits = Limits(memory=256 << 20) if how == "memory" else None
    allocation = 10.0 if clock is WorkClock else 5.0
    record = run(
        module,
        (how, args),
        budget=Budget(allocation, clock=clock()),
        mode=Isolated(watchdog=WATCHDOG if how in HANGING else SLACK, limits=limits),
    )
    return record, args


@pytest.mark.parametrize("clock", [WorkClock, WallClock], ids=["work", "wall"])
@pytest.mark.parametrize("how", list(ISOLATED))
def test_every_misbehaviour_isolated_gives_a_record_with_the_best_result(
    how: str, clock: type
) -> None:
    before = _session_processes()
    record, args = _isolated(how, clock)
    status, quality, ending = ISOLATED[how]
    assert (record.status, record.quality) == (status, quality), record.error
    if isinstance(ending, int):
        assert record.exit_code == ending
        assert record.error is not None and record.error.startswith("its process")
    elif ending == "watchdog":
        assert record.error is not None
        assert record.error.startswith(f"watchdog: no answer after {WATCHDOG:g} s of wall time")
    else:
        assert (record.error or None) == ending or (record.error or "").startswith(ending)
    assert args == ["original"]  # the child's changes stay in the child
    assert _session_processes() <= before  # nothing of the run is left
    print("the caller's standard output still works")


def test_a_crashed_runs_record_names_the_signal() -> None:
    record, _ = _isolated("segfault", WorkClock)
    assert record.error == "its process was killed by SIGSEGV (signal 11)"
    assert record.time_used == 2.0  # the ticks it reported before it died
    record, _ = _isolated("os-exit", WorkClock)
    assert record.error == "its process exited with code 3 before it answered"


@pytest.mark.parametrize("how", ["raise", "os-exit", "segfault", "loop", "fork", "mutate"])
def test_a_misbehaving_contract_isolated_gives_a_record(how: str) -> None:
    before = _session_processes()
    record, args = _isolated(how, WorkClock, kind="contract")
    expected = {
        "raise": Status.FAILED,
        "os-exit": Status.CRASHED,
        "segfault": Status.CRASHED,
        "loop": Status.FAILED,
        "fork": Status.COMPLETED,
        "mutate": Status.COMPLETED,
    }[how]
    assert record.status is expected
    assert record.quality == (0.9 if expected is Status.COMPLETED else 0.0)
    assert args == ["original"]
    assert _session_processes() <= before


@interruptible("ticks-on", registry=MODULES, inputs=())
def ticks_on(ctx: Context) -> Iterator[Result]:
    for i in range(1, 1000):
        ctx.tick(1)
        yield Result(i, min(1.0, i / 100))


def test_on_the_work_clock_an_isolated_run_ends_as_a_hard_run_does() -> None:
    module = MODULES.get("ticks-on")
    assert module is not None
    for allocation, used in ((7.0, 7.0), (7.5, 8.0)):  # at its allocation, or the tick past it
        clock = WorkClock()
        record = run(module, budget=Budget(allocation, clock=clock), mode=Isolated())
        assert (record.status, record.result, record.time_used) == (
            Status.INTERRUPTED, Result(7, 0.07), used,
        )  # fmt: skip
        assert clock.now() == used  # the caller's clock moved as if the module had run here
        hard = run(module, budget=Budget(allocation, clock=WorkClock()), mode=Hard())
        assert (hard.status, hard.result, hard.time_used) == (
            Status.INTERRUPTED,
            Result(7, 0.07),
            used,
        )


# --- in-process runs: what does not end the interpreter ----------------------------------------

IN_PROCESS = {
    "raise": (Status.FAILED, 0.2),
    "garbage": (Status.FAILED, 0.2),
    "nan-quality": (Status.FAILED, 0.2),
    "exit": (Status.FAILED, 0.2),
    "close-stdout": (Status.COMPLETED, 0.9),
    "mutate": (Status.COMPLETED, 0.9),
}


@pytest.mark.parametrize("clock", [WorkClock, WallClock], ids=["work", "wall"])
@pytest.mark.parametrize("hard", [False, True], ids=["soft", "hard"])
@pytest.mark.parametrize("how", list(IN_PROCESS))
def test_in_process_runs_survive_what_does_not_end_the_interpreter(
    how: str, hard: bool, clock: type, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys, "stdout", io.StringIO())  # what "close-stdout" closes
    module = MODULES.get("misbehaving")
    assert module is not None
    args: list[Any] = ["original"]
    record = run(
        module, (how, args), budget=Budget(10.0, clock=clock()), mode=Hard() if hard else Soft()
    )
    assert (record.status, record.quality) == IN_PROCESS[how]
    assert args == (["original", "changed"] if how == "mutate" else ["original"])


def test_in_process_hard_mode_on_the_wall_clock_answers_at_the_deadline_of_a_loop() -> None:
    module = MODULES.get("misbehaving")
    assert module is not None
    for how in ("loop", "sleep"):
        record = run(module, (how, []), budget=Budget(0.2, clock=WallClock()), mode=Hard())
        assert (record.status, record.quality) == (Status.INTERRUPTED, 0.2)


# --- the builder and the catalogue: one bad trial among many -----------------------------------

BAD_TRIAL = 37  # the trial (of 60) that misbehaves


def _draw(seed: int, trial: int) -> int:
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0, trial)))
    return int(rng.integers(1_000_000))


class OneBadTrial:
    """Instances of `misbehaving`: the one whose draw is `target` misbehaves as `how`."""

    def __init__(self, how: str, target: int) -> None:
        self.how, self.target = how, target

    def instance(self, rng: np.random.Generator, qualities: tuple[float, ...]) -> Instance:
        draw = int(rng.integers(1_000_000))
        return Instance(((self.how if draw == self.target else "none"), []))

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


BUILDER_CASES = {
    "os-exit": "its process exited with code 3 before it answered",
    "segfault": "its process was killed by SIGSEGV (signal 11)",
    "abort": "its process was killed by SIGABRT (signal 6)",
    "sigterm": "its process was killed by SIGTERM (signal 15)",
    "loop": "watchdog: no answer after 0.5 s of wall time",
    "raise": "RuntimeError: broken",
    "memory": "MemoryError",  # under the mode's limits, each trial's own (a process per run)
    "exit": "SystemExit: 3",
    "keyboard-interrupt": "KeyboardInterrupt",  # the module's own: a failed trial
    "base-exception": f"{Escape.__module__}.Escape: out",
}


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize("how", list(BUILDER_CASES))
def test_the_builder_measures_the_other_trials_when_one_crashes_or_hangs(
    how: str, workers: int
) -> None:
    module = MODULES.get("misbehaving")
    assert module is not None
    problems = OneBadTrial(how, _draw(0, BAD_TRIAL))
    before = _session_processes()
    # Filling 256 MB takes a few tenths of a second: the watchdog is not what ends it.
    mode = Isolated(SLACK, Limits(memory=256 << 20)) if how == "memory" else Isolated(WATCHDOG)
    build = build_profile(module, problems, time=[1, 2, 3], trials=60, workers=workers, mode=mode)
    assert (build.failures, dict(build.reasons)) == (1, {BUILDER_CASES[how]: 1})
    assert build.first_failure is not None
    assert build.first_failure.startswith(
        f"{BUILDER_CASES[how]} (trial {BAD_TRIAL} at input qualities [])"
    )
    # The 59 good trials reach 0.9 at time 3; the bad one keeps what it had registered, 0.2,
    # whether it raised, its process died or the watchdog ended it (as `run` keeps it).
    mean = build.profile.mean
    assert mean is not None
    assert mean[-1] == pytest.approx((59 * 0.9 + 0.2) / 60)
    assert "1 x " + BUILDER_CASES[how] in build.summary()
    assert _session_processes() <= before


def test_the_catalogue_reports_a_crashing_trial_and_goes_on() -> None:
    module = MODULES.get("misbehaving")
    assert module is not None
    # Trial 2 of 5 crashes once it has had 2 ticks: given 3 (of 1, 2, 3), or interrupted later.
    problems = OneBadTrial("segfault", _draw(check_seed(0), 2))
    before = _session_processes()
    report = check_module(module, problems, trials=5, time=[1, 2, 3], mode=Isolated(WATCHDOG))
    checks = {check.name: check for check in report.checks}
    assert not checks["errors"].passed
    assert checks["errors"].message == (
        "its process was killed by SIGSEGV (signal 11) (allocation 3, trial 2); 1 of 20 runs failed"
    )
    assert checks["quality"].passed
    assert _session_processes() <= before


# --- the commands: one bad trial in a run of 100 -----------------------------------------------


@pytest.fixture
def faulty_count(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """`faulty-count` in the process-wide registry, with its problem set: the one trial of 100
    (trial 37 of the profile builder's seed 0) that segfaults after its second result."""
    fresh = Registry()
    monkeypatch.setattr("anytime.library.REGISTRY", fresh)
    monkeypatch.setattr("anytime.problems._MEASUREMENTS", {})
    for module in COMMANDS:
        fresh.add(module)
    register_problems("faulty-count", OneBadTrial("segfault", _draw(0, BAD_TRIAL)), time=[1, 2, 3])
    register_problems(
        "faulty-check", OneBadTrial("segfault", _draw(check_seed(0), 2)), time=[1, 2, 3]
    )
    yield "faulty-count"


def test_anytime_profile_writes_its_file_with_one_crashing_trial_in_100(
    cli: Cli, faulty_count: str, tmp_path: Path
) -> None:
    out = tmp_path / "faulty.yaml"
    before = _session_processes()
    code, stdout, stderr = cli(
        "profile", faulty_count, "--trials", "100", "--quiet", "--no-plugins", "-o", str(out)
    )
    assert (code, stderr) == (0, "")
    failed = "1 of 100 runs failed; first: its process was killed by SIGSEGV (signal 11) (trial 37"
    assert failed in stdout
    assert "  1 x its process was killed by SIGSEGV (signal 11)" in stdout
    profile = load_profile(out)
    assert profile.mean is not None and profile.mean[-1] == pytest.approx((99 * 0.9 + 0.2) / 100)
    assert _session_processes() <= before


def test_anytime_check_reports_a_crashing_run_and_finishes(cli: Cli, faulty_count: str) -> None:
    before = _session_processes()
    code, stdout, stderr = cli("check", "faulty-check", "--trials", "5", "--quiet", "--no-plugins")
    assert (code, stderr) == (
        1,
        "anytime: error: module 'faulty-check' fails 1 of 6 checks: errors\n",
    )
    assert (
        "its process was killed by SIGSEGV (signal 11) (allocation 3, trial 2); 1 of 20 runs failed"
        in stdout
    )
    assert _session_processes() <= before


@contract("crashes-when-long", registry=MODULES, inputs=())
def crashes_when_long(ctx: Context) -> Result:
    """A contract that answers allocations under 4 ticks and ends its process on longer ones."""
    if ctx.allocation >= 4:
        os._exit(3)
    ctx.tick(ctx.allocation)
    return Result(ctx.allocation, ctx.allocation / 10)


def test_a_contract_made_interruptible_and_isolated_keeps_the_contracts_before_a_crash() -> None:
    module = MODULES.get("crashes-when-long")
    assert module is not None
    made = make_interruptible(module, t0=1, r=2)  # contracts of 1, 2, then 4 ticks
    before = _session_processes()
    record = run(made, budget=20, mode=Isolated())
    assert (record.status, record.result, record.registered, record.exit_code) == (
        Status.CRASHED, Result(2.0, 0.2), 2, 3,
    )  # fmt: skip
    assert record.time_used == 3.0  # 1 + 2 ticks of the contracts that answered
    assert _session_processes() <= before
