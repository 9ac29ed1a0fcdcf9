"""Conditional performance profiles: `CPP : Q_in x T -> Pr(Q_out)` as numpy tables.

A profile is an array `P[q_1, ..., q_m, t, k]`: for each grid value of each quality-carrying
input and each time allocation, a distribution over K output-quality bins. Between grid points
it is interpolated multilinearly (the papers use linear interpolation); outside the grid it is
clamped to the nearest end, so asking for more time than the table covers gives the quality of
its longest run, and asking below the lowest input quality gives that of the lowest.

A bin stands for one quality value, its representative, when a distribution is propagated into
the next module. A measured profile knows each bin's mean (`bin_mean`, the mean quality of the
trials that fell in it), and the representative is that mean, interpolated as the distribution
is: so any measured distribution (a point mass at 0 or 1, a module with two outcomes) stands for
exactly its measured qualities, and the mean is exact. Without bin means, a bin's midpoint is
moved so that the cell's distribution has the profile's exact mean where the per-cell `mean`
table is known (the exact curve of a deterministic profile, or a sample mean): so bin width does
not blur expected quality, no result counts as exactly 0, and a module that always reaches 1.0
as exactly 1.0.

No result is an outcome of its own: downstream modules are not run on a missing input. A
measured profile knows, per cell, the probability that the module has no result
(`no_result_table`); it counts as quality 0, in the first bin's mass.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

import numpy as np
from attrs import field, frozen
from numpy.typing import ArrayLike, NDArray

from anytime.errors import ProfileError
from anytime.vocabulary import (
    PROFILE_KINDS,
    UNITS,
    ProfileKind,
    Unit,
    array_field,
    arrays_field,
    optional_array_field,
)

Array = NDArray[np.float64]

#: Rows of a distribution may miss 1 by this much (the file format's tolerance); so may the
#: other sums a profile keeps consistent (the bin means' mean, no result within the first bin).
SUM_TOLERANCE = 1e-6


def axis_names(names: Sequence[str]) -> tuple[str, ...]:
    """The names of a profile's input axes, as strings (a converter)."""
    return tuple(str(name) for name in names)


def _optional_number(value: Any) -> Any:
    """A real number as a Python float; anything else as given, for `_validate` to refuse."""
    if isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    ):
        return float(value)
    return value


def default_bins(k: int = 10) -> Array:
    """K equal-width quality bins on [0, 1] (K+1 edges)."""
    return np.round(np.linspace(0.0, 1.0, k + 1), 12)  # 0.3, not 0.30000000000000004


