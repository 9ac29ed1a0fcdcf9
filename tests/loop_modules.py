"""Toy modules for the loops' tests: `(map tour depots)` compiles and runs.

`tour` has diminishing returns (a concave curve: equal shares are best), `climb` an S-shaped
curve (nothing, then a steep rise: the marginal-value rule concentrates the time), `sense` a
world model that `route` (a tour on it) reads. Every curve is linear in its input qualities, so the
profiles' interpolation on the grid [0, 1] is exact.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from anytime.library import AnytimeLibrary, RegistrySource
from anytime.modules import Context, Registry, Result, elementary, interruptible
from anytime.profiles import tabulate

TIME = np.arange(0, 41, 1, dtype=np.float64)
LINEAR = [[0.0, 1.0]]


def tour_curve(t: Any, q: Any) -> Any:
    return np.asarray(q) * -np.expm1(-0.1 * np.asarray(t))


def climb_curve(t: Any, q: Any) -> Any:
    return np.asarray(q) * np.clip((np.asarray(t) - 8.0) / 8.0, 0.0, 1.0)


def route_curve(t: Any, depot: Any, world: Any) -> Any:
    return np.asarray(depot) * np.asarray(world) * -np.expm1(-0.1 * np.asarray(t))


def sense_curve(t: Any) -> Any:
    return np.minimum(np.asarray(t) / 10.0, 1.0)


def _iterate(curve: Any, q: float, ctx: Context, value: Any) -> Iterator[Result]:
    while True:
        yield Result((value, ctx.elapsed), float(curve(ctx.elapsed, q)))
        ctx.tick(1)


def _on_depots(curve: Any) -> Any:
    """A module that tours one depot, its quality the curve's at the depot's quality."""

    def run(ctx: Context, depot: Result) -> Iterator[Result]:
        yield from _iterate(curve, depot.quality, ctx, depot.value)

    return run


def loop_registry() -> Registry:
    registry = Registry()

    for name, curve in (("tour", tour_curve), ("climb", climb_curve)):
        run = _on_depots(curve)
        run.__name__ = run.__qualname__ = name
        profile = tabulate(curve, TIME, input_grids=LINEAR, inputs=["depot"])
        interruptible(name, inputs=["depot"], profile=profile, registry=registry)(run)

    @interruptible(
        "route",
        inputs=["depot", "world"],
        profile=tabulate(route_curve, TIME, input_grids=LINEAR * 2, inputs=["depot", "world"]),
        registry=registry,
    )
    def route(ctx: Context, depot: Result, world: Result) -> Iterator[Result]:
        while True:
            quality = route_curve(ctx.elapsed, depot.quality, world.quality)
            yield Result((depot.value, ctx.elapsed), float(quality))
            ctx.tick(1)

    @interruptible("sense", inputs=[], profile=tabulate(sense_curve, TIME), registry=registry)
    def sense(ctx: Context, sensor: Any) -> Iterator[Result]:
        while True:
            yield Result(("world", sensor), float(sense_curve(ctx.elapsed)))
            ctx.tick(1)

    @elementary("count-items", registry=registry)
    def count_items(items: Result) -> Any:
        return len(items.value)

    return registry


def loop_library() -> AnytimeLibrary:
    return AnytimeLibrary([RegistrySource(loop_registry())])
