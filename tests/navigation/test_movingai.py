"""The MovingAI `.map`/`.scen` loader on the shipped samples, CRLF files and malformed files."""

from pathlib import Path

import numpy as np
import pytest
from anytime_navigation.movingai import (
    MapError,
    Scenario,
    load_map,
    load_problems,
    load_scenarios,
)
from anytime_navigation.resources import data_file

from anytime.errors import AnytimeError

SAMPLES = Path(str(data_file("maps")))

# name, width, height, padded side, problems (the README table)
MAPS = [
    ("random512-10-0", 512, 512, 512, 1780),
    ("8room_000", 512, 512, 512, 2140),
    ("maze512-1-0", 512, 512, 512, 12120),
    ("arena", 49, 49, 64, 160),
]


@pytest.mark.parametrize(
    ("name", "width", "height", "side", "problems"), MAPS, ids=lambda v: str(v)
)
def test_sample_maps(name: str, width: int, height: int, side: int, problems: int) -> None:
    path = SAMPLES / f"{name}.map"
    blocked, w, h = load_map(path)
    assert (w, h) == (width, height)
    assert blocked.shape == (side, side) and blocked.dtype == bool
    rows = path.read_text().splitlines()[4:]
    assert len(rows) == height
    characters = np.array([list(row) for row in rows])
    np.testing.assert_array_equal(blocked[:height, :width], np.isin(characters, list("@OTW")))
    assert blocked[:height, :width].sum() == sum(row.count(c) for row in rows for c in "@OTW")
    # Padding: right and bottom, all blocked.
    assert blocked[height:, :].all() and blocked[:, width:].all()

    grid, w, h, scenarios = load_problems(path)  # checks every start and goal is free
    np.testing.assert_array_equal(grid, blocked)
    assert len(scenarios) == problems
    assert all(s.width == width and s.height == height for s in scenarios)
    assert all(not blocked[s.start[1], s.start[0]] for s in scenarios)


def test_scenario_fields() -> None:
    scenarios = load_scenarios(SAMPLES / "8room_000.map.scen")
    assert scenarios[0] == Scenario(0, "8room_000.map", 512, 512, (105, 484), (105, 485), 1.0)
    assert scenarios[1].optimal == pytest.approx(2**0.5)
    assert scenarios[-1].bucket == max(s.bucket for s in scenarios)


def test_old_style_arena_scenarios() -> None:
    scenarios = load_scenarios(SAMPLES / "arena.map.scen")
    assert scenarios[0] == Scenario(0, "maps/dao/arena.map", 49, 49, (1, 11), (1, 12), 1.0)
    assert scenarios[2].optimal == 3.41421


def test_scenarios_without_a_version_line(tmp_path: Path) -> None:
    text = (SAMPLES / "arena.map.scen").read_text().split("\n", 1)[1]
    (tmp_path / "a.scen").write_text(text)
    assert load_scenarios(tmp_path / "a.scen") == load_scenarios(SAMPLES / "arena.map.scen")


def test_crlf_files(tmp_path: Path) -> None:
    for name in ("arena.map", "arena.map.scen"):
        text = (SAMPLES / name).read_text()
        (tmp_path / name).write_bytes(text.replace("\n", "\r\n").encode())
        assert b"\r\n" in (tmp_path / name).read_bytes()
    blocked, w, h, scenarios = load_problems(tmp_path / "arena.map")
    expected, *_ = load_map(SAMPLES / "arena.map")
    np.testing.assert_array_equal(blocked, expected)
    assert (w, h) == (49, 49)
    assert scenarios == load_scenarios(SAMPLES / "arena.map.scen")


def test_padding_of_a_non_square_map(tmp_path: Path) -> None:
    path = tmp_path / "m.map"
    path.write_text("type octile\nheight 2\nwidth 5\nmap\n.@.GS\nTOW..\n")
    blocked, w, h = load_map(path)
    assert (w, h) == (5, 2)
    assert blocked.shape == (8, 8)
    expected = np.ones((8, 8), dtype=bool)
    expected[:2, :5] = [[0, 1, 0, 0, 0], [1, 1, 1, 0, 0]]
    np.testing.assert_array_equal(blocked, expected)