@frozen
class ConditionalPerformanceProfile:
    """Output-quality distributions over (input qualities..., time), with interpolation.

    Attributes:
        input_grids: one increasing grid of qualities in [0, 1] per quality-carrying input.
        time: increasing, non-negative time allocations (in `time_unit`).
        bins: K+1 increasing edges in [0, 1]; bin k is [bins[k], bins[k+1]).
        probability: shape (*grid sizes, len(time), K); the last axis sums to 1.
        mean: optional exact expected quality per cell, shape probability.shape[:-1].
        samples: optional number of trials behind each cell (a measured profile).
        std: optional standard deviation of the measured quality per cell.
        step: the module's step, in `time_unit`, or None (unknown): the most time it used past
            any moment before it next registered a result or returned (an interruptible
            module: the largest gap between its results, counting from its start and to its
            end), or past its allocation (a contract module). The profile builder measures it
            as the maximum over all its trials; it bounds how far a run overshoots the time it
            is given. A compiled program's profile has none.
        no_result_table: optional probability that the module has no result, per cell, shape
            probability.shape[:-1] (file key `no_result`; `no_result(q, t)` interpolates it).
            A trial without a result counts as quality 0, in the first bin's mass, so it is at
            most `probability[..., 0]`. None: always a result, or not known (0 either way); a
            table of zeros is kept as None.
        bin_mean: optional mean quality of the trials that fell in each bin of each cell, shape
            probability.shape (the bin's midpoint where it has no mass), each within its bin
            (the first bin also holds qualities below the first edge and the last above the
            last, as `point_mass` places them); with `mean`, `probability @ bin_mean == mean`.
            `representatives` stands each bin for it.
    """

    input_grids: tuple[Array, ...] = arrays_field()
    time: Array = array_field()
    bins: Array = array_field()
    probability: Array = array_field()
    inputs: tuple[str, ...] = field(default=(), converter=axis_names)
    mean: Array | None = optional_array_field()
    samples: Array | None = optional_array_field()
    std: Array | None = optional_array_field()
    module: str = ""
    kind: ProfileKind = "interruptible"
    time_unit: Unit = "ticks"
    step: float | None = field(default=None, converter=_optional_number)
    no_result_table: Array | None = optional_array_field()
    bin_mean: Array | None = optional_array_field()

    def __attrs_post_init__(self) -> None:
        _validate(self)
        if self.no_result_table is not None and not np.any(self.no_result_table):
            # Never without a result is what None says too: one form, so files round-trip.
            object.__setattr__(self, "no_result_table", None)

    # --- shape -----------------------------------------------------------------------------

    @property
    def n_inputs(self) -> int:
        return len(self.input_grids)

    @property
    def n_bins(self) -> int:
        return len(self.bins) - 1

    @property
    def values(self) -> Array:
        """The quality each bin stands for: its midpoint."""
        return (self.bins[:-1] + self.bins[1:]) / 2

    @property
    def cell_shape(self) -> tuple[int, ...]:
        return self.probability.shape[:-1]

    # --- interpolation ---------------------------------------------------------------------

    def _corners(self, q: Array, t: Array) -> list[tuple[np.ndarray, Array]]:
        """The grid corners around each point of a batch, for multilinear interpolation: for
        each corner, its index into a table of this profile's cell shape flattened (N,) and
        its weight (N,); 2^k corners for k axes of more than one point.

        `q` has shape (N, m), `t` shape (N,). Points outside the grid are clamped to its ends.
        A gather of flat indices costs less per call than indexing with a tuple of arrays per
        axis, which is what small batches (the allocators' climbs) pay.
        """
        axes = [*self.input_grids, self.time]
        coords = [*(q[:, i] for i in range(self.n_inputs)), t]
        strides = np.cumprod([1] + [len(grid) for grid in axes[:0:-1]])[::-1]
        corners: list[tuple[np.ndarray, Array]] = [
            (np.zeros(t.shape, dtype=np.intp), np.ones(t.shape))
        ]
        for grid, x, stride in zip(axes, coords, strides, strict=True):
            if len(grid) == 1:  # one point: every point is at it
                continue
            x = np.minimum(np.maximum(x, grid[0]), grid[-1])
            i = np.minimum(np.searchsorted(grid, x, side="right") - 1, len(grid) - 2)
            w = (x - grid[i]) / (grid[i + 1] - grid[i])
            step = i * stride
            # Each corner so far splits into its lower and upper neighbour on this axis.
            lower = [(index + step, weight * (1 - w)) for index, weight in corners]
            upper = [(index + step + stride, weight * w) for index, weight in corners]
            corners = lower + upper
        return corners

    def interpolate(self, table: Array, q: ArrayLike, t: ArrayLike) -> Array:
        """Interpolate any `table` of this profile's cell shape (optionally with trailing axes,
        such as a compiled program's allocation table) at points (q, t), as the profile is."""
        q_flat, t_flat, batch = self._flat(q, t)
        trailing = table.shape[len(self.cell_shape) :]
        cells = table.reshape(-1, *trailing)
        out = np.zeros((t_flat.size, *trailing))
        for index, w in self._corners(q_flat, t_flat):
            out += w.reshape((-1, *([1] * len(trailing)))) * cells[index]
        return out.reshape((*batch, *trailing))

    def _flat(self, q: ArrayLike, t: ArrayLike) -> tuple[Array, Array, tuple[int, ...]]:
        """Points (q, t) as a flat batch: q (N, m), t (N,), and the batch's shape."""
        t_arr = np.asarray(t, dtype=np.float64)
        q_arr = np.asarray(q, dtype=np.float64).reshape((*t_arr.shape, self.n_inputs))
        t_flat = t_arr.reshape(-1)
        return q_arr.reshape((t_flat.size, self.n_inputs)), t_flat, t_arr.shape

    def distribution(self, q: ArrayLike, t: ArrayLike) -> Array:
        """Output-quality distribution at input qualities `q` (..., m) and times `t` (...)."""
        return self.interpolate(self.probability, q, t)

    @property
    def mean_table(self) -> Array:
        """The expected quality per cell: `mean`, else the bin means' (or midpoints') mean."""
        if self.mean is not None:
            return self.mean
        if self.bin_mean is not None:
            table: Array = np.einsum("...k,...k->...", self.probability, self.bin_mean)
            return table
        return self.probability @ self.values

    def expected(self, q: ArrayLike, t: ArrayLike) -> Array:
        """Expected output quality at input qualities `q` (..., m) and times `t` (...)."""
        return self.interpolate(self.mean_table, q, t)

    def no_result(self, q: ArrayLike, t: ArrayLike) -> Array:
        """The probability that the module has no result at input qualities `q` (..., m) and
        times `t` (...), interpolated as `expected` is: 0 where the profile does not say (it
        was measured before the builder recorded it, or is analytic)."""
        if self.no_result_table is None:
            return np.zeros(np.broadcast_shapes(np.shape(t), np.shape(q)[:-1]))
        return self.interpolate(self.no_result_table, q, t)

    def representatives(self, q: ArrayLike, t: ArrayLike) -> Array:
        """The quality each bin stands for at (q, t), shape (..., K).

        With a `bin_mean` table, each bin's mass-weighted mean over the interpolated cells: the
        interpolation of `probability * bin_mean` divided by the interpolated probability. So
        a measured distribution stands for exactly its measured qualities (a point mass at 0
        or 1, a module with two outcomes), and the distribution's mean is the interpolated
        `expected`. A bin without mass at (q, t) takes the rule below.

        Without it, and without a `mean` table, the bin midpoints. With a `mean` table, each
        midpoint moves the same fraction of the way to its bin's lower edge (or upper edge) so
        that the distribution's mean is the profile's expected quality, staying inside its
        bin: so no result (a mean of exactly 0) stands for 0, not for the first bin's midpoint,
        and a module that always reaches 1.0 stands for 1.0. (A mean the bins cannot hold,
        below the mean of the lower edges or above that of the upper ones, is met as closely
        as the bins allow.)"""
        distribution = self.distribution(q, t)
        shifted = self._shifted_midpoints(distribution, q, t)
        if self.bin_mean is None:
            return shifted
        moments = self.interpolate(self.probability * self.bin_mean, q, t)
        exact = np.divide(moments, distribution, out=shifted, where=distribution > 0)
        # Within the bin means it mixes, so that rounding never moves a mixture of one value
        # (a grid point; a bin whose mean is the same everywhere) off that value.
        low, high = self._held_range(self.bin_mean, q, t)
        return np.clip(np.where(distribution > 0, np.clip(exact, low, high), exact), 0.0, 1.0)

    def _held_range(self, table: Array, q: ArrayLike, t: ArrayLike) -> tuple[Array, Array]:
        """Per bin at (q, t), the least and greatest of `table` (shaped like `probability`)
        over the interpolation's corners that give the bin mass (+inf, -inf where none do)."""
        q_flat, t_flat, batch = self._flat(q, t)
        low = np.full((t_flat.size, self.n_bins), np.inf)
        high = np.full((t_flat.size, self.n_bins), -np.inf)
        probability, values = (a.reshape(-1, self.n_bins) for a in (self.probability, table))
        for index, w in self._corners(q_flat, t_flat):
            held = w[:, None] * probability[index] > 0
            low = np.where(held, np.minimum(low, values[index]), low)
            high = np.where(held, np.maximum(high, values[index]), high)
        return low.reshape((*batch, self.n_bins)), high.reshape((*batch, self.n_bins))

    def _shifted_midpoints(self, distribution: Array, q: ArrayLike, t: ArrayLike) -> Array:
        """The midpoints, moved by one common fraction so that `distribution` has the mean."""
        values = np.broadcast_to(self.values, distribution.shape)
        if self.mean is None:
            return values.copy()
        lower, upper = self.bins[:-1], self.bins[1:]
        mean = self.expected(q, t)[..., None]
        at_mid = distribution @ self.values
        down = (at_mid - distribution @ lower)[..., None]  # how far the mean can fall, and rise
        up = (distribution @ upper - at_mid)[..., None]
        gap = mean - at_mid[..., None]
        share_down = np.divide(-gap, down, out=np.zeros_like(gap), where=(gap < 0) & (down > 0))
        share_up = np.divide(gap, up, out=np.zeros_like(gap), where=(gap > 0) & (up > 0))
        moved = (
            values
            - np.minimum(share_down, 1.0) * (self.values - lower)
            + np.minimum(share_up, 1.0) * (upper - self.values)
        )
        return np.clip(moved, 0.0, 1.0)

    def standard_error(self, q: ArrayLike, t: ArrayLike) -> Array:
        """Standard error of the measured expected quality (0 for analytic profiles)."""
        if self.samples is None or self.std is None:
            return np.zeros(np.shape(t))
        se = self.std / np.sqrt(np.maximum(self.samples, 1))
        return self.interpolate(se, q, t)

    def transition(self, t: float, input_values: Sequence[ArrayLike] | None = None) -> Array:
        """Transition tensor at time t: P[out bin | input bins], shape (K_1, ..., K_m, K).

        `input_values` are the qualities the input bins stand for (default: this profile's own
        bin midpoints for every input).
        """
        values = self._input_values(input_values)
        mesh = np.meshgrid(*values, indexing="ij")
        q = np.stack(mesh, axis=-1) if values else np.zeros((0,))
        t_arr = np.full(mesh[0].shape if values else (), float(t))
        return self.distribution(q, t_arr)

    def propagate(
        self,
        input_distributions: Sequence[ArrayLike],
        t: ArrayLike,
        input_values: Sequence[ArrayLike] | None = None,
    ) -> Array:
        """Output distribution when the inputs' qualities are themselves distributions.

        Inputs are taken as independent. Each `input_distributions[i]` has shape (..., K_i)
        (a batch of distributions over that input's bins) and `t` broadcasts against the batch.
        Returns shape (..., K).
        """
        values = self._input_values(input_values)
        dists = [np.asarray(d, dtype=np.float64) for d in input_distributions]
        if len(dists) != self.n_inputs:
            raise ProfileError(
                f"{self.module or 'profile'}: expected {self.n_inputs} input distributions,"
                f" got {len(dists)}"
            )
        batch = np.broadcast_shapes(np.shape(t), *(d.shape[:-1] for d in dists))
        t_arr = np.broadcast_to(np.asarray(t, dtype=np.float64), batch)
        if not dists:
            return self.distribution(np.zeros((*batch, 0)), t_arr)
        grid = np.stack(np.meshgrid(*values, indexing="ij"), axis=-1)  # (K_1..K_m, m)
        combos = grid.shape[:-1]
        q = np.broadcast_to(grid, (*batch, *combos, self.n_inputs))
        t_full = np.broadcast_to(t_arr.reshape((*batch, *([1] * len(combos)))), (*batch, *combos))
        out = self.distribution(q, t_full)  # (*batch, K_1..K_m, K)
        for d in dists:  # contract one input axis at a time with its distribution
            d = np.broadcast_to(d, (*batch, d.shape[-1]))
            out = np.einsum("...i,...ir->...r", d, out.reshape((*batch, d.shape[-1], -1)))
        return out.reshape((*batch, self.n_bins))

    def _input_values(self, input_values: Sequence[ArrayLike] | None) -> list[Array]:
        if input_values is None:
            return [self.values] * self.n_inputs
        return [np.asarray(v, dtype=np.float64) for v in input_values]


