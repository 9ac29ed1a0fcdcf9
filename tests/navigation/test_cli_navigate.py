"""`anytime navigate`: end to end on a small world, and one-line errors for bad input."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
from anytime_navigation.frames import NO_DYNAMIC_PROFILE
from conftest import Cli

from anytime.plot import MISSING_MATPLOTLIB


def navigate(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "anytime", "navigate", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_json_end_to_end():
    done = navigate("--size", "32", "--seed", "2", "--radius", "8", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert set(result) == {
        "seed", "size", "frames", "completion_time", "energy", "value", "utility",
        "predicted_utility", "prediction_error", "optimal_utility", "utility_ratio",
        "route_length", "optimal_length", "policy",
    }  # fmt: skip
    assert math.isclose(result["utility"], result["value"] - result["energy"])
    assert result["frames"] > 1 and result["size"] == 32
    assert result["route_length"] >= result["optimal_length"]


def _map(tmp_path, rows):
    path = tmp_path / "m.map"
    path.write_text(
        f"type octile\nheight {len(rows)}\nwidth {len(rows[0])}\nmap\n" + "\n".join(rows) + "\n"
    )
    return str(path)


@pytest.mark.parametrize(
    "args, words",
    [
        (["--map", "/no/such.map"], "cannot read"),
    ],
)
def test_bad_input_one_line(args, words):
    done = navigate(*args)
    assert done.returncode == 1
    assert words in done.stderr and done.stderr.count("\n") == 1
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize(
    "args, message",
    [
        (["--start", "1,1"], "anytime navigate: error: --start and --goal need --map\n"),
        (["--policy", "fixed"], "anytime navigate: error: --policy fixed needs --contract TICKS\n"),
    ],
)
def test_options_that_do_not_go_together_are_usage_errors(args, message):
    done = navigate(*args)
    assert (done.returncode, done.stderr) == (2, message)


def test_bad_maps(tmp_path):
    malformed = tmp_path / "bad.map"
    malformed.write_text("not a map\n")
    walled = _map(tmp_path, ["....", "@@@@", "....", "...."])
    for args, words in [
        (["--map", str(malformed)], "error"),
        (["--map", walled, "--start", "0,1", "--goal", "3,3"], "blocked"),
        (["--map", walled, "--start", "0,0", "--goal", "3,3"], "cannot be reached"),
    ]:
        done = navigate(*args)
        assert done.returncode == 1, (args, done.stderr)
        assert words in done.stderr and "Traceback" not in done.stderr


def test_navigate_out_without_matplotlib_says_so_before_the_run(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Installed without the plot extra, `--out` is one line naming the extra (it was an
    internal error after the whole run)."""
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    code, out, err = cli("navigate", "--size", "32", "--quiet", "--out", str(tmp_path / "o"))
    assert (code, out) == (1, "")
    assert err == f"anytime: error: {MISSING_MATPLOTLIB}\n"
    assert not (tmp_path / "o").exists()


def test_the_stopping_policy_without_a_dynamic_profile_is_bad_input(
    cli: Cli, tmp_path: Path
) -> None:
    """A profile directory with find-path's profile but not its dynamic profile: one line."""
    shipped = Path(__file__).parents[2] / "domains/navigation/anytime_navigation/profiles"
    (tmp_path / "find-path.yaml").write_text((shipped / "find-path.yaml").read_text())
    args = ("--size", "32", "--quiet", "--policy", "stopping", "--profiles", str(tmp_path))
    code, out, err = cli("navigate", *args)
    assert (code, out) == (1, "")
    assert err == f"anytime: error: {NO_DYNAMIC_PROFILE}\n"


def test_the_stopping_policy_runs(cli: Cli) -> None:
    args = ("--size", "32", "--seed", "3", "--quiet", "--policy", "stopping", "--json")
    code, out, err = cli("navigate", *args)
    assert (code, err) == (0, "")
    assert json.loads(out)["policy"] == "stopping"
