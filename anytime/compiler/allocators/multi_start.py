"""A multi-start local search for programs where dp is not exact: DAGs, best-of, if, stochastic
profiles, modules that are not input-monotone.

Time allocation over such programs is global compilation, NP-complete in general (Zilberstein &
Russell); the exact search is exponential in the number of modules. The search here is the
papers' hill-climbing, made robust against its local maxima by where it starts, which is what
hill-climbing needs on a landscape of few, wide basins (a best-of's diversify-or-commit choice,
a module whose quality only rises past a threshold):

1. From the equal split with the papers' first step (one equal share): hill-climbing itself,
   so the result is never below it.
2. From Romanenko's proportional split, from dp's allocation with the program taken as a tree
   (relaxed dp), and from the best few points of a coarse lattice of the simplex (every split
   in multiples of g units, g chosen so that a cell evaluates at most `SEED_POINTS` of them): a
   global look at the landscape that finds the basins, each point climbed with trades of g
   units, halved down to one.
3. From the neighbouring totals' best allocations (the optimum at T is usually near the one at
   T +- dt), the difference added as an equal split or taken away in proportion, climbed
   again; repeated while some cell improves (at most `ROUNDS` times).

Each cell keeps the best of its climbs. All climbs of all cells run in lockstep on batches, in
chunks within the memory cap. A small program's time goes to the evaluator's cost per call, so
the number of calls is what is kept small: trade sizes are halved rather than lowered one unit
at a time (2-3x fewer calls; benchmarks/bench_allocators.py measured the gaps staying within
their targets), and the coarse lattices of many cells are evaluated in one call. The result is
a lattice allocation no worse than hill-climbing's, the equal split's and the proportional
split's, with no bound on its gap to the optimum (benchmarks/bench_allocators.py measures it
against the exhaustive search).
"""

from __future__ import annotations

from math import comb

import numpy as np

from anytime.compiler.allocators.dynamic_programming import (
    DynamicProgramming,
    dp_obstacle,
    relaxable,
)
from anytime.compiler.allocators.hill_climbing import (
    IMPROVEMENT,
    HillClimbing,
    climb,
    least_climbing_memory,
)
from anytime.compiler.allocators.lattice import compositions, equal_split, proportional_split
from anytime.compiler.allocators.memory import (
    DEFAULT_MEMORY,
    chunk_rows,
    expected_in_chunks,
    row_bytes,
)
from anytime.compiler.allocators.proportional import Proportional
from anytime.compiler.allocators.protocol import Evaluates
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
        if n <= 1:  # nothing to split: the papers' hill-climbing says all there is
            return HillClimbing(self.memory).allocate(evaluator, quality, units, dt)
        # The papers' hill-climbing is the first start (equal split, one equal share's trades,
        # halving): climbed in lockstep with the others, its row ends where hill-climbing
        # alone would, so the result is never below it.
        first = np.where(units > 0, np.maximum(units // n, 1), 0)
        cells = np.arange(len(units))
        starts, steps, owners = [equal_split(units, n)], [first], [cells]
        if len(evaluator.model.anytime_nodes) == n:  # not a restricted evaluator
            proportional, _ = Proportional(self.memory).allocate(evaluator, quality, units, dt)
            starts.append(proportional)
            steps.append(first)
            owners.append(cells)
            seed = _relaxed_dp(evaluator, quality, units, dt, self.memory)
            if seed is not None:
                starts.append(seed)
                steps.append(first)
                owners.append(cells)
        grid, spacing, owner = self._coarse_seeds(evaluator, quality, units, dt)
        starts.append(grid)
        steps.append(spacing)
        owners.append(owner)
        allocation = np.zeros((len(units), n), dtype=np.int64)
        best = np.full(len(units), -np.inf)
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
        """Climb every start (each for the cell `owners` says) with trades from its first
        size, halving it, and keep each cell's best: `allocation` and `best` where no climb
        does better. All climbs move in lockstep, so the evaluator is called once per step of
        the longest climb: what costs a small program most is that count, not the rows."""
        start, step, owner = np.concatenate(starts), np.concatenate(steps), np.concatenate(owners)
        q = quality[owner]
        value = expected_in_chunks(evaluator, q, start * dt, self.memory)
        top, top_value = climb(evaluator, q, start, value, step, dt, self.memory)
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
        """The best `SEEDS` points of each cell's coarse lattice, their spacing and cell. The
        lattices of as many cells as the memory cap holds are evaluated in one call."""
        n = evaluator.n_modules
        lattices = {total: _coarse_lattice(total, n) for total in set(units.tolist())}
        sizes = [len(lattices[total][0]) for total in units.tolist()]
        limit = chunk_rows(evaluator.model, self.memory, 16 * n)
        seeds, spacing, owner = [], [], []
        for cells in _groups(sizes, limit):
            lattice = [lattices[int(units[cell])] for cell in cells]
            points = np.concatenate([points for points, _ in lattice])
            count = [sizes[cell] for cell in cells]
            value = evaluator.expected(np.repeat(quality[cells], count, axis=0), points * dt)
            ends = np.cumsum(count)
            for cell, (cell_points, g), end, size in zip(cells, lattice, ends, count, strict=True):
                keep = min(SEEDS, size)
                top = np.argsort(-value[end - size : end], kind="stable")[:keep]
                seeds.append(cell_points[top])
                spacing.append(np.full(keep, g))
                owner.append(np.full(keep, cell))
        return np.concatenate(seeds), np.concatenate(spacing), np.concatenate(owner)


def _coarse_lattice(total: int, n: int) -> tuple[np.ndarray, int]:
    """Every split of `total` units among n modules in multiples of g units (the remainder
    as an equal split), g the least that keeps them within `SEED_POINTS`; and g (0 for no
    time)."""
    k = coarse_parts(total, n)
    g = total // k if k else 0
    points = compositions(k, n) * g + equal_split(np.full(1, total - k * g), n)
    return points, max(g, 1) if total > 0 else 0


def _groups(sizes: list[int], limit: int) -> list[list[int]]:
    """Consecutive indices of `sizes` in groups whose sizes sum to at most `limit` (a group
    of one where one alone is more)."""
    groups: list[list[int]] = [[]]
    held = 0
    for index, size in enumerate(sizes):
        if groups[-1] and held + size > limit:
            groups.append([])
            held = 0
        groups[-1].append(index)
        held += size
    return groups if groups[0] else []


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