@frozen
class PerformanceProfile(ConditionalPerformanceProfile):
    """A profile with no quality-carrying input: time -> distribution of output quality."""

    input_grids: tuple[Array, ...] = arrays_field(default=())

    def at(self, t: ArrayLike) -> Array:
        """Output distribution at time(s) t."""
        return self.distribution(np.zeros((*np.shape(t), 0)), t)

    def expected_at(self, t: ArrayLike) -> Array:
        """Expected output quality at time(s) t."""
        return self.expected(np.zeros((*np.shape(t), 0)), t)


def new_profile(**fields: Any) -> ConditionalPerformanceProfile:
    """A profile of the fitting class: a `PerformanceProfile` when it has no input axes."""
    if len(fields.get("input_grids", ())) == 0:
        return PerformanceProfile(**fields)
    return ConditionalPerformanceProfile(**fields)


def point_mass(quality: ArrayLike, bins: ArrayLike) -> Array:
    """Distributions putting all mass in the bin that holds each quality (1.0 in the last bin)."""
    q = np.asarray(quality, dtype=np.float64)
    edges = np.asarray(bins, dtype=np.float64)
    k = np.clip(np.searchsorted(edges, q, side="right") - 1, 0, len(edges) - 2)
    return np.eye(len(edges) - 1)[k]


