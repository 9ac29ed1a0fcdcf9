"""What a compilation reports: the JSON of `anytime compile --json` and a table for people."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from anytime.compiler.result import CompiledProgram

MAX_ROWS = 25  # rows of the human table by default; a longer time grid is thinned to fit


def allocation_json(modules: Sequence[str], shares: Sequence[float]) -> dict[str, float]:
    """An allocation as `--json` prints it everywhere: `{module: time}`, in the program's
    order. A module called more than once gets its occurrence as a suffix (`find-path#1`,
    `find-path#2`), so no share is lost to a repeated key."""
    if len(modules) != len(shares):
        raise ValueError(f"{len(modules)} modules but {len(shares)} shares")
    repeated = {name for name in modules if modules.count(name) > 1}
    seen: dict[str, int] = {}
    data: dict[str, float] = {}
    for name, share in zip(modules, shares, strict=True):
        if name in repeated:
            seen[name] = seen.get(name, 0) + 1
            name = f"{name}#{seen[name]}"
        data[name] = float(share)
    return data


def compiled_to_dict(compiled: CompiledProgram) -> dict[str, Any]:
    """The report as JSON-ready data, as `anytime compile --json` prints it (docs/cli.md, "JSON
    output"): the table as one row per input quality and budget (`budgets`), each with its
    allocation as `{module: time}`."""
    profile = compiled.profile
    grids = [grid.tolist() for grid in profile.input_grids]
    expected = compiled.expected
    error = compiled.standard_error
    bounds = compiled.dependence
    rows = []
    for cell in np.ndindex(*(len(grid) for grid in grids)):
        for j, budget in enumerate(profile.time.tolist()):
            at = (*cell, j)
            rows.append(
                {
                    "budget": budget,
                    "input_quality": [grid[i] for grid, i in zip(grids, cell, strict=True)],
                    "expected_quality": float(expected[at]),
                    "expected_quality_se": 0.0 if error is None else float(error[at]),
                    "allocation": allocation_json(
                        compiled.modules, compiled.allocation[at].tolist()
                    ),
                    "baselines": {
                        name: float(value[at]) for name, value in compiled.baselines.items()
                    },
                    "expected_quality_if_dependent": (
                        None
                        if bounds is None
                        else [float(bounds[(0, *at)]), float(bounds[(1, *at)])]
                    ),
                }
            )
    report: dict[str, Any] = {
        "schema": compiled.name,
        "allocator": compiled.allocator,
        "modules": list(allocation_json(compiled.modules, [0.0] * len(compiled.modules))),
        "inputs": list(compiled.model.quality_inputs),
        "time_unit": profile.time_unit,
        "time_grid": profile.time.tolist(),
        "input_grids": grids,
        "budgets": rows,
        "exhaustive_gap": compiled.exhaustive_gap,
        "exact": compiled.exact,
        "dp_obstacle": None if compiled.dp_obstacle is None else compiled.dp_obstacle.message,
        "approximations": [note.message for note in compiled.approximations],
        "kept_smaller": list(compiled.kept_smaller),
        "method_note": compiled.note,
        "warnings": [warning.message for warning in compiled.warnings],
    }
    return report


def format_report(compiled: CompiledProgram, rows: int = MAX_ROWS) -> str:
    """The compiled profile against the baselines, at the best input quality, as a table of
    at most `rows` totals spread over the time grid, both ends included (0: every total); a
    thinned table says so."""
    profile = compiled.profile
    best = (-1,) * profile.n_inputs  # the highest grid quality of every input
    expected = compiled.expected[best]
    allocation = compiled.allocation[best]
    baselines = {name: value[best] for name, value in compiled.baselines.items()}
    n = len(profile.time)
    shown = n if rows <= 0 else min(rows, n)
    rows_at = np.unique(np.linspace(0, n - 1, shown).round().astype(int))
    bounds = None
    if compiled.dependence is not None:
        bounds = np.stack([compiled.dependence[0][best], compiled.dependence[1][best]])
    ranged = ["if dependent"] if bounds is not None else []
    header = [f"T ({profile.time_unit})", "compiled", *ranged, *baselines, "allocation"]
    header[-1] += " (" + ", ".join(compiled.modules) + ")" if compiled.modules else ""
    table = [header]
    for j in rows_at:
        shares = ", ".join(f"{a:g}" for a in allocation[j])
        table.append(
            [
                f"{profile.time[j]:g}",
                f"{expected[j]:.3f}",
                *([] if bounds is None else [f"{bounds[0, j]:.3f}-{bounds[1, j]:.3f}"]),
                *(f"{value[j]:.3f}" for value in baselines.values()),
                shares,
            ]
        )
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    lines = [f"schema {compiled.name}: {compiled.allocator}"]
    if compiled.model.quality_inputs:
        lines[0] += (
            f" (table at input quality {profile.input_grids[0][-1]:g} of "
            f"{', '.join(compiled.model.quality_inputs)})"
        )
    for row in table:
        cells = [
            cell.rjust(w) if i < len(row) - 1 else cell
            for i, (cell, w) in enumerate(zip(row, widths, strict=True))
        ]
        lines.append("  " + "  ".join(cells).rstrip())
    if len(rows_at) < n:
        lines.append(
            f"  ({len(rows_at)} of the {n} totals shown: --rows 0 shows every one, --json gives"
            " the whole table)"
        )
    gap = compiled.exhaustive_gap
    lines.append(
        "  gap to the exhaustive optimum: "
        + ("not computed (too many modules or allocations)" if gap is None else f"{gap:.2e}")
    )
    lines.append(f"  note: {compiled.note}")
    lines.extend(f"  warning: {warning.message}" for warning in compiled.warnings)
    return "\n".join(lines) + "\n"
