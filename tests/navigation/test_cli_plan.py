"""`anytime plan`: the JSON and table output on the shipped arena map with both planners, one
explicit problem, and every kind of bad input as a one-line message with its exit code."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from unittest.mock import ANY

import numpy as np
import pytest
from anytime_navigation.cli.plan import ATP_OPTIONS
from anytime_navigation.movingai import load_map, load_scenarios
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.following import Follower
from anytime_navigation.planning.planner import (
    LARGE_MAP_OPTIONS,
    SCATTERED_MAP_OPTIONS,
    SMALL_MAP_OPTIONS,
    SMALL_WALLED_MAP_OPTIONS,
    SPARSE_MAP_OPTIONS,
    WALLED_MAP_OPTIONS,
    atp,
)
from anytime_navigation.resources import data_file
from conftest import Cli

from anytime.plugin import Context

MAPS = Path(str(data_file("maps")))
ARENA = str(MAPS / "arena.map")
RANDOM = str(MAPS / "random512-10-0.map")
KEYS = {
    "start",
    "goal",
    "route_length",
    "optimal_length",
    "expansions",
    "seconds",
    "first_quality",
    "final_quality",
}

#: A 5x3 map split by a wall: (0, 0) and (4, 0) are free and not connected.
SPLIT = "type octile\nheight 3\nwidth 5\nmap\n..@..\n..@..\n..@..\n"


def _json(cli: Cli, *argv: str, map: str = ARENA) -> dict:
    code, out, err = cli("plan", "--map", map, *argv, "--json")
    assert (code, err) == (0, "")
    return json.loads(out)


def test_astar_lengths_are_the_scen_optimal_lengths(cli: Cli) -> None:
    result = _json(cli, "--limit", "160")  # the whole file: 160 small problems
    scenarios = load_scenarios(MAPS / "arena.map.scen")
    assert len(result["problems"]) == 160
    for problem, scenario in zip(result["problems"], scenarios, strict=True):
        assert set(problem) == KEYS
        assert (tuple(problem["start"]), tuple(problem["goal"])) == (scenario.start, scenario.goal)
        assert problem["optimal_length"] == scenario.optimal
        # The old-style arena file prints 6 significant digits: 11.8284 for 11.828427...
        assert math.isclose(problem["route_length"], scenario.optimal, rel_tol=1e-5)
        assert problem["first_quality"] == problem["final_quality"] == 1.0
        assert problem["expansions"] >= 0 and problem["seconds"] >= 0
    summary = result["summary"]
    assert summary["problem_count"] == 160
    assert summary["planner"] == "astar" and summary["movement"] == 8
    assert summary["optimal_from"] == "scen"
    assert summary["mean_length_ratio"] == 1.0
    assert summary["mean_first_quality"] == summary["mean_final_quality"] == 1.0
    assert summary["expansions"] == sum(p["expansions"] for p in result["problems"])
    assert summary["seconds"] == pytest.approx(sum(p["seconds"] for p in result["problems"]))


def test_atp_quality_is_optimal_over_executed_length(cli: Cli) -> None:
    result = _json(cli, "--planner", "atp", "--limit", "60")
    problems = result["problems"]
    assert len(problems) == 60
    for problem in problems:
        assert set(problem) == KEYS
        assert 0.0 < problem["first_quality"] <= 1.0
        assert 0.0 < problem["final_quality"] <= 1.0
        assert problem["route_length"] >= problem["optimal_length"] * (1 - 1e-5)
        length, optimal = problem["route_length"], problem["optimal_length"]
        quality = min(1.0, optimal / length) if length else 1.0
        assert problem["final_quality"] == pytest.approx(quality, abs=1e-5)
    summary = result["summary"]
    assert summary["planner"] == "atp"
    assert summary["mean_length_ratio"] >= 1.0
    assert 0.0 < summary["mean_final_quality"] <= 1.0
    assert summary["expansions"] == sum(p["expansions"] for p in problems) > 0


@pytest.mark.parametrize("name", sorted(ATP_OPTIONS))
def test_atp_options_are_atps_keyword_arguments(cli: Cli, name: str) -> None:
    """`--atp-options` plans with `LARGE_MAP_OPTIONS`, `SCATTERED_MAP_OPTIONS`,
    `SMALL_MAP_OPTIONS`, `SMALL_WALLED_MAP_OPTIONS`, `SPARSE_MAP_OPTIONS`, `WALLED_MAP_OPTIONS`
    or `atp`'s own defaults (the navigation task's): the same plans and ticks as `atp` called
    with them. By
    default they are chosen by the map: random512-10-0's obstacles are scattered and sparse."""
    assert ATP_OPTIONS == {
        "large-maps": LARGE_MAP_OPTIONS,
        "scattered-maps": SCATTERED_MAP_OPTIONS,
        "small-maps": SMALL_MAP_OPTIONS,
        "small-walled-maps": SMALL_WALLED_MAP_OPTIONS,
        "sparse-maps": SPARSE_MAP_OPTIONS,
        "walled-maps": WALLED_MAP_OPTIONS,
        "task": {},
    }
    default = _json(cli, "--planner", "atp", "--start", "489,1", "--goal", "33,493", map=RANDOM)
    assert default["summary"]["atp_options"] == "sparse-maps"
    assert default["summary"]["atp_options_by_map"] is True
    chosen = _json(
        cli,
        "--planner",
        "atp",
        "--start",
        "489,1",
        "--goal",
        "33,493",
        "--atp-options",
        name,
        map=RANDOM,
    )
    if name == "sparse-maps":
        assert chosen["problems"] == [{**default["problems"][0], "seconds": ANY}]
    assert chosen["summary"]["atp_options"] == name
    assert chosen["summary"]["atp_options_by_map"] is False
    blocked = load_map(MAPS / "random512-10-0.map")[0]
    ctx = Context()
    plans = list(
        atp(ctx, (489, 1), (33, 493), Pyramid.build(blocked), movement=8, **ATP_OPTIONS[name])
    )
    assert plans and chosen["problems"][0]["expansions"] == ctx.ticks


