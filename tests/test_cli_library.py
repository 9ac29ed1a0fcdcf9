"""`anytime library list|show` and `anytime parse --check-calls/--profiles`, as users meet them."""

import importlib.metadata
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import Cli

from anytime import REGISTRY, Registry, Result, interruptible
from anytime.library import PLUGIN_GROUP
from anytime.profiles import Exponential, tabulate
from anytime.profiles.io import save_profile

TOY_PLUGIN = Path(__file__).resolve().parent / "plugins" / "toy_plugin"
HERE = f"python module {__name__}"

FIND_PATH = tabulate(
    lambda t, q: q * t / 400,
    time=[0, 100, 200, 400],
    bins=[0.0, 0.25, 0.5, 0.75, 1.0],
    input_grids=[[0.5, 1.0]],
    inputs=["domain"],
    module="find-path",
)
VISION = tabulate(Exponential(0.05), time=[0, 10, 20], module="get-domain-description")
MERGE = tabulate(
    lambda t, a, b: a * b * t / 100,
    time=[0, 50, 100],
    input_grids=[[0.5, 1.0], [0.5, 1.0]],
    inputs=["left", "right"],
    module="merge",
)


@pytest.fixture
def registry(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Registry:
    """The command's in-process registry: a fresh one, with one module; no installed plugins.

    The working directory is `tmp_path`, which holds `profiles/` with three profile files.
    """
    fresh = Registry()

    @interruptible("plan-route", inputs=["domain"], profile=FIND_PATH, registry=fresh)
    def plan_route(ctx: Any, start: Any, goal: Any, domain: Any) -> Iterator[Result]:
        yield Result(None, 0.0)

    monkeypatch.setattr("anytime.library.REGISTRY", fresh)
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **selection: [])
    monkeypatch.chdir(tmp_path)
    (tmp_path / "profiles").mkdir()
    save_profile(FIND_PATH, "profiles/find-path.yaml")
    save_profile(VISION, "profiles/vision.yaml")
    save_profile(MERGE, "profiles/merge.yaml")
    return fresh


def test_library_list_prints_a_table(cli: Cli, registry: Registry) -> None:
    code, out, err = cli("library", "list", "--profiles", "profiles")
    assert (code, err) == (0, "")
    assert out.splitlines() == [
        "NAME                    KIND           INPUTS       PROFILE"
        "                                        ORIGIN",
        "find-path               interruptible  domain       2 input grid pts x 4 times x 4 bins,"
        " ticks     profile file profiles/find-path.yaml",
        "get-domain-description  interruptible  -            3 times x 10 bins, ticks"
        "                       profile file profiles/vision.yaml",
        "merge                   interruptible  left, right  2x2 input grid pts x 3 times x 10"
        " bins, ticks  profile file profiles/merge.yaml",
        f"plan-route              interruptible  domain       2 input grid pts x 4 times x 4 bins,"
        f" ticks     {HERE}",
    ]


def test_library_list_json(cli: Cli, registry: Registry) -> None:
    code, out, err = cli("library", "list", "--json", "--profiles", "profiles")
    assert (code, err) == (0, "")
    rows = json.loads(out)
    assert [row["module"] for row in rows] == [
        "find-path",
        "get-domain-description",
        "merge",
        "plan-route",
    ]
    assert rows[0] == {
        "module": "find-path",
        "kind": "interruptible",
        "inputs": ["domain"],
        "arity": None,
        "origin": "profile file profiles/find-path.yaml",
        "profile": {
            "description": "2 input grid pts x 4 times x 4 bins, ticks",
            "file": "profiles/find-path.yaml",
            "input_grid_points": [2],
            "time_points": 4,
            "bins": 4,
            "time_unit": "ticks",
            "measured": False,
        },
        "profile_error": None,
    }
    assert (rows[3]["arity"], rows[3]["origin"], rows[3]["profile"]["file"]) == (3, HERE, None)


