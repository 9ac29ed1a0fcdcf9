"""The legal moves of a grid one at a time, for tests to check the vectorised code against."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

#: Each move once: the forward half of the 4- or 8-neighbourhood.
MOVES = {
    4: ((1, 0), (0, 1)),
    8: ((1, 0), (0, 1), (1, 1), (-1, 1)),
}


def legal_moves(
    blocked: np.ndarray, movement: int
) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Every legal move once, ((x, y), (x', y')): both cells free and, for a diagonal, both
    orthogonal neighbours (no corner cutting)."""
    side = blocked.shape[0]
    moves = []
    for y in range(side):
        for x in range(side):
            for dx, dy in MOVES[movement]:
                nx, ny = x + dx, y + dy
                if not (0 <= nx < side and 0 <= ny < side) or blocked[y, x] or blocked[ny, nx]:
                    continue
                if dx and dy and (blocked[y, nx] or blocked[ny, x]):
                    continue
                moves.append(((x, y), (nx, ny)))
    return moves


def draw_free_pair(
    blocked: np.ndarray, data: st.DataObject
) -> tuple[tuple[int, int], tuple[int, int]] | None:
    """Two free cells (x, y) drawn by hypothesis (possibly the same one); None when the map
    has fewer than two."""
    free = np.argwhere(~blocked)
    if len(free) < 2:
        return None
    i, k = data.draw(st.integers(0, len(free) - 1)), data.draw(st.integers(0, len(free) - 1))
    (sy, sx), (gy, gx) = free[i], free[k]
    return (int(sx), int(sy)), (int(gx), int(gy))
