"""The robot's world: an N x N grid of free and blocked cells (Zilberstein & Russell, "The path
planning problem").

Representation shared by the whole domain: `blocked[y, x]` is a numpy bool array, row `y`,
column `x`, (0, 0) the upper-left corner as in MovingAI maps; a position is a tuple `(x, y)`.
Movement is 4-connected (the papers' model, step cost 1) or 8-connected octile (diagonal cost
sqrt 2, a diagonal step only when both orthogonal neighbours are free: no corner cutting, the
MovingAI rule).

Reachability is the same under both models. A diagonal step from (x, y) to (x+dx, y+dy) is allowed
only when (x+dx, y) and (x, y+dy) are free, so it can be replaced by two orthogonal steps through
free cells; conversely every orthogonal step is an 8-connected move. Hence the cells reachable
without corner cutting are exactly the 4-connected component of the start, and `reachable`
labels 4-connected components for both models (checked against a BFS in the tests). Allowing
corner cutting would make it the 8-connected component, which is larger.
"""

from __future__ import annotations

import math
from typing import Any

import attrs
import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

Position = tuple[int, int]
BoolGrid = NDArray[np.bool_]

MOVEMENTS = (4, 8)
SQRT2 = math.sqrt(2.0)

#: The structuring element of 4-connectivity, which is also reachability under octile movement
#: without corner cutting (see the module docstring).
_FOUR = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)


def _read_only_grid(value: Any) -> BoolGrid:
    grid = np.array(value, dtype=bool, copy=True)
    grid.setflags(write=False)
    return grid


def _position(value: Any) -> Position:
    x, y = value
    return (int(x), int(y))


def _check_movement(movement: int) -> None:
    if movement not in MOVEMENTS:
        raise ValueError(f"movement must be 4 or 8, got {movement!r}")


def move_distance(
    dx: NDArray[np.float64], dy: NDArray[np.float64], movement: int
) -> NDArray[np.float64]:
    """The length of the shortest move sequence across the offsets (dx, dy), both >= 0, on an
    open grid: Manhattan for 4-connected moves, octile for 8-connected ones (a metric: the
    heuristic it gives is consistent with edges that cost it)."""
    if movement == 4:
        return np.asarray(dx + dy)
    return np.asarray(np.maximum(dx, dy) + (SQRT2 - 1.0) * np.minimum(dx, dy))


def is_power_of_two(n: int) -> bool:
    return n > 0 and n & (n - 1) == 0


def reachable(blocked: BoolGrid, start: Position, movement: int = 4) -> BoolGrid:
    """The cells reachable from `start` (an empty mask if `start` is blocked).

    Same answer for 4 and 8 (octile without corner cutting): see the module docstring.
    """
    _check_movement(movement)
    blocked = np.asarray(blocked, dtype=bool)
    x, y = start
    height, width = blocked.shape
    if not (0 <= x < width and 0 <= y < height):
        raise ValueError(f"start {start} is outside the {width}x{height} grid")
    if blocked[y, x]:
        return np.zeros_like(blocked)
    # imported here, not with the plugin: scipy.ndimage takes ~0.7 s, every command paid it
    from scipy import ndimage

    labels, _ = ndimage.label(~blocked, structure=_FOUR)
    return np.asarray(labels == labels[y, x])


@frozen
class World:
    """One navigation problem: the true map, start, goal and movement model.

    The grid is copied and made read-only. Start and goal must be free cells inside the grid;
    that the goal is reachable is not required here (`random_world` guarantees it; check
    `reachable` for loaded maps).
    """

    blocked: BoolGrid = field(
        converter=_read_only_grid, eq=attrs.cmp_using(eq=np.array_equal), hash=False
    )
    start: Position = field(converter=_position)
    goal: Position = field(converter=_position)
    movement: int = field(default=4)

    @blocked.validator
    def _check_blocked(self, _: attrs.Attribute[BoolGrid], grid: BoolGrid) -> None:
        if grid.ndim != 2 or grid.shape[0] != grid.shape[1]:
            raise ValueError(f"the grid must be square, got shape {grid.shape}")
        if not is_power_of_two(grid.shape[0]):
            raise ValueError(f"the grid side must be a power of two, got {grid.shape[0]}")

    @start.validator
    @goal.validator
    def _check_position(self, attribute: attrs.Attribute[Position], position: Position) -> None:
        x, y = position
        n = self.blocked.shape[0]
        if not (0 <= x < n and 0 <= y < n):
            raise ValueError(f"{attribute.name} {position} is outside the {n}x{n} grid")
        if self.blocked[y, x]:
            raise ValueError(f"{attribute.name} {position} is a blocked cell")

    @movement.validator
    def _check_movement(self, _: attrs.Attribute[int], movement: int) -> None:
        _check_movement(movement)

    @property
    def size(self) -> int:
        """N, the side of the grid."""
        return int(self.blocked.shape[0])

    def is_connected(self) -> bool:
        """Whether the goal is reachable from the start under the movement model."""
        x, y = self.goal
        return bool(reachable(self.blocked, self.start, self.movement)[y, x])


def random_world(
    size: int = 128,
    seed: int = 0,
    density: float = 0.2,
    min_side: int = 2,
    max_side: int | None = None,
    movement: int = 4,
) -> World:
    """A random world of rectangular obstacles, start (0, 0) and goal (N-1, N-1), connected.

    Rectangles with sides drawn uniformly in [min_side, max_side] (default N // 8) are placed
    uniformly (clipped at the border) until the blocked fraction reaches `density`. A rectangle
    that would cover the start or the goal or disconnect them is rejected, so connectivity holds
    by construction. Gives up adding after 100 consecutive rejections (the density then falls
    short; only with very high densities). Reproducible: the same arguments give the same world.
    """
    if not is_power_of_two(size) or size < 2:
        raise ValueError(f"size must be a power of two >= 2, got {size}")
    if not 0.0 <= density < 1.0:
        raise ValueError(f"density must be in [0, 1), got {density}")
    if max_side is None:
        max_side = max(min_side, size // 8)
    if not 1 <= min_side <= max_side:
        raise ValueError(f"need 1 <= min_side <= max_side, got {min_side} and {max_side}")
    _check_movement(movement)
    rng = np.random.default_rng(seed)
    start, goal = (0, 0), (size - 1, size - 1)
    blocked = np.zeros((size, size), dtype=bool)
    target = density * size * size
    count = 0
    rejected = 0
    while count < target and rejected < 100:
        w, h = rng.integers(min_side, max_side + 1, size=2)
        x0, y0 = rng.integers(0, size, size=2)
        candidate = blocked.copy()
        candidate[y0 : y0 + h, x0 : x0 + w] = True
        added = int(candidate.sum()) - count
        if (
            added == 0
            or candidate[start[1], start[0]]
            or candidate[goal[1], goal[0]]
            or not reachable(candidate, start, movement)[goal[1], goal[0]]
        ):
            rejected += 1
            continue
        blocked, count, rejected = candidate, count + added, 0
    return World(blocked, start, goal, movement)
