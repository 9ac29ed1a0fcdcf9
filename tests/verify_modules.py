"""A small plugin for the tests of `anytime verify` (tests/test_verify.py, tests/cli/
test_cli_verify.py): a promise that holds, and one that is wrong because one quality number
does not carry what the next module needs.

A problem hides a number x in [10, 100]. `guess` (contract) estimates it: off by a fraction e
of x that halves every 4 ticks of its allocation, e = e0 2^(-t/4), e0 drawn by the problem
from [0.2, 0.6]; above x or below it as the problem says (its `side`). `guess-low` is the same
estimator with a flaw: it always errs below x. `polish` (interruptible) refines an estimate with
a descent that can only lower it: one tick quarters the error of an estimate above x, and leaves
one below x as it is. Every quality is the true one, 1 - |estimate - x| / x.

`polish`'s profile is measured, as a plugin would measure it, on estimates of each quality that
err above or below x with equal chance (`Roughs`). That is what `guess` feeds it (`HiddenNumbers`:
the side is a fair coin), so the schema `fair`, (polish (guess x) x), delivers its promise. But
`guess-low` feeds it estimates below x only, of the same qualities: the quality of its input
does not capture the side of its error, which is all that matters to `polish`, so the schema
`low`, (polish (guess-low x) x), is promised (1 - q) / 2 more than it delivers wherever `polish`
runs. `over` calls `overrun`, a contract module that ticks one tick past its allocation
(declaring a step of 0): every run with time uses more than its budget.

The profiles are measured when first needed (`library()`, `PLUGIN`), once per process, in about
a second, with a fixed seed.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator
from typing import Any

import attrs
import numpy as np

from anytime import parse_schemas
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.measure.builder import build_profile
from anytime.modules import AnytimeModule
from anytime.plugin import (
    Context,
    Instance,
    Plugin,
    ProgramProblems,
    Result,
    contract,
    interruptible,
    tabulate,
)
from anytime.runtime.modes import SOFT

SCHEMAS = """
(defschema fair (x) (polish (guess x) x))
(defschema low (x) (polish (guess-low x) x))
(defschema over (x) (overrun x))
"""
#: The totals the schemas are compiled for, and their lattice.
TOTALS = tuple(range(0, 13, 2))
RESOLUTION = 1.0
GUESS_TIME = list(range(0, 9))
POLISH_TIME = list(range(0, 5))
POLISH_QUALITIES = [0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
#: Trials per cell of the measured profiles.
TRIALS = 400


class Hidden:
    """A hidden number, how far off a first guess is (e0) and on which side (+1 above)."""

    def __init__(self, x: float, e0: float, side: int) -> None:
        self.x, self.e0, self.side = x, e0, side

    def __repr__(self) -> str:
        return f"Hidden(x={self.x:.3f}, e0={self.e0:.3f}, side={self.side:+d})"


def quality(estimate: float | None, x: float) -> float:
    if estimate is None:
        return 0.0
    return max(0.0, 1.0 - abs(estimate - x) / x)


def _guess(ctx: Context, hidden: Hidden, side: int) -> Result:
    ticks = math.floor(ctx.allocation + 1e-9) if math.isfinite(ctx.allocation) else 8
    ctx.tick(ticks)
    e = hidden.e0 * 2.0 ** (-ticks / 4)
    return Result(hidden.x * (1.0 + side * e), 1.0 - e)


@contract("guess", inputs=[], step=0)
def guess(ctx: Context, hidden: Hidden) -> Result:
    """x, off by e0 2^(-t/4) of it, on the problem's side."""
    return _guess(ctx, hidden, hidden.side)


@contract("guess-low", inputs=[], step=0)
def guess_low(ctx: Context, hidden: Hidden) -> Result:
    """As `guess`, but always below x."""
    return _guess(ctx, hidden, -1)


@interruptible("polish", inputs=["rough"], step=1)
def polish(ctx: Context, rough: Result, hidden: Hidden) -> Iterator[Result]:
    """A descent from above: each tick quarters the error of an estimate above x; one below x
    stays as it is. A result after every tick."""
    value = float(rough.value)
    while True:
        ctx.tick()
        if value > hidden.x:
            value = hidden.x + (value - hidden.x) / 4
        yield Result(value, quality(value, hidden.x))


@contract("overrun", inputs=[], step=0)
def overrun(ctx: Context, hidden: Hidden) -> Result:
    """The exact answer, one tick past its allocation (its declared step says it stops in
    time: it does not)."""
    ctx.tick(ctx.allocation + 1)
    return Result(hidden.x, 1.0)


# --- problem sets -------------------------------------------------------------------------------


def hidden(rng: np.random.Generator) -> Hidden:
    x = float(rng.uniform(10, 100))
    e0 = float(rng.uniform(0.2, 0.6))
    side = 1 if rng.random() < 0.5 else -1
    return Hidden(x, e0, side)


class Guesses:
    """For `guess`: a hidden number."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        problem = hidden(rng)
        return Instance((problem,), problem.x)

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class Roughs:
    """For `polish`: an estimate of the quality asked for, above or below x with equal
    chance."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (q,) = input_qualities
        problem = hidden(rng)
        rough = Result(problem.x * (1.0 + problem.side * (1.0 - q)), q)
        return Instance((rough, problem), problem.x)

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class HiddenNumbers:
    """For the programs: a hidden number, scored against it."""

    def instance(self, rng: np.random.Generator) -> Instance:
        problem = hidden(rng)
        return Instance((problem,), problem.x)

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class Unscored:
    """For the programs, without a score: a run counts the quality its result reports."""

    def instance(self, rng: np.random.Generator) -> Instance:
        return Instance((hidden(rng),))


# --- the measured modules, the library, the plugin ---------------------------------------------


@functools.cache
def modules() -> tuple[AnytimeModule, ...]:
    """The modules with their profiles (measured once per process)."""
    measured_guess = build_profile(
        guess, Guesses(), time=GUESS_TIME, trials=TRIALS, seed=1, mode=SOFT
    ).profile
    measured_polish = build_profile(
        polish,
        Roughs(),
        time=POLISH_TIME,
        input_grids=[POLISH_QUALITIES],
        trials=TRIALS,
        seed=2,
        mode=SOFT,
    ).profile
    exact = tabulate(lambda t: np.ones_like(t), GUESS_TIME, kind="contract", module="overrun")
    return (
        attrs.evolve(guess, profile_source=measured_guess),
        attrs.evolve(guess_low, profile_source=attrs.evolve(measured_guess, module="guess-low")),
        attrs.evolve(polish, profile_source=measured_polish),
        attrs.evolve(overrun, profile_source=exact),
    )


def library() -> AnytimeLibrary:
    lab = AnytimeLibrary()
    for module in modules():
        lab.add(LibraryEntry.of_module(module))
    return lab


def plugin() -> Plugin:
    """The plugin, as an entry point names it (`verify_modules:plugin`)."""
    problems = ProgramProblems.of(HiddenNumbers(), time_grid=TOTALS, resolution=RESOLUTION)
    return Plugin(
        name="lab",
        modules=modules(),
        program_problems={"fair": problems, "low": problems, "over": problems},
    )


def schemas() -> Any:
    return parse_schemas(SCHEMAS, "lab.any", library().known_functions())
