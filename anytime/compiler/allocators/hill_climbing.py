"""`HillClimbing`: the papers' algorithm as written (Zilberstein & Russell, "Time allocation
algorithm"): start with equal shares; while some trade of s units from module i to module j
raises E[Q_out], make the best one; then halve s, until s < epsilon (one unit). It is
O(n^2 log(T/epsilon)) evaluations per cell and may stop at a local maximum. The papers leave
`initial-resolution(T)` open; we start with one equal share, T/n, so that the first trades
can hand a module's whole share to another (measured in benchmarks/bench_compiler.py: half the
mean gap to the optimum of starting with T/2n).
"""

from __future__ import annotations

import numpy as np

from anytime.compiler.allocators.lattice import equal_split
from anytime.compiler.allocators.memory import DEFAULT_MEMORY, expected_in_chunks, row_bytes
from anytime.compiler.allocators.protocol import Evaluates, nothing_to_allocate
from anytime.profiles.profile import Array

IMPROVEMENT = 1e-12  # a trade must raise E[Q_out] by more than this to count


def trades(n: int) -> np.ndarray:
    """Every trade of one unit from one module to another, as rows `(n (n - 1), n)`."""
    pairs = np.array([(i, j) for i in range(n) for j in range(n) if i != j]).reshape(-1, 2)
    trade = np.zeros((len(pairs), n), dtype=np.int64)
    trade[np.arange(len(pairs)), pairs[:, 0]] = -1
    trade[np.arange(len(pairs)), pairs[:, 1]] = 1
    return trade


def climb(
    evaluator: Evaluates,
    quality: Array,
    allocation: np.ndarray,
    best: Array,
    step: np.ndarray,
    dt: float,
    memory: int,
) -> tuple[np.ndarray, Array]:
    """The papers' hill-climbing from `allocation (R, n)` (expected qualities `best`), every row
    in lockstep: while some trade of `step` units from one module to another raises E[Q_out],
    make the best one; else halve the step, until it is below one unit. Returns the final
    allocations and qualities (the inputs are not changed)."""
    allocation, best, step = allocation.copy(), best.copy(), step.copy()
    n = allocation.shape[1]
    trade = trades(n)
    per_row = len(trade) * (row_bytes(evaluator.model) + 16 * n + 8 * quality.shape[1])
    chunk = max(1, memory // per_row)
    active = step >= 1
    while active.any():
        for start in range(0, int(active.sum()), chunk):
            rows = np.flatnonzero(active)[start : start + chunk]
            candidates = allocation[rows, None, :] + step[rows, None, None] * trade[None]
            # Only trades a module can afford are evaluated (a negative share is no call, and
            # would widen the batch's distributions for nothing).
            valid = (candidates >= 0).all(axis=2)
            row, column = np.nonzero(valid)
            value = np.full(valid.shape, -np.inf)
            if len(row):
                value[row, column] = evaluator.expected(
                    quality[rows[row]], candidates[row, column] * dt
                )
            choice = value.argmax(axis=1)
            top = value[np.arange(len(rows)), choice]
            gain = top > best[rows] + IMPROVEMENT
            allocation[rows[gain]] = candidates[gain, choice[gain]]
            best[rows[gain]] = top[gain]
            step[rows[~gain]] = step[rows[~gain]] // 2
        active = step >= 1
    return allocation, best


def least_climbing_memory(evaluator: Evaluates, rows: int) -> int:
    """What hill-climbing holds at the least: its rows' allocations, and one row's trades."""
    n = evaluator.n_modules
    trade = n * (n - 1)
    return 8 * rows * (3 * n + 4) + trade * (row_bytes(evaluator.model) + 16 * n)


class HillClimbing:
    """The papers' hill-climbing time allocation, run on every cell in lockstep."""

    name = "hill-climbing"

    def __init__(self, memory: int = DEFAULT_MEMORY) -> None:
        self.memory = memory

    def memory_needed(self, evaluator: Evaluates, units: np.ndarray) -> int:
        return least_climbing_memory(evaluator, len(units))

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        n = evaluator.n_modules
        if n == 0:
            return nothing_to_allocate(evaluator, quality, units)
        allocation = equal_split(units, n)
        best = expected_in_chunks(evaluator, quality, allocation * dt, self.memory)
        if n == 1:
            return allocation, best
        step = np.maximum(units // n, 1)  # initial-resolution(T): one equal share
        step[units <= 0] = 0
        return climb(evaluator, quality, allocation, best, step, dt, self.memory)