def test_library_list_without_modules(cli: Cli, registry: Registry) -> None:
    registry.remove("plan-route")
    assert cli("library", "list") == (
        0,
        "no modules found (looked in: installed plugins, in-process registry)\n",
        "",
    )
    assert cli("library", "list", "--json", "--no-plugins") == (0, "[]\n", "")


def test_library_show_one_input(cli: Cli, registry: Registry) -> None:
    code, out, err = cli("library", "show", "Plan-Route")
    assert (code, err) == (0, "")
    assert out.splitlines() == [
        "name:        plan-route",
        "kind:        interruptible",
        f"origin:      {HERE}",
        "parameters:  start, goal, domain",
        "inputs:      domain",
        "profile:     in memory",
        "axes:",
        "  input quality (domain)  0.5, 1",
        "  time (ticks)            0, 100, 200, 400",
        "  quality bins            0, 0.25, 0.5, 0.75, 1 (4 bins)",
        "",
        "expected quality (rows: domain quality; columns: time in ticks):",
        "  domain \\ time  0      100    200    400",
        "  0.5            0.000  0.125  0.250  0.500",
        "  1              0.000  0.250  0.500  1.000",
    ]


def test_library_show_profile_file_with_two_inputs(cli: Cli, registry: Registry) -> None:
    code, out, err = cli("library", "show", "merge", "--profiles", "profiles")
    assert (code, err) == (0, "")
    assert out.splitlines() == [
        "name:        merge",
        "kind:        interruptible (profile only)",
        "origin:      profile file profiles/merge.yaml",
        "parameters:  not known (profile only: calls are not checked for arity)",
        "inputs:      left, right",
        "profile:     profiles/merge.yaml",
        "axes:",
        "  input quality (left)   0.5, 1",
        "  input quality (right)  0.5, 1",
        "  time (ticks)           0, 50, 100",
        "  quality bins           0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1 (10 bins)",
        "",
        "expected quality (rows: left, right quality; columns: time in ticks; the diagonal:"
        " every input at its i-th grid pt):",
        "  left, right \\ time  0      50     100",
        "  0.5, 0.5            0.000  0.125  0.250",
        "  1, 1                0.000  0.500  1.000",
    ]


def test_library_show_many_times_and_no_input(cli: Cli, registry: Registry) -> None:
    save_profile(
        tabulate(Exponential(0.1), time=range(0, 100, 10), module="vision"),
        "profiles/vision.yaml",
    )
    code, out, _ = cli("library", "show", "vision", "--profiles", "profiles")
    assert code == 0
    assert out.splitlines()[-3:] == [
        "expected quality by time (ticks; 6 of 10 times, --times 0 shows every one):",
        "  time     0      20     40     50     70     90",
        "  quality  0.000  0.865  0.982  0.993  0.999  1.000",
    ]


def test_library_show_json(cli: Cli, registry: Registry) -> None:
    code, out, _ = cli("library", "show", "find-path", "--json", "--profiles", "profiles")
    assert code == 0
    data = json.loads(out)
    assert data["parameters"] == []
    assert data["profile"]["input_grids"] == [[0.5, 1.0]]
    assert data["profile"]["time_grid"] == [0.0, 100.0, 200.0, 400.0]
    assert data["profile"]["quality_bins"] == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert data["profile"]["expected_quality_table"] == [
        [0.0, 0.125, 0.25, 0.5],
        [0.0, 0.25, 0.5, 1.0],
    ]


def test_library_show_an_unknown_name(cli: Cli, registry: Registry) -> None:
    assert cli("library", "show", "find-pth", "--profiles", "profiles") == (
        1,
        "",
        "anytime: error: no module named 'find-pth'; did you mean 'find-path'?\n",
    )


