"""Evaluating allocations: the output-quality distribution of a program for batches of them.

Distributions flow through the dataflow graph in topological order, each as a batch of discrete
distributions: `values (B, K)` with `probs (B, K)`. Given their inputs' qualities, the outcomes
of different calls are independent (each module's profile is conditioned on its inputs'
qualities and nothing else): that is the profiles' model, and the evaluation is exact under it.

- **Shared results.** Where a result is read more than once (a best-of over one sensed map, a
  diamond, a join reading a result twice), the readers' inputs are correlated, and taking them
  as independent is wrong (a best-of of two planners on one map is not the better of two
  independent draws). The evaluator conditions on each shared result's outcome: it replicates
  the batch's row once per outcome of the shared result (its quality values and no result),
  weighted by its probability, evaluates the rest of the program given that outcome, and mixes
  the rows back at the end -- variable elimination by enumeration over the shared results,
  which makes the expectation exact for any DAG. Where the joint outcomes of the shared results
  would exceed `ENUMERATION_LIMIT` rows per row, it samples them instead: `SAMPLES` draws of
  the shared results per row (stratified, the same uniforms for every row and every
  allocation, so that allocations are compared on common draws), each evaluated exactly given
  the draw; the expectation is then an estimate, and its standard error is returned with it
  (`Dist.error`).
- A module whose profile is deterministic (a point mass at the cell mean everywhere) maps each
  combination of input qualities to the exact quality its curve gives there: no binning.
- A module with a stochastic profile gives a distribution over its quality bins (the profile's
  interpolated distribution mixed over the input combinations), each standing for its
  representative (`ConditionalPerformanceProfile.representatives`): so the expected quality is
  the profile's exact mean where it has one, never a bin midpoint.
- An elementary function combines the input qualities (min by default). A `best-of` is one:
  its quality is the maximum of its alternatives' (independent given the shared results).
- **Dependent alternatives.** Alternatives run on one problem are rarely independent: a problem
  hard for one is often hard for all, which no profile conditioned on input qualities can say.
  A best-of written with `:dependence D` is taken as the mixture the schema states: with
  probability D one draw decides every alternative (comonotone, the least below), else they
  are independent -- a copula (the mixture of two), so the marginals stay the profiles'.
  An evaluator made with `coupling="least"` or `"most"` takes the alternatives of every
  best-of judged by quality as coupled as unfavourably (their maximum stochastically smallest:
  comonotone, CDF `min_i F_i`) or as favourably (CDF `max(0, sum_i F_i - (n - 1))`) as their
  marginal distributions allow -- the Frechet-Hoeffding bounds, sharp for the best-of itself
  -- and carries that through the rest of the program (callees included): where the
  program's later modules are monotone in their inputs' qualities, the two evaluations bound
  what any dependence between the alternatives can do (`CompiledProgram.dependence`). A
  best-of with alternatives judged by their predicted mean stays independent in both.
- An `if` is the mixture of its branches, and a called schema is its callee: each is evaluated
  as the program it is, at the allocation its compiled table gives for the qualities that reach
  it (what the runtime runs), never by interpolating its compiled profile between input grid
  points (which over-claims: the table's optimum interpolated is above what any one
  allocation delivers).
- A loop (`map`, `repeat`) is looked up in its own compiled profile for the count it is planned
  for (`anytime.compiler.loops`), as a module is in its profile.

The distributions are `anytime.compiler.dist`'s: equal values of a support merged, a support
larger than `MAX_SUPPORT` folded onto a grid for the program's output; for a result that other
calls read, the evaluation samples it instead (folding would move the qualities they see).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from anytime.compiler.dist import MAX_SUPPORT, NO_RESULT, Dist, bounded, compact
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
from anytime.profiles.profile import Array, ConditionalPerformanceProfile

__all__ = [
    "ENUMERATION_LIMIT",
    "NO_RESULT",
    "SAMPLES",
    "SAMPLING_SEED",
    "Evaluator",
    "read_nodes",
    "shared_nodes",
]

#: The most joint outcomes of the shared results enumerated per evaluated row; beyond, sampled.
ENUMERATION_LIMIT = 4096
#: Draws of the shared results per row where they are sampled.
SAMPLES = 4096
#: The seed of the sampling's uniforms (fixed: the same program is evaluated on the same draws).
SAMPLING_SEED = 20_260_417


class _Sample(Exception):
    """Enumerating the shared results' joint outcomes would take too many rows: sample them."""


