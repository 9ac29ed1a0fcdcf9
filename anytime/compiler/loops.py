"""Loops: how a map's or a repeat's time is split among its calls, and the loop's own profile.

A loop's result quality is the **mean** of its calls' qualities (a call without a result counts
0; no calls at all, 1). The mean keeps the loop's expectation separable, E[mean] = mean of the
calls' expectations, so the best split of its time is a separable resource-allocation problem
(Ibaraki & Katoh, *Resource Allocation Problems*, 1988), solved at run time from the per-call
profile, each call's curve at the quality of its own item:

- identical concave curves (a repeat, or a map over items of one quality, of a module with
  diminishing returns): equal shares, which are then optimal;
- otherwise the marginal-value rule: give the next time to the call whose expected quality
  rises most per unit, looking past flat stretches to the steepest chord of its curve (greedy
  on the concave hull, Ibaraki & Katoh ch. 4); it stops when more time raises no call, leaving
  the rest unused.

Both the compiler (the loop's profile for each count, its items all at the collection's
quality) and the runtime (the items' own qualities) use `split_units`, so what runs is what was
compiled. A split is never worse than one for less time: for each budget the best split found
for any budget up to it is kept.
"""

from __future__ import annotations

import numpy as np

from anytime.compiler.evaluate import MAX_SUPPORT, Dist, binned_profile, fold
from anytime.compiler.model import ModuleNode
from anytime.profiles.profile import Array, ConditionalPerformanceProfile

TOLERANCE = 1e-12  # a gain smaller than this is none


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


def identical_concave(curves: Array) -> np.ndarray:
    """Per row (B,): whether its calls' curves (B, c, U+1) are one curve, non-decreasing and
    concave, so that equal shares are optimal."""
    same = np.all(np.abs(curves - curves[:, :1]) <= TOLERANCE, axis=(1, 2))
    rises = np.diff(curves[:, 0], axis=-1)
    concave = np.all(np.diff(rises, axis=-1) <= TOLERANCE, axis=-1)
    return np.asarray(same & concave & np.all(rises >= -TOLERANCE, axis=-1))


def equal_units(units: np.ndarray, calls: int) -> np.ndarray:
    """`units` (B,) shared by `calls` as equally as whole units allow (the first ones get the
    remainder)."""
    base = units[:, None] // calls
    extra = np.arange(calls)[None, :] < (units % calls)[:, None]
    return np.asarray(base + extra, dtype=np.int64)


def marginal_units(curves: Array, units: np.ndarray) -> np.ndarray:
    """The marginal-value rule on curves (B, c, U+1) for budgets `units` (B,): repeatedly give
    the call with the steepest next chord (largest gain per unit over its next j units, the
    smallest such j) those j units, while some gain is left and the budget allows."""
    b, c, top = curves.shape[0], curves.shape[1], curves.shape[2] - 1
    split = np.zeros((b, c), dtype=np.int64)
    left = units.astype(np.int64).copy()
    steps = np.arange(1, top + 1)
    active = left > 0
    while np.any(active):
        at = split[active]  # (A, c)
        ahead = at[:, :, None] + steps[None, None, :]  # (A, c, U)
        fits = (ahead <= top) & (steps[None, None, :] <= left[active][:, None, None])
        here = np.take_along_axis(curves[active], at[:, :, None], axis=2)
        there = np.take_along_axis(curves[active], np.minimum(ahead, top), axis=2)
        rate = np.where(fits, (there - here) / steps, -np.inf)
        flat = rate.reshape(len(at), -1)
        best = np.argmax(flat, axis=1)  # the first call, then the shortest chord, on ties
        gain = flat[np.arange(len(at)), best]
        go = gain > TOLERANCE
        which, size = best // top, best % top + 1
        index = np.flatnonzero(active)[go]
        split[index, which[go]] += size[go]
        left[index] -= size[go]
        active[np.flatnonzero(active)[~go]] = False
        active &= left > 0
    return split


def split_units(curves: Array, units: np.ndarray) -> tuple[np.ndarray, Array]:
    """The run-time split of each budget `units` (B,) among calls with expected-quality curves
    (B, c, U+1) on the lattice: equal shares for identical concave curves, the marginal-value
    rule otherwise. Returns the split (B, c) in units and its expected mean quality (B,)."""
    b, c = curves.shape[:2]
    if c == 0:
        return np.zeros((b, 0), dtype=np.int64), np.ones(b)
    equal = identical_concave(curves)
    split = np.where(equal[:, None], equal_units(units, c), 0)
    if not np.all(equal):
        split[~equal] = marginal_units(curves[~equal], units[~equal])
    value = np.take_along_axis(curves, split[:, :, None], axis=2)[:, :, 0].mean(axis=1)
    return split, value


def best_splits(curves: Array) -> np.ndarray:
    """For curves (B, c, U+1), the split (B, U+1, c) of every budget 0..U, each never worse
    than one for a smaller budget (which it then keeps, leaving the rest unused)."""
    b, c, width = curves.shape
    rows = np.repeat(curves, width, axis=0)
    budgets = np.tile(np.arange(width), b)
    split, value = split_units(rows, budgets)
    value = value.reshape(b, width)
    split = split.reshape(b, width, c)
    # The best budget up to each one: its own unless a smaller one is better by more than
    # rounding.
    own = value >= np.maximum.accumulate(value, axis=1) - TOLERANCE
    best = np.maximum.accumulate(np.where(own, np.arange(width), 0), axis=1)
    return np.take_along_axis(split, best[:, :, None], axis=1)


def run_time_split(call: ModuleNode, qualities: Array, share: float, dt: float) -> Array:
    """The shares of time (c,) a loop gives its calls at run time: `qualities` (c, m) their
    inputs' qualities, `share` the loop's time. Equal shares of the whole share where they are
    optimal, else the lattice split, the part of the share below one unit to the first call."""
    c = len(qualities)
    if c == 0:
        return np.zeros(0)
    units = int(np.floor(share / dt + 1e-9))
    curves = call_curves(call, qualities[None], units, dt)
    if identical_concave(curves)[0]:
        return np.full(c, share / c)
    split = best_splits(curves)[0, units] * dt
    split[0] += share - units * dt
    return np.asarray(split, dtype=np.float64)


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
