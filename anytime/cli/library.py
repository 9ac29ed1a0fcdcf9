"""`anytime library list|show`: the anytime library's modules and their profiles."""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from anytime.cli.common import (
    EXIT_INPUT,
    EXIT_OK,
    format_table,
    json_text,
    library_options,
    non_negative_int,
    open_library,
)
from anytime.errors import ProfileError
from anytime.library import LibraryEntry
from anytime.profiles.dynamic import DynamicProfile
from anytime.profiles.dynamic_io import dynamic_profile_path
from anytime.profiles.profile import ConditionalPerformanceProfile


def add_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    library = commands.add_parser(
        "library",
        help="list the anytime library's modules, or show one with its profile",
        description="The anytime library: modules of installed plugins (entry-point group "
        "'anytime.plugins'), modules registered in-process, and profile files.",
    )
    library_commands = library.add_subparsers(
        dest="library_command", metavar="COMMAND", required=True
    )
    listing = library_commands.add_parser(
        "list",
        help="every module: name, kind, inputs, profile, origin",
        description="List every module of the library: its name, kind, quality-carrying "
        "inputs, a summary of its profile, and where it was defined.",
    )
    listing.add_argument("--json", action="store_true", help="print a JSON list")
    library_options(listing)
    listing.set_defaults(run=run_library_list)
    show = library_commands.add_parser(
        "show",
        help="one module: its declaration, profile axes and expected quality",
        description="Show one module: kind, origin, parameters and inputs, its profile's axes "
        "and a table of expected output quality by input quality and time; and, when it has "
        "one (NAME.dynamic.yaml beside its profile), what its dynamic profile observes and the "
        "expected gain of one more step by quality state and time.",
    )
    show.add_argument("name", metavar="NAME", help="the module's name (case-insensitive)")
    show.add_argument("--json", action="store_true", help="print JSON")
    show.add_argument(
        "--times",
        type=non_negative_int,
        default=SHOWN_TIMES,
        metavar="N",
        help=f"the tables show N times spread over the profile's grid, both ends included"
        f" (default: {SHOWN_TIMES}; 0: every time)",
    )
    library_options(show)
    show.set_defaults(run=run_library_show)


def run_library_list(args: argparse.Namespace) -> int:
    library = open_library(args)
    errors: list[ProfileError] = []
    rows: list[dict[str, Any]] = []
    for entry in library:
        try:
            profile = entry.profile
        except ProfileError as error:
            errors.append(error)
            rows.append(_entry_json(entry, None) | {"profile_error": str(error)})
        else:
            rows.append(_entry_json(entry, profile))
    if args.json:
        print(json_text(rows))
    elif not rows:
        where = ", ".join(source.name for source in library.sources)
        print(f"no modules found (looked in: {where})")
    else:
        table = [["NAME", "KIND", "INPUTS", "PROFILE", "ORIGIN"]]
        for row in rows:
            if row["profile_error"] is not None:
                summary = "unreadable (error below)"
            else:
                summary = row["profile"]["description"] if row["profile"] else "no profile"
            inputs = ", ".join(row["inputs"]) or "-"
            table.append([row["module"], row["kind"], inputs, summary, row["origin"]])
        print(format_table(table), end="")
    from anytime.cli import describe  # the one place errors become messages (cli/__init__)

    for unreadable in errors:  # every unreadable profile, after the listing
        print(describe(unreadable), file=sys.stderr)
    return EXIT_INPUT if errors else EXIT_OK