class _Rows:
    """The rows an evaluation works on: each of the batch's rows, replicated once per joint
    outcome (or draw) of the shared results conditioned on so far. Replicas of one batch row
    are contiguous; `origin` maps a row to its batch row, `weight` is the probability of its
    outcome (1/draws where sampled), `draw` the index of its draw."""

    def __init__(self, batch: int, sampled: bool) -> None:
        self.batch, self.sampled = batch, sampled
        self.origin = np.arange(batch)
        self.weight = np.ones(batch)
        self.draw = np.zeros(batch, dtype=np.intp)
        self.variance = np.zeros(batch)  # of nested sampled evaluations, per row

    @property
    def count(self) -> int:
        return len(self.origin)

    @property
    def factor(self) -> int:
        return self.count // self.batch if self.batch else 1

    def replicate(self, copies: int, outputs: dict[int, Dist]) -> None:
        """Every row `copies` times (the outputs so far with them)."""
        self.origin = np.repeat(self.origin, copies)
        self.weight = np.repeat(self.weight, copies)
        self.draw = np.repeat(self.draw, copies)
        self.variance = np.repeat(self.variance, copies)
        for index, dist in outputs.items():
            outputs[index] = dist.rows(np.repeat(np.arange(len(dist.values)), copies))

    def condition(self, dist: Dist, outputs: dict[int, Dist], index: int) -> Dist:
        """Condition on the outcome of `dist` (a shared result's distribution, compacted):
        enumerate its outcomes, or draw one per row; returns it as a point per row."""
        width = dist.values.shape[1]
        if not self.sampled:
            if self.factor * width > ENUMERATION_LIMIT:
                raise _Sample
            self.replicate(width, outputs)
            self.weight = self.weight * dist.probs.reshape(-1)
            return Dist.point(dist.values.reshape(-1))
        if self.factor == 1:  # the first draw: SAMPLES replicas of each row
            self.replicate(SAMPLES, outputs)
            self.weight = self.weight / SAMPLES
            self.draw = np.tile(np.arange(SAMPLES), self.batch)
            dist = dist.rows(np.repeat(np.arange(len(dist.values)), SAMPLES))
        u = _uniforms(index)[self.draw]
        cdf = np.cumsum(dist.probs, axis=1)
        pick = np.minimum((cdf < u[:, None] * cdf[:, -1:]).sum(axis=1), width - 1)
        return Dist.point(np.take_along_axis(dist.values, pick[:, None], axis=1)[:, 0])

    def collapse(self, dist: Dist) -> Dist:
        """Per batch row, the mixture of its replicas' distributions."""
        if self.factor == 1 and not self.variance.any():
            return dist
        values = dist.values.reshape(self.batch, -1)
        probs = (self.weight[:, None] * dist.probs).reshape(self.batch, -1)
        variance = (self.weight**2 * self.variance).reshape(self.batch, -1).sum(axis=1)
        if self.sampled and self.factor > 1:  # the draws' spread
            means = dist.expected().reshape(self.batch, -1)
            spread = np.ptp(means, axis=1) > 1e-12  # draws that all agree are no estimate
            variance = variance + np.where(spread, means.var(axis=1, ddof=1), 0.0) / self.factor
        error = np.sqrt(variance) if self.sampled or self.variance.any() else None
        return Dist(values, probs, error)


def _uniforms(index: int) -> Array:
    """The stratified uniforms of node `index`'s draws: one in each of `SAMPLES` equal strata,
    in an order of their own (Latin hypercube sampling across nodes)."""
    rng = np.random.default_rng([SAMPLING_SEED, index])
    u: Array = (rng.permutation(SAMPLES) + rng.random(SAMPLES)) / SAMPLES
    return u


def shared_nodes(model: CompileModel) -> frozenset[int]:
    """The nodes whose result is read more than once (by two calls, or twice by one)."""
    reads: dict[int, int] = {}
    slots = [s for node in model.nodes for s in node.slots] + [model.output]
    for slot in slots:
        if slot.kind == "node":
            reads[slot.index] = reads.get(slot.index, 0) + 1
    return frozenset(i for i, n in reads.items() if n > 1)


def read_nodes(model: CompileModel) -> frozenset[int]:
    """The nodes whose result some call reads."""
    return frozenset(s.index for node in model.nodes for s in node.slots if s.kind == "node")


