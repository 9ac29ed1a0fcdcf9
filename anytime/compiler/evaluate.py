"""Evaluating allocations: the output-quality distribution of a program for batches of them.

Distributions flow through the dataflow graph in topological order, each as a batch of discrete
distributions: `values (B, K)` with `probs (B, K)`. The inputs of a call are taken as
independent (their joint distribution is the product), which is exact for trees and an
approximation for DAGs, where a shared result makes later inputs correlated.

- A module whose profile is deterministic (a point mass at the cell mean everywhere) maps each
  combination of input qualities to the exact quality its curve gives there: no binning.
- A module with a stochastic profile gives a distribution over its quality bins (the profile's
  interpolated distribution mixed over the input combinations), each standing for its
  representative (`ConditionalPerformanceProfile.representatives`): so the expected quality is
  the profile's exact mean where it has one, never a bin midpoint.
- An elementary function combines the input qualities (min by default). A `best-of` is one:
  its quality is the maximum of its alternatives', so its distribution is that of the maximum
  of independent variables (the product of their CDFs), computed exactly on the joint support.
- An `if` is the mixture of its branches' compiled output distributions, weighted by the
  branches' probabilities.
- A loop (`map`, `repeat`) is looked up in its own compiled profile for the count it is planned
  for (`anytime.compiler.loops`), as a module is in its profile.

When a support grows past `MAX_SUPPORT` values it is folded onto a fixed grid by splitting each
value's mass between its two neighbouring grid points, which keeps the mean exact.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.compiler.model import (
    ChoiceNode,
    CompileModel,
    CompileNode,
    ElementaryNode,
    IfNode,
    LoopNode,
    ModuleNode,
    Slot,
    TestNode,
)
from anytime.profiles.profile import Array, ConditionalPerformanceProfile, new_profile

MAX_SUPPORT = 64
FOLD_GRID = np.linspace(0.0, 1.0, 41)

#: The value that stands for "no result" in a distribution's support: its own outcome, never a
#: quality. It counts 0 in an expectation; a call one of whose inputs has it is not made (it
#: has no result either) unless its module accepts a missing input; a best-of's maximum skips
#: it (an alternative without a result is not a candidate).
NO_RESULT = -1.0


@frozen
class Dist:
    """A batch of discrete quality distributions."""

    values: Array  # (B, K)
    probs: Array  # (B, K)

    def expected(self) -> Array:
        """The expected quality, no result counting 0."""
        expected: Array = np.einsum("bk,bk->b", np.maximum(self.values, 0.0), self.probs)
        return expected

    def missing(self) -> Array:
        """The probability of no result."""
        missing: Array = np.einsum("bk,bk->b", self.values == NO_RESULT, self.probs)
        return missing

    @classmethod
    def point(cls, quality: ArrayLike) -> Dist:
        q = np.asarray(quality, dtype=np.float64).reshape(-1, 1)
        return cls(q, np.ones_like(q))


def fold(dist: Dist, grid: Array = FOLD_GRID) -> Dist:
    """The distribution on `grid`, each value's mass split between its neighbours (mean kept),
    and the mass of no result kept as its own outcome."""
    present = dist.values != NO_RESULT
    v = np.clip(dist.values, grid[0], grid[-1])
    i = np.clip(np.searchsorted(grid, v, side="right") - 1, 0, len(grid) - 2)
    upper = (v - grid[i]) / (grid[i + 1] - grid[i])
    out = np.zeros((len(v), len(grid) + 1))
    rows = np.broadcast_to(np.arange(len(v))[:, None], v.shape)
    probs = np.where(present, dist.probs, 0.0)
    np.add.at(out, (rows, i), probs * (1 - upper))
    np.add.at(out, (rows, i + 1), probs * upper)
    out[:, -1] = dist.missing()
    values = np.broadcast_to(np.append(grid, NO_RESULT), out.shape).copy()
    return Dist(values, out)


class Evaluator:
    """Evaluates batches of allocations of one compiled model."""

    def __init__(self, model: CompileModel) -> None:
        self.model = model

    @property
    def n_modules(self) -> int:
        return len(self.model.anytime_nodes)

    def evaluate(
        self,
        quality: ArrayLike,
        allocation: ArrayLike,
        observed: Mapping[int, float] | None = None,
        seen: dict[int, list[Dist]] | None = None,
    ) -> Dist:
        """Output distributions for a batch.

        Args:
            quality: program input qualities, shape (B, m) or (m,) (broadcast).
            allocation: time per anytime module, shape (B, n) in allocation-vector order.
            observed: node index -> the quality its result was seen to have (a node that has
                already run); its output is that quality, whatever its allocation.
            seen: filled with node index -> the distributions of its quality-carrying inputs.
        """
        alloc = np.atleast_2d(np.asarray(allocation, dtype=np.float64))
        batch = len(alloc)
        m = len(self.model.quality_inputs)
        q = np.asarray(quality, dtype=np.float64)
        q = np.broadcast_to(q.reshape(-1, m) if q.size else np.zeros((1, m)), (batch, m))
        outputs: dict[int, Dist] = {}
        for node in self.model.nodes:
            if observed is not None and node.index in observed:
                outputs[node.index] = Dist.point(np.full(batch, observed[node.index]))
                continue
            inputs = [self._source(slot, outputs, q, batch) for slot in node.slots]
            if seen is not None:
                seen[node.index] = inputs
            outputs[node.index] = self._node(node, inputs, alloc, batch)
        return self._source(self.model.output, outputs, q, batch)

    def expected(
        self,
        quality: ArrayLike,
        allocation: ArrayLike,
        observed: Mapping[int, float] | None = None,
    ) -> Array:
        """Expected output quality for a batch (shape (B,))."""
        return self.evaluate(quality, allocation, observed).expected()

    @staticmethod
    def _source(slot: Slot, outputs: dict[int, Dist], q: Array, batch: int) -> Dist:
        if slot.kind == "node":
            return outputs[slot.index]
        if slot.kind == "input":
            return Dist.point(q[:, slot.index])
        return Dist.point(np.full(batch, slot.value))

    @staticmethod
    def _node(node: CompileNode, inputs: list[Dist], alloc: Array, batch: int) -> Dist:
        if isinstance(node, IfNode):
            return _mixture(node, inputs, alloc, batch)
        if isinstance(node, TestNode):  # its quality flows nowhere
            return Dist.point(np.ones(batch))
        q, p = _combinations(inputs, batch)  # (B, C1..Cm, m), (B, C1..Cm)
        if isinstance(node, ChoiceNode):
            out = _choice(node, inputs, q, p, batch)
            return fold(out) if out.values.shape[1] > MAX_SUPPORT else out
        missing = np.any(q == NO_RESULT, axis=-1)  # some input has no result
        q = np.maximum(q, 0.0)  # what a module that accepts a missing input is looked up at
        match node:
            case ElementaryNode(combine=combine, entry=entry):
                values = combine(np.moveaxis(q, -1, 0)) if inputs else np.ones(p.shape)
                module = entry.module if entry is not None else None
                if module is None or not module.accepts_missing:
                    values = np.where(missing, NO_RESULT, values)
                out = Dist(values.reshape(batch, -1), p.reshape(batch, -1))
            case ModuleNode() | LoopNode():  # a loop: its profile for the count planned
                t = np.broadcast_to(
                    alloc[:, node.time_index].reshape((batch,) + (1,) * (p.ndim - 1)), p.shape
                )
                # The call is not made (no result) where an input lacks one, or where its share
                # is less than its step: it could not answer within it.
                present = p if node.accepts_missing else np.where(missing, 0.0, p)
                present = np.where(node.starts(t), present, 0.0)
                run = node.run_time(t)
                out = _from_profile(node.profile, node.deterministic, q, run, present, batch)
                gone = (p - present).reshape(batch, -1).sum(axis=1)
                if np.any(gone > 0):
                    out = Dist(
                        np.column_stack([out.values, np.full(batch, NO_RESULT)]),
                        np.column_stack([out.probs, gone]),
                    )
        return fold(out) if out.values.shape[1] > MAX_SUPPORT else out


def _choice(node: ChoiceNode, inputs: list[Dist], q: Array, p: Array, batch: int) -> Dist:
    """A best-of: the best alternative that has a result, as the runtime judges them. An
    alternative whose quality is known (its module reports it) is judged by it; one whose
    module does not report it by what its profile predicts, its mean given a result, so the
    runtime picks it, and gets its whole distribution, where that mean beats the others."""
    if not any(node.estimated):  # all judged by their quality: the maximum
        return Dist(np.max(q, axis=-1).reshape(batch, -1), p.reshape(batch, -1))
    judged, present = [], []
    for dist, estimated in zip(inputs, node.estimated, strict=True):
        if not estimated:
            judged.append(dist)
            present.append(dist)
            continue
        missing = dist.missing()
        kept = np.where(dist.values == NO_RESULT, 0.0, dist.probs)
        given = kept / np.where(missing < 1, 1 - missing, 1.0)[:, None]
        mean = np.einsum("bk,bk->b", np.maximum(dist.values, 0.0), given)
        # Judged: its predicted mean if it has a result, else it is no candidate.
        judged.append(
            Dist(
                np.column_stack([mean, np.full(batch, NO_RESULT)]),
                np.column_stack([1 - missing, missing]),
            )
        )
        present.append(Dist(dist.values, given))
    q, p = _combinations(judged, batch)
    winner = np.argmax(q, axis=-1)  # the first of equals, as the runtime
    best = np.take_along_axis(q, winner[..., None], axis=-1)[..., 0]
    estimated = np.asarray(node.estimated)[winner] & (best != NO_RESULT)
    values = [np.where(estimated, NO_RESULT, best).reshape(batch, -1)]
    probs = [np.where(estimated, 0.0, p).reshape(batch, -1)]
    for i, dist in enumerate(present):
        if node.estimated[i]:  # where it wins, its own distribution given a result
            mass = np.where(estimated & (winner == i), p, 0.0).reshape(batch, -1).sum(axis=1)
            values.append(dist.values)
            probs.append(mass[:, None] * dist.probs)
    return Dist(np.concatenate(values, axis=1), np.concatenate(probs, axis=1))


def _from_profile(
    profile: ConditionalPerformanceProfile,
    deterministic: bool,
    q: Array,
    t: Array,
    p: Array,
    batch: int,
) -> Dist:
    """A profile's output for every input combination (qualities `q`, run time `t`, their
    probabilities `p`), no result its own outcome where the profile records it."""
    if deterministic:
        values = profile.expected(q, t)
        out = Dist(values.reshape(batch, -1), p.reshape(batch, -1))
    else:
        out = _binned(profile, q, t, p, batch)
    none = profile.no_result(q, t)
    if not np.any(none > 0):
        return out
    # The no-result mass is part of the lowest quality's: move it to its own outcome there.
    w = p.reshape(batch, -1)
    share = np.einsum("bc,bc->b", w, none.reshape(batch, -1))
    return _split_lowest(out, share)


def _split_lowest(out: Dist, share: Array) -> Dist:
    """`out` with mass `share` (B,) of its lowest support value moved to no result (that
    value's mass holds it: a no-result trial scores the lowest quality, 0); the remaining
    mass there keeps the mean."""
    values, probs = out.values.copy(), out.probs.copy()
    low = np.argmin(np.where(probs > 0, values, np.inf), axis=1)
    rows = np.arange(len(values))
    mass = probs[rows, low]
    moved = np.minimum(share, mass)
    left = mass - moved
    values[rows, low] = np.divide(
        values[rows, low] * mass, left, out=np.zeros_like(mass), where=left > 1e-15
    )
    probs[rows, low] = left
    return Dist(
        np.column_stack([values, np.full(len(values), NO_RESULT)]),
        np.column_stack([probs, moved]),
    )


def _binned(
    profile: ConditionalPerformanceProfile, q: Array, t: Array, p: Array, batch: int
) -> Dist:
    """A stochastic module's output: its distribution mixed over the input combinations, each
    bin standing for the mass-weighted mean of the combinations' representatives (so the
    output's mean is the profile's expected quality, mixed the same way: exact where the
    profile has a `mean` table)."""
    k = profile.n_bins
    d = profile.distribution(q, t).reshape(batch, -1, k)
    v = profile.representatives(q, t).reshape(batch, -1, k)
    w = p.reshape(batch, -1)
    probs = np.einsum("bc,bck->bk", w, d)
    moments = np.einsum("bc,bck,bck->bk", w, d, v)
    values = np.divide(
        moments, probs, out=np.broadcast_to(profile.values, probs.shape).copy(), where=probs > 0
    )
    return Dist(np.clip(values, 0.0, 1.0), probs)


def _mixture(node: IfNode, inputs: list[Dist], alloc: Array, batch: int) -> Dist:
    """An if: each branch's output distribution (its compiled profile at the if's time),
    weighted by the branch's probability; the supports are concatenated (a mixture)."""
    values, probs = [], []
    for plan in node.branches:
        profile = plan.compiled.profile
        q, p = _combinations([inputs[a] for a in plan.axes], batch)
        t = np.broadcast_to(
            alloc[:, node.time_index].reshape((batch,) + (1,) * (p.ndim - 1)), p.shape
        )
        q = np.maximum(q, 0.0)  # a branch's own program decides what a missing input means
        branch = _from_profile(profile, plan.deterministic, q, t, p, batch)
        values.append(branch.values)
        probs.append(plan.probability * branch.probs)
    out = Dist(np.concatenate(values, axis=1), np.concatenate(probs, axis=1))
    return fold(out) if out.values.shape[1] > MAX_SUPPORT else out