def test_options_chosen_by_the_map(cli: Cli, tmp_path: Path) -> None:
    """On a map of scattered obstacles, 30% of its cells blocked, the default options are the
    scattered-map ones: the same plans and ticks as `--atp-options scattered-maps`; the table
    says they were chosen by the map."""
    rng = np.random.default_rng(4)  # a seed whose corners are connected
    rows = np.where(rng.random((128, 128)) < 0.3, "@", ".")  # 11,426 free cells: not small
    rows[0, 0] = rows[127, 127] = "."
    path = tmp_path / "scattered.map"
    path.write_text(
        "type octile\nheight 128\nwidth 128\nmap\n" + "".join("".join(row) + "\n" for row in rows)
    )
    argv = ("--planner", "atp", "--start", "0,0", "--goal", "127,127")
    by_map = _json(cli, *argv, map=str(path))
    named = _json(cli, *argv, "--atp-options", "scattered-maps", map=str(path))
    assert by_map["summary"]["atp_options"] == "scattered-maps"
    assert by_map["summary"]["atp_options_by_map"] is True
    assert by_map["problems"] == [{**named["problems"][0], "seconds": ANY}]
    code, out, err = cli("plan", "--map", str(path), *argv)
    assert (code, err) == (0, "")
    assert "atp (scattered-maps options, chosen by the map, monotone), 8-connected" in out


def test_a_map_smaller_than_the_options_levels(cli: Cli, tmp_path: Path) -> None:
    """A 4 x 4 map of scattered, dense obstacles: its pyramid's top is level 2, the
    scattered-map options' second plan's level, so it is planned without one. By default it is
    small: one search of its cells."""
    path = tmp_path / "tiny.map"
    path.write_text("type octile\nheight 4\nwidth 4\nmap\n.@..\n..@.\n@...\n..@.\n")
    argv = ("--planner", "atp", "--start", "0,0", "--goal", "3,3")
    for name in ("scattered-maps", "large-maps"):
        result = _json(cli, *argv, "--atp-options", name, map=str(path))
        assert result["summary"]["atp_options"] == name
        assert result["problems"][0]["final_quality"] == 1.0
    by_map = _json(cli, *argv, map=str(path))
    assert by_map["summary"]["atp_options"] == "small-maps"
    assert by_map["problems"][0]["first_quality"] == 1.0


