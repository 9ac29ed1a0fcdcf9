"""Program-level problem sets: how a plugin says, for one of its schemas, what problems the
compiled program is promised for, so that `anytime verify` can check the promise.

A module's problem set (`anytime.measure.trials.ProblemSet`) makes a problem whose inputs have
the qualities it is asked for, because the profile builder measures a module at every point of
a grid of input qualities. A program is run as a whole, on the problems it meets: its problem
set draws them, inputs and their qualities together, and may say how to score its result.

- `instance(rng)` draws one problem: an `Instance` whose `args` are the program's inputs in
  the schema's order (a quality-carrying input as a `Result` of its quality; a plain value
  has quality 1, as `run_program` reads it) and whose `reference` is whatever `score` needs.
- `score(instance, value)`, optional: the true quality in [0, 1] of the program's result
  `value` on the problem (None when the program had no result). Without it, a run's realised
  quality is the quality its result reports (0 without a result): right only for programs
  whose output module reports its true quality.

A plugin lists them in `Plugin.program_problems`, by schema name, each as
`ProgramProblems.of(problems, time_grid=..., resolution=...)`; the time grid and resolution,
when given, are the compilation the promise is meant for (`anytime verify`'s defaults).
Problem sets travel to worker processes with the program, so they should pickle (a top-level
class instance).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from attrs import field, frozen

from anytime.measure.trials import Instance

__all__ = ["ProgramProblemSet", "ProgramProblems", "ScoredProgramProblemSet"]


class ProgramProblemSet(Protocol):
    """Draws problems for a program (see the module's docstring)."""

    def instance(self, rng: np.random.Generator) -> Instance:
        """A random problem: the program's inputs (`args`, in the schema's order) and what
        `score` compares a result against (`reference`)."""
        ...


class ScoredProgramProblemSet(ProgramProblemSet, Protocol):
    """A program problem set that also scores the program's result."""

    def score(self, instance: Instance, value: Any) -> float:
        """The true quality in [0, 1] of the result `value` (None: no result) on `instance`."""
        ...


def _grid(values: Sequence[float] | None) -> tuple[float, ...] | None:
    if values is None:
        return None
    grid = tuple(float(v) for v in values)
    if not grid or not all(math.isfinite(v) and v >= 0 for v in grid):
        raise ValueError(f"time_grid: expected finite totals >= 0, got {list(values)!r}")
    if any(b <= a for a, b in zip(grid, grid[1:], strict=False)):
        raise ValueError(f"time_grid: expected increasing totals, got {list(values)!r}")
    return grid


def _resolution(value: float | None) -> float | None:
    if value is None:
        return None
    resolution = float(value)
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution: expected a finite number > 0, got {value!r}")
    return resolution


def _check_problems(_: Any, attribute: Any, value: Any) -> None:
    if not callable(getattr(value, "instance", None)):
        raise TypeError(
            f"ProgramProblems.problems: expected a problem set with an instance(rng) method,"
            f" got {type(value).__name__}"
        )


@frozen
class ProgramProblems:
    """How `anytime verify` checks one schema's promise: the problems to run it on.

    Attributes:
        problems: draws a problem (`instance(rng)`) and, optionally, scores the program's
            result (`score(instance, value)`).
        time_grid: the totals the promise is meant for (None: as `anytime compile` chooses).
        resolution: the allocation lattice the promise is meant for (None: as compile does).
    """

    problems: ProgramProblemSet = field(validator=_check_problems)
    time_grid: tuple[float, ...] | None = field(default=None, converter=_grid)
    resolution: float | None = field(default=None, converter=_resolution)

    @classmethod
    def of(
        cls,
        problems: ProgramProblemSet,
        *,
        time_grid: Sequence[float] | None = None,
        resolution: float | None = None,
    ) -> ProgramProblems:
        """Run the program on problems drawn by `problems`, compiled on `time_grid` (its
        totals) with allocations on multiples of `resolution`, when given."""
        return cls(problems, time_grid, resolution)

    @property
    def name(self) -> str:
        """The problem set's class name, for messages."""
        return type(self.problems).__qualname__

    @property
    def scored(self) -> bool:
        """Whether the problem set scores results (else a run counts its result's quality)."""
        return callable(getattr(self.problems, "score", None))
