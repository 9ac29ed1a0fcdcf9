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

from collections.abc import Iterator, Mapping, Sequence
from math import comb, prod
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from anytime.compiler.evaluate import (
    ENUMERATION_LIMIT,
    FOLD_GRID,
    MAX_SUPPORT,
    SAMPLES,
    Evaluator,
    shared_nodes,
)
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
CHUNK = 200_000  # rows evaluated at once, at most
DEFAULT_MEMORY = 10**9  # bytes an allocator's search may hold at once, unless told otherwise
#: How much more than the arrays `row_bytes` counts numpy's temporaries take (measured with
#: tracemalloc on random programs, benchmarks/bench_allocators.py).
WORKSPACE = 3


class Evaluates(Protocol):
    """What hill-climbing and the exhaustive search need: batched expected quality."""

    @property
    def model(self) -> CompileModel: ...

    @property
    def n_modules(self) -> int: ...

    def expected(self, quality: ArrayLike, allocation: ArrayLike) -> Array: ...


class Allocator(Protocol):
    name: str

    def memory_needed(self, evaluator: Evaluator, units: np.ndarray) -> int:
        """The bytes the search holds at the least (with its smallest chunks) for these
        totals, so that a table that cannot fit the cap is refused before it starts."""
        ...

    def allocate(
        self, evaluator: Evaluator, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        """Allocations `(C, n)` in units, and their expected output qualities `(C,)`."""
        ...


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


def row_bytes(model: CompileModel) -> int:
    """About how many bytes evaluating one allocation of `model` holds at its peak: every
    node's output distribution (they are kept to the end) and the largest node's working
    arrays (its input combinations, a called program's own evaluation for each), from the
    support sizes the evaluator's distributions reach (a deterministic module's is its inputs'
    product, a stochastic one's its bins, a support past `MAX_SUPPORT` is folded), times the
    rows the evaluator makes of each for the shared results' outcomes (see `Evaluator`)."""
    kept, peak, factor, _ = _footprint(model)
    return 8 * WORKSPACE * (kept + peak) * factor


def _footprint(model: CompileModel) -> tuple[int, int, int, int]:
    """(values kept, the largest node's working values, rows per evaluated row, the output's
    support) of evaluating one allocation of `model`: a shared result is conditioned on, so
    its readers see one of its values per row, and the rows multiply by its support."""
    support: dict[int, int] = {}
    shared = shared_nodes(model)
    kept, peak, factor = 0, 0, 1
    for node in model.nodes:
        sizes = [support[s.index] if s.kind == "node" else 1 for s in node.slots]
        combos = prod(sizes)
        work = combos * (len(sizes) + 6)
        out = combos
        if isinstance(node, TestNode):
            out = 1
        elif isinstance(node, IfNode):
            nested = [
                (prod(sizes[a] for a in p.axes), _footprint(p.compiled.model))
                for p in node.branches
            ]
            out = sum(c * (f[3] + 1) for c, f in nested)
            work = out * (len(sizes) + 6) + sum(c * f[2] * (f[0] + f[1]) for c, f in nested)
        elif isinstance(node, ModuleNode) and node.callee is not None:
            inner = _footprint(node.callee.model)
            out = combos * (inner[3] + 1)
            work = combos * (len(sizes) + 6) + combos * inner[2] * (inner[0] + inner[1])
        elif isinstance(node, ModuleNode | LoopNode):
            if not node.deterministic:
                out = node.profile.n_bins
                work = combos * (len(sizes) + 6 + 4 * node.profile.n_bins)
            # A call that may not be made, or a profile that records no result: one more value.
            out += _step(node) > 0 or node.profile.no_result_table is not None or out < combos
        if out > MAX_SUPPORT:
            out = len(FOLD_GRID) + 1
        if node.index in shared:  # conditioned on: one value a row, the rows multiplied
            factor *= out
            out = 1
        support[node.index] = out
        kept += 2 * out
        peak = max(peak, work)
    factor = min(factor, max(ENUMERATION_LIMIT, SAMPLES))
    output = support.get(model.output.index, 1) if model.output.kind == "node" else 1
    output *= factor  # the replicas mixed back, compacted or folded
    return kept, peak, factor, output if output <= MAX_SUPPORT else len(FOLD_GRID) + 1


def chunk_rows(model: CompileModel, memory: int, per_row: int = 0) -> int:
    """How many rows to evaluate at once within `memory` bytes (each row also holding
    `per_row` bytes of the caller's own): at least one, at most `CHUNK`."""
    return int(min(CHUNK, max(1, memory // (row_bytes(model) + per_row))))


def expected_in_chunks(
    evaluator: Evaluates, quality: Array, allocation: np.ndarray, memory: int
) -> Array:
    """`evaluator.expected` of rows `quality (R, m)`, `allocation (R, n)`, a chunk at a time."""
    step = chunk_rows(evaluator.model, memory)
    if len(allocation) <= step:
        return evaluator.expected(quality, allocation)
    return np.concatenate(
        [
            evaluator.expected(quality[i : i + step], allocation[i : i + step])
            for i in range(0, len(allocation), step)
        ]
    )


def check_memory(name: str, needed: int, memory: int) -> None:
    """Refuse a search whose least memory `needed` is over the cap `memory`, with both."""
    if needed > memory:
        raise CompileError(
            f"the {name} search needs about {format_bytes(needed)} of memory at the least, "
            f"more than the cap of {format_bytes(memory)}: raise the cap (memory=, --memory), "
            "or use a coarser time grid, fewer input qualities or another allocator"
        )


def format_bytes(size: float) -> str:
    """A byte count for people: 512 B, 3.2 kB, 1.5 MB, 2 GB (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB"):
        if size < 1000 or unit == "GB":
            return f"{size:.3g} {unit}" if unit != "B" else f"{size:.0f} B"
        size /= 1000
    raise AssertionError(size)


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


def least_useful_time(profile: ConditionalPerformanceProfile) -> float:
    """Romanenko's `T*`: the first time on the profile's grid at which, with perfect inputs, its
    expected quality rises above what it gives with no time (its first variant; for a profile
    that never improves, its first time)."""
    best_input = np.ones((len(profile.time), profile.n_inputs))
    curve = profile.expected(best_input, profile.time)
    better = curve > curve[0] + 1e-12
    return float(profile.time[np.argmax(better)] if np.any(better) else profile.time[0])


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


class Proportional:
    """Romanenko's proportional split: each module's share of T is proportional to `T*`."""

    name = "proportional"

    def __init__(self, memory: int = DEFAULT_MEMORY) -> None:
        self.memory = memory

    def memory_needed(self, evaluator: Evaluates, units: np.ndarray) -> int:
        return 8 * len(units) * (evaluator.n_modules + 2) + row_bytes(evaluator.model)

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        nodes = evaluator.model.anytime_nodes
        if not nodes:
            return nothing_to_allocate(evaluator, quality, units)
        star = np.array([least_useful_time(n.profile) + _step(n) for n in nodes])
        allocation = proportional_split(units, star)
        return allocation, expected_in_chunks(evaluator, quality, allocation * dt, self.memory)


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
            case ModuleNode(callee=callee) if callee is not None and any(
                slot.kind == "node" for slot in node.slots
            ):
                return (
                    f"the called schema '{node.name}' reads a result computed in the program, "
                    "whose quality falls between its table's grid points, where the schema "
                    "runs the allocation its table gives there, not the optimum dp would assume"
                )
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


def relaxable(model: CompileModel) -> bool:
    """Whether relaxed dp can run on the program: it has no if (whose output is a mixture)."""
    return not any(isinstance(node, IfNode) for node in model.nodes)


class DynamicProgramming:
    """Local compilation by dynamic programming over budgets, for monotone deterministic trees."""

    name = "dp"

    def __init__(self, memory: int = DEFAULT_MEMORY, relaxed: bool = False) -> None:
        """With `relaxed`, dp also runs where it is not exact but can run (a DAG, stochastic
        or non-monotone modules; not an if): a shared result is planned as if each reader had
        its own copy, and its time is the largest any reader gives it. The allocations are
        then a heuristic (a seed for a search), and their qualities the tree's, not the
        program's."""
        self.memory = memory
        self.relaxed = relaxed

    def memory_needed(self, evaluator: Evaluator, units: np.ndarray) -> int:
        """The largest node's candidate splits (every split of every budget among its own run
        and its subtrees), and their values for one input-quality cell at a time."""
        top = int(units.max(initial=0))
        parts = [
            (1 if isinstance(node, ModuleNode | LoopNode) else 0)
            + sum(slot.kind == "node" for slot in node.slots)
            for node in evaluator.model.nodes
            if not isinstance(node, TestNode | IfNode)
        ]
        return max((_split_bytes(top, k, 1) for k in parts), default=0)

    def allocate(
        self, evaluator: Evaluator, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        model = evaluator.model
        reason = dp_obstacle(model)
        if reason is not None and not (self.relaxed and relaxable(model)):
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
                node, best, cells, top, dt, budgets, self.memory
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
                if slot.kind == "node":  # a shared result (relaxed): the largest budget given
                    given = budget.get(slot.index)
                    share = split[:, column]
                    budget[slot.index] = share if given is None else np.maximum(given, share)
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
        memory: int,
    ) -> tuple[Array, np.ndarray, np.ndarray]:
        parts = (1 if isinstance(node, ModuleNode | LoopNode) else 0) + sum(
            s.kind == "node" for s in node.slots
        )
        # Every split of every budget up to `top` (or of `budgets` only): the own time first,
        # then each child's.
        with_slack = compositions(top, parts + 1)
        candidates = with_slack[:, :parts]
        spent = candidates.sum(axis=1)
        if budgets is not None:
            keep = np.isin(spent, budgets)
            candidates, spent = candidates[keep], spent[keep]
        # The best split for each budget: candidates that spend exactly that budget.
        order = np.argsort(spent, kind="stable")
        bounds = np.searchsorted(spent[order], np.arange(top + 2))
        table = np.full((len(cells), top + 1), -np.inf)
        index = np.zeros((len(cells), top + 1), dtype=np.int64)
        fixed = _split_bytes(top, parts, 0)
        per_cell = max(1, _split_bytes(top, parts, 1) - fixed)
        step = max(1, (memory - fixed) // per_cell)
        for first in range(0, len(cells), step):  # a chunk of input-quality cells at a time
            rows = slice(first, first + step)
            value = DynamicProgramming._values(node, best, cells, rows, candidates, dt)
            for budget in range(top + 1):
                members = order[bounds[budget] : bounds[budget + 1]]
                if len(members) == 0:
                    continue
                pick = value[:, members].argmax(axis=1)
                table[rows, budget] = value[np.arange(len(value)), members[pick]]
                index[rows, budget] = members[pick]
        return table, index, candidates

    @staticmethod
    def _values(
        node: ModuleNode | ElementaryNode | ChoiceNode | LoopNode,
        best: dict[int, Array],
        cells: Array,
        rows: slice,
        candidates: np.ndarray,
        dt: float,
    ) -> Array:
        """The node's quality for every candidate split, for the input-quality cells `rows`."""
        cells = cells[rows]
        n_cells, n_rows = len(cells), len(candidates)
        qualities = []
        column = 1 if isinstance(node, ModuleNode | LoopNode) else 0
        for slot in node.slots:
            if slot.kind == "node":
                qualities.append(best[slot.index][rows][:, candidates[:, column]])
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
        return np.where(infeasible, -np.inf, value)


def _split_bytes(top: int, parts: int, cells: int) -> int:
    """What dp holds for a node of `parts` parts: its candidate splits of every budget up to
    `top` (with their slack column, and the sort), and their values for `cells` cells."""
    splits = comb(top + parts, parts)
    return 8 * splits * (2 * parts + 4) + 8 * WORKSPACE * cells * splits * (parts + 4)


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
    def model(self) -> CompileModel:
        return self.evaluator.model

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
