"""`anytime profile --dynamic / --traces` writes a module's dynamic profile and traces, and
`anytime library show` tells what a dynamic profile says."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from conftest import Cli

from anytime.profiles import tabulate
from anytime.profiles.dynamic import DynamicProfile, QualityTraces
from anytime.profiles.dynamic_io import load_dynamic_profile, load_traces, save_dynamic_profile
from anytime.profiles.io import load_profile, save_profile


def test_profile_writes_the_dynamic_profile_beside_the_profile_and_the_traces(
    cli: Cli, tmp_path: Path
) -> None:
    out, traces = tmp_path / "g.yaml", tmp_path / "g.traces.yaml"
    base = ("profile", "get-domain-description", "--trials", "3", "--quiet", "-o", str(out))
    code, text, err = cli(*base, "--dynamic", "--states", "4", "--traces", str(traces))
    assert code == 0, err
    dynamic = tmp_path / "g.dynamic.yaml"
    assert text.splitlines()[-1] == f"wrote {out}, {dynamic}, {traces}"
    recorded = load_traces(traces)
    assert recorded.trials == 3 and recorded.module == "get-domain-description"
    assert load_dynamic_profile(dynamic) == DynamicProfile.from_traces(recorded, states=4)
    profile = load_profile(out)
    assert profile.mean is not None
    np.testing.assert_array_equal(recorded.quality.mean(axis=-2), profile.mean)


def test_profile_json_names_the_files_it_wrote(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "g.yaml"
    base = ("profile", "get-domain-description", "--trials", "2", "-o", str(out), "--json")
    code, text, err = cli(*base)
    assert code == 0, err
    data = json.loads(text)
    assert (data["file"], data["dynamic_file"], data["traces_file"]) == (str(out), None, None)
    code, text, err = cli(*base, "--dynamic")
    assert code == 0, err
    assert json.loads(text)["dynamic_file"] == str(tmp_path / "g.dynamic.yaml")
    assert not (tmp_path / "g.traces.yaml").exists()


def test_states_without_dynamic_is_a_usage_error(cli: Cli) -> None:
    code, _, err = cli("profile", "get-domain-description", "--states", "4")
    assert code == 2
    assert err.splitlines()[-1] == "anytime profile: error: --states K goes with --dynamic"
    code, _, err = cli("profile", "get-domain-description", "--entered", "4")
    assert code == 2
    assert err.splitlines()[-1] == "anytime profile: error: --entered C goes with --dynamic"


def test_entered_makes_the_state_remember_when_a_run_entered_its_bin(
    cli: Cli, tmp_path: Path
) -> None:
    out, traces = tmp_path / "g.yaml", tmp_path / "g.traces.yaml"
    base = ("profile", "get-domain-description", "--trials", "3", "--quiet", "-o", str(out))
    code, _, err = cli(
        *base, "--dynamic", "--states", "4", "--entered", "3", "--ends", "--traces", str(traces)
    )
    assert code == 0, err
    dynamic = load_dynamic_profile(tmp_path / "g.dynamic.yaml")
    recorded = load_traces(traces)
    assert dynamic == DynamicProfile.from_traces(recorded, states=4, entered=3, ends=True)
    assert dynamic.classes == 3 and dynamic.ends
    code, _, err = cli("profile", "get-domain-description", "--ends")
    assert code == 2
    assert err.splitlines()[-1] == "anytime profile: error: --ends goes with --dynamic"


def test_traces_that_cannot_be_written_are_an_input_error(cli: Cli, tmp_path: Path) -> None:
    missing = tmp_path / "no" / "t.yaml"
    code, text, err = cli(
        "profile",
        "get-domain-description",
        "--trials",
        "2",
        "--quiet",
        "-o",
        str(tmp_path / "g.yaml"),
        "--traces",
        str(missing),
    )
    assert code == 1 and text == ""
    assert err == f"anytime: error: cannot write '{missing}': No such file or directory\n"


def hand_profiles(directory: Path, entered: list[int] | None = None, ends: bool = False) -> Path:
    """A profile-only module 'hand' (no inputs, times 0, 1, 2) and its dynamic profile (with
    entry classes `entered`; with `ends`, the first run ending at time 1)."""
    directory.mkdir()
    save_profile(
        tabulate(lambda t: 0.4 * t, time=[0, 1, 2], module="hand"), directory / "hand.yaml"
    )
    traces = QualityTraces(
        module="hand",
        time=[0, 1, 2],
        quality=[[0.0, 0.6, 0.8], [0.0, 0.2, 0.7]],
        scored=[[False, True, True], [False, True, True]],
        estimate=[[0.0, 0.3, 0.9], [0.0, 0.1, 0.4]],
        reports="estimate",
        finished=[1.0, 2.0] if ends else None,
    )
    dynamic = DynamicProfile.from_traces(traces, bins=[0, 0.5, 1], entered=entered, ends=ends)
    save_dynamic_profile(dynamic, directory / "hand.dynamic.yaml")
    return directory


def test_library_show_tells_what_the_dynamic_profile_says(cli: Cli, tmp_path: Path) -> None:
    profiles = hand_profiles(tmp_path / "p")
    code, text, err = cli("library", "show", "hand", "--profiles", str(profiles), "--no-plugins")
    assert code == 0, err
    section = text[text.index("dynamic profile:") :]
    assert section == (
        f"dynamic profile: {profiles / 'hand.dynamic.yaml'}\n"
        "  observed        the module's own estimate of its quality, with P(true quality |"
        " estimate)\n"
        "  states          2 quality bins: 0, 0.5, 1\n"
        "  time (ticks)    0, 1, 2\n"
        "  samples         2 trials per cell\n"
        "  estimate right  67% of runs (in the true quality's bin)\n"
        "  expected gain in true quality of the next step (rows: state; columns: time in"
        " ticks):\n"
        "    state \\ from time  0       1\n"
        "    [0, 0.5)           +0.400  +0.350\n"
        "    [0.5, 1]           -       -\n"
    )


def test_library_show_names_the_entry_classes_of_the_states(cli: Cli, tmp_path: Path) -> None:
    profiles = hand_profiles(tmp_path / "p", entered=[0, 1, 3])
    code, text, err = cli("library", "show", "hand", "--profiles", str(profiles), "--no-plugins")
    assert code == 0, err
    lines = text[text.index("dynamic profile:") :].splitlines()
    assert lines[3] == (
        "  entered         each bin in 2 classes of the time the run entered it, from 0, 1 (4"
        " states)"
    )
    assert lines[-5:] == [
        "    state \\ from time  0       1",
        "    [0, 0.5) since 0   +0.400  +0.350",
        "    [0, 0.5) since 1   -       -",
        "    [0.5, 1] since 0   -       -",
        "    [0.5, 1] since 1   -       -",
    ]


def test_library_show_gives_no_gain_for_a_run_that_ended(cli: Cli, tmp_path: Path) -> None:
    profiles = hand_profiles(tmp_path / "p", ends=True)
    args = ("library", "show", "hand", "--profiles", str(profiles), "--no-plugins")
    code, text, err = cli(*args, "--json")
    assert code == 0, err
    dynamic = json.loads(text)["dynamic_profile"]
    assert dynamic["ends"] is True and dynamic["states"] == 4
    assert [row[2:] for row in dynamic["expected_gain"]] == [[None, None], [None, None]]
    code, text, err = cli(*args)
    assert code == 0, err
    assert "  ended           a state per bin for runs that ended by themselves\n" in text
    assert " ended " not in text[text.index("expected gain") :]  # no row for ended runs


def test_library_show_json_carries_the_dynamic_profile(cli: Cli, tmp_path: Path) -> None:
    profiles = hand_profiles(tmp_path / "p")
    args = ("library", "show", "hand", "--profiles", str(profiles), "--no-plugins", "--json")
    code, text, err = cli(*args)
    assert code == 0, err
    dynamic = json.loads(text)["dynamic_profile"]
    assert dynamic == {
        "file": str(profiles / "hand.dynamic.yaml"),
        "observed": "estimate",
        "states": 2,
        "quality_bins": [0.0, 0.5, 1.0],
        "entered": None,
        "ends": False,
        "time_grid": [0.0, 1.0, 2.0],
        "time_unit": "ticks",
        "samples": 2,
        "input_quality": [],
        "expected_gain": [[0.4, None], [0.35, None]],
        "estimate_in_true_bin": round(2 / 3, 12),
    }
    (profiles / "hand.dynamic.yaml").unlink()
    code, text, err = cli(*args)
    assert code == 0 and json.loads(text)["dynamic_profile"] is None


def test_library_show_names_a_broken_dynamic_profile(cli: Cli, tmp_path: Path) -> None:
    profiles = hand_profiles(tmp_path / "p")
    path = profiles / "hand.dynamic.yaml"
    path.write_text(path.read_text().replace("observed: estimate", "observed: sometimes"))
    code, text, err = cli("library", "show", "hand", "--profiles", str(profiles), "--no-plugins")
    assert code == 1 and text == ""
    assert err == (
        f"anytime: error: {path}: observed: expected 'true' or 'estimate' or 'none', got"
        " 'sometimes'\n"
    )


def test_profile_outputs_that_are_one_file_are_refused_before_measuring(
    cli: Cli, tmp_path: Path
) -> None:
    """`--traces` naming the profile's own file (or its dynamic profile's) would replace it
    after the whole measurement: refused up front, nothing written."""
    out = tmp_path / "g.yaml"
    base = ("profile", "get-domain-description", "--trials", "2", "--quiet", "-o", str(out))
    dynamic = tmp_path / "g.dynamic.yaml"
    link = tmp_path / "link.yaml"
    link.symlink_to(out)
    spelled = f"{tmp_path}/./g.dynamic.yaml"
    cases = [
        ((*base, "--traces", str(out)), f"--traces '{out}' is also the profile's file"),
        ((*base, "--traces", str(link)), f"--traces '{link}' is also the profile's file"),
        (
            (*base, "--dynamic", "--traces", spelled),
            f"--traces '{spelled}' is also the dynamic profile's file",
        ),
    ]
    for argv, message in cases:
        code, text, err = cli(*argv)
        assert (code, text) == (1, "")
        assert err == f"anytime: error: {message}; give another file\n"
    assert not out.exists() and not dynamic.exists()
