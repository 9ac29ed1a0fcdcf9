"""`anytime verify`: the promise table, the exit status (1 when a budget fails), the compile
options it shares with `anytime compile`, and its error messages. The plugin is the lab of
tests/verify_modules.py, as if installed (its entry point found by importlib.metadata)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
import verify_modules as lab

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

RULE = "(|realised - promised| <= max(0.01, 3 se), no run over its budget)"


@pytest.fixture
def lab_any(lab_plugin: Path) -> str:
    """The lab's schema file, with the lab plugin installed (and no other)."""
    (lab_plugin / "lab.any").write_text(lab.SCHEMAS + "(defschema plain (x) (guess x))\n")
    return "lab.any"


def test_a_promise_that_holds(cli: Cli, lab_any: str) -> None:
    code, out, err = cli("verify", lab_any, "--schema", "fair", "--runs", "100", "--quiet")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0] == (
        "schema fair: 100 runs per budget on HiddenNumbers problems, seed 0, scored by"
        " HiddenNumbers.score"
    )
    assert lines[1] == "  T (ticks)  promised  realised ± se      z  over budget   ok"
    assert [line.split()[0] for line in lines[2:-1]] == ["0", "2", "4", "6", "8", "10", "12"]
    assert all(line.endswith("yes") for line in lines[2:-1])
    assert lines[-1] == f"  passed at all 7 budgets {RULE}"


def test_a_wrong_promise_exits_1(cli: Cli, lab_any: str) -> None:
    code, out, err = cli("verify", lab_any, "--schema", "low", "--runs", "100", "--budgets", "0,4")
    assert (code, err) == (1, "")
    lines = out.splitlines()
    assert lines[2].split() == ["0", "0.000", "0.000", "±", "0.000", "+0.00", "0/100", "yes"]
    assert lines[3].split()[-1] == "NO"
    assert lines[4] == f"  FAILED at 1 of 2 budgets {RULE}:"
    assert lines[5:] == ["    T = 4: realised 0.093 below the promise (tolerance 0.025)"]


def test_runs_over_budget_exit_1(cli: Cli, lab_any: str) -> None:
    code, out, _ = cli("verify", lab_any, "--schema", "over", "--runs", "3", "--budgets", "4")
    assert code == 1
    row = ["4", "1.000", "1.000", "±", "0.000", "+0.00", "3/3", "NO"]
    assert out.splitlines()[2].split() == row
    assert out.splitlines()[-1] == "    T = 4: 3 of 3 runs over budget"


def test_json_and_workers(cli: Cli, lab_any: str) -> None:
    args = ("verify", lab_any, "--schema", "low", "--runs", "30", "--json", "--budgets", "2,8")
    code, out, _ = cli(*args)
    assert code == 1
    one = json.loads(out)
    assert list(one) == [
        "schema", "time_unit", "problem_set", "scored", "runs_per_budget", "seed", "passed",
        "min_tolerance", "sigmas", "budgets", "dependence_fit", "seconds",
    ]  # fmt: skip
    assert (one["schema"], one["passed"], [b["budget"] for b in one["budgets"]]) == (
        "low",
        False,
        [2.0, 8.0],
    )
    code, out, _ = cli(*args, "--workers", "2")
    two = json.loads(out)
    del one["seconds"], two["seconds"]
    assert (code, two) == (1, one)


def test_the_compile_options_override_the_problem_sets(cli: Cli, lab_any: str) -> None:
    """The lab declares totals 0 to 12 every 2 ticks on a lattice of 1; --time-grid gives
    others, on its own step's lattice as `anytime compile` does."""
    code, out, _ = cli(
        "verify", lab_any, "--schema", "fair", "--runs", "20", "--time-grid", "0:8:4", "--json"
    )
    assert code == 0
    assert [b["budget"] for b in json.loads(out)["budgets"]] == [0.0, 4.0, 8.0]
    code, out, _ = cli(
        "verify", lab_any, "--schema", "fair", "--runs", "20", "--time-unit", "seconds"
    )
    assert (code, out) == (1, "")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--schema", "fair", "--budgets", "5"],
            "anytime: error: budget 5 is not a total of the compiled table of schema 'fair'"
            " (0, 2, ..., 12)",
        ),
        (
            [],
            "anytime: error: lab.any defines 4 schemas: say which one to verify with --schema NAME",
        ),
        (
            ["--schema", "nope"],
            "lab.any: error: no schema named 'nope' (the file defines: fair, low, over, plain)",
        ),
        (
            ["--schema", "plain"],
            "anytime: error: no program problem set is declared for schema 'plain' (declared"
            " for: fair, low, over); a plugin declares them in Plugin.program_problems",
        ),
        (
            ["--schema", "fair", "--time-unit", "seconds"],
            "lab.any: error: schema 'fair': the time grid is in seconds but its modules'"
            " profiles are in ticks",
        ),
        (
            ["--schema", "fair", "--no-plugins"],
            "anytime: error: no program problem set is declared for schema 'fair' (declared"
            " for: none); a plugin declares them in Plugin.program_problems",
        ),
    ],
)
def test_bad_input_exits_1_with_one_line(
    cli: Cli, lab_any: str, argv: list[str], message: str
) -> None:
    code, out, err = cli("verify", lab_any, "--runs", "2", *argv)
    assert (code, out, err) == (1, "", message + "\n")


def test_a_file_that_cannot_be_read(cli: Cli, lab_any: str) -> None:
    code, out, err = cli("verify", "no-such-file.any", "--schema", "fair")
    assert (code, out, err) == (
        1,
        "",
        "anytime: error: cannot read 'no-such-file.any': No such file or directory\n",
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--runs", "0"], "argument --runs: expected a whole number from 1 to 100000, got 0"),
        (
            ["--budgets", "x"],
            "argument --budgets: expected totals separated by commas, got 'x'",
        ),
        (["--budgets", "-4"], "argument --budgets: expected finite totals >= 0, got '-4'"),
        (
            ["--workers", "2", "--scheduler", "tcp://localhost:1"],
            "argument --scheduler: not allowed with argument --workers",
        ),
        (
            ["--seed", "-1"],
            "argument --seed: expected a whole number >= 0 (at most 2**64 - 1), got -1",
        ),
        (
            ["--time-grid", "0:inf:1"],
            "argument --time-grid: expected finite numbers, got '0:inf:1'",
        ),
        (
            ["--resolution", "0.0001"],
            "--resolution 0.0001: allocations on its multiples up to 12 make a lattice of"
            " 120,001 points, more than the limit of 20,000; give a larger --resolution",
        ),
    ],
)
def test_usage_errors_exit_2_with_one_line(
    cli: Cli, lab_any: str, argv: list[str], message: str
) -> None:
    code, out, err = cli("verify", lab_any, "--schema", "fair", *argv)
    assert (code, out, err) == (2, "", f"anytime verify: error: {message}\n")


@pytest.mark.slow  # Dask gives up connecting after 30 s
def test_a_scheduler_that_cannot_be_reached(cli: Cli, lab_any: str) -> None:
    pytest.importorskip("distributed")
    code, out, err = cli(
        "verify", lab_any, "--schema", "fair", "--runs", "2", "--scheduler", "tcp://127.0.0.1:9"
    )
    assert (code, out) == (1, "")
    assert err.startswith(
        "anytime: error: cannot connect to the Dask scheduler at tcp://127.0.0.1:9"
    )
