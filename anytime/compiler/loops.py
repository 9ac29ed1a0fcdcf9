"""Loops: how a map's or a repeat's time is split among its calls, and the loop's own profile.

A loop's result quality is the **mean** of its calls' qualities (a call without a result counts
0; no calls at all, 1). The mean keeps the loop's expectation separable, E[mean] = mean of the
calls' expectations, so the best split of its time is a separable resource-allocation problem
(Ibaraki & Katoh, *Resource Allocation Problems*, 1988), solved at run time from the per-call
profile, each call's curve at the quality of its own item:

- identical concave curves (a repeat, or a map over items of one quality, of a module with
  diminishing returns): equal shares, which are then optimal;
- concave curves that differ (items of different qualities): the marginal-value rule, each
  next unit of time to the call whose expected quality it raises most, which is optimal for
  separable concave problems (Ibaraki & Katoh, ch. 4; Gross 1956);
- any other curves (S-shaped, discrete variants): the marginal-value rule can be far from the
  best there (unit by unit it stops at an S-curve's flat start; looking ahead to the steepest
  chord it still missed by up to 22% on benchmarks/bench_loops.py's cases), so the split is
  exact instead, by dynamic
  programming over the calls (the max-plus recursion of the separable problem, O(c U^2) for c
  calls and U lattice units).

In every case time that raises no call is left unused.

Both the compiler (the loop's profile for each count, its items all at the collection's
quality) and the runtime (the items' own qualities) use `best_splits`, so what runs is what was
compiled. A loop's expectation never falls as its time grows: each rule leaves unused the time
that would lower it.
"""

from __future__ import annotations

import numpy as np

from anytime.compiler.dist import MAX_SUPPORT, Dist, binned_profile, fold
from anytime.compiler.model import ModuleNode
from anytime.profiles.profile import Array, ConditionalPerformanceProfile

TOLERANCE = 1e-12  # a gain smaller than this is none
#: A curve whose gains grow by less than this from one unit to the next is taken as concave: a
#: measured profile's means carry sampling error (about 1e-3 to 1e-2 a cell), and a converged
#: curve's last gains, a few 1e-4 apart by chance, must not turn equal shares into a lattice
#: split that starves some calls of time (below one unit a call, the lattice cannot share
#: equally). The loss of equal shares on such a curve is of the order of this tolerance.
CONCAVITY_TOLERANCE = 1e-3


def call_curves(call: ModuleNode, qualities: Array, units: int, dt: float) -> Array:
    """Each call's expected quality with 0..units lattice units of time: `qualities` (B, c, m)
    the qualities of each call's inputs, in the call's profile-axis order; shape (B, c, units+1).
    A share less than the module's step gives it no run, quality 0."""
    share = np.arange(units + 1) * dt
    b, c, m = qualities.shape
    q = np.broadcast_to(qualities[:, :, None, :], (b, c, units + 1, m))
    t = np.broadcast_to(call.run_time(share), (b, c, units + 1))
    curves: Array = np.where(call.starts(share), call.profile.expected(q, t), 0.0)
    return curves


def concave(curves: Array) -> np.ndarray:
    """Per row (B,): whether every call's curve (B, c, U+1) is non-decreasing and concave
    (diminishing returns)."""
    rises = np.diff(curves, axis=-1)
    falls = np.diff(rises, axis=-1)
    return np.asarray(
        np.all(rises >= -TOLERANCE, axis=(1, 2)) & np.all(falls <= CONCAVITY_TOLERANCE, axis=(1, 2))
    )


def identical_concave(curves: Array) -> np.ndarray:
    """Per row (B,): whether its calls' curves (B, c, U+1) are one concave, non-decreasing
    curve, so that equal shares are optimal."""
    same = np.all(np.abs(curves - curves[:, :1]) <= TOLERANCE, axis=(1, 2))
    return np.asarray(same & concave(curves))


