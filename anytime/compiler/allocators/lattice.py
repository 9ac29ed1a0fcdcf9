"""The allocators' lattice: allocations are whole numbers of time units `dt` summing exactly to
`T / dt`, so that every allocator's results are comparable."""

from __future__ import annotations

from collections.abc import Iterator
from math import comb

import numpy as np

from anytime.profiles.profile import Array


def compositions(total: int, parts: int) -> np.ndarray:
    """Every way to write `total` as an ordered sum of `parts` non-negative integers, in
    lexicographic order (built column by column in numpy: memory is the result's only)."""
    if parts == 0:
        return np.zeros((1 if total == 0 else 0, 0), dtype=np.int64)
    rows = np.zeros((1, 0), dtype=np.int64)
    spent = np.zeros(1, dtype=np.int64)
    for _ in range(parts - 1):
        # Each row grows by every value from 0 to what it has left, in increasing order.
        room = total - spent + 1
        start = np.repeat(np.cumsum(room) - room, room)
        value = np.arange(int(room.sum()), dtype=np.int64) - start
        rows = np.column_stack([np.repeat(rows, room, axis=0), value])
        spent = np.repeat(spent, room) + value
    return np.column_stack([rows, total - spent])


def composition_blocks(total: int, parts: int, limit: int) -> Iterator[np.ndarray]:
    """`compositions(total, parts)` in lexicographic blocks of at most `limit` rows where it
    can (a block fixes the leading parts; one with a single free part is one row)."""
    if parts <= 1 or comb(total + parts - 1, parts - 1) <= limit:
        yield compositions(total, parts)
        return
    for first in range(total + 1):
        for block in composition_blocks(total - first, parts - 1, limit):
            yield np.column_stack([np.full(len(block), first, dtype=np.int64), block])


def equal_split(units: np.ndarray, n: int) -> np.ndarray:
    """Equal shares on the lattice: the remainder goes one unit each to the first modules."""
    base = units[:, None] // n
    extra = np.arange(n)[None, :] < (units[:, None] % n)
    return (base + extra).astype(np.int64)


def proportional_split(units: np.ndarray, weights: Array) -> np.ndarray:
    """`units` split in proportion to `weights` on the lattice (largest remainders first),
    the weights one vector `(n,)` or one per row `(C, n)`; an equal split where every weight
    is 0."""
    weights = np.broadcast_to(
        np.asarray(weights, dtype=np.float64), (len(units), np.shape(weights)[-1])
    )
    n = weights.shape[1]
    if n == 0:
        return np.zeros((len(units), 0), dtype=np.int64)
    total = weights.sum(axis=1, keepdims=True)
    share = np.divide(weights, total, out=np.full(weights.shape, 1.0 / n), where=total > 0)
    exact = units[:, None] * share
    base = np.floor(exact + 1e-9).astype(np.int64)
    left = units - base.sum(axis=1)
    rank = np.argsort(np.argsort(-(exact - base), axis=1, kind="stable"), axis=1)
    split: np.ndarray = base + (rank < left[:, None])
    return np.where((total > 0), split, equal_split(units, n))