def run_library_show(args: argparse.Namespace) -> int:
    entry = open_library(args)[args.name]
    profile = entry.profile
    dynamic = entry.dynamic_profile
    if args.json:
        data = _entry_json(entry, profile, full=True)
        data["dynamic_profile"] = None if dynamic is None else _dynamic_facts(entry, dynamic)
        print(json_text(data))
        return EXIT_OK
    kind = entry.kind if entry.module is not None else f"{entry.kind} (profile only)"
    if entry.module is not None:
        parameters = ", ".join(entry.parameters) or "none"
    else:
        parameters = "not known (profile only: calls are not checked for arity)"
    fields = [
        ["name:", entry.name],
        ["kind:", kind],
        ["origin:", entry.origin],
        ["parameters:", parameters],
        ["inputs:", ", ".join(entry.inputs) or "none"],
    ]
    step = _step_line(entry, profile)
    if step is not None:
        fields.append(["step:", step])
    if profile is None:
        fields.append(["profile:", "none"])
        print(format_table(fields), end="")
        return EXIT_OK  # a dynamic profile is found beside a profile file only
    file = entry.profile_file
    fields.append(["profile:", str(file) if file is not None else "in memory"])
    axes = [
        [f"input quality ({name})", _numbers(grid)]
        for name, grid in zip(_axis_names(profile), profile.input_grids, strict=True)
    ]
    axes.append([f"time ({profile.time_unit})", _numbers(profile.time)])
    axes.append(["quality bins", f"{_numbers(profile.bins)} ({profile.n_bins} bins)"])
    if profile.samples is not None:
        low, high = int(profile.samples.min()), int(profile.samples.max())
        axes.append(["samples per cell", f"{low}" if low == high else f"{low} to {high}"])
    missing = profile.no_result_table
    if missing is not None:  # None: a result in every cell, or not known
        cells = f"{int(np.count_nonzero(missing))} of {missing.size} cells"
        axes.append(["no result", f"in {cells}, probability up to {missing.max():.3g}"])
    lines = [format_table(fields) + "axes:", *format_table(axes, indent=2).splitlines(), ""]
    lines.extend(_expected_table(profile, args.times))
    if dynamic is not None:
        lines.extend(["", *_dynamic_lines(entry, dynamic, args.times)])
    print("\n".join(lines))
    return EXIT_OK


#: At most this many states (rows) in `library show`'s table of a dynamic profile.
SHOWN_STATES = 5

_OBSERVED = {
    "true": "the module's true quality (it reports it)",
    "estimate": "the module's own estimate of its quality, with P(true quality | estimate)",
    "none": "nothing (the module reports no quality): one state",
}


def _dynamic_lines(entry: LibraryEntry, dynamic: DynamicProfile, times: int) -> list[str]:
    """What the dynamic profile observes, its axes, and the expected one-step gain of a few
    states at a few times, at the input-quality grid's highest point."""
    facts = _dynamic_facts(entry, dynamic)
    unit = dynamic.time_unit
    fields = [
        ["observed", _OBSERVED[dynamic.observed]],
        ["states", f"{dynamic.n_bins} quality bins: {_numbers(dynamic.bins, '.3g')}"],
        [f"time ({unit})", _numbers(dynamic.time)],
        ["samples", f"{dynamic.samples} trials per cell"],
    ]
    if dynamic.ends:
        fields.insert(2, ["ended", "a state per bin for runs that ended by themselves"])
    if dynamic.entered is not None:  # each bin split by when the run entered it
        since = [f"{dynamic.time[int(e)]:g}" for e in dynamic.entered[:-1]]
        fields.insert(
            2,
            [
                "entered",
                f"each bin in {dynamic.classes} classes of the time the run entered it, from"
                f" {', '.join(since)} ({dynamic.n_states} states)",
            ],
        )
    if facts["input_quality"]:
        names = list(dynamic.inputs) or [f"#{i + 1}" for i in range(len(facts["input_quality"]))]
        cell = ", ".join(
            f"{name}={q:g}" for name, q in zip(names, facts["input_quality"], strict=True)
        )
        fields.append(["shown at", f"{cell} (the highest input qualities)"])
    agreement = facts["estimate_in_true_bin"]
    if agreement is not None:
        fields.append(["estimate right", f"{agreement:.0%} of runs (in the true quality's bin)"])
    lines = [f"dynamic profile: {facts['file']}", *format_table(fields, indent=2).splitlines()]
    gain = np.array(facts["expected_gain"], dtype=float)  # null (unoccupied) -> nan
    if gain.size == 0:
        return lines
    steps = _spread(gain.shape[0], times or gain.shape[0])
    states = _spread(dynamic.running_states, SHOWN_STATES)  # an ended run has no next step
    edges = dynamic.bins
    rows = [["state \\ from time", *(f"{dynamic.time[j]:g}" for j in steps)]]
    for k in states:
        b = int(dynamic.state_bin[k])
        label = f"[{edges[b]:.3g}, {edges[b + 1]:.3g}{']' if b == dynamic.n_bins - 1 else ')'}"
        if k >= dynamic.running_states:
            label += " ended"
        elif dynamic.entered is not None:
            label += f" since {dynamic.time[int(dynamic.entered[k % dynamic.classes])]:g}"
        rows.append([label, *("-" if np.isnan(g) else f"{g:+.3f}" for g in gain[steps, k])])
    title = (
        f"  expected gain in true quality of the next step (rows: state; columns: time in {unit}"
        f"{_thinned(len(steps), gain.shape[0])}):"
    )
    return [*lines, title, *format_table(rows, indent=4).splitlines()]