def equal_units(units: np.ndarray, calls: int) -> np.ndarray:
    """`units` (...) shared by `calls` as equally as whole units allow (the first ones get the
    remainder): shape (..., calls)."""
    base = units[..., None] // calls
    extra = np.arange(calls) < (units % calls)[..., None]
    return np.asarray(base + extra, dtype=np.int64)


def marginal_units(curves: Array) -> np.ndarray:
    """The marginal-value rule for every budget 0..U: each next unit to the call whose
    expected quality it raises most (the first on ties; to none when it raises none). For
    concave curves the splits are optimal and nested, so one pass gives them all:
    shape (B, U+1, c)."""
    b, c, width = curves.shape
    split = np.zeros((b, c), dtype=np.int64)
    out = np.zeros((b, width, c), dtype=np.int64)
    rows = np.arange(b)
    for budget in range(1, width):
        here = np.take_along_axis(curves, split[:, :, None], axis=2)[:, :, 0]
        there = np.take_along_axis(curves, np.minimum(split + 1, width - 1)[:, :, None], axis=2)
        gain = np.where(split < width - 1, there[:, :, 0] - here, -np.inf)
        best = np.argmax(gain, axis=1)
        go = gain[rows, best] > TOLERANCE
        split[rows[go], best[go]] += 1
        out[:, budget] = split
    return out


