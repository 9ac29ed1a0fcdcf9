"""Toy modules whose output quality follows their tabulated profiles exactly, shared by the
compiler's and the runtime's tests: `(refine (both (sense x) (guess x)))` compiles and runs.

The curves are linear in the input quality, so the profiles' interpolation on the grid [0, 1]
is exact too.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from anytime.modules import Context, Registry, Result, contract, elementary, interruptible
from anytime.profiles import tabulate

TIME = np.arange(0, 41, 5, dtype=np.float64)
LINEAR = [[0.0, 1.0]]  # an input grid on which a curve linear in q interpolates exactly


def sense_curve(t: Any, q: Any) -> Any:
    return np.asarray(q) * -np.expm1(-0.1 * np.asarray(t))


def guess_curve(t: Any, q: Any) -> Any:
    return (0.5 + 0.5 * np.asarray(q)) * np.minimum(np.asarray(t) / 40.0, 1.0)


def refine_curve(t: Any, q: Any) -> Any:
    return np.asarray(q) * -np.expm1(-0.05 * np.asarray(t))


def toy_registry() -> Registry:
    """A fresh registry holding `sense`, `guess` (a contract), `both` and `refine`."""
    registry = Registry()

    @interruptible(
        "sense",
        inputs=["x"],
        profile=tabulate(sense_curve, TIME, input_grids=LINEAR, inputs=["x"]),
        registry=registry,
    )
    def sense(ctx: Context, x: Result) -> Iterator[Result]:
        while True:
            yield Result(("sensed", ctx.elapsed), float(sense_curve(ctx.elapsed, x.quality)))
            ctx.tick(1)

    @contract(
        "guess",
        inputs=["x"],
        profile=tabulate(guess_curve, TIME, input_grids=LINEAR, inputs=["x"], kind="contract"),
        registry=registry,
    )
    def guess(ctx: Context, x: Result) -> Result:
        ctx.tick(ctx.allocation)
        return Result("guessed", float(guess_curve(ctx.allocation, x.quality)))

    @elementary("both", registry=registry)
    def both(a: Result, b: Result) -> Any:
        return (a.value, b.value)

    @interruptible(
        "refine",
        inputs=["m"],
        profile=tabulate(refine_curve, TIME, input_grids=LINEAR, inputs=["m"]),
        registry=registry,
    )
    def refine(ctx: Context, m: Result) -> Iterator[Result]:
        while True:
            yield Result(("plan", m.value), float(refine_curve(ctx.elapsed, m.quality)))
            ctx.tick(1)

    return registry
