"""Every numeric option is checked when it is parsed (finite, in range, not too large for
memory): one line, exit status 2, before any work."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from anytime.cli.common import MAX_LATTICE_POINTS, MAX_TIME_POINTS, MAX_TRIALS

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]


def arg(command: str, option: str, problem: str) -> str:
    return f"anytime {command}: error: argument {option}: {problem}\n"


TIME_GRID = [
    ("0:inf:1", "expected finite numbers, got '0:inf:1'"),
    ("0:nan:1", "expected finite numbers, got '0:nan:1'"),
    (
        "0:1e12:1",
        f"'0:1e12:1' has 1,000,000,000,001 totals, more than the limit of {MAX_TIME_POINTS:,}:"
        " give a larger STEP",
    ),
    (
        "0:1e308:1e-308",
        "'0:1e308:1e-308' has infinitely many totals, more than the limit of 10,000: give a"
        " larger STEP",
    ),
    ("5:1:1", "expected START:STOP:STEP with 0 <= START <= STOP and STEP > 0, got '5:1:1'"),
    ("0:10:0", "expected START:STOP:STEP with 0 <= START <= STOP and STEP > 0, got '0:10:0'"),
    ("0:10", "expected START:STOP:STEP (three numbers), got '0:10'"),
]


@pytest.mark.parametrize("command", ["compile", "plot"])
@pytest.mark.parametrize(("grid", "problem"), TIME_GRID, ids=[g for g, _ in TIME_GRID])
def test_time_grid(cli: Cli, command: str, grid: str, problem: str) -> None:
    code, out, err = cli(command, "x.any", f"--time-grid={grid}")
    assert (code, out, err) == (2, "", arg(command, "--time-grid", problem))


CASES = [
    (
        ["compile", "x.any", "--resolution", "0"],
        "--resolution",
        "expected a finite number > 0, got 0",
    ),
    (
        ["compile", "x.any", "--resolution", "inf"],
        "--resolution",
        "expected a finite number > 0, got inf",
    ),
    (
        ["compile", "x.any", "--input-quality", "0,1.5"],
        "--input-quality",
        "expected qualities from 0 to 1, got '0,1.5'",
    ),
    (
        ["compile", "x.any", "--input-quality", "nan"],
        "--input-quality",
        "expected qualities from 0 to 1, got 'nan'",
    ),
    (
        ["profile", "m", "--trials", str(10**12)],
        "--trials",
        f"expected a whole number from 1 to {MAX_TRIALS}, got {10**12}",
    ),
    (["profile", "m", "--trials", "10**12"], "--trials", "expected a whole number, got '10**12'"),
    (
        ["check", "m", "--trials", "0"],
        "--trials",
        f"expected a whole number from 1 to {MAX_TRIALS}, got 0",
    ),
    (
        ["profile", "m", "--workers", "0"],
        "--workers",
        "expected a whole number from 1 to 256, got 0",
    ),
    (
        ["profile", "m", "--seed=-1"],
        "--seed",
        "expected a whole number >= 0 (at most 2**64 - 1), got -1",
    ),
    (
        ["check", "m", "--seed", str(2**64)],
        "--seed",
        f"expected a whole number >= 0 (at most 2**64 - 1), got {2**64}",
    ),
    (
        ["calibrate", "m", "--seed=-1"],
        "--seed",
        "expected a whole number >= 0 (at most 2**64 - 1), got -1",
    ),
    (
        ["calibrate", "m", "--seconds", "inf"],
        "--seconds",
        "expected a number > 0 and <= 3600, got inf",
    ),
    (
        ["navigate", "--seed=-1"],
        "--seed",
        "expected a whole number >= 0 (at most 2**64 - 1), got -1",
    ),
    (["navigate", "--size", "12"], "--size", "expected a power of two from 8 to 4096, got 12"),
    (["navigate", "--size", "8192"], "--size", "expected a power of two from 8 to 4096, got 8192"),
    (["navigate", "--size=-4"], "--size", "expected a power of two from 8 to 4096, got -4"),
    (["navigate", "--radius", "0"], "--radius", "expected a whole number from 1 to 4096, got 0"),
    (["navigate", "--deadline", "nan"], "--deadline", "expected a finite number > 0, got nan"),
    (["navigate", "--contract", "-1"], "--contract", "expected a finite number > 0, got -1"),
    (
        ["navigate", "--moving-obstacles", "1001"],
        "--moving-obstacles",
        "expected a whole number from 0 to 1000, got 1001",
    ),
    (["navigate", "--start=-1,2"], "--start", "expected X,Y with X, Y >= 0, got '-1,2'"),
    (["plan", "--map", "m", "--goal=3,-2"], "--goal", "expected X,Y with X, Y >= 0, got '3,-2'"),
]


@pytest.mark.parametrize(("argv", "option", "problem"), CASES, ids=[" ".join(c[0]) for c in CASES])
def test_numeric_options(cli: Cli, argv: list[str], option: str, problem: str) -> None:
    code, out, err = cli(*argv)
    assert (code, out, err) == (2, "", arg(argv[0], option, problem))


def test_a_lattice_too_large_for_memory_is_refused_up_front(cli: Cli, navigation_any: Path) -> None:
    code, out, err = cli(
        "compile", str(navigation_any), "--schema", "navigate", "--time-grid", "0:3000:250",
        "--resolution", "1e-300",
    )  # fmt: skip
    assert (code, out) == (2, "")
    assert err == (
        "anytime compile: error: --resolution 1e-300: allocations on its multiples up to 3000"
        f" make a lattice of 3e+303 points, more than the limit of {MAX_LATTICE_POINTS:,}; give"
        " a larger --resolution\n"
    )
    code, out, err = cli(
        "compile", str(navigation_any), "--schema", "navigate", "--time-grid", "1e6:1000001:1"
    )
    assert (code, out) == (2, "")
    assert err == (
        "anytime compile: error: the time grid's step 1: allocations on its multiples up to"
        f" 1e+06 make a lattice of 1,000,002 points, more than the limit of"
        f" {MAX_LATTICE_POINTS:,}; give --resolution DT or a coarser --time-grid\n"
    )


def test_check_refuses_more_runs_than_it_keeps(cli: Cli) -> None:
    code, out, err = cli("check", "find-path", "--trials", "10000")
    assert (code, out) == (2, "")
    assert err == (
        "anytime check: error: --trials 10000: 6 cells x 22 runs each make 1,320,000 runs, more"
        " than the limit of 100,000; give fewer --trials\n"
    )