GOOD_MAP = "type octile\nheight 2\nwidth 3\nmap\n..@\n...\n"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "1: expected 'type octile', found end of file"),
        ("type tile\nheight 2\n", "1: expected 'type octile', found 'type tile'"),
        ("type octile\nwidth 3\nheight 2\nmap\n", "2: expected 'height <number>', found 'width 3'"),
        ("type octile\nheight two\n", "2: height is not an integer: 'two'"),
        ("type octile\nheight 0\n", "2: height must be positive, got 0"),
        ("type octile\nheight 2\n", "3: expected 'width <number>', found end of file"),
        ("type octile\nheight 2\nwidth 3\nmaps\n", "4: expected 'map', found 'maps'"),
        ("type octile\nheight 2\nwidth 3\nmap\n...\n..\n", "6: row 1 has 2 characters, expected 3"),
        (
            "type octile\nheight 2\nwidth 3\nmap\n...\n",
            "6: expected 2 map rows, found 1 (end of file)",
        ),
        (
            "type octile\nheight 2\nwidth 3\nmap\n...\n.x.\n",
            "6: unknown character 'x' at column 2 (passable: . G S; blocked: @ O T W)",
        ),
        (GOOD_MAP + "...\n", "7: unexpected text after the 2 map rows"),
        (
            "type octile\r\nheight 2\r\nwidth 3\r\nmap\r\n...\r\n..\r\n",
            "6: row 1 has 2 characters, expected 3",
        ),
        (
            "type octile\nheight 1\nwidth 16385\nmap\n" + "." * 16385 + "\n",
            "3: a 16385x1 map is padded to 32768x32768 cells, more than the limit of"
            " 1,048,576 cells (1024x1024) the planner takes",
        ),
    ],
    ids=[
        "empty",
        "type",
        "header-order",
        "height-not-int",
        "height-zero",
        "no-width",
        "map-line",
        "row-length",
        "too-few-rows",
        "unknown-character",
        "extra-row",
        "crlf-row-length",
        "padded-too-large",
    ],
)
def test_map_errors(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.map"
    path.write_bytes(text.encode())
    with pytest.raises(MapError) as caught:
        load_map(path)
    assert str(caught.value) == f"{path}:{message}"


def test_good_map_and_trailing_blank_lines(tmp_path: Path) -> None:
    path = tmp_path / "good.map"
    path.write_text(GOOD_MAP + "\n\n")
    blocked, w, h = load_map(path)
    assert (w, h) == (3, 2) and blocked.shape == (4, 4) and blocked[0, 2] and not blocked[1, 2]


def test_map_error_is_an_anytime_error_and_a_value_error(tmp_path: Path) -> None:
    path = tmp_path / "bad.map"
    path.write_text("type octile\nheight 2\nwidth 3\nmap\n...\n..\n")
    with pytest.raises(AnytimeError) as caught:
        load_map(path)
    assert isinstance(caught.value, ValueError)
    assert (caught.value.filename, caught.value.line) == (str(path), 6)
    assert caught.value.message == "row 1 has 2 characters, expected 3"


LINE = "0\tm.map\t3\t2\t0\t0\t1\t1\t1.41421356"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("version one\n", "1: version is not a number: 'one'"),
        ("version 1 2\n", "1: expected 'version <number>', found 'version 1 2'"),
        (
            f"version 1\n{LINE}\n0\tm.map\t3\t2\t0\t0\t1\n",
            "3: expected 9 tab-separated fields, found 7",
        ),
        (
            "version 1\n0\tm.map\t3\t2\ta\t0\t1\t1\t1\n",
            "2: field 5 (start x) is not an integer: 'a'",
        ),
        (
            "version 1\nb\tm.map\t3\t2\t0\t0\t1\t1\t1\n",
            "2: field 1 (bucket) is not an integer: 'b'",
        ),
        (
            "version 1\n0\tm.map\t3\t2\t0\t0\t1\t1\tfar\n",
            "2: field 9 (optimal length) is not a length: 'far'",
        ),
        (
            "version 1\n0\tm.map\t3\t2\t0\t0\t1\t1\t-1\n",
            "2: field 9 (optimal length) is not a length: '-1'",
        ),
        (
            "version 1\n0\tm.map\t3\t2\t0\t0\t1\t1\t0\n",
            "2: field 9 (optimal length) is 0 but the start is not the goal",
        ),
        ("version 1\n0\tm.map\t3\t0\t0\t0\t1\t1\t1\n", "2: map size 3x0 is not positive"),
        ("version 1\n0\tm.map\t3\t2\t3\t0\t1\t1\t1\n", "2: start (3, 0) is outside the 3x2 map"),
        ("version 1\n0\tm.map\t3\t2\t0\t0\t1\t-1\t1\n", "2: goal (1, -1) is outside the 3x2 map"),
        ("version 1\n0\tm.map\t3\t2\t2\t0\t1\t1\t1\n", "2: start (2, 0) is a blocked cell"),
        ("version 1\r\n0\tm.map\t3\t2\t0\t0\t2\t0\t1\r\n", "2: goal (2, 0) is a blocked cell"),
    ],
    ids=[
        "version-not-number",
        "version-fields",
        "field-count",
        "non-numeric",
        "bucket",
        "optimal",
        "negative-optimal",
        "zero-optimal",
        "size",
        "start-outside",
        "goal-outside",
        "start-blocked",
        "crlf-goal-blocked",
    ],
)
def test_scenario_errors(tmp_path: Path, text: str, message: str) -> None:
    (tmp_path / "m.map").write_text(GOOD_MAP)
    blocked, _, _ = load_map(tmp_path / "m.map")
    path = tmp_path / "bad.scen"
    path.write_bytes(text.encode())
    with pytest.raises(MapError) as caught:
        load_scenarios(path, blocked)
    assert str(caught.value) == f"{path}:{message}"


def test_scenarios_with_spaces_and_blank_lines(tmp_path: Path) -> None:
    path = tmp_path / "m.scen"
    path.write_text(f"version 1\n\n{LINE.replace(chr(9), '  ')}\n{LINE}\n\n")
    first, second = load_scenarios(path)
    assert first == second == Scenario(0, "m.map", 3, 2, (0, 0), (1, 1), 1.41421356)
