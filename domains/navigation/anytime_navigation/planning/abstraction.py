"""The quad-tree abstraction pyramid (Zilberstein & Russell, "Abstract description of the
domain").

Level n is a coarse grid in which the cell (x, y) stands for the 2^n x 2^n base cells
x * 2^n <= x' < (x + 1) * 2^n, y * 2^n <= y' < (y + 1) * 2^n; its obstacleness is the fraction
of them that is blocked. The papers' example: (3, 3) at level 1 is the base cells (6, 6), (6, 7),
(7, 6), (7, 7), and has obstacleness 0.25 when one of them is blocked. Level 0 is the base grid
(obstacleness 0 or 1), the top level log2(N) is one cell unless a lower top is chosen.

Arrays are indexed [y, x] like the base grid; positions are (x, y) tuples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import attrs
import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from ..world import BoolGrid, Position, is_power_of_two

FloatGrid = NDArray[np.float64]
Anchor = Literal["corner", "centre"]


def project(
    position: Position, from_level: int, to_level: int, anchor: Anchor = "corner"
) -> Position:
    """The position at `to_level` that corresponds to `position` at `from_level`.

    Up (to a coarser level) it is the cell containing the position: (x >> k, y >> k) for
    k = to_level - from_level. Down it is one cell of the block the position stands for: its
    upper-left cell (`anchor="corner"`, the papers' first listed base position, so that up then
    down is the block's origin) or its central cell (`anchor="centre"`, offset (2^k - 1) // 2,
    the upper-left of the central four when 2^k is even). Projecting down and back up is the
    identity with either anchor.
    """
    x, y = position
    if from_level < 0 or to_level < 0:
        raise ValueError(f"levels must be >= 0, got {from_level} and {to_level}")
    if to_level >= from_level:
        k = to_level - from_level
        return (x >> k, y >> k)
    k = from_level - to_level
    if anchor == "corner":
        offset = 0
    elif anchor == "centre":
        offset = ((1 << k) - 1) // 2
    else:
        raise ValueError(f"anchor must be 'corner' or 'centre', got {anchor!r}")
    return ((x << k) + offset, (y << k) + offset)


def cell_bounds(position: Position, level: int) -> tuple[int, int, int, int]:
    """The base cells a level cell stands for, half-open: (x0, y0, x1, y1), i.e.
    `blocked[y0:y1, x0:x1]`."""
    x, y = position
    side = 1 << level
    return (x * side, y * side, (x + 1) * side, (y + 1) * side)


def _levels(value: Any) -> tuple[FloatGrid, ...]:
    """The levels as views of one array, one after another (`Pyramid.stacked`), read-only: as
    given when they already are (`Pyramid.build` writes them so), else copied into one."""
    levels = tuple(value)
    if _stacked(levels) is not None and not any(level.flags.writeable for level in levels):
        return levels
    arrays = [np.asarray(level, dtype=np.float64) for level in levels]
    stacked = np.empty(sum(array.size for array in arrays))
    views = _views(stacked, [array.shape for array in arrays])
    for view, array in zip(views, arrays, strict=True):
        view[...] = array
    return _frozen(stacked, views)


def _views(stacked: NDArray[np.float64], shapes: Sequence[tuple[int, ...]]) -> list[FloatGrid]:
    """`stacked` cut into consecutive views of these shapes."""
    views, at = [], 0
    for shape in shapes:
        size = math.prod(shape)
        views.append(stacked[at : at + size].reshape(shape))
        at += size
    return views


def _frozen(stacked: NDArray[np.float64], views: list[FloatGrid]) -> tuple[FloatGrid, ...]:
    for view in views:
        view.setflags(write=False)
    stacked.setflags(write=False)
    return tuple(views)


def _stacked(
    levels: tuple[FloatGrid, ...],
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]] | None:
    """`Pyramid.stacked` of these levels: None unless they are consecutive float views of one
    array."""
    stacked = levels[0].base if levels and isinstance(levels[0], np.ndarray) else None
    if not isinstance(stacked, np.ndarray) or stacked.ndim != 1 or stacked.dtype != np.float64:
        return None
    origin = stacked.__array_interface__["data"][0]
    at = [0]
    for level in levels:
        if (
            not isinstance(level, np.ndarray)
            or level.base is not stacked
            or level.__array_interface__["data"][0] != origin + at[-1] * stacked.itemsize
            or not level.flags.c_contiguous
        ):
            return None
        at.append(at[-1] + level.size)
    sides = np.array([level.shape[1] for level in levels], dtype=np.int64)
    return stacked, np.array(at, dtype=np.int64), sides


def _levels_equal(a: tuple[FloatGrid, ...], b: tuple[FloatGrid, ...]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


@frozen
class Pyramid:
    """Obstacleness of every level, `levels[n][y, x]` in [0, 1], n = 0 .. top. Build it with
    `Pyramid.build(blocked)`."""

    levels: tuple[FloatGrid, ...] = field(
        converter=_levels, eq=attrs.cmp_using(eq=_levels_equal), hash=False
    )

    @classmethod
    def build(cls, blocked: BoolGrid, top: int | None = None) -> Pyramid:
        """The pyramid of a square power-of-two grid, up to level `top` (default log2(N): one
        cell). Each level's blocked counts are the 2 x 2 block sums of the level below; the
        counts are integers, so every level is exact."""
        grid = np.asarray(blocked, dtype=bool)
        if grid.ndim != 2 or grid.shape[0] != grid.shape[1] or not is_power_of_two(grid.shape[0]):
            raise ValueError(f"the grid must be square with a power-of-two side, got {grid.shape}")
        highest = grid.shape[0].bit_length() - 1
        if top is None:
            top = highest
        if not 0 <= top <= highest:
            raise ValueError(f"top must be in [0, {highest}], got {top}")
        # a count is at most 4^top: int32 holds it up to level 15
        counts: NDArray[np.signedinteger[Any]] = grid.astype(np.int32 if top <= 15 else np.int64)
        # written where they are kept, one level after another (`stacked`): not made apart and
        # copied (on a 1,024 x 1,024 map, half the build's time)
        side = grid.shape[0]
        shapes = [(side >> n, side >> n) for n in range(top + 1)]
        stacked = np.empty(sum(math.prod(shape) for shape in shapes))
        levels = _views(stacked, shapes)
        np.copyto(levels[0], grid)
        for n in range(1, top + 1):
            # the 2 x 2 sums, four strided views added (a reshape-sum over two axes is slower)
            c = counts
            counts = c[0::2, 0::2] + c[0::2, 1::2] + c[1::2, 0::2] + c[1::2, 1::2]
            np.multiply(counts, 1.0 / 4**n, out=levels[n])  # 4^-n is exact: the same as / 4^n
        return cls(_frozen(stacked, levels))

    @property
    def top(self) -> int:
        return len(self.levels) - 1

    def stacked(self) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]] | None:
        """The levels ravelled one after another, where each begins and each one's side: level
        n's obstacleness at (x, y) is `stacked[at[n] + y * side[n] + x]` (what compiled code
        reads any level from: `corridor_search.refine_step`); None when the levels are not
        views of one array (a pyramid unpickled: its levels are apart)."""
        return _stacked(self.levels)

    @property
    def size(self) -> int:
        """N, the side of the base grid."""
        return int(self.levels[0].shape[0])

    def side(self, level: int) -> int:
        """How many cells a row of `level` has: N / 2^level."""
        self._check_level(level)
        return int(self.levels[level].shape[0])

    def obstacleness(self, position: Position, level: int) -> float:
        x, y = self._check_position(position, level)
        return float(self.levels[level][y, x])

    def project(
        self, position: Position, from_level: int, to_level: int, anchor: Anchor = "corner"
    ) -> Position:
        """`project` with both levels and the position checked against this pyramid."""
        self._check_position(position, from_level)
        self._check_level(to_level)
        return project(position, from_level, to_level, anchor)

    def cell_bounds(self, position: Position, level: int) -> tuple[int, int, int, int]:
        return cell_bounds(self._check_position(position, level), level)

    def _check_level(self, level: int) -> None:
        if not 0 <= level <= self.top:
            raise ValueError(f"level must be in [0, {self.top}], got {level}")

    def _check_position(self, position: Position, level: int) -> Position:
        self._check_level(level)
        x, y = position
        side = self.levels[level].shape[0]
        if not (0 <= x < side and 0 <= y < side):
            raise ValueError(f"{position} is outside level {level} ({side}x{side} cells)")
        return (x, y)
