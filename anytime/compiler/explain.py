"""Allocations that explain themselves: why the compiled split of a total, and not another.

At a total T of the table, the compiled allocation gives each module a share. For each module,
`explain` evaluates the program with one more lattice unit of time given to it (the total
T + dt) and with one unit taken from it (T - dt): the marginal expected quality of its time,
the discrete derivative that marginal analysis of an optimal split compares (at an optimum
on the lattice, no unit moved from one module to another raises the expectation: what one
module would gain is at most what the other loses). It also evaluates every such move and
reports the best, which is not positive where the split is optimal among its neighbours.
A module whose share already covers its profile's longest measured time is at its profile's
ceiling: its profile says nothing of more time (it is clamped there), so more gains nothing.

Every allocation is evaluated in one batch by the compiled program's `Evaluator`, as the
compiler evaluated the table.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.compiler.evaluate import Evaluator
from anytime.compiler.model import CompileError, ModuleNode
from anytime.compiler.outcomes import Code, Note
from anytime.compiler.result import CompiledProgram

#: A marginal change smaller than this is zero (the evaluator's rounding).
TOLERANCE = 1e-9


@frozen
class ModuleMargin:
    """One module's share of a total and the marginal value of its time.

    Attributes:
        module: the module (the allocation vector's name for it).
        share: its time, in the program's time unit.
        gain: expected quality of the program with one more lattice unit given to this module
            (total T + dt), less the expected quality of the split.
        loss: expected quality of the split less that with one unit taken from this module
            (total T - dt); None when its share is less than a unit.
        at_ceiling: whether its share covers its profile's longest measured time (less the
            module's step): its profile is clamped beyond, so more time gains nothing.
    """

    module: str
    share: float
    gain: float
    loss: float | None
    at_ceiling: bool

    @property
    def code(self) -> Code | None:
        """What a reader should know of this module's margin (`AT_CEILING`, `ZERO_MARGINAL`,
        `MORE_TIME_LOWERS`), or None."""
        if self.at_ceiling:
            return Code.AT_CEILING
        if abs(self.gain) <= TOLERANCE:
            return Code.ZERO_MARGINAL
        if self.gain < 0:
            return Code.MORE_TIME_LOWERS
        return None

    @property
    def note(self) -> str:
        """The code's sentence, or ''."""
        return "" if self.code is None else Note.of(self.code).message


@frozen
class Move:
    """One lattice unit moved from one module to another, and the change it makes to the
    expected quality (<= 0 where the split is optimal among its neighbours)."""

    source: str
    target: str
    change: float


@frozen
class Explanation:
    """Why the compiled split of `total` is what it is.

    Attributes:
        total: the total time (a total of the table's time grid).
        input_quality: the program input qualities it is explained at (one per quality input).
        unit: the lattice unit dt, the compile result's resolution.
        expected: the expected output quality of the split.
        modules: each module's share and margins, in allocation-vector order.
        best_move: the move of one unit between two modules that raises the expectation most
            (or lowers it least); None with fewer than two modules or no time to move.
    """

    total: float
    input_quality: tuple[float, ...]
    unit: float
    expected: float
    modules: tuple[ModuleMargin, ...]
    best_move: Move | None

    @property
    def unused(self) -> float:
        """The time the split leaves unused: where a smaller total's split does better (the
        compile result's `kept_smaller`), more of the time would lower the expectation."""
        return max(self.total - sum(m.share for m in self.modules), 0.0)


def default_totals(compiled: CompiledProgram) -> tuple[float, ...]:
    """A few totals of the table's grid: a quarter, half and all of the way up (0 left out)."""
    time = compiled.profile.time
    picked = np.unique(np.rint((len(time) - 1) * np.array([0.25, 0.5, 1.0])).astype(int))
    return tuple(float(time[j]) for j in picked if time[j] > 0) or (float(time[-1]),)


