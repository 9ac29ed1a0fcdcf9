"""Analytic performance-profile families, and tabulating any quality curve onto a grid.

Each family is the expected output quality of a module as a function of its run time (with a
perfect input). `tabulate` turns a curve, optionally conditioned on input qualities, into a
deterministic `ConditionalPerformanceProfile`: a point mass per cell, with the exact curve kept
as the cell means.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from attrs import field, frozen
from numpy.typing import ArrayLike

from anytime.errors import ProfileError
from anytime.profiles.profile import (
    Array,
    ConditionalPerformanceProfile,
    default_bins,
    new_profile,
    point_mass,
)
from anytime.vocabulary import ProfileKind, Unit


def _check(condition: bool, message: str) -> None:
    if not condition:
        raise ProfileError(message)


@frozen
class Constant:
    """Quality `quality` whatever the time: an elementary (non-anytime) module."""

    quality: float

    def __attrs_post_init__(self) -> None:
        _check(0 <= self.quality <= 1, f"constant: quality must be in [0, 1], got {self.quality}")

    def __call__(self, t: ArrayLike) -> Array:
        return np.full(np.shape(t), float(self.quality))


@frozen
class Exponential:
    """`q(t) = q_max * (1 - exp(-rate * t))`: diminishing returns, the typical anytime curve."""

    rate: float
    q_max: float = 1.0

    def __attrs_post_init__(self) -> None:
        _check(self.rate > 0, f"exponential: rate must be > 0, got {self.rate}")
        _check(0 < self.q_max <= 1, f"exponential: q_max must be in (0, 1], got {self.q_max}")

    def __call__(self, t: ArrayLike) -> Array:
        t = np.maximum(np.asarray(t, dtype=np.float64), 0)
        return self.q_max * -np.expm1(-self.rate * t)


def _sorted_variants(variants: Sequence[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
    return tuple(sorted((float(t), float(q)) for t, q in variants))


@frozen
class Step:
    """A finite set of (time, quality) variants: the best variant that fits in the time.

    Before the cheapest variant's time the quality is 0. This is also how a module with
    discrete variants `{(T_k, Q_k)}` is described.
    """

    variants: tuple[tuple[float, float], ...] = field(converter=_sorted_variants)

    def __attrs_post_init__(self) -> None:
        _check(len(self.variants) > 0, "step: needs at least one (time, quality) variant")
        for t, q in self.variants:
            _check(t >= 0 and 0 <= q <= 1, f"step: variant ({t}, {q}) outside time >= 0, [0, 1]")

    def __call__(self, t: ArrayLike) -> Array:
        times = np.array([v[0] for v in self.variants])
        best = np.maximum.accumulate(np.array([v[1] for v in self.variants]))
        k = np.searchsorted(times, np.asarray(t, dtype=np.float64), side="right") - 1
        return np.where(k >= 0, best[np.maximum(k, 0)], 0.0)


@frozen
class DiscreteVariants:
    """A module with a finite set of (time, quality) variants (Romanenko's `{(T_k, Q_k)}`):
    with time t it delivers the best variant whose time fits, 0 before the cheapest.

    `profile(dt, horizon)` tabulates it on the allocators' lattice (every multiple of `dt`),
    with each variant's time rounded *up* to the lattice (a variant needing 15 with dt 10 is
    ready at 20: never promised early). On that lattice the tabulated profile is exact, so the
    exhaustive search and dp, which only evaluate lattice points, optimise the step function
    exactly; between lattice points the table interpolates linearly.
    """

    variants: tuple[tuple[float, float], ...] = field(converter=_sorted_variants)

    def __attrs_post_init__(self) -> None:
        _check(len(self.variants) > 0, "variants: needs at least one (time, quality) variant")
        for t, q in self.variants:
            _check(
                t >= 0 and 0 <= q <= 1, f"variants: ({t}, {q}) outside time >= 0, quality [0, 1]"
            )

    def __call__(self, t: ArrayLike) -> Array:
        return Step(self.variants)(t)

    def snapped(self, dt: float) -> DiscreteVariants:
        """The variants with their times rounded up to multiples of `dt`."""
        _check(dt > 0, f"variants: dt must be > 0, got {dt}")
        return DiscreteVariants(
            tuple((float(np.ceil(t / dt - 1e-9) * dt), q) for t, q in self.variants)
        )

    def profile(
        self,
        dt: float,
        horizon: float,
        *,
        module: str = "",
        kind: ProfileKind = "contract",
        time_unit: Unit = "ticks",
    ) -> ConditionalPerformanceProfile:
        """The deterministic profile on the lattice 0, dt, ..., >= horizon (snapped variants)."""
        steps = int(np.ceil(horizon / dt - 1e-9))
        lattice = np.arange(steps + 1) * dt
        return tabulate(self.snapped(dt), lattice, module=module, kind=kind, time_unit=time_unit)


@frozen
class VisionHyperbola:
    """The papers' vision profile: no output before `t_a`; `q_a` at `t_a`, rising along a
    hyperbola to 1.0 at `t_b`, and 1.0 after.

    The curve between is `q_a + (1 - q_a) * x * (1 + k) / (1 + k * x)` with
    `x = (t - t_a) / (t_b - t_a)`: a branch of a rectangular hyperbola through (t_a, q_a) and
    (t_b, 1), concave (fast early gains) with curvature `k` > 0.
    """

    t_a: float
    q_a: float
    t_b: float
    k: float = 4.0

    def __attrs_post_init__(self) -> None:
        _check(0 <= self.t_a < self.t_b, f"vision: need 0 <= t_a < t_b, got {self.t_a}, {self.t_b}")
        _check(0 <= self.q_a <= 1, f"vision: q_a must be in [0, 1], got {self.q_a}")
        _check(self.k > 0, f"vision: curvature k must be > 0, got {self.k}")

    def __call__(self, t: ArrayLike) -> Array:
        t = np.asarray(t, dtype=np.float64)
        x = np.clip((t - self.t_a) / (self.t_b - self.t_a), 0, 1)
        q = self.q_a + (1 - self.q_a) * x * (1 + self.k) / (1 + self.k * x)
        return np.where(t < self.t_a, 0.0, q)


#: A quality curve over time, optionally conditioned on input qualities: f(t, q_1, ..., q_m).
Curve = Callable[..., ArrayLike]


def tabulate(
    curve: Curve,
    time: ArrayLike,
    *,
    bins: ArrayLike | None = None,
    input_grids: Sequence[ArrayLike] = (),
    inputs: Sequence[str] = (),
    module: str = "",
    kind: ProfileKind = "interruptible",
    time_unit: Unit = "ticks",
) -> ConditionalPerformanceProfile:
    """A deterministic profile of `curve` on a grid (a `PerformanceProfile` without inputs).

    `curve(t, q_1, ..., q_m)` gets broadcast arrays (one axis per input, then time) and returns
    qualities in [0, 1]; with no input grids it is called as `curve(t)`. For example, a planner
    whose plan is as good as its map: `tabulate(lambda t, q: q * Exponential(0.02)(t), ...)`.
    """
    grids = [np.asarray(g, dtype=np.float64) for g in input_grids]
    t_grid = np.asarray(time, dtype=np.float64)
    edges = default_bins() if bins is None else np.asarray(bins, dtype=np.float64)
    mesh = np.meshgrid(*grids, t_grid, indexing="ij")
    quality = np.asarray(curve(mesh[-1], *mesh[:-1]), dtype=np.float64)
    quality = np.broadcast_to(quality, mesh[-1].shape)
    if not np.all(np.isfinite(quality)) or quality.min() < 0 or quality.max() > 1:
        raise ProfileError(f"{module or 'curve'}: the curve gives qualities outside [0, 1]")
    return new_profile(
        input_grids=grids,
        time=t_grid,
        bins=edges,
        probability=point_mass(quality, edges),
        mean=quality,
        inputs=inputs,
        module=module,
        kind=kind,
        time_unit=time_unit,
    )