#: How the alternatives of a best-of are coupled: independent given their inputs (the
#: profiles' model), or as unfavourably / favourably as their marginals allow.
Coupling = Literal["independent", "least", "most"]


class Evaluator:
    """Evaluates batches of allocations of one compiled model (`coupling`: see the module's
    doc, "Dependent alternatives")."""

    def __init__(self, model: CompileModel, coupling: Coupling = "independent") -> None:
        self.model = model
        self.coupling = coupling
        self.shared = shared_nodes(model)
        self.read = read_nodes(model)

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
        """Output distributions for a batch, exact under the profiles' model unless the shared
        results had to be sampled (then `error` holds each row's standard error).

        Args:
            quality: program input qualities, shape (B, m) or (m,) (broadcast); a quality of
                `NO_RESULT` is an input without a result.
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
        try:
            return self._evaluate(q, alloc, observed, seen, _Rows(batch, sampled=False))
        except _Sample:
            if seen is not None:
                seen.clear()
            return self._evaluate(q, alloc, observed, seen, _Rows(batch, sampled=True))

    def _evaluate(
        self,
        q: Array,
        alloc: Array,
        observed: Mapping[int, float] | None,
        seen: dict[int, list[Dist]] | None,
        rows: _Rows,
    ) -> Dist:
        outputs: dict[int, Dist] = {}
        for node in self.model.nodes:
            if observed is not None and node.index in observed:
                outputs[node.index] = Dist.point(np.full(rows.count, observed[node.index]))
                continue
            here = q[rows.origin]
            inputs = [self._source(slot, outputs, here, rows.count) for slot in node.slots]
            if seen is not None:
                seen[node.index] = [rows.collapse(d) for d in inputs]
            out = self._node(node, inputs, alloc[rows.origin], rows)
            if out.values.shape[1] > MAX_SUPPORT or node.index in self.shared:
                out = compact(out)
            if node.index in self.read and out.values.shape[1] > MAX_SUPPORT:
                if not rows.sampled:
                    raise _Sample  # folding it would move the qualities its readers see
                out = rows.condition(out, outputs, node.index)
            elif node.index in self.shared and out.values.shape[1] > 1:
                out = rows.condition(out, outputs, node.index)
            outputs[node.index] = out
        final = self._source(self.model.output, outputs, q[rows.origin], rows.count)
        return bounded(rows.collapse(final))

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

    def _node(self, node: CompileNode, inputs: list[Dist], alloc: Array, rows: _Rows) -> Dist:
        batch = rows.count
        if isinstance(node, IfNode):
            return _conditional(node, inputs, alloc, rows, self.coupling)
        if isinstance(node, TestNode):  # its quality flows nowhere
            return Dist.point(np.ones(batch))
        coupled = isinstance(node, ChoiceNode) and len(inputs) > 1 and not any(node.estimated)
        if coupled and self.coupling != "independent":
            return _coupled_maximum(inputs, self.coupling)
        q, p = _combinations(inputs, batch)  # (B, C1..Cm, m), (B, C1..Cm)
        if isinstance(node, ChoiceNode):
            independent = _choice(node, inputs, q, p, batch)
            if not coupled or node.dependence == 0:
                return independent
            return _mixed(independent, _coupled_maximum(inputs, "least"), node.dependence)
        missing = np.any(q == NO_RESULT, axis=-1)  # some input has no result
        q = np.maximum(q, 0.0)  # what a module that accepts a missing input is looked up at
        match node:
            case ElementaryNode(combine=combine, entry=entry):
                values = combine(np.moveaxis(q, -1, 0)) if inputs else np.ones(p.shape)
                module = entry.module if entry is not None else None
                if module is None or not module.accepts_missing:
                    values = np.where(missing, NO_RESULT, values)
                return Dist(values.reshape(batch, -1), p.reshape(batch, -1))
            case ModuleNode() | LoopNode():  # a loop: its profile for the count planned
                t = np.broadcast_to(
                    alloc[:, node.time_index].reshape((batch,) + (1,) * (p.ndim - 1)), p.shape
                )
                # The call is not made (no result) where an input lacks one, or where its share
                # is less than its step: it could not answer within it.
                present = p if node.accepts_missing else np.where(missing, 0.0, p)
                present = np.where(node.starts(t), present, 0.0)
                run = node.run_time(t)
                if isinstance(node, ModuleNode) and node.callee is not None:
                    out = _from_program(node.callee, q, run, present, rows, self.coupling)
                else:
                    out = _from_profile(node.profile, node.deterministic, q, run, present, batch)
                gone = (p - present).reshape(batch, -1).sum(axis=1)
                if np.any(gone > 0):
                    out = Dist(
                        np.column_stack([out.values, np.full(batch, NO_RESULT)]),
                        np.column_stack([out.probs, gone]),
                    )
                return out
        raise AssertionError(node)


def _coupled_maximum(inputs: list[Dist], coupling: Coupling) -> Dist:
    """The maximum of the inputs coupled as unfavourably ("least": comonotone, the CDF the
    least of theirs) or as favourably ("most": the CDF `max(0, sum - (n - 1))`) as their
    marginals allow; no result is the lowest outcome, as in a best-of."""
    support = np.sort(np.concatenate([dist.values for dist in inputs], axis=1), axis=1)
    cdfs = np.stack(
        [
            np.einsum("bsk,bk->bs", dist.values[:, None, :] <= support[:, :, None], dist.probs)
            for dist in inputs
        ]
    )
    if coupling == "least":
        cdf = cdfs.min(axis=0)
    else:
        cdf = np.clip(cdfs.sum(axis=0) - (len(inputs) - 1), 0.0, None)
    probs = np.diff(cdf, axis=1, prepend=0.0)
    return Dist(support, np.clip(probs, 0.0, None))


def _mixed(first: Dist, second: Dist, weight: float) -> Dist:
    """The mixture of two distributions of a batch, `second` with probability `weight`."""
    return Dist(
        np.concatenate([first.values, second.values], axis=1),
        np.concatenate([(1 - weight) * first.probs, weight * second.probs], axis=1),
    )


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


def _conditional(
    node: IfNode, inputs: list[Dist], alloc: Array, rows: _Rows, coupling: Coupling
) -> Dist:
    """An if: each branch run as its program, with the if's time, on the qualities that reach
    it, weighted by the branch's probability; the supports are concatenated (a mixture)."""
    batch = rows.count
    values, probs = [], []
    for plan in node.branches:
        q, p = _combinations([inputs[a] for a in plan.axes], batch)
        t = np.broadcast_to(
            alloc[:, node.time_index].reshape((batch,) + (1,) * (p.ndim - 1)), p.shape
        )
        branch = _from_program(plan.compiled, q, t, plan.probability * p, rows, coupling)
        values.append(branch.values)
        probs.append(branch.probs)
    return Dist(np.concatenate(values, axis=1), np.concatenate(probs, axis=1))


