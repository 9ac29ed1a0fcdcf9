"""A compile result: `CompiledProgram`, a contract algorithm and its profile, with what the
compilation found as fields, and its notes as codes (`anytime.compiler.outcomes`)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np
from attrs import frozen

from anytime.compiler import evaluate
from anytime.compiler.model import CompileError, CompileModel
from anytime.compiler.outcomes import Code, Note
from anytime.profiles.profile import Array, ConditionalPerformanceProfile


@frozen(eq=False)
class CompiledProgram:
    """A compiled schema: a contract algorithm and its profile.

    Attributes:
        name: the schema's name.
        model: the program resolved against the library.
        profile: the compiled conditional performance profile (kind contract): one input axis
            per quality-carrying program input, on `input_quality`, and the time grid.
        allocation: time per anytime module, shape (*input grids, time, n), in the time unit.
        allocator: the allocator that filled the table.
        requested: the allocator asked for ("auto" by default).
        dp_obstacle: why dp would not be exact for this program (None when it is), a `Note`
            (its code one of `DAG`, `IF_MIXTURE`, `UNKNOWN_MONOTONICITY`,
            `CALLEE_READS_RESULT`, `STOCHASTIC`, `NOT_INPUT_MONOTONE`).
        baselines: expected quality of the equal, MIN and MAX allocations, each shaped like
            `profile.mean`.
        exhaustive_gap: the largest amount by which the exhaustive optimum beats the table
            (None when the exhaustive search was not computable).
        standard_error: the standard error of each cell's expected quality, shaped like
            `profile.mean`: 0 where it is exact under the profiles' model (every cell, unless
            the joint outcomes of a DAG's shared results were too many to enumerate and were
            sampled there; see `anytime.compiler.evaluate`). None: every cell exact.
        kept_smaller: the totals of the time grid at which a smaller total's allocation does
            better and is kept, the rest of the time left unused (for some input quality).
        warnings: what the table cannot vouch for, one `Note` each: a module fed input
            qualities outside the grid its profile was measured on (`OUTSIDE_INPUT_GRID`: its
            profile is clamped there, and the allocator may exploit it).
        dependence: for a program with a best-of (itself or in what it calls), shape
            (2, *cells): the expected quality at the table's allocation if the alternatives
            of its best-ofs depended on each other as unfavourably, then as favourably, as
            their profiles allow (`anytime.compiler.evaluate`, "Dependent alternatives").
            The table takes them independent given their inputs' qualities, which a problem
            hard for every alternative breaks: what a run delivers lies between the two
            where the later modules are monotone in their inputs. None: no best-of.

    `exact` (under the profiles' model), `notes` and `note` are made from these fields.
    """

    name: str
    model: CompileModel
    profile: ConditionalPerformanceProfile
    allocation: Array
    allocator: str
    baselines: dict[str, Array]
    exhaustive_gap: float | None
    resolution: float
    requested: str = "auto"
    dp_obstacle: Note | None = None
    standard_error: Array | None = None
    kept_smaller: tuple[float, ...] = ()
    warnings: tuple[Note, ...] = ()
    dependence: Array | None = None

    @property
    def exact(self) -> bool:
        """Whether the table is the optimum of the program on its time lattice: found by an
        exact search (dp where dp is exact, or exhaustive) and evaluated without
        approximation."""
        optimal = self.allocator == "exhaustive" or (
            self.allocator == "dp" and self.dp_obstacle is None
        )
        return optimal and not self.approximations

    @property
    def exact_cells(self) -> np.ndarray:
        """Per cell of the table, whether its expected quality is exact (not sampled)."""
        if self.standard_error is None:
            return np.ones(self.expected.shape, dtype=bool)
        return np.asarray(self.standard_error == 0)

    @property
    def approximations(self) -> tuple[Note, ...]:
        """What the table's expectations approximate (`SAMPLED`), from the fields."""
        sampled = ~self.exact_cells
        if not sampled.any():
            return ()
        assert self.standard_error is not None
        return (
            Note.of(
                Code.SAMPLED,
                draws=evaluate.SAMPLES,
                sampled=int(sampled.sum()),
                cells=int(sampled.size),
                error=float(self.standard_error.max()),
            ),
        )

    @property
    def allocator_note(self) -> Note:
        """Which allocator filled the table and why, from the fields."""
        obstacle, chosen = self.dp_obstacle, self.allocator
        if self.requested == "auto" and obstacle is not None:
            return Note.of(Code.AUTO_FALLBACK, allocator=chosen, obstacle=obstacle)
        if self.requested == "dp" and obstacle is not None:
            return Note.of(Code.DP_FALLBACK, obstacle=obstacle)
        return Note.of(ALLOCATOR_CODES[chosen])

    @property
    def notes(self) -> tuple[Note, ...]:
        """How the allocator was chosen, what is approximate and where time is left unused."""
        kept: tuple[Note, ...] = ()
        if self.kept_smaller:
            kept = (Note.of(Code.KEPT_SMALLER, totals=len(self.kept_smaller)),)
        return (self.allocator_note, *self.approximations, *self.dependence_notes, *kept)

    @property
    def dependence_notes(self) -> tuple[Note, ...]:
        """How far a dependence between a best-of's alternatives could move the table."""
        if self.dependence is None:
            return ()
        below = float(np.max(self.expected - self.dependence[0], initial=0.0))
        above = float(np.max(self.dependence[1] - self.expected, initial=0.0))
        return (Note.of(Code.DEPENDENCE, below=below, above=above),)

    @property
    def codes(self) -> tuple[Code, ...]:
        """The codes of the notes (what `note` says; the warnings have their own)."""
        return tuple(note.code for note in self.notes)

    @property
    def note(self) -> str:
        """The notes as every report says them, one sentence each."""
        return "; ".join(note.message for note in self.notes)

    @property
    def modules(self) -> tuple[str, ...]:
        return self.model.module_names

    @property
    def expected(self) -> Array:
        assert self.profile.mean is not None
        return self.profile.mean

    def allocation_at(self, quality: Sequence[float], total: float) -> Array:
        """The allocation for program input qualities `quality` and total time `total`: the
        table interpolated like the profile, exactly the table's split at grid totals.

        It is never rescaled: where the compiler kept a smaller total's split (more time would
        not have helped), spending the rest would run the split it rejected. Between grid
        totals the split is the interpolation of its neighbours', which spends no more than
        `total` (each neighbour spends no more than its own); beyond the grid, the largest
        total's split, with a `BeyondTableWarning` (compile a larger time grid to use the rest).

        Raises:
            CompileError: not one quality in [0, 1] per quality-carrying program input, or a
                total that is not a number >= 0.
        """
        inputs = len(self.profile.input_grids)
        try:
            q = np.asarray(quality, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise CompileError(
                f"{self.name}: allocation_at: expected {inputs} input qualit"
                f"{'y' if inputs == 1 else 'ies'}, got {quality!r}"
            ) from None
        if len(q) != inputs or not np.all((q >= 0) & (q <= 1)):  # NaN fails too
            raise CompileError(
                f"{self.name}: allocation_at: expected {inputs} input qualit"
                f"{'y' if inputs == 1 else 'ies'} in [0, 1] (one per quality-carrying input),"
                f" got {[float(x) for x in q]}"
            )
        try:
            t = float(total)
        except (TypeError, ValueError):
            t = math.nan
        if not (t >= 0 and math.isfinite(t)):
            raise CompileError(
                f"{self.name}: allocation_at: expected a total time >= 0, got {total!r}"
            )
        largest = float(self.profile.time[-1])
        if t > largest * (1 + 1e-12):
            warnings.warn(
                f"{self.name}: a total of {t:g} is beyond the compiled table's largest,"
                f" {largest:g}: its split is used and the rest left unused (compile with a"
                " time grid up to the total to use it)",
                BeyondTableWarning,
                stacklevel=2,
            )
        return self.profile.interpolate(self.allocation, q, np.float64(t))


class BeyondTableWarning(UserWarning):
    """A compiled program was asked for a total beyond its table: the largest total's split
    is used."""


#: The note of each allocator where it was asked for (or chosen by "auto" where dp is exact).
ALLOCATOR_CODES = {
    "dp": Code.DP_EXACT,
    "hill-climbing": Code.HILL_CLIMBING,
    "multi-start": Code.MULTI_START,
    "exhaustive": Code.EXHAUSTIVE,
    "proportional": Code.PROPORTIONAL,
}