def _validate(p: ConditionalPerformanceProfile) -> None:
    """The invariants every profile keeps; messages name the field (files add their name)."""
    name = p.module or "profile"

    def fail(field_name: str, problem: str) -> NoReturn:
        raise ProfileError(f"{name}: {field_name}: {problem}")

    for i, grid in enumerate(p.input_grids):
        check_grid(grid, f"input_quality[{i}]", fail, unit_interval=True)
    check_grid(p.time, "time", fail, unit_interval=False)
    check_grid(p.bins, "quality_bins", fail, unit_interval=True, minimum=2)
    if len(p.inputs) not in (0, p.n_inputs):
        fail("inputs", f"expected one name per input grid ({p.n_inputs}), got {len(p.inputs)}")
    expected = (*(len(g) for g in p.input_grids), len(p.time), p.n_bins)
    if p.probability.shape != expected:
        fail("probability", f"expected shape {list(expected)}, got {list(p.probability.shape)}")
    _check_non_negative(p.probability, "probability", fail)
    sums = p.probability.sum(axis=-1)
    worst = np.unravel_index(np.argmax(np.abs(sums - 1)), sums.shape)
    if abs(sums[worst] - 1) > SUM_TOLERANCE:
        fail(
            "probability" + "".join(f"[{i}]" for i in worst),
            f"expected a row summing to 1 (within {SUM_TOLERANCE:g}), got {sums[worst]:.10g}",
        )
    for field_name, table in (("mean", p.mean), ("samples", p.samples), ("std", p.std)):
        if table is None:
            continue
        if table.shape != expected[:-1]:
            fail(field_name, f"expected shape {list(expected[:-1])}, got {list(table.shape)}")
        _check_non_negative(table, field_name, fail)
    if p.mean is not None and np.any(p.mean > 1):
        fail("mean", f"expected qualities in [0, 1], got {p.mean[p.mean > 1].flat[0]:g}")
    if p.no_result_table is not None:
        _check_no_result(p.no_result_table, p.probability, fail)
    if p.bin_mean is not None:
        _check_bin_mean(p.bin_mean, p.probability, p.bins, p.mean, fail)
    if p.kind not in PROFILE_KINDS:
        fail("kind", f"expected 'interruptible' or 'contract', got {p.kind!r}")
    if p.time_unit not in UNITS:
        fail("time_unit", f"expected 'ticks' or 'seconds', got {p.time_unit!r}")
    step = p.step
    if step is not None and not (isinstance(step, float) and math.isfinite(step) and step >= 0):
        got = f"{step:g}" if isinstance(step, float) else repr(step)
        fail("step", f"expected a finite number >= 0 (or None: unknown), got {got}")