def explain(
    compiled: CompiledProgram,
    totals: Sequence[float] | None = None,
    input_quality: ArrayLike | None = None,
) -> tuple[Explanation, ...]:
    """The split of each total and the marginal expected quality of each module's time.

    Args:
        totals: totals of the table's time grid (default: `default_totals`).
        input_quality: one quality of the table's grid per quality-carrying program input
            (default: the highest of the grid for each, as `format_report` shows the table).

    Raises:
        CompileError: a total not on the table's time grid, or input qualities that are not
            one per quality input, each on the table's grid.
    """
    time = compiled.profile.time
    wanted = default_totals(compiled) if totals is None else tuple(float(t) for t in totals)
    columns = [_grid_index(time, t, compiled.profile.time_unit) for t in wanted]
    cell, quality = _cell(compiled, input_quality)
    n, dt = len(compiled.modules), compiled.resolution
    splits = compiled.allocation[cell][columns]  # (totals, n), on the lattice
    unit = np.eye(n) * dt
    # Per total, the rows: the split, +dt to each module, -dt from each, and every move i -> j.
    sources, targets = np.nonzero(~np.eye(n, dtype=bool))
    steps = np.concatenate([np.zeros((1, n)), unit, -unit, unit[targets] - unit[sources]])
    rows = splits[:, None, :] + steps[None, :, :]  # (totals, 1 + 2n + n(n-1), n)
    valid = np.all(rows >= -1e-9 * max(dt, 1.0), axis=-1)
    evaluator = Evaluator(compiled.model)
    flat = np.maximum(rows.reshape(-1, n), 0.0)
    values = evaluator.expected(np.broadcast_to(quality, (len(flat), len(quality))), flat)
    values = np.where(valid.reshape(-1), values, np.nan).reshape(rows.shape[:2])
    base = values[:, :1]
    gains, losses = values[:, 1 : 1 + n] - base, base - values[:, 1 + n : 1 + 2 * n]
    moves = values[:, 1 + 2 * n :] - base
    ceilings = _ceilings(compiled)
    return tuple(
        Explanation(
            total=wanted[k],
            input_quality=tuple(float(q) for q in quality),
            unit=dt,
            expected=float(base[k, 0]),
            modules=tuple(
                ModuleMargin(
                    module=compiled.modules[i],
                    share=float(splits[k, i]),
                    gain=float(gains[k, i]),
                    loss=None if np.isnan(losses[k, i]) else float(losses[k, i]),
                    at_ceiling=bool(splits[k, i] >= ceilings[i] - 1e-9),
                )
                for i in range(n)
            ),
            best_move=_best_move(compiled.modules, sources, targets, moves[k]),
        )
        for k in range(len(wanted))
    )


def _grid_index(time: np.ndarray[Any, Any], total: float, unit: str) -> int:
    hit = np.flatnonzero(np.isclose(time, total, rtol=0, atol=1e-9 * max(1.0, abs(total))))
    if not len(hit):
        grid = ", ".join(f"{t:g}" for t in time[:6]) + (", ..." if len(time) > 6 else "")
        raise CompileError(
            f"explain: expected a total of the table's time grid ({grid} {unit};"
            f" {len(time)} totals up to {time[-1]:g}), got {total:g}"
        )
    return int(hit[0])


def _cell(
    compiled: CompiledProgram, input_quality: ArrayLike | None
) -> tuple[tuple[int, ...], np.ndarray[Any, Any]]:
    """The table's input-quality cell and its qualities: the highest of every grid by default,
    else the given qualities, each of which must be on its input's grid."""
    grids = compiled.profile.input_grids
    if input_quality is None:
        return tuple(len(grid) - 1 for grid in grids), np.array([g[-1] for g in grids])
    quality = np.atleast_1d(np.asarray(input_quality, dtype=np.float64))
    if not grids and quality.size:
        raise CompileError(
            f"explain: '{compiled.name}' has no quality input: expected no input qualities,"
            f" got {quality.tolist()}"
        )
    hits = [
        np.flatnonzero(np.isclose(grid, q, rtol=0, atol=1e-9))
        for grid, q in zip(grids, quality, strict=False)
    ]
    if quality.shape != (len(grids),) or not all(len(hit) for hit in hits):
        grid = ", ".join(f"{q:g}" for q in grids[0]) if grids else "none"
        raise CompileError(
            f"explain: expected {len(grids)} input qualities of the table's grid ({grid}),"
            f" one per quality input of '{compiled.name}', got {quality.tolist()}"
        )
    return tuple(int(hit[0]) for hit in hits), np.array(
        [g[hit[0]] for g, hit in zip(grids, hits, strict=True)]
    )


