"""Runs of a compiled program simulated by sampling, independently of the evaluator: in each
run every module draws its output from its own profile, given the qualities its inputs had in
that run (a bin from the interpolated distribution, standing for its representative; no result
with the share of the first bin's mass the profile gives it), a best-of takes the best present
alternative, an elementary function combines what it is given. Vectorised over runs."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from anytime.compiler.model import ChoiceNode, ElementaryNode, IfNode, ModuleNode, Slot, TestNode

Array = np.ndarray[Any, Any]


def simulate(
    compiled: Any, quality: Sequence[float], total: float, runs: int, rng: np.random.Generator
) -> Array:
    """The output quality of `runs` simulated runs with `total` time (0 for no result)."""
    q = np.broadcast_to(np.asarray(quality, dtype=np.float64), (runs, len(quality)))
    return np.nan_to_num(sample_runs(compiled, q, np.full(runs, float(total)), rng), nan=0.0)


def sample_runs(compiled: Any, quality: Array, total: Array, rng: np.random.Generator) -> Array:
    """One simulated run per row: input qualities `quality` (runs, m) (NaN: no result), time
    `total` (runs,); the output quality of each (NaN: no result). Each run is given the
    allocation the compiled table gives for its own input qualities (an input without a
    result looked up at quality 1, as the runtime does)."""
    model = compiled.model
    runs = len(total)
    looked = np.where(np.isnan(quality), 1.0, quality)
    share = compiled.profile.interpolate(compiled.allocation, looked, total)
    values: dict[int, Array] = {}

    def source(slot: Slot) -> Array:
        if slot.kind == "node":
            return values[slot.index]
        if slot.kind == "input":
            return quality[:, slot.index]
        return np.full(runs, slot.value)

    for node in model.nodes:
        inputs = [source(slot) for slot in node.slots]
        match node:
            case TestNode():
                continue
            case ChoiceNode():
                assert not any(node.estimated)
                stacked = np.column_stack(inputs)
                present = ~np.isnan(stacked)
                best = np.max(np.where(present, stacked, -np.inf), axis=1)
                values[node.index] = np.where(present.any(axis=1), best, np.nan)
            case ElementaryNode():
                stacked = np.stack(inputs)
                missing = np.isnan(stacked).any(axis=0)
                combined = node.combine(np.nan_to_num(stacked))
                values[node.index] = np.where(missing, np.nan, combined)
            case IfNode():
                given = share[:, node.time_index]
                first = rng.random(runs) < node.branches[0].probability
                out = np.full(runs, np.nan)
                for plan, taken in zip(node.branches, (first, ~first), strict=True):
                    q = np.column_stack([inputs[a] for a in plan.axes] or [np.zeros(runs)])
                    q = q[:, : len(plan.axes)]
                    out[taken] = sample_runs(plan.compiled, q[taken], given[taken], rng)
                values[node.index] = out
            case ModuleNode(callee=callee) if callee is not None:
                q = np.column_stack(inputs) if inputs else np.zeros((runs, 0))
                missing = np.isnan(q).any(axis=1)
                out = np.full(runs, np.nan)
                out[~missing] = sample_runs(
                    callee, q[~missing], share[~missing, node.time_index], rng
                )
                values[node.index] = out
            case ModuleNode():
                values[node.index] = _module(node, inputs, share[:, node.time_index], runs, rng)
            case _:
                raise NotImplementedError(type(node).__name__)
    return source(model.output)


def _module(
    node: ModuleNode, inputs: list[Array], share: Array, runs: int, rng: np.random.Generator
) -> Array:
    profile = node.profile
    q = np.column_stack(inputs) if inputs else np.zeros((runs, 0))
    missing = np.isnan(q).any(axis=1) | ~np.asarray(node.starts(share), dtype=bool)
    q = np.nan_to_num(q)
    t = np.asarray(node.run_time(share), dtype=np.float64)
    if node.deterministic:
        out = profile.expected(q, t)
    else:
        dist = profile.distribution(q, t)
        reps = profile.representatives(q, t)
        cdf = np.cumsum(dist, axis=1)
        u = rng.random(runs)
        pick = np.minimum((cdf < (u * cdf[:, -1])[:, None]).sum(axis=1), dist.shape[1] - 1)
        out = reps[np.arange(runs), pick]
        none = profile.no_result(q, t)
        first = dist[:, 0]
        gone = (pick == 0) & (rng.random(runs) * np.where(first > 0, first, 1.0) < none)
        out = np.where(gone, np.nan, out)
    return np.where(missing, np.nan, out)