def check_grid(
    grid: Array,
    name: str,
    fail: Callable[[str, str], NoReturn],
    *,
    unit_interval: bool,
    minimum: int = 1,
) -> None:
    if grid.ndim != 1 or len(grid) < minimum:
        fail(name, f"expected a list of at least {minimum} number(s), got shape {list(grid.shape)}")
    if not np.all(np.isfinite(grid)):
        fail(name, "expected finite numbers, got NaN or infinity")
    if np.any(grid < 0):
        fail(name, f"expected numbers >= 0, got {grid[grid < 0][0]:g}")
    if unit_interval and np.any(grid > 1):
        fail(name, f"expected qualities in [0, 1], got {grid[grid > 1][0]:g}")
    if np.any(np.diff(grid) <= 0):
        i = int(np.argmax(np.diff(grid) <= 0))
        fail(name, f"expected increasing values, got {grid[i]:g} then {grid[i + 1]:g}")


def _check_non_negative(table: Array, name: str, fail: Callable[[str, str], NoReturn]) -> None:
    bad = ~np.isfinite(table) | (table < 0)
    if np.any(bad):
        fail(name, f"expected finite numbers >= 0, got {table[bad].flat[0]:g}")


def _where(field_name: str, index: Sequence[int]) -> str:
    return field_name + "".join(f"[{int(i)}]" for i in index)