def _spread(n: int, most: int) -> np.ndarray[Any, Any]:
    """At most `most` indices spread evenly over range(n), both ends included."""
    return np.unique(np.round(np.linspace(0, n - 1, min(n, most)))).astype(int)


def _dynamic_facts(entry: LibraryEntry, dynamic: DynamicProfile) -> dict[str, Any]:
    """The facts `library show` gives of a dynamic profile, at the highest input qualities."""
    top = [float(grid[-1]) for grid in dynamic.input_grids]
    here = dynamic.at(top)
    # A state no run was in has no gain, nor has an ended run (it has no next step).
    occupied = (here.occupancy[:-1] > 0) & ~here.ended
    gain = np.where(occupied, np.round(here.expected_gain(), 12), np.nan)
    agreement = None
    if here.observation is not None and here.observed == "estimate":
        states = np.arange(here.n_states)
        right = here.observation[:, states, here.state_bin]  # (m, K): in its own bin
        agreement = round(float(np.mean(np.sum(here.occupancy * right, axis=-1))), 12)
    file = entry.profile_file
    return {
        "file": None if file is None else str(dynamic_profile_path(file)),
        "observed": dynamic.observed,
        "states": dynamic.n_states,
        "quality_bins": dynamic.bins.tolist(),
        "entered": None if dynamic.entered is None else [int(e) for e in dynamic.entered],
        "ends": dynamic.ends,
        "time_grid": dynamic.time.tolist(),
        "time_unit": dynamic.time_unit,
        "samples": dynamic.samples,
        "input_quality": top,
        "expected_gain": [[None if np.isnan(g) else float(g) for g in row] for row in gain],
        "estimate_in_true_bin": agreement,
    }


def _step_line(entry: LibraryEntry, profile: ConditionalPerformanceProfile | None) -> str | None:
    """'5 ticks (declared; measured 4)', '3 ticks (measured)', or None when unknown."""
    declared, measured = entry.declared_step, None if profile is None else profile.step
    step = declared if declared is not None else measured
    if step is None:
        return None
    unit = "" if profile is None else f" {profile.time_unit}"
    if step == 1:
        unit = unit.removesuffix("s")  # 1 tick, 1 second
    if declared is None:
        return f"{step:g}{unit} (measured)"
    if measured is None:
        return f"{step:g}{unit} (declared)"
    if measured > declared:  # what it means, and whether it matters
        return (
            f"{step:g}{unit} (declared; measured {measured:g}: its results came further apart"
            " than declared, which is right only if it stops at ctx.expired in between, as"
            " `anytime check` tests)"
        )
    return f"{step:g}{unit} (declared; measured {measured:g})"


def profile_summary(profile: ConditionalPerformanceProfile) -> str:
    """One line: '3 input grid pts x 4 times x 4 bins, ticks'."""
    parts = []
    if profile.n_inputs:
        sizes = "x".join(str(len(grid)) for grid in profile.input_grids)
        parts.append(f"{sizes} input grid pts")
    parts.append(f"{len(profile.time)} times")
    parts.append(f"{profile.n_bins} bins")
    measured = ", measured" if profile.samples is not None else ""
    return f"{' x '.join(parts)}, {profile.time_unit}{measured}"


