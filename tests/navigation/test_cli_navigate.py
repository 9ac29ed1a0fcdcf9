"""`anytime navigate`: end to end on a small world, and one-line errors for bad input."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from anytime_navigation.task.frames import NO_DYNAMIC_PROFILE
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
        "seed", "size", "policy", "time_unit", "frames", "completion_time", "route_length",
        "optimal_length", "energy", "value", "expected_utility", "realised_utility",
        "prediction_error", "optimal_utility", "utility_ratio", "moving_obstacles", "decisions",
        "collisions", "evasions",
    }  # fmt: skip
    assert math.isclose(result["realised_utility"], result["value"] - result["energy"])
    assert result["moving_obstacles"] == result["decisions"] == 0
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


def test_out_holds_exactly_one_runs_output(cli: Cli, tmp_path: Path) -> None:
    """A later, shorter run into the same `--out` leaves none of the earlier run's frames; the
    user's own files there are kept."""
    out = tmp_path / "o"
    out.mkdir()
    (out / "frame-999.png").write_bytes(b"an earlier run's frame")
    (out / "notes.txt").write_text("mine")
    code, stdout, err = cli("navigate", "--size", "16", "--quiet", "--out", str(out))
    assert (code, err) == (0, "")
    frames = sorted(p.name for p in out.glob("frame-*.png"))
    assert frames == [f"frame-{i:03d}.png" for i in range(len(frames))]
    assert f"wrote {len(frames)} frame pictures" in stdout
    assert (out / "notes.txt").read_text() == "mine"


def test_out_being_written_by_another_run_is_refused_before_the_run(
    cli: Cli, tmp_path: Path
) -> None:
    from anytime.plugin.cli import owned_directory

    out = tmp_path / "o"
    with owned_directory(out, ("frame-*.png",)):
        (out / "frame-000.png").write_bytes(b"the other run's")
        code, stdout, err = cli("navigate", "--size", "16", "--quiet", "--out", str(out))
        assert (code, stdout) == (1, "")
        assert err == (
            f"anytime: error: cannot write '{out}': another run (process {os.getpid()}) is"
            " writing there; wait for it or choose another directory\n"
        )
        assert (out / "frame-000.png").read_bytes() == b"the other run's"


def test_a_map_is_named_by_its_own_size(cli: Cli) -> None:
    """The arena is 49 x 49: the summary says so (not the 64 x 64 grid it is planned on)."""
    from anytime_navigation.resources import data_file

    code, out, _ = cli("navigate", "--map", str(data_file("maps", "arena.map")), "--quiet")
    assert code == 0
    assert out.splitlines()[0] == "navigation task: 49x49 map arena.map, seed 0, policy monitored"


def test_loading_the_searches_says_what_it_is_doing_when_it_takes_long(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import time

    from anytime_navigation.cli import navigate as command

    monkeypatch.setattr(command, "NOTICE_SECONDS", 0.01)
    monkeypatch.setattr(command, "compile_searches", lambda: time.sleep(0.5))
    command._ready_searches(say=True)
    assert capsys.readouterr().err == (
        "anytime: loading the planner's compiled searches (the first run after an install"
        " compiles them: about 20 to 60 seconds, once)\n"
    )
    command._ready_searches(say=False)
    assert capsys.readouterr().err == ""