def test_monotone_plans_are_those_followed_no_longer(cli: Cli) -> None:
    """`--monotone` registers a plan only when it is followed no longer than the last: the same
    plans and ticks as `atp(follow=Follower(...))`, and the final plan never followed longer
    than the first. The summary says whether the curve can fall: with the large-map options;
    not with `--monotone`, nor with the small-map options (the arena's), whose one plan is
    the optimal route, nor the sparse-map options (random 10%'s), whose plans are the first
    and the direct route; with A*, no curve."""
    argv = ("--planner", "atp", "--start", "489,1", "--goal", "33,493")
    on = _json(cli, *argv, "--monotone", "--atp-options", "large-maps", map=RANDOM)
    assert on["summary"]["monotone"] is True
    (problem,) = on["problems"]
    assert problem["final_quality"] >= problem["first_quality"]
    blocked = load_map(MAPS / "random512-10-0.map")[0]
    ctx = Context()
    plans = list(
        atp(
            ctx,
            (489, 1),
            (33, 493),
            Pyramid.build(blocked),
            movement=8,
            follow=Follower(blocked, 8),
            **LARGE_MAP_OPTIONS,
        )
    )
    assert plans and problem["expansions"] == ctx.ticks
    assert (
        _json(cli, *argv, "--atp-options", "large-maps", map=RANDOM)["summary"]["monotone"] is False
    )
    assert _json(cli, *argv, map=RANDOM)["summary"]["monotone"] is True
    small = _json(cli, "--planner", "atp", "--limit", "3")
    assert small["summary"]["atp_options"] == "small-maps"
    assert small["summary"]["monotone"] is True
    assert _json(cli, "--limit", "2", "--monotone")["summary"]["monotone"] is None  # A*


def test_one_explicit_problem(cli: Cli) -> None:
    astar = _json(cli, "--start", "1,11", "--goal", "45,40")
    atp = _json(cli, "--start", "1,11", "--goal", "45,40", "--planner", "atp")
    for result in (astar, atp):
        (problem,) = result["problems"]
        assert (problem["start"], problem["goal"]) == ([1, 11], [45, 40])
        assert result["summary"]["optimal_from"] == "astar"
    # Without a .scen file the optimal length is A*'s.
    assert astar["problems"][0]["optimal_length"] == astar["problems"][0]["route_length"]
    assert atp["problems"][0]["optimal_length"] == astar["problems"][0]["route_length"]
    assert 0.0 < atp["problems"][0]["final_quality"] <= 1.0


def test_four_connected_optimal_lengths_come_from_astar(cli: Cli) -> None:
    result = _json(cli, "--movement", "4", "--limit", "5")
    assert result["summary"]["optimal_from"] == "astar"
    assert result["summary"]["movement"] == 4
    for problem in result["problems"]:
        assert problem["route_length"] == problem["optimal_length"]
        assert problem["route_length"] == int(problem["route_length"])  # straight steps only


def test_table_and_summary_line(cli: Cli) -> None:
    code, out, err = cli("plan", "--map", ARENA, "--limit", "3", "--planner", "atp")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0].split() == [
        "#",
        "START",
        "GOAL",
        "LENGTH",
        "OPTIMAL",
        "EXPANSIONS",
        "SECONDS",
        "FIRST",
        "Q",
        "FINAL",
        "Q",
    ]
    assert lines[1].split()[:5] == ["1", "1,11", "1,12", "1.0000", "1.0000"]
    assert len(lines) == 6
    assert lines[-2].startswith(
        "3 problems, atp (small-maps options, chosen by the map, monotone), 8-connected"
        " (optimal lengths"
        " from the .scen"
        " file): mean length /"
        " optimal 1.0000, "
    )
    assert re.fullmatch(
        r"once: \d+\.\d{3} s loading the compiled searches, \d+\.\d{3} s building the"
        r" abstraction \(not in the times above\)",
        lines[-1],
    )