def _entry_json(
    entry: LibraryEntry, profile: ConditionalPerformanceProfile | None, full: bool = False
) -> dict[str, Any]:
    data: dict[str, Any] = {"module": entry.name, "kind": entry.kind, "inputs": list(entry.inputs)}
    if full:
        data["parameters"] = list(entry.parameters)
        measured = None if profile is None else profile.step
        declared = entry.declared_step
        data["step"] = declared if declared is not None else measured
        data["declared_step"], data["measured_step"] = declared, measured
    data["arity"] = entry.arity
    data["origin"] = entry.origin
    data["profile"] = None
    data["profile_error"] = None
    if profile is None:
        return data
    file = entry.profile_file
    summary: dict[str, Any] = {
        "description": profile_summary(profile),
        "file": None if file is None else str(file),
        "input_grid_points": [len(grid) for grid in profile.input_grids],
        "time_points": len(profile.time),
        "bins": profile.n_bins,
        "time_unit": profile.time_unit,
        "measured": profile.samples is not None,
    }
    if full:
        summary["input_grids"] = [grid.tolist() for grid in profile.input_grids]
        summary["time_grid"] = profile.time.tolist()
        summary["quality_bins"] = profile.bins.tolist()
        summary["expected_quality_table"] = _expected_cells(profile).tolist()
    data["profile"] = summary
    return data


def _expected_cells(profile: ConditionalPerformanceProfile) -> np.ndarray[Any, Any]:
    """Expected quality at every grid cell, shape `profile.cell_shape`."""
    mesh = np.meshgrid(*profile.input_grids, profile.time, indexing="ij")
    q = np.stack(mesh[:-1], axis=-1) if profile.n_inputs else np.zeros((*mesh[-1].shape, 0))
    return np.round(profile.expected(q, mesh[-1]), 12)


def _axis_names(profile: ConditionalPerformanceProfile) -> list[str]:
    if profile.inputs:
        return list(profile.inputs)
    return [f"#{i + 1}" for i in range(profile.n_inputs)]


#: At most this many time columns in `library show`.
SHOWN_TIMES = 6


def _thinned(shown: int, of: int) -> str:
    """What a title says of a table that shows some of the times."""
    return "" if shown == of else f"; {shown} of {of} times, --times 0 shows every one"


def _expected_table(profile: ConditionalPerformanceProfile, times: int) -> list[str]:
    """Expected quality: rows are input-quality grid points, columns `times` times spread over
    the grid (0: every one)."""
    n_times = len(profile.time)
    columns = _spread(n_times, times or n_times)
    table = _expected_cells(profile)
    names = _axis_names(profile)
    unit = f"{profile.time_unit}{_thinned(len(columns), n_times)}"
    if profile.n_inputs == 0:
        title = f"expected quality by time ({unit}):"
        rows = [["time", *(f"{profile.time[c]:g}" for c in columns)]]
        rows.append(["quality", *(f"{table[c]:.3f}" for c in columns)])
        return [title, *format_table(rows, indent=2).splitlines()]
    sizes = {len(grid) for grid in profile.input_grids}
    if profile.n_inputs == 1 or len(sizes) == 1:
        points = range(len(profile.input_grids[0]))
        index = [tuple([i] * profile.n_inputs) for i in points]
        labels = [", ".join(f"{g[i]:g}" for g in profile.input_grids) for i in points]
        note = "" if profile.n_inputs == 1 else "; the diagonal: every input at its i-th grid pt"
    else:
        top = [len(grid) - 1 for grid in profile.input_grids[1:]]
        index = [(i, *top) for i in range(len(profile.input_grids[0]))]
        labels = [f"{profile.input_grids[0][i]:g}" for i in range(len(profile.input_grids[0]))]
        rest = ", ".join(
            f"{name}={grid[-1]:g}"
            for name, grid in zip(names[1:], profile.input_grids[1:], strict=True)
        )
        note = f"; other inputs at their highest grid pt ({rest})"
        names = names[:1]
    title = f"expected quality (rows: {', '.join(names)} quality; columns: time in {unit}{note}):"
    rows = [[f"{', '.join(names)} \\ time", *(f"{profile.time[c]:g}" for c in columns)]]
    for label, cell in zip(labels, index, strict=True):
        rows.append([label, *(f"{table[(*cell, c)]:.3f}" for c in columns)])
    return [title, *format_table(rows, indent=2).splitlines()]


def _numbers(values: np.ndarray[Any, Any], spec: str = "g") -> str:
    return ", ".join(f"{v:{spec}}" for v in values)
