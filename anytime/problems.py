"""The problems a plugin declares, what the measuring layer runs modules and programs on.

This module is data and protocols only (it runs nothing): the library holds these
declarations, `anytime.measure` runs on them, so both import it and it imports neither.

A module's problem set (`ProblemSet`) makes a problem (`Instance`) whose inputs have the
qualities it is asked for, because the profile builder measures a module at every point of a
grid of input qualities (`Grid`); `Measurement.of(problems, time=...)` is how `anytime profile`
measures one module, declared in `Plugin.problem_sets` (or with `register_problems` for
interactive use).

Program-level problem sets say, for one of a plugin's schemas, what problems the compiled
program is promised for, so that `anytime verify` can check the promise. A program is run as a
whole, on the problems it meets: its problem set draws them, inputs and their qualities
together, and may say how to score its result.

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
Problem sets travel to worker processes with the module or the program, so they should pickle
(a top-level class instance).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np
from attrs import cmp_using, field, frozen
from numpy.typing import ArrayLike

from anytime.errors import AnytimeError
from anytime.modules import AnytimeModule
from anytime.profiles.profile import Array, default_bins
from anytime.text import did_you_mean

__all__ = [
    "BuildError",
    "Grid",
    "Instance",
    "Measurement",
    "ProblemSet",
    "ProgramProblemSet",
    "ProgramProblems",
    "ScoredProgramProblemSet",
    "register_problems",
    "registered_measurements",
    "registered_problems",
]


class BuildError(AnytimeError, ValueError):
    """A profile cannot be built as asked: bad grids, a problem set that breaks its contract."""


def _as_tuple(values: Sequence[Any]) -> tuple[Any, ...]:
    return tuple(values)


@frozen
class Instance:
    """One problem: the module's arguments after the context, and what the scorer needs.

    A quality-carrying argument may be a `Result` (whose quality must be the one asked for) or a
    plain value, which the builder wraps as `Result(value, asked quality)`.

    Attributes:
        args: the positional arguments after `ctx`, in the module's parameter order.
        reference: anything `ProblemSet.score` compares an output against (an optimal answer).
    """

    args: tuple[Any, ...] = field(converter=_as_tuple)
    reference: Any = None


class ProblemSet(Protocol):
    """What a domain supplies to measure a module. It must pickle (a top-level class instance)
    to reach worker processes, and should be small: instances are made on the workers."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        """A random problem whose quality-carrying inputs have `input_qualities` (axis order)."""
        ...

    def score(self, instance: Instance, value: Any) -> float:
        """The true quality in [0, 1] of the output `value` on `instance`."""
        ...


def _array(value: ArrayLike) -> Array:
    array = np.array(value, dtype=np.float64)
    array.setflags(write=False)
    return array


def _arrays(value: Sequence[ArrayLike]) -> tuple[Array, ...]:
    return tuple(_array(grid) for grid in value)


def _grids_equal(a: tuple[Array, ...], b: tuple[Array, ...]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


@frozen
class Grid:
    """The grids a profile is measured on.

    Attributes:
        time: increasing time allocations (ticks for the work clock, seconds for the wall clock).
        input_grids: one increasing grid of qualities per quality-carrying input.
        bins: K+1 edges of the quality histogram (default: 10 equal bins).
    """

    time: Array = field(converter=_array, eq=cmp_using(eq=np.array_equal), hash=False)
    input_grids: tuple[Array, ...] = field(
        default=(), converter=_arrays, eq=cmp_using(eq=_grids_equal), hash=False
    )
    bins: Array = field(
        factory=default_bins, converter=_array, eq=cmp_using(eq=np.array_equal), hash=False
    )

    @property
    def cell_shape(self) -> tuple[int, ...]:
        """The input-quality cells (no time axis)."""
        return tuple(len(grid) for grid in self.input_grids)


@frozen
class Measurement:
    """How `anytime profile` measures one module: its problem set and grid."""

    problems: ProblemSet
    grid: Grid

    @classmethod
    def of(
        cls,
        problems: ProblemSet,
        *,
        time: ArrayLike,
        input_grids: Sequence[ArrayLike] = (),
        bins: ArrayLike | None = None,
    ) -> Measurement:
        """Measure on `problems` at run times `time`, input qualities `input_grids` (one grid
        per input), into quality `bins` (default: ten equal bins)."""
        return cls(problems, Grid(time, input_grids, default_bins() if bins is None else bins))


_MEASUREMENTS: dict[str, Measurement] = {}


def register_problems(
    module: str | AnytimeModule,
    problems: ProblemSet,
    *,
    time: ArrayLike,
    input_grids: Sequence[ArrayLike] = (),
    bins: ArrayLike | None = None,
) -> Measurement:
    """Declare, for interactive use, how `anytime profile MODULE` measures `module` (a plugin
    gives a `Measurement.of(...)` per module in its `Plugin.problem_sets` instead). Registering
    a name again replaces the earlier declaration."""
    name = (module.name if isinstance(module, AnytimeModule) else module).lower()
    measurement = Measurement.of(problems, time=time, input_grids=input_grids, bins=bins)
    _MEASUREMENTS[name] = measurement
    return measurement


def registered_measurements() -> dict[str, Measurement]:
    """Module name -> the measurement declared with `register_problems` (a copy)."""
    return dict(_MEASUREMENTS)


def registered_problems(
    name: str, measurements: Mapping[str, Measurement] | None = None
) -> Measurement:
    """The measurement of module `name` in `measurements` (default: those registered with
    `register_problems`); an error lists the known ones."""
    source = _MEASUREMENTS if measurements is None else measurements
    found = source.get(name.lower())
    if found is not None:
        return found
    known = sorted(source)
    hint = did_you_mean(name.lower(), known)
    listed = ", ".join(known) if known else "none"
    raise BuildError(
        f"no problem set is registered for module '{name}' (registered: {listed}){hint}"
    )


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