SUMMARY = {
    "planner",
    "movement",
    "optimal_from",
    "problem_count",
    "mean_length_ratio",
    "expansions",
    "seconds",
    "mean_first_quality",
    "mean_final_quality",
    "load_seconds",
    "build_seconds",
    "atp_options",
    "atp_options_by_map",
    "monotone",
}


@pytest.mark.parametrize("planner", ["astar", "atp"])
def test_one_off_costs_are_their_own_fields(cli: Cli, planner: str) -> None:
    """Loading the compiled searches (once per process) and building the planner's description
    of the map (once per map) are reported apart; each problem's time is its planning alone,
    and the summary's time is their sum, with neither one-off cost in it."""
    result = _json(cli, "--planner", planner, "--limit", "5")
    summary = result["summary"]
    assert set(summary) == SUMMARY
    assert summary["load_seconds"] >= 0.0 and summary["build_seconds"] > 0.0
    assert summary["seconds"] == sum(p["seconds"] for p in result["problems"])
    for problem in result["problems"]:
        assert set(problem) == KEYS and problem["seconds"] > 0.0


def test_help(cli: Cli) -> None:
    code, out, _ = cli("plan", "--help")
    assert code == 0
    assert out.startswith("usage: anytime plan")
    assert "--planner {astar,atp}" in out
    assert "(8)" in " ".join(out.split())  # the default movement is said


def _split_map(tmp_path: Path) -> str:
    path = tmp_path / "split.map"
    path.write_text(SPLIT)
    return str(path)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--start", "60,3", "--goal", "1,11"], "--start 60,3 is outside the 49x49 map '{map}'"),
        (["--start", "1,11", "--goal", "1,49"], "--goal 1,49 is outside the 49x49 map '{map}'"),
        (["--start", "0,0", "--goal", "1,11"], "--start 0,0 is a blocked cell of '{map}'"),
    ],
    ids=["start-outside", "goal-outside", "start-blocked"],
)
def test_bad_positions(cli: Cli, argv: list[str], message: str) -> None:
    code, out, err = cli("plan", "--map", ARENA, *argv)
    assert (code, out) == (1, "")
    assert err == "anytime: error: " + message.format(map=ARENA) + "\n"


def test_unreachable_goal(cli: Cli, tmp_path: Path) -> None:
    split = _split_map(tmp_path)
    for planner in ("astar", "atp"):
        code, out, err = cli(
            "plan", "--map", split, "--start", "0,0", "--goal", "4,0", "--planner", planner
        )
        assert (code, out) == (1, "")
        assert (
            err
            == f"anytime: error: the goal 4,0 cannot be reached from the start 0,0 on '{split}'\n"
        )


def test_unreachable_scenario_goal(cli: Cli, tmp_path: Path) -> None:
    split = _split_map(tmp_path)
    scen = tmp_path / "split.map.scen"
    scen.write_text(
        "version 1\n0\tsplit.map\t5\t3\t0\t0\t1\t2\t2.0\n0\tsplit.map\t5\t3\t0\t0\t3\t1\t3\n"
    )
    code, out, err = cli("plan", "--map", split)  # the .scen next to the map
    assert (code, out) == (1, "")
    assert err == (
        f"anytime: error: {scen}: problem 2: the goal 3,1 cannot be reached from the start 0,0"
        f" on '{split}'\n"
    )
    code, _, _ = cli("plan", "--map", split, "--limit", "1")
    assert code == 0


