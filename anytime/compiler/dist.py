"""Batches of discrete quality distributions, as the evaluator passes them through a program.

A `Dist` holds `values (B, K)` with `probs (B, K)`, one distribution a row; `NO_RESULT` in a
support is the outcome "no result". Equal values of a support are merged (`compact`). A support
still larger than `MAX_SUPPORT` values is, for the program's output, folded onto a fixed grid by
splitting each value's mass between its two neighbouring grid points, which keeps the mean exact
(`fold`, `bounded`). `binned_profile` makes a contract profile of output distributions (a
compiled program's, a loop's).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

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
    """A batch of discrete quality distributions; `error` (B,), where set, is the standard
    error of each row's expectation, estimated by sampling the shared results (None: exact)."""

    values: Array  # (B, K)
    probs: Array  # (B, K)
    error: Array | None = None

    def expected(self) -> Array:
        """The expected quality, no result counting 0."""
        expected: Array = np.einsum("bk,bk->b", np.maximum(self.values, 0.0), self.probs)
        return expected

    def missing(self) -> Array:
        """The probability of no result."""
        missing: Array = np.einsum("bk,bk->b", self.values == NO_RESULT, self.probs)
        return missing

    def rows(self, index: np.ndarray) -> Dist:
        """The distributions of rows `index`."""
        error = None if self.error is None else self.error[index]
        return Dist(self.values[index], self.probs[index], error)

    @property
    def standard_error(self) -> Array:
        """`error`, with 0 for an exact row."""
        return np.zeros(len(self.values)) if self.error is None else self.error

    @classmethod
    def concatenate(cls, parts: Sequence[Dist]) -> Dist:
        """The rows of `parts` one after another (supports padded with massless zeros)."""
        if len(parts) == 1:
            return parts[0]
        width = max(part.values.shape[1] for part in parts)

        def padded(table: Array) -> Array:
            return np.pad(table, ((0, 0), (0, width - table.shape[1])))

        errors = [part.error for part in parts]
        error = None
        if any(e is not None for e in errors):
            error = np.concatenate([part.standard_error for part in parts])
        return cls(
            np.concatenate([padded(part.values) for part in parts]),
            np.concatenate([padded(part.probs) for part in parts]),
            error,
        )

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
    return Dist(values, out, dist.error)


def compact(dist: Dist) -> Dist:
    """The same distributions with equal values merged and values without mass dropped (rows
    padded with massless zeros to the widest row's support)."""
    if dist.values.shape[1] <= 1:
        return dist
    key = np.where(dist.probs > 0, dist.values, np.inf)
    order = np.argsort(key, axis=1, kind="stable")
    key = np.take_along_axis(key, order, axis=1)
    probs = np.take_along_axis(dist.probs, order, axis=1)
    new = np.ones(key.shape, dtype=bool)
    new[:, 1:] = key[:, 1:] != key[:, :-1]
    group = np.cumsum(new, axis=1) - 1
    kept = np.isfinite(key)
    width = max(int(np.max(np.where(kept, group + 1, 0), initial=0)), 1)
    rows = np.broadcast_to(np.arange(len(key))[:, None], key.shape)
    out_p = np.zeros((len(key), width))
    out_v = np.zeros((len(key), width))
    np.add.at(out_p, (rows[kept], group[kept]), probs[kept])
    out_v[rows[kept], group[kept]] = key[kept]
    return Dist(out_v, out_p, dist.error)


def bounded(dist: Dist) -> Dist:
    """`dist` compacted, and folded if its support is still past `MAX_SUPPORT` (the mean kept):
    for a distribution no call reads."""
    if dist.values.shape[1] <= MAX_SUPPORT:
        return dist
    dist = compact(dist)
    return fold(dist) if dist.values.shape[1] > MAX_SUPPORT else dist


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
