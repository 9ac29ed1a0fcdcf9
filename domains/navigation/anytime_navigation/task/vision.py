"""Anytime vision, the papers' `get-domain-description` (Zilberstein & Russell, "Anytime
sensing", Figure 8): the map of the world the planner sees.

The model, with `q = VisionHyperbola(t_a, q_a, t_b, k)`:

- given less than `t_a` ticks the sensor produces no description, and the robot falls back on
  its prior, "every position is free" (the papers' example for a domain with scarce obstacles);
- given `t >= t_a` ticks it produces a map in which each base cell is wrongly identified
  (blocked read as free or free as blocked) with probability `1 - q(t)`: `q_a` at `t_a`, rising
  along the hyperbola to 1.0 at `t_b`.

Quality is the papers' "1 - probability that a cell is wrongly identified". For a sensed map the
`Result` carries the model quality `q(t)`, the expected fraction of correct cells; the realised
fraction of one map is `fraction_correct` (it differs by sampling error). The prior has no model
probability, so its quality is its realised fraction correct against the true map, that is
1 - the blocked fraction. That is not 0, the hyperbola's value below `t_a`: the profile counts
what the sensor produces, the module what the robot has.

Errors come from one uniform draw per cell, fixed by the seed: a cell is wrong at `t` when its
draw is below `1 - q(t)`. Since `q` never decreases, the wrong cells at `t' > t` are a subset of
those at `t` (a cell read correctly stays correct), and a contract run with allocation `t`
gives the same map as the interruptible run at `t` with the same seed.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from anytime.plugin import Context, Result
from anytime.plugin.compose import VisionHyperbola

from ..world import BoolGrid, World

FloatGrid = NDArray[np.float64]


#: Vision's time scale, in ticks: comparable to what the ATP needs on a 128 x 128 map (about
#: 1000-1500 A* expansions to run to completion), so that the compiler has a real trade-off;
#: Q_A above the prior's fraction correct (about 0.8 at the default density): a first
#: sensed map is worth more than none.
T_A, Q_A, T_B = 100.0, 0.85, 1000.0


def _grid(value: Any) -> BoolGrid:
    grid = np.array(value, dtype=bool)
    grid.setflags(write=False)
    return grid


@frozen
class DomainDescription:
    """The map the planner sees: `blocked[y, x]` as sensed, and the movement model."""

    blocked: BoolGrid = field(converter=_grid, eq=False)
    movement: int = 4


@frozen
class Sensor:
    """What the robot's sensor looks at.

    Attributes:
        truth: the true map `blocked[y, x]` (the sensor's subject, hidden from the planner).
        seed: fixes which cells vision gets wrong.
        window: the half-open box (x0, y0, x1, y1) of cells the sensor sees; None: all of them.
        known: what the robot believes about the cells outside the window (from earlier
            frames); None: the prior, every cell free.
        movement: 4 or 8, passed on to the planner with the map.
        t_a, q_a, t_b: vision's profile (`VisionHyperbola`), in ticks.
    """

    truth: BoolGrid = field(converter=_grid, eq=False)
    seed: int = 0
    window: tuple[int, int, int, int] | None = None
    known: BoolGrid | None = field(default=None, eq=False)
    movement: int = 4
    t_a: float = T_A
    q_a: float = Q_A
    t_b: float = T_B


def _truth(world_or_blocked: World | BoolGrid) -> BoolGrid:
    blocked = world_or_blocked.blocked if isinstance(world_or_blocked, World) else world_or_blocked
    blocked = np.asarray(blocked, dtype=bool)
    if blocked.ndim != 2:
        raise ValueError(f"the map must be a 2-D grid blocked[y, x], got shape {blocked.shape}")
    return blocked


def _read_only(grid: BoolGrid) -> BoolGrid:
    grid.setflags(write=False)
    return grid


def error_draws(shape: tuple[int, ...], seed: int) -> FloatGrid:
    """The per-cell uniform draws in [0, 1) that decide which cells are wrong, from the seed."""
    return np.random.default_rng(seed).random(shape)


def prior_map(world_or_blocked: World | BoolGrid) -> BoolGrid:
    """The map without a description: every cell free (read-only)."""
    return _read_only(np.zeros_like(_truth(world_or_blocked)))


def fraction_correct(seen: BoolGrid, world_or_blocked: World | BoolGrid) -> float:
    """The realised quality of a map: the fraction of cells it identifies correctly."""
    truth = _truth(world_or_blocked)
    seen = np.asarray(seen, dtype=bool)
    if seen.shape != truth.shape:
        raise ValueError(f"the map has shape {seen.shape}, the world {truth.shape}")
    return float(np.mean(seen == truth))


def sensed_map(truth: BoolGrid, draws: FloatGrid, quality: float) -> BoolGrid:
    """`truth` with the cells whose draw is below `1 - quality` flipped (read-only)."""
    return _read_only(truth ^ (draws < 1.0 - quality))


def _time(allocation: float, t_b: float) -> float:
    # An unbounded contract senses to perfection and no longer: nothing improves after t_b.
    return t_b if math.isinf(allocation) else allocation


def sense(
    ctx: Context,
    world_or_blocked: World | BoolGrid,
    *,
    t_a: float,
    q_a: float,
    t_b: float,
    seed: int,
    k: float = 4.0,
) -> Result:
    """Contract vision: spend the whole allocation `ctx.allocation`, return the map it buys.

    Below `t_a` the result is the prior (all free) with its realised quality; from `t_a` on, a
    sensed map with model quality `q(t)` (see the module docstring). An infinite allocation is
    spent as `t_b`, the time of perfect vision.

    Args:
        ctx: the context; its allocation is the contract time `t`, reported with `ctx.tick`.
        world_or_blocked: the true map, a `World` or a `blocked[y, x]` grid.
        t_a, q_a, t_b, k: the vision profile (`VisionHyperbola`).
        seed: fixes which cells are wrong.
    """
    curve = VisionHyperbola(t_a, q_a, t_b, k)
    truth = _truth(world_or_blocked)
    t = _time(ctx.allocation, t_b)
    if t < 0:
        raise ValueError(f"vision: the allocation must be >= 0, got {ctx.allocation}")
    ctx.tick(t)
    if t < t_a:
        prior = prior_map(truth)
        return Result(prior, fraction_correct(prior, truth))
    quality = float(curve(t))
    return Result(sensed_map(truth, error_draws(truth.shape, seed), quality), quality)


def sense_progressively(
    ctx: Context,
    world_or_blocked: World | BoolGrid,
    *,
    t_a: float,
    q_a: float,
    t_b: float,
    seed: int,
    k: float = 4.0,
    steps: int = 16,
) -> Iterator[Result]:
    """Interruptible vision: the prior at once, then sensed maps as time passes.

    After the prior it works `t_a` ticks, then `steps` equal steps up to `t_b`, and after each
    yields the map `sense` would give for the time spent so far, but only when its quality beats
    the last one yielded (if `q_a` is below the prior's quality, the first sensed maps are worse
    than assuming all free and are kept back). It never ticks past the allocation: when the time
    left cannot pay for the next step it spends it and stops, keeping the last map yielded.

    Arguments as for `sense`; `steps` is the number of refinements between `t_a` and `t_b`.
    """
    if steps < 1:
        raise ValueError(f"vision: steps must be >= 1, got {steps}")
    curve = VisionHyperbola(t_a, q_a, t_b, k)
    truth = _truth(world_or_blocked)
    prior = prior_map(truth)
    best = fraction_correct(prior, truth)
    yield Result(prior, best)
    draws = error_draws(truth.shape, seed)
    spent = 0.0
    for t in [t_a, *np.linspace(t_a, t_b, steps + 1)[1:]]:
        work = float(t) - spent
        if ctx.expired:
            return
        if work > ctx.remaining:
            ctx.tick(ctx.remaining)
            return
        ctx.tick(work)
        spent = float(t)
        quality = float(curve(t))
        if quality > best:
            best = quality
            yield Result(sensed_map(truth, draws, quality), quality)