def test_scenario_of_another_size(cli: Cli, tmp_path: Path) -> None:
    split = _split_map(tmp_path)
    scen = tmp_path / "other.scen"
    scen.write_text("version 1\n0\tother.map\t4\t3\t0\t0\t1\t2\t2.0\n")
    code, out, err = cli("plan", "--map", split, "--scen", str(scen))
    assert (code, out) == (1, "")
    assert err == f"anytime: error: {scen}: problem 1: it is for a 4x3 map, '{split}' is 5x3\n"


def test_missing_files(cli: Cli, tmp_path: Path) -> None:
    code, out, err = cli("plan", "--map", str(tmp_path / "none.map"))
    assert (code, out) == (1, "")
    assert (
        err == f"anytime: error: cannot read '{tmp_path / 'none.map'}': No such file or directory\n"
    )
    split = _split_map(tmp_path)
    code, _, err = cli("plan", "--map", split)
    assert code == 1
    assert err == (
        f"anytime: error: no scenario file '{split}.scen' next to the map: give --scen FILE.scen,"
        " or --start X,Y --goal X,Y\n"
    )
    code, _, err = cli("plan", "--map", split, "--scen", str(tmp_path / "none.scen"))
    assert code == 1
    assert (
        err
        == f"anytime: error: cannot read '{tmp_path / 'none.scen'}': No such file or directory\n"
    )


def test_malformed_map_and_scenario(cli: Cli, tmp_path: Path) -> None:
    bad = tmp_path / "bad.map"
    bad.write_text(SPLIT.replace("..@..\n..@..\n..@..", "..@..\n..x..\n..@.."))
    code, out, err = cli("plan", "--map", str(bad))
    assert (code, out) == (1, "")
    assert err == (
        f"{bad}:6: error: unknown character 'x' at column 3 (passable: . G S; blocked: @ O T W)\n"
    )
    scen = tmp_path / "bad.scen"
    scen.write_text("version 1\n0\tsplit.map\t5\t3\t0\t0\t1\t2\n")
    code, out, err = cli("plan", "--map", _split_map(tmp_path), "--scen", str(scen))
    assert (code, out) == (1, "")
    assert err == f"{scen}:2: error: expected 9 tab-separated fields, found 8\n"
    code, _, err = cli("plan", "--map", _split_map(tmp_path), "--start", "2,0", "--goal", "0,0")
    assert (code, err) == (
        1,
        f"anytime: error: --start 2,0 is a blocked cell of '{tmp_path / 'split.map'}'\n",
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--start", "1,11"], "anytime plan: error: --start and --goal go together"),
        (["--goal", "1,11"], "anytime plan: error: --start and --goal go together"),
        (
            ["--start", "1,11", "--goal", "1,12", "--scen", ARENA + ".scen"],
            "anytime plan: error: give either --scen or --start/--goal, not both",
        ),
        (
            ["--start", "1;11", "--goal", "1,12"],
            "anytime plan: error: argument --start: expected X,Y (two whole numbers), got '1;11'",
        ),
        (
            ["--start", "1,11", "--goal", "1,2,3"],
            "anytime plan: error: argument --goal: expected X,Y (two whole numbers), got '1,2,3'",
        ),
        (["--limit", "0"], "anytime plan: error: argument --limit: expected a number >= 1, got 0"),
        (["--movement", "6"], "anytime plan: error: argument --movement: invalid choice: 6"),
        (["--planner", "dijkstra"], "anytime plan: error: argument --planner: invalid choice"),
    ],
    ids=[
        "start-alone",
        "goal-alone",
        "scen-and-start",
        "bad-start",
        "bad-goal",
        "zero-limit",
        "bad-movement",
        "bad-planner",
    ],
)
def test_usage_errors(cli: Cli, argv: list[str], message: str) -> None:
    code, out, err = cli("plan", "--map", ARENA, *argv)
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert err.splitlines()[-1].startswith(message)


def test_map_is_required(cli: Cli) -> None:
    code, _, err = cli("plan")
    assert code == 2
    assert (
        err.splitlines()[-1] == "anytime plan: error: the following arguments are required: --map"
    )
