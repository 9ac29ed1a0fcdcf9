"""Progress bars (tqdm) on standard error: drawn on a terminal, silent on a pipe or a file and
with --quiet, on every command that can run long."""

from __future__ import annotations

import io
from collections.abc import Callable

import pytest

from anytime.measure.progress import ProgressBar, timed_progress

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_bar_draws_on_a_terminal_only() -> None:
    terminal, pipe = Terminal(), io.StringIO()
    for stream in (terminal, pipe):
        with ProgressBar(10, label="approach", stream=stream) as bar:
            for _ in range(10):
                bar.update()
        assert bar.done == 10
    assert pipe.getvalue() == ""
    last = terminal.getvalue().rstrip("\n").split("\r")[-1]
    assert last.startswith("approach: 100%|")
    assert "| 10/10 trials [" in last and " trials/s]" in last
    assert terminal.getvalue().endswith("\n")


def test_quiet_is_silent_on_a_terminal_too() -> None:
    terminal = Terminal()
    with ProgressBar(3, label="x", stream=terminal, enabled=False) as bar:
        bar.update(3)
    with timed_progress(0.01, label="x", stream=terminal, enabled=False):
        pass
    assert terminal.getvalue() == ""


def test_a_count_not_known_in_advance() -> None:
    terminal = Terminal()
    with ProgressBar(None, label="navigate (monitored)", unit="frames", stream=terminal) as bar:
        bar.update()
        bar.update()
    assert (
        terminal.getvalue()
        .rstrip("\n")
        .split("\r")[-1]
        .startswith("navigate (monitored): 2 frames [")
    )


def test_a_timed_bar_fills_over_its_seconds() -> None:
    terminal, pipe = Terminal(), io.StringIO()
    for stream in (terminal, pipe):
        with timed_progress(0.05, label="wait calibration", stream=stream):
            pass
    assert pipe.getvalue() == ""
    assert terminal.getvalue().startswith("\rwait calibration:   0%|")
    assert terminal.getvalue().endswith("\n")


@pytest.mark.parametrize("command", ["profile", "check", "calibrate", "navigate", "plan"])
def test_every_long_command_has_quiet(cli: Cli, command: str) -> None:
    code, out, _ = cli(command, "--help")
    assert code == 0
    assert "--quiet " in out or "--quiet\n" in out


def test_no_bar_when_stderr_is_not_a_terminal(cli: Cli) -> None:
    code, out, err = cli("check", "get-domain-description", "--trials", "1")
    assert (code, err) == (0, "")
    assert "all 6 checks passed" in out