def _combinations(inputs: list[Dist], batch: int) -> tuple[Array, Array]:
    """Every combination of the inputs' support values, with its (independent) probability."""
    m = len(inputs)
    if m == 0:
        return np.zeros((batch, 0)), np.ones(batch)
    values, probs = [], []
    for axis, dist in enumerate(inputs):
        shape = [batch] + [1] * m
        shape[axis + 1] = dist.values.shape[1]
        values.append(dist.values.reshape(shape))
        probs.append(dist.probs.reshape(shape))
    q = np.stack(np.broadcast_arrays(*values), axis=-1)
    p = probs[0]
    for extra in probs[1:]:
        p = p * extra
    return q, np.broadcast_to(p, q.shape[:-1])


def binned_profile(
    output: Dist,
    bins: Array,
    *,
    input_grids: Sequence[Array],
    time: Array,
    cell_shape: tuple[int, ...],
    inputs: Sequence[str],
    module: str,
    time_unit: str,
) -> ConditionalPerformanceProfile:
    """A contract profile from output distributions, one row per cell (time fastest), binned
    on `bins`, with the exact expected quality kept as the profile's mean, each bin's exact
    mean, and the probability of no result (in the lowest bin's mass, as a measured profile
    has it). A compiled program's profile and a loop's are made so."""
    k = np.clip(np.searchsorted(bins, output.values, side="right") - 1, 0, len(bins) - 2)
    probability = np.zeros((len(output.values), len(bins) - 1))
    rows = np.broadcast_to(np.arange(len(k))[:, None], k.shape)
    np.add.at(probability, (rows, k), output.probs)
    moments = np.zeros_like(probability)
    np.add.at(moments, (rows, k), output.probs * np.maximum(output.values, 0.0))
    total = probability.sum(axis=1, keepdims=True)
    probability /= total
    lower, upper = bins[:-1], bins[1:]
    bin_mean = np.divide(
        moments / total,
        probability,
        out=np.broadcast_to((lower + upper) / 2, probability.shape).copy(),
        where=probability > 1e-15,
    )
    bin_mean = np.clip(bin_mean, lower, upper)
    mean = np.clip(output.expected(), 0.0, 1.0)
    no_result = np.minimum(output.missing(), probability[:, 0])
    return new_profile(
        input_grids=list(input_grids),
        time=time,
        bins=bins,
        probability=probability.reshape(*cell_shape, len(bins) - 1),
        mean=mean.reshape(cell_shape),
        bin_mean=bin_mean.reshape(*cell_shape, len(bins) - 1),
        no_result_table=no_result.reshape(cell_shape) if np.any(no_result > 0) else None,
        inputs=inputs,
        module=module,
        kind="contract",
        time_unit=time_unit,
    )
