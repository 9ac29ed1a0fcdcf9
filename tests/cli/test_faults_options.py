"""Issue 37, item 11: options that would make a result meaningless are refused, not accepted
silently. A --resolution larger than the largest total of the time grid (every allocation would
be 0) and `calibrate --to` without the --profile it converts are usage errors (exit 2), before
any work, with the limit in the message."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]


def test_a_resolution_larger_than_the_largest_total_is_refused(
    cli: Cli, navigation_any: Path
) -> None:
    code, out, err = cli(
        "compile", str(navigation_any), "--schema", "navigate", "--time-grid", "0:3000:250",
        "--resolution", "1e300",
    )  # fmt: skip
    assert (code, out, err) == (
        2,
        "",
        "anytime compile: error: --resolution 1e+300: larger than the largest total of the time"
        " grid, 3000, so every allocation would be 0; give at most 3000\n",
    )


def test_a_resolution_of_the_largest_total_is_accepted(cli: Cli, navigation_any: Path) -> None:
    code, _, err = cli(
        "compile", str(navigation_any), "--schema", "navigate", "--time-grid", "0:3000:3000",
        "--resolution", "3000", "--json",
    )  # fmt: skip
    assert (code, err) == (0, "")


def test_calibrate_refuses_to_without_a_profile(cli: Cli) -> None:
    code, out, err = cli("calibrate", "find-path", "--to", "seconds")
    assert (code, out) == (2, "")
    assert err.endswith(
        "anytime calibrate: error: --to seconds: --to converts a --profile FILE, and none was"
        " given\n"
    )