def _ceilings(compiled: CompiledProgram) -> np.ndarray[Any, Any]:
    """The share from which each module's profile is clamped: its longest measured time,
    plus the step a module reserves out of its share."""
    return np.array(
        [
            float(node.profile.time[-1]) + (node.step if isinstance(node, ModuleNode) else 0.0)
            for node in compiled.model.anytime_nodes
        ]
    )


def _best_move(
    modules: Sequence[str],
    sources: np.ndarray[Any, Any],
    targets: np.ndarray[Any, Any],
    changes: np.ndarray[Any, Any],
) -> Move | None:
    if not len(changes) or np.all(np.isnan(changes)):
        return None
    best = int(np.nanargmax(changes))
    return Move(modules[sources[best]], modules[targets[best]], float(changes[best]))


# --- reports -----------------------------------------------------------------------------------


def explanation_to_dict(explanation: Explanation) -> dict[str, Any]:
    """An explanation as JSON-ready data (the `explain` list of `anytime compile --json`)."""
    move = explanation.best_move
    return {
        "total": explanation.total,
        "input_quality": list(explanation.input_quality),
        "unit": explanation.unit,
        "expected_quality": explanation.expected,
        "unused": explanation.unused,
        "modules": [
            {
                "module": m.module,
                "share": m.share,
                "gain": m.gain,
                "loss": m.loss,
                "at_ceiling": m.at_ceiling,
                "note": m.note,
            }
            for m in explanation.modules
        ],
        "best_move": None
        if move is None
        else {"from": move.source, "to": move.target, "change": move.change},
    }


def format_explanations(compiled: CompiledProgram, explanations: Sequence[Explanation]) -> str:
    """The explanations as text: per total, each module's share, gain and loss."""
    unit = compiled.profile.time_unit
    lines = [f"schema {compiled.name}: why these splits"]
    if explanations:
        first = explanations[0]
        lines[0] += f" (one unit = {first.unit:g} {unit}"
        if first.input_quality:
            qualities = ", ".join(f"{q:g}" for q in first.input_quality)
            lines[0] += (
                f"; at input quality {qualities} of {', '.join(compiled.model.quality_inputs)}"
            )
        lines[0] += ")"
    lines.append(
        "  the change in expected quality with one unit more (+1) or less (-1) for a module"
    )
    for e in explanations:
        lines.append(f"  T = {e.total:g} {unit}: expected quality {e.expected:.5f}")
        if e.unused > 1e-9 * max(1.0, e.total):
            lines[-1] += f" ({e.unused:g} {unit} unused: a smaller total's split does better)"
        table = [["module", "share", "+1 unit", "-1 unit", ""]]
        for m in e.modules:
            less = "-" if m.loss is None else f"{-m.loss:+.5f}"
            table.append([m.module, f"{m.share:g}", f"{m.gain:+.5f}", less, m.note])
        widths = [max(len(row[i]) for row in table) for i in range(5)]
        for row in table:
            numbers = (c.rjust(w) for c, w in zip(row[1:4], widths[1:4], strict=True))
            lines.append(("    " + "  ".join([row[0].ljust(widths[0]), *numbers, row[4]])).rstrip())
        if e.best_move is not None:
            move = e.best_move
            verdict = (
                "no move of one unit gains"
                if move.change <= TOLERANCE
                else "a move gains: the split is not optimal among its neighbours"
            )
            lines.append(
                f"    best move of one unit: {move.source} -> {move.target},"
                f" {move.change:+.5f} ({verdict})"
            )
    return "\n".join(lines) + "\n"
