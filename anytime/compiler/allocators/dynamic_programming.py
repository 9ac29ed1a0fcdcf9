"""`DynamicProgramming`: local compilation. For a tree whose modules are deterministic and
input-monotone, the best output of a subtree given its time depends on nothing else, so each
node keeps the best quality of its subtree for every budget and the parent chooses how to split
its budget between its own run and its subtrees: exact, pseudo-polynomial in T / dt.
`dp_obstacle` says, as a code, why it would not be exact for a program.
"""

from __future__ import annotations

from math import comb

import numpy as np

from anytime.compiler.allocators.lattice import compositions
from anytime.compiler.allocators.memory import CHUNK, DEFAULT_MEMORY, WORKSPACE
from anytime.compiler.allocators.protocol import Evaluates, nothing_to_allocate
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
from anytime.compiler.outcomes import Code, Note
from anytime.profiles.profile import Array


def dp_obstacle(model: CompileModel) -> Note | None:
    """Why local compilation would not be exact for this program (None: it is exact)."""
    shape = model.graph.shape
    if shape == "dag":
        return Note.of(Code.DAG)
    for node in model.nodes:
        match node:
            case TestNode() | ChoiceNode():
                continue  # a test's quality flows nowhere; a best-of's is the max of its inputs
            case IfNode():
                return Note.of(Code.IF_MIXTURE)
            case ElementaryNode(monotone=False):
                return Note.of(Code.UNKNOWN_MONOTONICITY, function=node.name)
            case ElementaryNode():
                continue
            case ModuleNode(callee=callee) if callee is not None and any(
                slot.kind == "node" for slot in node.slots
            ):
                return Note.of(Code.CALLEE_READS_RESULT, schema=node.name)
        if not node.deterministic:
            return Note.of(Code.STOCHASTIC, module=node.name)
        mean = node.profile.mean
        assert mean is not None
        for axis in range(node.profile.n_inputs):
            if np.any(np.diff(mean, axis=axis) < -1e-12):
                return Note.of(Code.NOT_INPUT_MONOTONE, module=node.name, input=axis + 1)
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

    def memory_needed(self, evaluator: Evaluates, units: np.ndarray) -> int:
        """The largest node's candidate splits (every split of every budget among its own run
        and its subtrees), and their values for one input-quality cell at a time."""
        top = int(units.max(initial=0))
        parts = [
            (1 if isinstance(node, ModuleNode | LoopNode) else 0)
            + sum(slot.kind == "node" for slot in node.slots)
            for node in evaluator.model.nodes
            if not isinstance(node, TestNode | IfNode)
        ]
        return max((split_bytes(top, k, 1) for k in parts), default=0)

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
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
        fixed = split_bytes(top, parts, 0)
        per_cell = max(1, split_bytes(top, parts, 1) - fixed)
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


def split_bytes(top: int, parts: int, cells: int) -> int:
    """What dp holds for a node of `parts` parts: its candidate splits of every budget up to
    `top` (with their slack column, and the sort), and their values for `cells` cells."""
    splits = comb(top + parts, parts)
    return 8 * splits * (2 * parts + 4) + 8 * WORKSPACE * cells * splits * (parts + 4)