def test_library_errors_are_one_line_with_exit_1(cli: Cli, registry: Registry) -> None:
    assert cli("library", "list", "--profiles", "nope") == (
        1,
        "",
        "anytime: error: profile directory 'nope' does not exist\n",
    )
    save_profile(tabulate(Exponential(0.1), time=[0, 1], module="plan-route"), "profiles/p.yaml")
    assert cli("library", "list", "--profiles", "profiles") == (
        1,
        "",
        f"anytime: error: module 'plan-route' is defined twice: in {HERE} and in "
        "profile file profiles/p.yaml\n",
    )
    Path("profiles/p.yaml").unlink()
    Path("profiles/bad.yaml").write_text("format: anytime-profile/1\n")
    assert cli("library", "show", "x", "--profiles", "profiles") == (
        1,
        "",
        "anytime: error: profiles/bad.yaml: time: missing field (expected a list of times, got"
        " nothing)\n",
    )


def test_library_list_reports_an_unreadable_profile_and_lists_the_rest(
    cli: Cli, registry: Registry
) -> None:
    @interruptible("sense", inputs=[], profile=Path("missing.yaml").resolve(), registry=registry)
    def sense(ctx: Any) -> Iterator[Result]:
        yield Result(None, 1.0)

    code, out, err = cli("library", "list")
    assert code == 1
    assert out.splitlines() == [
        "NAME        KIND           INPUTS  PROFILE                                     ORIGIN",
        f"plan-route  interruptible  domain  2 input grid pts x 4 times x 4 bins, ticks  {HERE}",
        f"sense       interruptible  -       unreadable (error below)                    {HERE}",
    ]
    missing = Path("missing.yaml").resolve()
    problem = f"{missing}: no such profile file (the profile of module 'sense', from {HERE})"
    assert err == f"anytime: error: {problem}\n"
    code, out, err = cli("library", "list", "--json")
    assert code == 1
    row = json.loads(out)[1]
    assert (row["module"], row["profile"]) == ("sense", None)
    assert row["profile_error"] == problem  # the error itself, without the command's prefix
    assert err == f"anytime: error: {problem}\n"


def test_library_needs_a_subcommand(cli: Cli) -> None:
    code, _, err = cli("library")
    assert code == 2
    assert err.endswith("error: the following arguments are required: COMMAND\n")
    code, out, _ = cli("library", "show", "--help")
    assert code == 0
    assert "--profiles DIR" in out and "--no-plugins" in out


# --- parse checks calls against the library ----------------------------------------------------

SCHEMA = """\
;; sense, then plan
(defschema navigate (start goal sensor)
  (setf domain (get-domain-descripton sensor))
  (setf plan (find-path start goal domain))
  plan)
"""


def test_parse_with_profiles_reports_an_unknown_function_at_its_call(
    cli: Cli, registry: Registry
) -> None:
    Path("nav.any").write_text(SCHEMA)
    assert cli("parse", "nav.any", "--profiles", "profiles") == (
        1,
        "",
        "nav.any:3:17: error: unknown function 'get-domain-descripton';"
        " did you mean 'get-domain-description'?\n"
        "    (setf domain (get-domain-descripton sensor))\n"
        "                  ^~~~~~~~~~~~~~~~~~~~~\n",
    )
    Path("nav.any").write_text(SCHEMA.replace("descripton", "description"))
    code, out, err = cli("parse", "nav.any", "--profiles", "profiles")
    assert (code, err) == (0, "")
    assert out.startswith("; navigate: chain, 2 steps\n")


def test_parse_without_a_library_does_not_check_functions(cli: Cli, registry: Registry) -> None:
    Path("nav.any").write_text(SCHEMA)
    assert cli("parse", "nav.any")[0] == 0
    code, _, err = cli("parse", "nav.any", "--check-calls")
    assert code == 1
    assert err.splitlines()[0] == (
        "nav.any:3:17: error: unknown function 'get-domain-descripton'"
        " (known: navigate, plan-route)"
    )


