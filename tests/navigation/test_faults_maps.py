"""Issue 37, item 13: a map is bounded by the work it makes, the cells of the square it is
padded to, not only by its side: a 1 x 4097 map (padded to 8192 x 8192, which took `plan` 21 s
and `navigate` over a minute) is refused up front by both commands, one line, exit 1."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import Cli


@pytest.mark.parametrize("command", ["plan", "navigate"])
def test_a_map_padded_beyond_the_cell_limit_is_refused(
    cli: Cli, tmp_path: Path, command: str
) -> None:
    path = tmp_path / "thin.map"
    path.write_text("type octile\nheight 4097\nwidth 1\nmap\n" + ".\n" * 4097)
    argv = ["--map", str(path)] + (
        ["--start", "0,0", "--goal", "0,4096"] if command == "plan" else []
    )
    code, out, err = cli(command, *argv)
    assert (code, out) == (1, "")
    assert err == (
        f"{path}:2: error: a 1x4097 map is padded to 8192x8192 cells, more than the limit of"
        " 1,048,576 cells (1024x1024) the planner takes\n"
    )


def test_the_largest_map_within_the_limit_is_read(tmp_path: Path) -> None:
    from anytime_navigation.movingai import load_map

    path = tmp_path / "thin.map"
    path.write_text("type octile\nheight 1\nwidth 1024\nmap\n" + "." * 1024 + "\n")
    blocked, width, height = load_map(path)
    assert (width, height, blocked.shape) == (1024, 1, (1024, 1024))
