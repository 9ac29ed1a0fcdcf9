"""Toy modules for the tests of `best-of` and `if`, shared by the compiler's and the runtime's
tests: two contract modules with known stochastic profiles (`steady` and `gamble`, returning
the quality given to `library`), preconditions, conditions with and without a declared
probability, and an interruptible module that must not serve as a precondition."""

from __future__ import annotations

from typing import Any

import numpy as np

from anytime.compiler import CompiledProgram, compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary, RegistrySource
from anytime.modules import Context, Registry, Result, contract, elementary, interruptible
from anytime.profiles import new_profile
from anytime.profiles.profile import ConditionalPerformanceProfile

TIME = np.arange(0, 11, dtype=np.float64)  # the lattice: dt = 1
BINS = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
MID = (BINS[1:] + BINS[:-1]) / 2


def steady() -> ConditionalPerformanceProfile:
    """A reliable module: its mass moves steadily from the lowest bin to the highest."""
    x = np.minimum(TIME / 10, 1)[:, None]
    probability = np.hstack([(1 - x) ** 2, 2 * x * (1 - x) * 0.5, 2 * x * (1 - x) * 0.5, x**2])
    return new_profile(
        input_grids=[], time=TIME, bins=BINS, probability=probability, kind="contract"
    )


def gamble() -> ConditionalPerformanceProfile:
    """A risky module: after 2 units it is excellent or useless, half and half."""
    probability = np.where((TIME >= 2)[:, None], [0.5, 0.0, 0.0, 0.5], [1.0, 0.0, 0.0, 0.0])
    return new_profile(
        input_grids=[], time=TIME, bins=BINS, probability=probability, kind="contract"
    )


def library(**qualities: float) -> AnytimeLibrary:
    registry = Registry()
    for name, profile in (("steady", steady()), ("gamble", gamble())):

        def run(ctx: Context, name: str = name) -> Result:
            ctx.tick(ctx.allocation)
            return Result((name, ctx.allocation), qualities.get(name, 0.5))

        run.__name__ = run.__qualname__ = name
        contract(name, inputs=[], profile=profile, registry=registry)(run)

    @elementary("left-clear?", inputs=[], registry=registry)
    def left_clear(w: Any) -> bool:
        return "left" in w

    @elementary("right-clear?", inputs=[], registry=registry)
    def right_clear(w: Any) -> bool:
        return "right" in w

    @elementary("sunny?", inputs=[], registry=registry, probability=0.7)
    def sunny(w: Any) -> bool:
        return "sun" in w

    @elementary("cloudy?", inputs=[], registry=registry)
    def cloudy(w: Any) -> bool:
        return "cloud" in w

    @interruptible(
        "slow-test",
        inputs=[],
        profile=steady().__class__(
            input_grids=[], time=TIME, bins=BINS, probability=steady().probability
        ),
        registry=registry,
    )
    def slow_test(ctx: Context, w: Any) -> Any:
        yield Result(True, 1.0)

    return AnytimeLibrary([RegistrySource(registry)])


BEST_OF = """(defschema choose (w)
  (best-of (when (left-clear? w) (steady))
           (when (right-clear? w) (gamble))))"""


def compiled(text: str, lib: AnytimeLibrary | None = None, **options: Any) -> CompiledProgram:
    schemas = parse_schemas(text)
    return compile_program(
        schemas.programs[0], lib or library(), TIME, source=schemas.source, **options
    )
