"""Ctrl-C ends any command with one line, `anytime: interrupted`, and exit status 130: no
traceback (the profile builder's workers included), and no half-written output (every file is
written to a temporary file renamed over it once complete)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import anytime.files
import anytime.library
from anytime.launch import Terminated
from anytime.measure.builder import Instance, register_problems
from anytime.modules import Context, Registry, Result, interruptible

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

INTERRUPTED = "anytime: interrupted\n"

MODULES = Registry()


@interruptible("pressed", inputs=[], registry=MODULES)
def pressed(ctx: Context, x: float) -> Iterator[Result]:
    """A module that raises KeyboardInterrupt itself (no Ctrl-C was pressed)."""
    ctx.tick(1)
    yield Result(x, 0.5)
    raise KeyboardInterrupt


class Problems:
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance(args=(float(rng.random()),))

    def score(self, instance: Instance, value: Any) -> float:
        return 0.5


register_problems(pressed, Problems(), time=[0, 1, 2])


@pytest.mark.parametrize("isolation", ["process", "none"])
def test_a_modules_own_keyboard_interrupt_is_a_failed_trial(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, isolation: str
) -> None:
    """No SIGINT reached the command: the interrupt is the module's, each trial fails (keeping
    the result it had), and the profile is written (a Ctrl-C is the tests below)."""
    monkeypatch.setattr(anytime.library, "REGISTRY", MODULES)
    out = tmp_path / "pressed.yaml"
    out.write_text("old\n")
    argv = ["profile", "pressed", "--trials", "4", "--no-plugins", "--quiet", "-o", str(out)]
    code, stdout, err = cli(*argv, "--isolation", isolation)
    assert (code, err) == (0, "")
    assert "4 of 4 runs failed; first: KeyboardInterrupt (trial 0 at input qualities [])" in stdout
    assert "  4 x KeyboardInterrupt\n" in stdout
    assert out.read_text() != "old\n"


def test_interrupted_before_the_rename_keeps_the_old_file(
    cli: Cli, navigation_any: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def replace(*args: object) -> None:
        raise KeyboardInterrupt

    out = tmp_path / "navigate.yaml"
    out.write_text("old\n")
    monkeypatch.setattr(anytime.files.os, "replace", replace)
    code, stdout, err = cli(
        "compile", str(navigation_any), "--schema", "navigate", "--time-grid", "0:1000:250",
        "-o", str(out),
    )  # fmt: skip
    assert (code, stdout, err) == (130, "", INTERRUPTED)
    assert out.read_text() == "old\n" and os.listdir(tmp_path) == ["navigate.yaml"]


def test_a_plugin_command_interrupted(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import anytime_navigation.cli.navigate as navigate

    def run_task(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(navigate, "run_task", run_task)
    (tmp_path / "events.jsonl").write_text("old\n")
    code, stdout, err = cli("navigate", "--size", "16", "--out", str(tmp_path))
    assert (code, stdout, err) == (130, "", INTERRUPTED)
    assert (tmp_path / "events.jsonl").read_text() == "old\n"


@pytest.mark.parametrize(
    ("signal_raised", "said", "status"),
    [(KeyboardInterrupt, INTERRUPTED, 130), (Terminated, "anytime: terminated\n", 143)],
)
def test_an_interrupt_compiled_code_reports_as_an_error_still_ends_as_one(
    cli: Cli,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    signal_raised: type[KeyboardInterrupt],
    said: str,
    status: int,
) -> None:
    """A signal handled while compiled code calls back into Python surfaces as a SystemError
    caused by the interrupt (numba's, as a compiled call returns; CI saw it under `anytime
    navigate`): still one line and the interrupt's status, not an internal error."""
    import anytime_navigation.cli.navigate as navigate

    def run_task(*args: object, **kwargs: object) -> None:
        try:
            raise signal_raised
        except KeyboardInterrupt as interrupt:
            message = (
                "CPUDispatcher(<function refine_step>) returned a result with an exception set"
            )
            raise SystemError(message) from interrupt

    monkeypatch.setattr(navigate, "run_task", run_task)
    code, stdout, err = cli("navigate", "--size", "16", "--out", str(tmp_path))
    assert (code, stdout, err) == (status, "", said)


def _interrupt(
    argv: list[str], cwd: Path, sent: signal.Signals = signal.SIGINT
) -> subprocess.CompletedProcess[str]:
    """Run `anytime ARGV` in a process group of its own, send the group SIGINT once the command
    runs (as a terminal's Ctrl-C does: worker processes get it too), and wait for the end; for
    SIGTERM, send it to the command's process alone (as `timeout` and CI runners do), and check
    that no process of the group is left once it has ended."""
    code = (
        "import sys; from anytime.cli import main; print('ready', flush=True);"
        f" sys.exit(main({argv!r}))"
    )
    process = subprocess.Popen(
        [sys.executable, "-c", code],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    assert process.stdout is not None
    assert process.stdout.readline() == "ready\n"
    time.sleep(1.0)  # into the command's work (not a timing assertion: any moment will do)
    if sent == signal.SIGINT:
        os.killpg(process.pid, signal.SIGINT)
    else:
        os.kill(process.pid, sent)
    stdout, stderr = _communicate(process)
    _no_process_left(process.pid)
    return subprocess.CompletedProcess(argv, process.returncode, stdout, stderr)


def _communicate(process: subprocess.Popen[str]) -> tuple[str, str]:
    """The command's output once it has ended; if it has not within a minute, its process group
    is killed (so that a failing test leaves nothing running) and the test fails."""
    try:
        return process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        raise


def _no_process_left(group: int) -> None:
    for _ in range(50):  # stopped workers may take a moment to be reaped
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return
        time.sleep(0.1)
    os.killpg(group, signal.SIGKILL)
    raise AssertionError(f"processes of group {group} were left running")


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a process")
def test_ctrl_c_in_the_profile_builders_worker_pool(tmp_path: Path) -> None:
    out = tmp_path / "find-path.yaml"
    out.write_text("old\n")
    argv = ["profile", "find-path", "--trials", "5000", "--workers", "2", "-o", str(out)]
    done = _interrupt(argv, tmp_path)
    assert (done.returncode, done.stdout, done.stderr) == (130, "", INTERRUPTED)
    assert out.read_text() == "old\n" and os.listdir(tmp_path) == ["find-path.yaml"]


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a process")
@pytest.mark.parametrize("isolation", ["process", "none"])
def test_ctrl_c_in_the_profile_builder_without_workers(tmp_path: Path, isolation: str) -> None:
    """The user's Ctrl-C (a SIGINT to the command) stops the build, whether the trial it meets
    runs in the command's process or in a child of its own, unlike a module's own interrupt."""
    out = tmp_path / "find-path.yaml"
    out.write_text("old\n")
    argv = ["profile", "find-path", "--trials", "5000", "--isolation", isolation, "-o", str(out)]
    done = _interrupt(argv, tmp_path)
    assert (done.returncode, done.stdout, done.stderr) == (130, "", INTERRUPTED)
    assert out.read_text() == "old\n" and os.listdir(tmp_path) == ["find-path.yaml"]


@pytest.mark.skipif(sys.platform == "win32", reason="SIGTERM to a process")
def test_sigterm_to_the_profile_builder_stops_its_workers(tmp_path: Path) -> None:
    """SIGTERM to the command alone (its workers are not sent it) is handled like Ctrl-C: the
    workers are stopped, none is left, the old file is kept; one line and status 143."""
    out = tmp_path / "find-path.yaml"
    out.write_text("old\n")
    argv = ["profile", "find-path", "--trials", "5000", "--workers", "2", "-o", str(out)]
    done = _interrupt(argv, tmp_path, signal.SIGTERM)
    assert (done.returncode, done.stdout, done.stderr) == (143, "", "anytime: terminated\n")
    assert out.read_text() == "old\n" and os.listdir(tmp_path) == ["find-path.yaml"]


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a process")
def test_ctrl_c_in_navigate(tmp_path: Path) -> None:
    done = _interrupt(["navigate", "--size", "64", "--compare", "--out", str(tmp_path)], tmp_path)
    assert (done.returncode, done.stdout, done.stderr) == (130, "", INTERRUPTED)
    assert [p for p in os.listdir(tmp_path) if ".partial" in p] == []


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a process")
@pytest.mark.parametrize("after", [0.5, 1.0])
def test_ctrl_c_while_the_command_starts(tmp_path: Path, after: float) -> None:
    """The installed `anytime` command, interrupted while it is still importing the framework
    and its plugins (or, on a fast machine, just after): one line and 130 either way, where it
    printed a traceback from the imports. (Within the interpreter's own first tens of
    milliseconds, before any of the command's code runs, Python itself reports the interrupt.)"""
    command = Path(sys.executable).parent / "anytime"
    process = subprocess.Popen(
        [str(command), "profile", "find-path", "--trials", "5000", "-o", "find-path.yaml"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    time.sleep(after)  # some moment of the start-up (not a timing assertion: any will do)
    os.killpg(process.pid, signal.SIGINT)
    stdout, stderr = _communicate(process)
    assert (process.returncode, stdout, stderr) == (130, "", INTERRUPTED)
    assert os.listdir(tmp_path) == []


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a process")
def test_ctrl_c_in_verifys_worker_pool(tmp_path: Path, navigation_any: Path) -> None:
    argv = ["verify", str(navigation_any), "--schema", "navigate", "--runs", "10000"]
    done = _interrupt([*argv, "--workers", "2"], tmp_path)
    assert (done.returncode, done.stdout, done.stderr) == (130, "", INTERRUPTED)