def exact_units(curves: Array) -> np.ndarray:
    """The best split of every budget 0..U by dynamic programming over the calls (the
    separable problem's max-plus recursion, exact for any curves; a budget need not be
    spent): shape (B, U+1, c). O(c U^2) per row, in chunks of rows."""
    b, c, width = curves.shape
    out = np.zeros((b, width, c), dtype=np.int64)
    budget = np.arange(width)
    before = budget[:, None] - budget[None, :]  # (u, j): the budget left for earlier calls
    fits = before >= 0
    chunk = max(1, 4_000_000 // (width * width))
    for lo in range(0, b, chunk):
        part = curves[lo : lo + chunk]
        value = np.zeros((len(part), width))  # no calls yet: 0 at every budget
        choices = []
        for call in range(c):
            candidates = np.where(
                fits, value[:, np.maximum(before, 0)] + part[:, call, None, :], -np.inf
            )
            choice = np.argmax(candidates, axis=2)  # (rows, u): its units, the fewest on ties
            choices.append(choice)
            # Non-decreasing in the budget: time no call can use is left to the "no calls" 0.
            value = np.max(candidates, axis=2)
        left = np.broadcast_to(budget, (len(part), width)).copy()
        for call in reversed(range(c)):
            units = np.take_along_axis(choices[call], left, axis=1)
            out[lo : lo + chunk, :, call] = units
            left -= units
    return out


def best_splits(curves: Array) -> np.ndarray:
    """The run-time rule's split (B, U+1, c) of every budget 0..U among calls with
    expected-quality curves (B, c, U+1): equal shares for identical concave curves, the
    marginal-value rule for concave ones, dynamic programming otherwise (where the
    marginal-value rule can be far from the best: benchmarks/bench_loops.py)."""
    b, c, width = curves.shape
    out = np.zeros((b, width, c), dtype=np.int64)
    if c == 0:
        return out
    equal = identical_concave(curves)
    smooth = concave(curves) & ~equal
    other = ~(equal | smooth)
    out[equal] = equal_units(np.arange(width), c)
    if np.any(smooth):
        out[smooth] = marginal_units(curves[smooth])
    if np.any(other):
        out[other] = exact_units(curves[other])
    return out


def run_time_split(call: ModuleNode, qualities: Array, share: float, dt: float) -> Array:
    """The shares of time (c,) a loop gives its calls at run time: `qualities` (c, m) their
    inputs' qualities, `share` the loop's time. Equal shares of the whole share where they are
    optimal, else the lattice split (the part of the share below one unit unused, as in the
    compiled table)."""
    c = len(qualities)
    if c == 0:
        return np.zeros(0)
    units = int(np.floor(share / dt + 1e-9))
    curves = call_curves(call, qualities[None], units, dt)
    if identical_concave(curves)[0]:
        return np.full(c, share / c)
    return np.asarray(best_splits(curves)[0, units] * dt, dtype=np.float64)


def loop_profiles(
    call: ModuleNode, most: int, lattice: Array, name: str
) -> tuple[ConditionalPerformanceProfile, ...]:
    """The loop's profile for each count 0..most: for every cell of the call's input grids
    (every item at that quality) and every time on `lattice` (multiples of its step `dt`),
    the distribution of the mean quality of the calls under the run-time split."""
    profile = call.profile
    grids = profile.input_grids
    m = len(grids)
    cells = (
        np.stack(np.meshgrid(*grids, indexing="ij"), axis=-1).reshape(-1, m)
        if m
        else np.zeros((1, 0))
    )
    cell_shape = (*(len(g) for g in grids), len(lattice))
    q_rows = np.repeat(cells, len(lattice), axis=0)  # (cells * times, m), time fastest
    profiles = []
    for count in range(most + 1):
        if count == 0:
            output = Dist.point(np.ones(len(q_rows)))
        else:
            shares = _compiled_shares(call, cells, count, lattice)
            output = _mean_of_calls(call, q_rows, shares)
        profiles.append(
            binned_profile(
                output,
                profile.bins,
                input_grids=grids,
                time=np.asarray(lattice, dtype=np.float64),
                cell_shape=cell_shape,
                inputs=profile.inputs,
                module=f"{name} x{count}",
                time_unit=profile.time_unit,
            )
        )
    return tuple(profiles)


def _compiled_shares(call: ModuleNode, cells: Array, count: int, lattice: Array) -> Array:
    """The shares (cells * times, count) the run-time rule gives `count` calls whose items are
    all at a cell's qualities, for each time of the lattice: as `run_time_split` does."""
    dt = float(lattice[1] - lattice[0]) if len(lattice) > 1 else 1.0
    m = cells.shape[1]
    qualities = np.ascontiguousarray(np.broadcast_to(cells[:, None, :], (len(cells), count, m)))
    curves = call_curves(call, qualities, len(lattice) - 1, dt)
    shares = best_splits(curves) * dt  # (cells, times, count)
    equal = identical_concave(curves)
    shares[equal] = np.asarray(lattice)[:, None] / count
    return shares.reshape(-1, count)


def _mean_of_calls(call: ModuleNode, q: Array, shares: Array) -> Dist:
    """The distribution of the mean quality of independent calls (B rows of input qualities
    `q`, shares (B, c)): a running mean, folded when its support grows (mean kept exact); a
    deterministic call's is a point mass at the mean of the calls' curves."""
    if call.deterministic:
        t = call.run_time(shares)
        qualities = np.broadcast_to(q[:, None, :], (*t.shape, q.shape[1]))
        each = np.where(call.starts(shares), call.profile.expected(qualities, t), 0.0)
        return Dist.point(each.mean(axis=1))
    total: Dist | None = None
    for i in range(shares.shape[1]):
        share = shares[:, i]
        started = np.asarray(call.starts(share), dtype=bool)
        t = call.run_time(share)
        probs = np.where(started[:, None], call.profile.distribution(q, t), 0.0)
        values = np.maximum(call.profile.representatives(q, t), 0.0)
        probs = np.column_stack([probs, ~started])  # not started: quality 0
        values = np.column_stack([values, np.zeros(len(q))])
        one = Dist(values, probs)
        if total is None:
            total = one
            continue
        k = i + 1  # calls in the mean after this one
        v = (total.values[:, :, None] * (k - 1) + one.values[:, None, :]) / k
        p = total.probs[:, :, None] * one.probs[:, None, :]
        total = Dist(v.reshape(len(q), -1), p.reshape(len(q), -1))
        if total.values.shape[1] > MAX_SUPPORT:
            total = fold(total)
    assert total is not None
    return total
