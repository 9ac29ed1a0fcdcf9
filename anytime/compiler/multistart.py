"""A multi-start local search for programs where dp is not exact: DAGs, best-of, if, stochastic
profiles, modules that are not input-monotone.

Time allocation over such programs is global compilation, NP-complete in general (Zilberstein &
Russell); the exact search is exponential in the number of modules. The search here is the
papers' hill-climbing, made robust against its local maxima by where it starts, which is what
hill-climbing needs on a landscape of few, wide basins (a best-of's diversify-or-commit choice,
a module whose quality only rises past a threshold):

1. From the equal split with the papers' first step (one equal share): hill-climbing itself,
   so the result is never below it.
2. From Romanenko's proportional split, and from the best few points of a coarse lattice of the
   simplex (every split in multiples of g units, g chosen so that a cell evaluates at most
   `SEED_POINTS` of them): a global look at the landscape that finds the basins, each point
   climbed with trades from g units down to one.
3. From the neighbouring totals' best allocations (the optimum at T is usually near the one at
   T +- dt), the difference added as an equal split or taken away in proportion, climbed
   again; repeated while some cell improves (at most `ROUNDS` times).

Each cell keeps the best of its climbs. All climbs of all cells run in lockstep on batches, in
chunks within the memory cap. The result is a lattice allocation no worse than hill-climbing's,
the equal split's and the proportional split's, with no bound on its gap to the optimum
(benchmarks/bench_allocators.py measures it against the exhaustive search).
"""

from __future__ import annotations

from math import comb

import numpy as np

from anytime.compiler.allocators import (
    DEFAULT_MEMORY,
    IMPROVEMENT,
    DynamicProgramming,
    Evaluates,
    HillClimbing,
    Proportional,
    chunk_rows,
    climb,
    compositions,
    dp_obstacle,
    equal_split,
    expected_in_chunks,
    least_climbing_memory,
    proportional_split,
    relaxable,
    row_bytes,
)
from anytime.compiler.evaluate import Evaluator
from anytime.profiles.profile import Array

SEED_POINTS = 1500  # points of the coarse lattice a cell evaluates, at most
SEEDS = 3  # of which the best few are climbed
ROUNDS = 3  # rounds of starts from the neighbouring totals' allocations
DP_UNITS = 50  # the finest lattice of the relaxed dp seed, in units