def _first(bad: NDArray[np.bool_]) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(bad)[0])


def _check_no_result(
    table: Array, probability: Array, fail: Callable[[str, str], NoReturn]
) -> None:
    """Probabilities per cell, each at most its cell's first-bin mass (no result scores 0)."""
    cells = probability.shape[:-1]
    if table.shape != cells:
        fail("no_result", f"expected shape {list(cells)}, got {list(table.shape)}")
    bad = ~np.isfinite(table) | (table < 0) | (table > 1)
    if np.any(bad):
        index = _first(bad)
        fail(
            _where("no_result", index), f"expected a probability in [0, 1], got {table[index]:.10g}"
        )
    first = probability[..., 0]
    bad = table > first + SUM_TOLERANCE
    if np.any(bad):
        index = _first(bad)
        fail(
            _where("no_result", index),
            f"expected at most the first bin's probability, {_where('probability', index)}[0]"
            f" = {first[index]:.10g}, which counts every trial without a result (within"
            f" {SUM_TOLERANCE:g}), got {table[index]:.10g}",
        )


def _check_bin_mean(
    table: Array,
    probability: Array,
    bins: Array,
    mean: Array | None,
    fail: Callable[[str, str], NoReturn],
) -> None:
    """Qualities per bin of each cell, within the bin, and agreeing with the cell's `mean`."""
    if table.shape != probability.shape:
        fail("bin_mean", f"expected shape {list(probability.shape)}, got {list(table.shape)}")
    # The first bin holds every quality below its upper edge, the last every one from its
    # lower edge (as `point_mass` and the builder place them).
    lower = np.concatenate(([0.0], bins[1:-1]))
    upper = np.concatenate((bins[1:-1], [1.0]))
    bad = ~np.isfinite(table) | (table < lower) | (table > upper)
    if np.any(bad):
        index = _first(bad)
        k = index[-1]
        fail(
            _where("bin_mean", index),
            f"expected a quality within bin {k}, [{lower[k]:g}, {upper[k]:g}], got"
            f" {table[index]:.10g}",
        )
    if mean is None:
        return
    implied = np.einsum("...k,...k->...", probability, table)
    gap = np.abs(implied - mean)
    if np.any(gap > SUM_TOLERANCE):
        index = _first(gap > SUM_TOLERANCE)
        fail(
            _where("bin_mean", index),
            f"expected bin means whose mean over the bins is {_where('mean', index)} ="
            f" {mean[index]:.10g} (within {SUM_TOLERANCE:g}), got {implied[index]:.10g}",
        )