def _from_program(
    compiled: Any, q: Array, t: Array, weight: Array, rows: _Rows, coupling: Coupling
) -> Dist:
    """A compiled program (a called schema, an if's branch) for every input combination
    (qualities `q` (B, C.., m), time `t`, probabilities `weight` (B, C..)): the mixture of its
    output distributions, each evaluated at the allocation its table gives for that
    combination and time, as the runtime runs it. A combination without mass is not
    evaluated; the variance of a sampled evaluation goes to `rows`."""
    batch = rows.count
    w = weight.reshape(-1)
    live = w > 0
    qf = q.reshape(len(w), -1)[live]
    out = _run_compiled(compiled, qf, t.reshape(-1)[live], coupling)
    k = out.values.shape[1]
    values, probs = np.zeros((len(w), k)), np.zeros((len(w), k))
    values[live] = out.values
    probs[live] = w[live, None] * out.probs
    if out.error is not None:
        variance = np.zeros(len(w))
        variance[live] = (w[live] * out.error) ** 2
        rows.variance = rows.variance + variance.reshape(batch, -1).sum(axis=1)
    return Dist(values.reshape(batch, -1), probs.reshape(batch, -1))


def _run_compiled(compiled: Any, q: Array, t: Array, coupling: Coupling) -> Dist:
    """A compiled program's output at input qualities `q` (N, m) and totals `t` (N,): its
    model evaluated at `allocation_at` of each (an input without a result is looked up as
    the runtime does, at quality 1, and reaches the program as no result)."""
    if len(t) == 0:
        return Dist(np.zeros((0, 1)), np.zeros((0, 1)))
    looked = np.where(q == NO_RESULT, 1.0, q)
    split = compiled.profile.interpolate(compiled.allocation, looked, t)
    out: Dist = Evaluator(compiled.model, coupling).evaluate(q, split)
    return out


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
