"""The memory an allocator's search holds, and evaluation in chunks within a cap.

A search evaluates batches of allocations; `row_bytes` estimates what evaluating one holds at
its peak, so that the searches size their chunks (`chunk_rows`, `expected_in_chunks`) and the
compiler refuses a table whose least memory is over the cap before it starts (`check_memory`).
"""

from __future__ import annotations

from math import prod

import numpy as np

from anytime.compiler.allocators.protocol import Evaluates
from anytime.compiler.dist import FOLD_GRID, MAX_SUPPORT
from anytime.compiler.evaluate import ENUMERATION_LIMIT, SAMPLES, shared_nodes
from anytime.compiler.model import (
    CompileError,
    CompileModel,
    IfNode,
    LoopNode,
    ModuleNode,
    TestNode,
    reserved_step,
)
from anytime.profiles.profile import Array

CHUNK = 200_000  # rows evaluated at once, at most
DEFAULT_MEMORY = 10**9  # bytes an allocator's search may hold at once, unless told otherwise
#: How much more than the arrays `row_bytes` counts numpy's temporaries take (measured with
#: tracemalloc on random programs, benchmarks/bench_allocators.py).
WORKSPACE = 3


def row_bytes(model: CompileModel) -> int:
    """About how many bytes evaluating one allocation of `model` holds at its peak: every
    node's output distribution (they are kept to the end) and the largest node's working
    arrays (its input combinations, a called program's own evaluation for each), from the
    support sizes the evaluator's distributions reach (a deterministic module's is its inputs'
    product, a stochastic one's its bins, a support past `MAX_SUPPORT` is folded), times the
    rows the evaluator makes of each for the shared results' outcomes (see `Evaluator`)."""
    kept, peak, factor, _ = footprint(model)
    return 8 * WORKSPACE * (kept + peak) * factor


def footprint(model: CompileModel) -> tuple[int, int, int, int]:
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
                (prod(sizes[a] for a in p.axes), footprint(p.compiled.model)) for p in node.branches
            ]
            out = sum(c * (f[3] + 1) for c, f in nested)
            work = out * (len(sizes) + 6) + sum(c * f[2] * (f[0] + f[1]) for c, f in nested)
        elif isinstance(node, ModuleNode) and node.callee is not None:
            inner = footprint(node.callee.model)
            out = combos * (inner[3] + 1)
            work = combos * (len(sizes) + 6) + combos * inner[2] * (inner[0] + inner[1])
        elif isinstance(node, ModuleNode | LoopNode):
            if not node.deterministic:
                out = node.profile.n_bins
                work = combos * (len(sizes) + 6 + 4 * node.profile.n_bins)
            # A call that may not be made, or a profile that records no result: one more value.
            out += (
                reserved_step(node) > 0 or node.profile.no_result_table is not None or out < combos
            )
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
