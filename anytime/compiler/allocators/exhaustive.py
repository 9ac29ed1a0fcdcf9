"""`Exhaustive`: every allocation of the lattice simplex; exact, and exponential in n (the
reference for small programs)."""

from __future__ import annotations

from math import comb

import numpy as np

from anytime.compiler.allocators.lattice import composition_blocks
from anytime.compiler.allocators.memory import DEFAULT_MEMORY, chunk_rows, row_bytes
from anytime.compiler.allocators.protocol import Evaluates, nothing_to_allocate
from anytime.compiler.model import CompileError
from anytime.profiles.profile import Array

EXHAUSTIVE_LIMIT = 4_000_000  # rows the exhaustive search may evaluate in one compile


class Exhaustive:
    """Every allocation on the lattice; the reference for small programs. The allocations of
    each total are generated and evaluated a block at a time, within the memory cap."""

    name = "exhaustive"

    def __init__(self, memory: int = DEFAULT_MEMORY, limit: int | None = None) -> None:
        self.memory = memory
        # The most allocations it evaluates (None: `EXHAUSTIVE_LIMIT`; a benchmark's reference
        # may raise it).
        self.limit = limit

    @staticmethod
    def rows(units: np.ndarray, n: int) -> int:
        """How many allocations the search evaluates for these totals."""
        return sum(comb(int(u) + n - 1, n - 1) for u in units) if n else len(units)

    @staticmethod
    def computable(units: np.ndarray, n: int) -> bool:
        return Exhaustive.rows(units, n) <= EXHAUSTIVE_LIMIT

    def memory_needed(self, evaluator: Evaluates, units: np.ndarray) -> int:
        """Its rows' results, and the smallest block: one allocation for each cell of a total."""
        n = evaluator.n_modules
        cells = max(np.unique(units, return_counts=True)[1], default=0)
        return 8 * len(units) * (n + 2) + cells * (row_bytes(evaluator.model) + 24 * n)

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        n = evaluator.n_modules
        if n == 0:
            return nothing_to_allocate(evaluator, quality, units)
        rows = self.rows(units, n)
        limit = EXHAUSTIVE_LIMIT if self.limit is None else self.limit
        if rows > limit:
            raise CompileError(
                f"exhaustive search would evaluate {rows:,} allocations (more than "
                f"{limit:,}); use dp or hill-climbing, or a coarser time grid"
            )
        allocation = np.zeros((len(units), n), dtype=np.int64)
        best = np.full(len(units), -np.inf)
        for total in np.unique(units):  # one simplex per distinct total, all its cells at once
            cells = np.flatnonzero(units == total)
            per_block = chunk_rows(evaluator.model, self.memory, 24 * n) // len(cells)
            for chunk in composition_blocks(int(total), n, max(1, per_block)):
                q = np.repeat(quality[cells], len(chunk), axis=0)
                a = np.tile(chunk, (len(cells), 1))
                value = evaluator.expected(q, a * dt).reshape(len(cells), len(chunk))
                choice = value.argmax(axis=1)
                top = value[np.arange(len(cells)), choice]
                better = top > best[cells]
                allocation[cells[better]] = chunk[choice[better]]
                best[cells[better]] = top[better]
        return allocation, best
