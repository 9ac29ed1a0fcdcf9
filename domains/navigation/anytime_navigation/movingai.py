"""Loader for MovingAI grid benchmark files (`.map` and `.scen`).

Format (N. Sturtevant, "Benchmarks for Grid-Based Pathfinding", IEEE Transactions on
Computational Intelligence and AI in Games, 2012; https://movingai.com/benchmarks/): a `.map`
has the header lines `type octile`, `height H`, `width W`, `map`, then H rows of W characters,
`.` `G` `S` passable and `@` `O` `T` `W` blocked. A `.scen` has an optional `version N` line,
then one problem per line with nine tab-separated fields: bucket, map, width, height, start x,
start y, goal x, goal y, optimal length (optimal for octile movement without corner cutting).
The old style (for example `arena.map.scen`: map field `maps/dao/arena.map`, short lengths,
sometimes no version line) is read the same way. CRLF line ends are tolerated.
Every error is a `MapError` whose message is `FILE:LINE: what is wrong`.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from attrs import frozen
from numpy.typing import NDArray

from anytime.plugin import AnytimeError
from anytime.plugin.cli import read_input

from .world import BoolGrid, Position

PASSABLE = ".GS"
BLOCKED = "@OTW"

# Character code -> 0 passable, 1 blocked, 2 not a map character.
_CODES = np.full(256, 2, dtype=np.uint8)
_CODES[[ord(c) for c in PASSABLE]] = 0
_CODES[[ord(c) for c in BLOCKED]] = 1

#: The largest `.map` file read: a map of 8000 x 8000 cells (the largest MovingAI maps are
#: 1024 x 1024, about 1 MiB).
MAX_MAP_BYTES = 64 << 20
#: The largest `.scen` file read (the largest shipped one is under 1 MiB).
MAX_SCENARIO_BYTES = 64 << 20
#: The most cells of the square a map is padded to, which is what planning costs (the planner
#: builds its grid, abstraction and searches on all of them): 1024 x 1024, the MovingAI
#: benchmark's largest maps (the shipped ones are 512 x 512). A thin map is padded to a square of
#: its long side: 1 x 4097 cells make 8192 x 8192, which took `plan` 21 s and `navigate` over a
#: minute; 1024 x 1024 take `navigate` about 5 s.
MAX_PADDED_CELLS = 1024 * 1024

_SCEN_FIELDS = (
    "bucket",
    "map",
    "width",
    "height",
    "start x",
    "start y",
    "goal x",
    "goal y",
    "optimal length",
)


class MapError(AnytimeError, ValueError):
    """A MovingAI `.map` or `.scen` file is malformed; the message is `FILE:LINE: what`."""

    def __init__(self, filename: str, line: int, message: str) -> None:
        self.filename = filename
        self.line = line
        self.message = message
        super().__init__(f"{filename}:{line}: {message}")


@frozen
class Scenario:
    """One problem of a `.scen` file; positions are (x, y) = (column, row)."""

    bucket: int
    map: str
    width: int
    height: int
    start: Position
    goal: Position
    optimal: float


def _read_lines(path: str | os.PathLike[str], limit: int, kind: str) -> list[str]:
    # Only a regular file within the limit is read (a FIFO or /dev/zero is refused unread).
    # latin-1 decodes every byte, so a stray byte is reported as an unknown character; CRLF
    # and CR become LF as universal newlines would (str.splitlines would also split at \x85).
    data = read_input(path, limit=limit, kind=kind)
    text = data.decode("latin-1").replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if lines[-1] == "":
        lines.pop()
    return lines


def padded_side(width: int, height: int) -> int:
    """The power of two the map is padded to: the smallest one >= max(width, height)."""
    return 1 << max(0, (max(width, height) - 1).bit_length())


def _header_value(name: str, lines: list[str], index: int, key: str) -> int:
    if index >= len(lines):
        raise MapError(name, index + 1, f"expected '{key} <number>', found end of file")
    parts = lines[index].split()
    if len(parts) != 2 or parts[0] != key:
        raise MapError(name, index + 1, f"expected '{key} <number>', found {lines[index]!r}")
    try:
        value = int(parts[1])
    except ValueError:
        raise MapError(name, index + 1, f"{key} is not an integer: {parts[1]!r}") from None
    if value <= 0:
        raise MapError(name, index + 1, f"{key} must be positive, got {value}")
    return value


def load_map(path: str | os.PathLike[str]) -> tuple[BoolGrid, int, int]:
    """Read a `.map` file: (blocked, width, height).

    `blocked[y, x]` is a square bool array whose side is the smallest power of two >= both
    width and height (the abstraction pyramid needs it); the map occupies the upper-left
    `height x width` corner and the padding, on the right and at the bottom, is blocked.
    Coordinates of the file are therefore unchanged.

    Raises:
        MapError: the file is malformed.
        InputFileError: it is not a regular file or is larger than `MAX_MAP_BYTES` (unread).
        OSError: it cannot be read.
    """
    name = os.fspath(path)
    lines = _read_lines(path, MAX_MAP_BYTES, "map files")
    if not lines or lines[0].split() != ["type", "octile"]:
        found = repr(lines[0]) if lines else "end of file"
        raise MapError(name, 1, f"expected 'type octile', found {found}")
    height = _header_value(name, lines, 1, "height")
    width = _header_value(name, lines, 2, "width")
    side = padded_side(width, height)
    if side * side > MAX_PADDED_CELLS:  # refused before its rows are looked at
        raise MapError(
            name,
            2 if height >= width else 3,
            f"a {width}x{height} map is padded to {side}x{side} cells, more than the limit of"
            f" {MAX_PADDED_CELLS:,} cells (1024x1024) the planner takes",
        )
    if len(lines) < 4 or lines[3].strip() != "map":
        found = repr(lines[3]) if len(lines) >= 4 else "end of file"
        raise MapError(name, 4, f"expected 'map', found {found}")
    rows = lines[4 : 4 + height]
    if len(rows) < height:
        raise MapError(
            name, len(lines) + 1, f"expected {height} map rows, found {len(rows)} (end of file)"
        )
    for y, row in enumerate(rows):
        if len(row) != width:
            raise MapError(name, 5 + y, f"row {y} has {len(row)} characters, expected {width}")
    for offset, extra in enumerate(lines[4 + height :]):
        if extra.strip():
            raise MapError(
                name, 5 + height + offset, f"unexpected text after the {height} map rows"
            )
    codes = _CODES[
        np.frombuffer("".join(rows).encode("latin-1"), dtype=np.uint8).reshape(height, width)
    ]
    bad = np.argwhere(codes == 2)
    if len(bad):
        y, x = (int(v) for v in bad[0])
        raise MapError(
            name,
            5 + y,
            f"unknown character {rows[y][x]!r} at column {x + 1} "
            f"(passable: {' '.join(PASSABLE)}; blocked: {' '.join(BLOCKED)})",
        )
    blocked: NDArray[np.bool_] = np.ones((side, side), dtype=bool)
    blocked[:height, :width] = codes == 1
    return blocked, width, height


def _int_field(name: str, line: int, fields: list[str], index: int) -> int:
    try:
        return int(fields[index])
    except ValueError:
        raise MapError(
            name,
            line,
            f"field {index + 1} ({_SCEN_FIELDS[index]}) is not an integer: {fields[index]!r}",
        ) from None


def load_scenarios(path: str | os.PathLike[str], blocked: BoolGrid | None = None) -> list[Scenario]:
    """Read a `.scen` file: its problems in file order.

    Start and goal must lie inside the map size given on their line; when the map's `blocked`
    grid (from `load_map`) is passed they must also be free cells of it.
    """
    name = os.fspath(path)
    lines = _read_lines(path, MAX_SCENARIO_BYTES, "scenario files")
    first = 0
    if lines and lines[0].split()[:1] == ["version"]:
        parts = lines[0].split()
        if len(parts) != 2:
            raise MapError(name, 1, f"expected 'version <number>', found {lines[0]!r}")
        try:
            float(parts[1])
        except ValueError:
            raise MapError(name, 1, f"version is not a number: {parts[1]!r}") from None
        first = 1
    scenarios = []
    for index in range(first, len(lines)):
        text, line = lines[index], index + 1
        if not text.strip():
            continue
        fields = text.strip().split("\t") if "\t" in text else text.split()
        if len(fields) != len(_SCEN_FIELDS):
            raise MapError(
                name,
                line,
                f"expected {len(_SCEN_FIELDS)} tab-separated fields, found {len(fields)}",
            )
        bucket, width, height, sx, sy, gx, gy = (
            _int_field(name, line, fields, i) for i in (0, 2, 3, 4, 5, 6, 7)
        )
        try:
            optimal = float(fields[8])
        except ValueError:
            optimal = math.nan
        if not math.isfinite(optimal) or optimal < 0:
            raise MapError(name, line, f"field 9 (optimal length) is not a length: {fields[8]!r}")
        if optimal == 0 and (sx, sy) != (gx, gy):  # every quality would divide by it
            raise MapError(
                name, line, "field 9 (optimal length) is 0 but the start is not the goal"
            )
        if width <= 0 or height <= 0:
            raise MapError(name, line, f"map size {width}x{height} is not positive")
        for label, (x, y) in (("start", (sx, sy)), ("goal", (gx, gy))):
            if not (0 <= x < width and 0 <= y < height):
                raise MapError(
                    name, line, f"{label} ({x}, {y}) is outside the {width}x{height} map"
                )
            if blocked is not None:
                rows, columns = blocked.shape
                if not (x < columns and y < rows):
                    raise MapError(name, line, f"{label} ({x}, {y}) is outside the loaded map")
                if blocked[y, x]:
                    raise MapError(name, line, f"{label} ({x}, {y}) is a blocked cell")
        scenarios.append(Scenario(bucket, fields[1], width, height, (sx, sy), (gx, gy), optimal))
    return scenarios


def load_problems(
    map_path: str | os.PathLike[str], scen_path: str | os.PathLike[str] | None = None
) -> tuple[BoolGrid, int, int, list[Scenario]]:
    """A map and its scenarios (default: `MAP.scen` next to it), the scenarios checked against
    the map: (blocked, width, height, scenarios)."""
    blocked, width, height = load_map(map_path)
    if scen_path is None:
        scen_path = Path(os.fspath(map_path) + ".scen")
    return blocked, width, height, load_scenarios(scen_path, blocked)