@pytest.fixture
def toy_plugins(
    monkeypatch: pytest.MonkeyPatch, registry: Registry
) -> Iterator[list[importlib.metadata.EntryPoint]]:
    """The toy plugin package's entry points, as if installed (and a broken one)."""
    monkeypatch.syspath_prepend(str(TOY_PLUGIN))
    found = [
        importlib.metadata.EntryPoint("broken", "toy_anytime_plugin.broken", PLUGIN_GROUP),
        importlib.metadata.EntryPoint("toy", "toy_anytime_plugin", PLUGIN_GROUP),
    ]
    monkeypatch.setattr(
        importlib.metadata,
        "entry_points",
        lambda **selection: found if selection.get("group") == PLUGIN_GROUP else [],
    )
    before = {module.name for module in REGISTRY}
    yield found
    for module in list(REGISTRY):  # the toy plugin registers in the process-wide registry
        if module.name not in before:
            REGISTRY.remove(module.name)
    for name in list(sys.modules):
        if name.startswith("toy_anytime_plugin"):
            del sys.modules[name]


def test_parse_with_the_library_sees_plugins_and_warns_about_broken_ones(
    cli: Cli, toy_plugins: list[Any]
) -> None:
    Path("toy.any").write_text("(defschema p (d)\n  (toy-cont d 10))\n")
    code, out, err = cli("parse", "toy.any", "--check-calls")
    assert (code, out) == (1, "")
    assert err == (
        "anytime: warning: plugin 'broken' (toy_anytime_plugin.broken): ModuleNotFoundError:"
        " No module named 'nope_not_installed'\n"
        "toy.any:2:4: error: unknown function 'toy-cont'; did you mean 'toy-count'?\n"
        "    (toy-cont d 10))\n"
        "     ^~~~~~~~\n"
    )
    Path("toy.any").write_text("(defschema p (d)\n  (toy-count d))\n")
    code, _, err = cli("parse", "toy.any", "--check-calls", "--no-plugins")
    assert err.splitlines()[0] == (
        "toy.any:2:4: error: unknown function 'toy-count' (known: p, plan-route)"
    )
    code, _, err = cli("parse", "toy.any", "--check-calls")
    assert (
        err.splitlines()[1] == "toy.any:2:4: error: function 'toy-count' takes 2 arguments, got 1"
    )


def test_library_list_shows_plugin_modules(cli: Cli, toy_plugins: list[Any]) -> None:
    code, out, err = cli("library", "list")
    assert code == 0
    assert err.startswith("anytime: warning: plugin 'broken' (toy_anytime_plugin.broken): ")
    assert out.splitlines()[1:] == [
        f"plan-route  interruptible  domain  2 input grid pts x 4 times x 4 bins, ticks  {HERE}",
        "toy-count   interruptible  data    2 input grid pts x 4 times x 4 bins, ticks"
        "  plugin 'toy' (toy_anytime_plugin)",
    ]


def test_a_dynamic_profile_from_another_build_is_said_not_used_silently(
    cli: Cli, registry: Registry
) -> None:
    """A profile measured again on another grid leaves the old dynamic profile beside it: the
    library warns (one line on the command line), naming both files and what differs."""
    import numpy as np

    from anytime.profiles import DynamicProfile, QualityTraces, save_dynamic_profile

    save_profile(
        tabulate(Exponential(0.1), time=range(0, 100, 10), module="vision"),
        "profiles/vision.yaml",
    )
    time = np.arange(0.0, 50.0, 10.0)  # the old build's grid
    quality = np.minimum(np.cumsum(np.full((20, len(time)), 0.2), axis=1), 1.0)
    traces = QualityTraces(
        module="vision", time=time, quality=quality, scored=np.ones(quality.shape, bool)
    )
    save_dynamic_profile(
        DynamicProfile.from_traces(traces, states=3), "profiles/vision.dynamic.yaml"
    )
    code, out, err = cli("library", "show", "vision", "--profiles", "profiles")
    assert code == 0 and "dynamic profile:" in out
    assert err == (
        "anytime: warning: profiles/vision.dynamic.yaml: not from the build that measured"
        " profiles/vision.yaml (they differ in their time grid); measure both again with"
        " `anytime profile vision --dynamic`\n"
    )