class MultiStart:
    """Hill-climbing from many starts: the papers', the proportional split, the best points of
    a coarse lattice and the neighbouring totals' allocations."""

    name = "multi-start"

    def __init__(self, memory: int = DEFAULT_MEMORY) -> None:
        self.memory = memory

    def memory_needed(self, evaluator: Evaluates, units: np.ndarray) -> int:
        """Its climbers' allocations and one row's trades, or one cell's coarse lattice."""
        n = evaluator.n_modules
        lattice = SEED_POINTS * (row_bytes(evaluator.model) + 16 * max(n, 1))
        return max(least_climbing_memory(evaluator, len(units) * (SEEDS + 2)), lattice)

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        n = evaluator.n_modules
        # The papers' hill-climbing first: the result is never below it.
        allocation, best = HillClimbing(self.memory).allocate(evaluator, quality, units, dt)
        if n <= 1:  # nothing to split
            return allocation, best
        first = np.where(units > 0, np.maximum(units // n, 1), 0)
        starts, steps, owners = [], [], []
        if len(evaluator.model.anytime_nodes) == n:  # not a restricted evaluator
            proportional, _ = Proportional(self.memory).allocate(evaluator, quality, units, dt)
            starts.append(proportional)
            steps.append(first)
            owners.append(np.arange(len(units)))
            seed = _relaxed_dp(evaluator, quality, units, dt, self.memory)
            if seed is not None:
                starts.append(seed)
                steps.append(first)
                owners.append(np.arange(len(units)))
        grid, spacing, owner = self._coarse_seeds(evaluator, quality, units, dt)
        starts.append(grid)
        steps.append(spacing)
        owners.append(owner)
        allocation, best = self._climb_all(
            evaluator, quality, dt, starts, steps, owners, allocation, best
        )
        for _ in range(ROUNDS):
            starts, steps, owners = _from_neighbours(quality, units, allocation)
            if not starts:
                break
            improved = best.copy()
            allocation, best = self._climb_all(
                evaluator, quality, dt, starts, steps, owners, allocation, best
            )
            if not np.any(best > improved):
                break
        return allocation, best

    def _climb_all(
        self,
        evaluator: Evaluates,
        quality: Array,
        dt: float,
        starts: list[np.ndarray],
        steps: list[np.ndarray],
        owners: list[np.ndarray],
        allocation: np.ndarray,
        best: Array,
    ) -> tuple[np.ndarray, Array]:
        """Climb every start (each for the cell `owners` says), trying every trade size from
        its first down to one unit, and keep each cell's best: `allocation` and `best` where no
        climb does better."""
        start, step, owner = np.concatenate(starts), np.concatenate(steps), np.concatenate(owners)
        q = quality[owner]
        value = expected_in_chunks(evaluator, q, start * dt, self.memory)
        top, top_value = climb(evaluator, q, start, value, step, dt, self.memory, True)
        allocation, best = allocation.copy(), best.copy()
        # The best climb of each cell: order by value, the first start of equals winning.
        order = np.lexsort((np.arange(len(owner)), -top_value, owner))
        first = order[np.r_[True, owner[order][1:] != owner[order][:-1]]]
        cells = owner[first]
        take = top_value[first] > best[cells] + IMPROVEMENT
        allocation[cells[take]] = top[first[take]]
        best[cells[take]] = top_value[first[take]]
        return allocation, best

    def _coarse_seeds(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The best `SEEDS` points of each cell's coarse lattice, their spacing and cell."""
        n = evaluator.n_modules
        seeds, spacing, owner = [], [], []
        for total in np.unique(units):
            cells = np.flatnonzero(units == total)
            k = coarse_parts(int(total), n)
            g = int(total) // k if k else 0
            points = compositions(k, n) * g
            points = points + equal_split(np.full(len(points), int(total) - k * g), n)
            value = np.empty((len(cells), len(points)))
            per = max(1, chunk_rows(evaluator.model, self.memory, 16 * n) // len(points))
            for first in range(0, len(cells), per):
                part = cells[first : first + per]
                q = np.repeat(quality[part], len(points), axis=0)
                a = np.tile(points, (len(part), 1)) * dt
                value[first : first + per] = evaluator.expected(q, a).reshape(len(part), -1)
            keep = min(SEEDS, len(points))
            top = np.argsort(-value, axis=1, kind="stable")[:, :keep]
            seeds.append(points[top].reshape(-1, n))
            spacing.append(np.full(top.size, max(g, 1) if total > 0 else 0))
            owner.append(np.repeat(cells, keep))
        return np.concatenate(seeds), np.concatenate(spacing), np.concatenate(owner)


def _relaxed_dp(
    evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float, memory: int
) -> np.ndarray | None:
    """dp's allocations on the program taken as a tree (a seed: exact for a tree of
    deterministic monotone modules, near the optimum for few shared results), moved onto
    each total; None where relaxed dp cannot run or would not fit the memory cap."""
    if not isinstance(evaluator, Evaluator) or not relaxable(evaluator.model):
        return None
    # Where dp is exact its answer is the optimum: on the lattice itself. Elsewhere on a
    # lattice of at most `DP_UNITS` units: dp costs (units)^(k+1) at a node of k children, and
    # a seed needs only to land in the right basin; the climbs refine it.
    exact = dp_obstacle(evaluator.model) is None
    coarse = 1 if exact else max(1, -(-int(units.max(initial=0)) // DP_UNITS))
    dp = DynamicProgramming(memory, relaxed=True)
    if dp.memory_needed(evaluator, units // coarse) > memory:
        return None
    allocation, _ = dp.allocate(evaluator, quality, units // coarse, dt * coarse)
    return _moved(allocation * coarse, units)


def coarse_parts(total: int, n: int) -> int:
    """The most parts k <= total that the coarse lattice of n modules may split a total into:
    the largest k with at most `SEED_POINTS` compositions of k into n parts."""
    k = 0
    while k < total and comb(k + 1 + n - 1, n - 1) <= SEED_POINTS:
        k += 1
    return k


def _from_neighbours(
    quality: Array, units: np.ndarray, allocation: np.ndarray
) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Starts for each cell from the allocations of the next smaller and larger totals at the
    same input qualities, moved onto its own total: the difference added as an equal split,
    or taken away in proportion to the shares; the first trade size is the difference."""
    _, group = np.unique(quality, axis=0, return_inverse=True)
    group = group.reshape(-1)
    order = np.lexsort((units, group))
    same = group[order][1:] == group[order][:-1]
    lower, upper = order[:-1][same], order[1:][same]  # neighbours: lower total, upper total
    starts, steps, owners = [], [], []
    for source, target in ((lower, upper), (upper, lower)):
        if not len(source):
            continue
        moved = _moved(allocation[source], units[target])
        starts.append(moved)
        steps.append(np.maximum(np.abs(units[target] - units[source]), 1))
        owners.append(target)
    return starts, steps, owners


def _moved(allocation: np.ndarray, units: np.ndarray) -> np.ndarray:
    """Each row of `allocation` moved onto its total in `units`: more time added as an equal
    split, less taken away in proportion to the shares."""
    spent = allocation.sum(axis=1)
    grown = allocation + equal_split(np.maximum(units - spent, 0), allocation.shape[1])
    return np.where((units >= spent)[:, None], grown, proportional_split(units, allocation))
