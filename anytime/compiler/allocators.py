"""Time allocators: how a total time T is split among a program's anytime modules.

All allocators work on one lattice: allocations are whole numbers of time units `dt`, summing
exactly to `T / dt`, so their results are comparable (the exhaustive search is the reference).
Each works on a batch of cells at once: rows of program input qualities `q (C, m)` and totals
`units (C,)`, returning allocations `(C, n)` in units and their expected output qualities.

- `HillClimbing`: the papers' algorithm as written (Zilberstein & Russell, "Time allocation
  algorithm"): start with equal shares; while some trade of s units from module i to module j
  raises E[Q_out], make the best one; then halve s, until s < epsilon (one unit). It is
  O(n^2 log(T/epsilon)) evaluations per cell and may stop at a local maximum. The papers leave
  `initial-resolution(T)` open; we start with one equal share, T/n, so that the first trades
  can hand a module's whole share to another (measured in benchmarks/bench_compiler.py: half the
  mean gap to the optimum of starting with T/2n).
- `Exhaustive`: every allocation of the lattice simplex; exact, and exponential in n.
- `Proportional`: Romanenko's rule for sharing a decision time T_d among alternatives,
  `T_i = T_d * T_i* / sum_j T_j*`, with `T_i*` a lower bound on the time module i needs: here
  the least time at which its expected quality (with perfect inputs) rises above its value at
  no time, i.e. its first variant. Applied to every anytime module (a multi-module
  alternative so gets the sum of its modules' bounds). Kept as a baseline: it looks at no
  profile beyond that first point.
- `DynamicProgramming`: local compilation. For a tree whose modules are deterministic and
  input-monotone, the best output of a subtree given its time depends on nothing else, so each
  node keeps the best quality of its subtree for every budget and the parent chooses how to split
  its budget between its own run and its subtrees: exact, pseudo-polynomial in T / dt.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from math import comb
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from anytime.compiler.evaluate import Evaluator
from anytime.compiler.model import (
    ChoiceNode,
    CompileError,
    CompileModel,
    ElementaryNode,
    IfNode,
    LoopNode,
    ModuleNode,
    TestNode,
)
from anytime.profiles.profile import Array, ConditionalPerformanceProfile

IMPROVEMENT = 1e-12  # a trade must raise E[Q_out] by more than this to count
EXHAUSTIVE_LIMIT = 4_000_000  # rows the exhaustive search may evaluate in one compile
CHUNK = 200_000  # rows evaluated at once


class Evaluates(Protocol):
    """What hill-climbing and the exhaustive search need: batched expected quality."""

    @property
    def n_modules(self) -> int: ...

    def expected(self, quality: ArrayLike, allocation: ArrayLike) -> Array: ...


class Allocator(Protocol):
    name: str

    def allocate(
        self, evaluator: Evaluator, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        """Allocations `(C, n)` in units, and their expected output qualities `(C,)`."""
        ...


def compositions(total: int, parts: int) -> np.ndarray:
    """Every way to write `total` as an ordered sum of `parts` non-negative integers."""
    if parts == 0:
        return np.zeros((1 if total == 0 else 0, 0), dtype=np.int64)
    if parts == 1:
        return np.array([[total]], dtype=np.int64)
    bars = np.array(list(itertools.combinations(range(total + parts - 1), parts - 1)))
    edges = np.column_stack([np.full(len(bars), -1), bars, np.full(len(bars), total + parts - 1)])
    return np.diff(edges, axis=1) - 1


def nothing_to_allocate(
    evaluator: Evaluates, quality: Array, units: np.ndarray
) -> tuple[np.ndarray, Array]:
    """A program without anytime modules: no time to split, its quality whatever T is."""
    allocation = np.zeros((len(units), 0), dtype=np.int64)
    return allocation, evaluator.expected(quality, allocation)


def equal_split(units: np.ndarray, n: int) -> np.ndarray:
    """Equal shares on the lattice: the remainder goes one unit each to the first modules."""
    base = units[:, None] // n
    extra = np.arange(n)[None, :] < (units[:, None] % n)
    return (base + extra).astype(np.int64)


class HillClimbing:
    """The papers' hill-climbing time allocation, run on every cell in lockstep."""

    name = "hill-climbing"

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        n = evaluator.n_modules
        if n == 0:
            return nothing_to_allocate(evaluator, quality, units)
        allocation = equal_split(units, n)
        best = evaluator.expected(quality, allocation * dt)
        if n == 1:
            return allocation, best
        pairs = np.array([(i, j) for i in range(n) for j in range(n) if i != j])
        trade = np.zeros((len(pairs), n), dtype=np.int64)
        trade[np.arange(len(pairs)), pairs[:, 0]] = -1
        trade[np.arange(len(pairs)), pairs[:, 1]] = 1
        step = np.maximum(units // n, 1)  # initial-resolution(T): one equal share
        active = units > 0
        while active.any():
            rows = np.flatnonzero(active)
            candidates = allocation[rows, None, :] + step[rows, None, None] * trade[None]
            valid = (candidates >= 0).all(axis=2)
            flat = candidates.reshape(-1, n)
            q = np.repeat(quality[rows], len(pairs), axis=0)
            value = evaluator.expected(q, flat * dt).reshape(len(rows), len(pairs))
            value[~valid] = -np.inf
            choice = value.argmax(axis=1)
            gain = value[np.arange(len(rows)), choice] > best[rows] + IMPROVEMENT
            better = rows[gain]
            allocation[better] = candidates[gain, choice[gain]]
            best[better] = value[gain, choice[gain]]
            stuck = rows[~gain]
            step[stuck] //= 2
            active[stuck] = step[stuck] >= 1
        return allocation, best


class Exhaustive:
    """Every allocation on the lattice; the reference for small programs."""

    name = "exhaustive"

    @staticmethod
    def rows(units: np.ndarray, n: int) -> int:
        """How many allocations the search evaluates for these totals."""
        return sum(comb(int(u) + n - 1, n - 1) for u in units) if n else len(units)

    @staticmethod
    def computable(units: np.ndarray, n: int) -> bool:
        return Exhaustive.rows(units, n) <= EXHAUSTIVE_LIMIT

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        n = evaluator.n_modules
        if n == 0:
            return nothing_to_allocate(evaluator, quality, units)
        rows = self.rows(units, n)
        if rows > EXHAUSTIVE_LIMIT:
            raise CompileError(
                f"exhaustive search would evaluate {rows:,} allocations (more than "
                f"{EXHAUSTIVE_LIMIT:,}); use dp or hill-climbing, or a coarser time grid"
            )
        allocation = np.zeros((len(units), n), dtype=np.int64)
        best = np.full(len(units), -np.inf)
        for total in np.unique(units):  # one simplex per distinct total, all its cells at once
            cells = np.flatnonzero(units == total)
            candidates = compositions(int(total), n)
            for start in range(0, len(candidates), max(1, CHUNK // len(cells))):
                chunk = candidates[start : start + max(1, CHUNK // len(cells))]
                q = np.repeat(quality[cells], len(chunk), axis=0)
                a = np.tile(chunk, (len(cells), 1))
                value = evaluator.expected(q, a * dt).reshape(len(cells), len(chunk))
                choice = value.argmax(axis=1)
                top = value[np.arange(len(cells)), choice]
                better = top > best[cells]
                allocation[cells[better]] = chunk[choice[better]]
                best[cells[better]] = top[better]
        return allocation, best


def least_useful_time(profile: ConditionalPerformanceProfile) -> float:
    """Romanenko's `T*`: the first time on the profile's grid at which, with perfect inputs, its
    expected quality rises above what it gives with no time (its first variant; for a profile
    that never improves, its first time)."""
    best_input = np.ones((len(profile.time), profile.n_inputs))
    curve = profile.expected(best_input, profile.time)
    better = curve > curve[0] + 1e-12
    return float(profile.time[np.argmax(better)] if np.any(better) else profile.time[0])


def proportional_split(units: np.ndarray, weights: Array) -> np.ndarray:
    """`units` split in proportion to `weights` on the lattice (largest remainders first);
    an equal split when every weight is 0."""
    n = len(weights)
    if n == 0 or not weights.sum() > 0:
        return equal_split(units, n) if n else np.zeros((len(units), 0), dtype=np.int64)
    exact = units[:, None] * (weights / weights.sum())[None, :]
    base = np.floor(exact + 1e-9).astype(np.int64)
    left = units - base.sum(axis=1)
    rank = np.argsort(np.argsort(-(exact - base), axis=1, kind="stable"), axis=1)
    split: np.ndarray = base + (rank < left[:, None])
    return split


class Proportional:
    """Romanenko's proportional split: each module's share of T is proportional to `T*`."""

    name = "proportional"

    def allocate(
        self, evaluator: Evaluator, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        nodes = evaluator.model.anytime_nodes
        if not nodes:
            return nothing_to_allocate(evaluator, quality, units)
        star = np.array([least_useful_time(n.profile) + _step(n) for n in nodes])
        allocation = proportional_split(units, star)
        return allocation, evaluator.expected(quality, allocation * dt)


def _step(node: ModuleNode | IfNode | LoopNode) -> float:
    """The part of a node's share it reserves for its last step (see `ModuleNode.run_time`)."""
    return node.step if isinstance(node, ModuleNode) else 0.0


def dp_obstacle(model: CompileModel) -> str | None:
    """Why local compilation would not be exact for this program (None: it is exact)."""
    shape = model.graph.shape
    if shape == "dag":
        return (
            "the program is a DAG (a result is used twice), and local compilation is exact "
            "only for chains and trees"
        )
    for node in model.nodes:
        match node:
            case TestNode() | ChoiceNode():
                continue  # a test's quality flows nowhere; a best-of's is the max of its inputs
            case IfNode():
                return "an if's output is a mixture of its branches, not a function of its time"
            case ElementaryNode(monotone=False):
                return (
                    f"the quality combination of '{node.name}' is not known to be monotone "
                    "(only min and max are)"
                )
            case ElementaryNode():
                continue
        if not node.deterministic:
            return (
                f"module '{node.name}' has a stochastic profile; local compilation is exact "
                "only when every module's quality is a function of its input qualities and time"
            )
        mean = node.profile.mean
        assert mean is not None
        for axis in range(node.profile.n_inputs):
            if np.any(np.diff(mean, axis=axis) < -1e-12):
                return (
                    f"module '{node.name}' is not input-monotone: a better quality of input "
                    f"{axis + 1} lowers its output somewhere"
                )
    return None


class DynamicProgramming:
    """Local compilation by dynamic programming over budgets, for monotone deterministic trees."""

    name = "dp"

    def allocate(
        self, evaluator: Evaluator, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        model = evaluator.model
        reason = dp_obstacle(model)
        if reason is not None:
            raise CompileError(f"dp does not apply: {reason}")
        cells, inverse = np.unique(quality, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        top = int(units.max(initial=0))
        best: dict[int, Array] = {}  # node -> (Q, top+1) best quality per budget
        choice: dict[int, np.ndarray] = {}  # node -> (Q, top+1) index of the best split
        splits: dict[int, np.ndarray] = {}  # node -> (R, parts) candidate splits
        root = model.output.index if model.output.kind == "node" else -1
        totals = np.unique(units)
        for node in model.nodes:
            if isinstance(node, TestNode | IfNode):
                continue  # a test's quality flows nowhere; an if is an obstacle to dp
            # Inner subtrees may get any budget; the root only the totals asked for.
            budgets = totals if node.index == root else None
            best[node.index], choice[node.index], splits[node.index] = self._node(
                node, best, cells, top, dt, budgets
            )
        n = evaluator.n_modules
        if n == 0:
            return nothing_to_allocate(evaluator, quality, units)
        allocation = np.zeros((len(units), n), dtype=np.int64)
        assert model.output.kind == "node"  # anytime modules exist, so the output is a call
        root = model.output.index
        value = best[root][inverse, units]
        # Walk down from the root, handing each subtree its budget.
        budget = {root: units.astype(np.int64)}
        for node in reversed(model.nodes):
            if node.index not in budget:
                continue
            split = splits[node.index][choice[node.index][inverse, budget[node.index]]]
            column = 0
            if isinstance(node, ModuleNode | LoopNode):
                allocation[:, node.time_index] = split[:, 0]
                column = 1
            for slot in node.slots:
                if slot.kind == "node":
                    budget[slot.index] = split[:, column]
                    column += 1
        return allocation, value

    @staticmethod
    def _node(
        node: ModuleNode | ElementaryNode | ChoiceNode | LoopNode,
        best: dict[int, Array],
        cells: Array,
        top: int,
        dt: float,
        budgets: np.ndarray | None,
    ) -> tuple[Array, np.ndarray, np.ndarray]:
        children = [s.index for s in node.slots if s.kind == "node"]
        parts = (1 if isinstance(node, ModuleNode | LoopNode) else 0) + len(children)
        # Every split of every budget up to `top` (or of `budgets` only): the own time first,
        # then each child's.
        with_slack = compositions(top, parts + 1)
        candidates = with_slack[:, :parts]
        spent = candidates.sum(axis=1)
        if budgets is not None:
            keep = np.isin(spent, budgets)
            candidates, spent = candidates[keep], spent[keep]
        n_cells, n_rows = len(cells), len(candidates)
        qualities = []
        column = 1 if isinstance(node, ModuleNode | LoopNode) else 0
        for slot in node.slots:
            if slot.kind == "node":
                qualities.append(best[slot.index][:, candidates[:, column]])
                column += 1
            elif slot.kind == "input":
                qualities.append(np.repeat(cells[:, [slot.index]], n_rows, axis=1))
            else:
                qualities.append(np.full((n_cells, n_rows), slot.value))
        q = np.stack(qualities, axis=-1) if qualities else np.zeros((n_cells, n_rows, 0))
        # A subtree cannot spend a budget it has no use for (no anytime module): -inf there.
        infeasible = np.isneginf(q).any(axis=-1)
        q = np.where(np.isneginf(q), 0.0, q)
        if isinstance(node, ModuleNode | LoopNode):
            t = np.broadcast_to(node.run_time(candidates[:, 0] * dt), (n_cells, n_rows))
            step = max(1, CHUNK // max(n_cells, 1))  # bounds the interpolation's memory
            value = (
                np.concatenate(
                    [
                        node.profile.expected(q[:, i : i + step], t[:, i : i + step])
                        for i in range(0, n_rows, step)
                    ],
                    axis=1,
                )
                if n_rows
                else np.zeros((n_cells, 0))
            )
        elif isinstance(node, ElementaryNode):
            value = node.combine(np.moveaxis(q, -1, 0)) if qualities else np.ones((n_cells, n_rows))
        else:  # a best-of: the best of its alternatives
            value = np.max(q, axis=-1) if qualities else np.ones((n_cells, n_rows))
        value = np.where(infeasible, -np.inf, value)
        # The best split for each budget: candidates that spend exactly that budget.
        table = np.full((n_cells, top + 1), -np.inf)
        index = np.zeros((n_cells, top + 1), dtype=np.int64)
        order = np.argsort(spent, kind="stable")
        bounds = np.searchsorted(spent[order], np.arange(top + 2))
        for budget in range(top + 1):
            members = order[bounds[budget] : bounds[budget + 1]]
            if len(members) == 0:
                continue
            pick = value[:, members].argmax(axis=1)
            table[:, budget] = value[np.arange(n_cells), members[pick]]
            index[:, budget] = members[pick]
        return table, index, candidates


class _Restricted:
    """A program's evaluator with the allocation fixed except at the positions `free`, and
    some nodes' qualities fixed (`observed`)."""

    def __init__(
        self,
        evaluator: Evaluator,
        base: Array,
        free: Sequence[int],
        observed: Mapping[int, float],
    ) -> None:
        self.evaluator, self.base, self.free, self.observed = evaluator, base, list(free), observed

    @property
    def n_modules(self) -> int:
        return len(self.free)

    def expected(self, quality: ArrayLike, allocation: ArrayLike) -> Array:
        part = np.atleast_2d(np.asarray(allocation, dtype=np.float64))
        full = np.tile(self.base, (len(part), 1))
        full[:, self.free] = part
        return self.evaluator.expected(quality, full, dict(self.observed))


def reallocate(
    model: CompileModel,
    resolution: float,
    qualities: Sequence[float],
    allocation: Array,
    free: Sequence[int],
    budget: float,
    observed: Mapping[int, float],
) -> Array:
    """The best split of `budget` among the allocation positions `free` during a run, the
    others kept as in `allocation` and the nodes in `observed` at the qualities seen: the
    compiler's own search on its lattice (exhaustive where affordable, else hill-climbing),
    whatever the lattice cannot hold going to the first free position. Used by the runtime to
    re-split a best-of's time among its applicable alternatives and to re-plan adaptively."""
    new = np.array(allocation, dtype=np.float64)
    free = list(free)
    if not free:
        return new
    new[free] = 0.0
    if budget <= 0:
        return new
    units = np.array([int(np.floor(budget / resolution + 1e-9))])
    restricted = _Restricted(Evaluator(model), new, free, observed)
    q = np.asarray(qualities, dtype=np.float64).reshape(1, -1)
    search = Exhaustive() if Exhaustive.computable(units, len(free)) else HillClimbing()
    split, _ = search.allocate(restricted, q, units, resolution)
    new[free] = split[0] * resolution
    new[free[0]] += budget - units[0] * resolution
    return new


ALLOCATORS: dict[
    str, type[HillClimbing] | type[Exhaustive] | type[DynamicProgramming] | type[Proportional]
] = {
    "hill-climbing": HillClimbing,
    "exhaustive": Exhaustive,
    "dp": DynamicProgramming,
    "proportional": Proportional,
}
