"""The profile file format, `anytime-profile/1`: reading (validated) and writing (exact).

A profile file is one YAML mapping (docs/profiles.md says more)::

    format: anytime-profile/1          # required, the version of this format
    module: find-path                  # default: the file name without its extension
    kind: interruptible                # or contract; default interruptible
    time_unit: ticks                   # or seconds; default ticks
    step: 5                            # optional: the module's step, in time_unit (measured)
    inputs: [domain]                   # quality-carrying inputs in axis order; may be empty
    input_quality: [[0.8, 0.9, 1.0]]   # one increasing grid of qualities per input
    time: [0, 100, 200, 400]           # required: increasing allocations >= 0
    quality_bins: [0.0, 0.25, 0.5, 0.75, 1.0]   # required: K+1 increasing edges in [0, 1]
    probability:                       # shape (input grids..., time, K); rows sum to 1
      - [[1, 0, 0, 0], [0.5, 0.5, 0, 0], [0, 0.5, 0.5, 0], [0, 0, 0.5, 0.5]]
      - ...
    mean: [[...], ...]                 # optional: expected quality per cell
    std: [[...], ...]                  # optional: standard deviation per cell (measured)
    samples: [[...], ...]              # optional: trials per cell (measured)
    bin_mean: [[[...], ...], ...]      # optional: mean quality per bin of each cell (measured)
    no_result: [[...], ...]            # optional: probability of no result per cell (measured)

A deterministic profile gives `expected:` (shape without the last axis) instead of
`probability:` and `mean:`: each cell is a point mass in the bin holding that quality, and the
quality itself is kept as the profile's `mean`, so expected quality is exact, not a bin midpoint
(it must lie between the first and last bin edges).
Exactly one of `probability` and `expected` must be given; `std`, `samples` and `no_result` go
with either, `bin_mean` (shape of `probability`) only with `probability`. `no_result` is written
only where some cell may have no result, so the files of modules that always have one do not
carry it; a file without it (every file written before it existed) has None, and so has one
without `bin_mean`.
`step` is the most time the module used past any moment before it next registered a result or
returned (interruptible), or past its allocation (contract); a file without it (every file
written before it existed) has an unknown step, None. A bad `step` names its line and column.
`inputs` may be left out when the input axes have no names; when given it names every axis.
`inputs` may be left out when the input axes have no names; when given it names every axis.

The file's YAML (a safe loader only) is `anytime.profiles.io.document`'s, its field-by-field
checks `anytime.profiles.io.reader`'s, and its binary companion for large tables
`anytime.profiles.io.companion`'s: the formats of dynamic profiles and quality traces
(`anytime.profiles.dynamic_io`) share them.

Writing uses repr precision for floats (integral values as integers), so save -> load gives
back an equal profile. A profile whose probabilities are exactly the point masses of its `mean`
is written as `expected:`, so a hand-written `expected:` file keeps its form. A profile without
a module name takes the file's name when loaded back; a profile without input axes comes back
as a `PerformanceProfile`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np

from anytime.errors import ProfileError
from anytime.profiles.io.companion import is_large, place_tables
from anytime.profiles.io.document import (
    EXPONENT,
    MAX_CELLS,
    describe,
    format_number,
    plain,
    write_document,
)
from anytime.profiles.io.reader import Reader, read_document
from anytime.profiles.profile import (
    Array,
    ConditionalPerformanceProfile,
    new_profile,
    point_mass,
)
from anytime.vocabulary import PROFILE_KINDS, UNITS, ProfileKind, Unit

FORMAT = "anytime-profile/1"

#: Every field a file may have, in the order they are written. A compiled program's file adds
#: `modules`, `allocation` (its time-allocation table) and `compiled` (the rest of the compile
#: result, see `anytime.compiler.storage`); reading it as a profile skips them. A file whose
#: tables are in a binary companion has `tables` in their place (`read_profile_file`).
FIELDS = (
    "format",
    "module",
    "kind",
    "time_unit",
    "step",
    "inputs",
    "input_quality",
    "time",
    "quality_bins",
    "probability",
    "expected",
    "mean",
    "std",
    "samples",
    "bin_mean",
    "no_result",
    "modules",
    "allocation",
    "compiled",
)


#: The tables of a profile, in the order they are written; a companion can hold any of them,
#: and the time grid when it is longer than `LONG_GRID`.
TABLES = ("probability", "expected", "mean", "std", "samples", "bin_mean", "no_result")
LONG_GRID = 1_000


# --- reading ---------------------------------------------------------------------------------


def load_profile(path: str | os.PathLike[str]) -> ConditionalPerformanceProfile:
    """Read and validate a profile file; every problem is a `ProfileError` naming the file."""
    return read_profile_file(path)[0]


def read_profile_file(
    path: str | os.PathLike[str],
) -> tuple[ConditionalPerformanceProfile, Mapping[Any, Any]]:
    """The validated profile of a file and the file's mapping, the tables of its companion (if
    it has one) in it as arrays: what a reader of the fields beyond the profile's needs."""
    reader, data = read_document(path, TABLES, "profile files")
    fields = check_fields(reader, data)
    return build_profile(reader, fields), fields


def profile_from_dict(
    data: object, filename: str | os.PathLike[str]
) -> ConditionalPerformanceProfile:
    """Validate the parsed contents of a profile file and build the profile.

    `filename` prefixes every message, and its stem is the module name when none is given.
    """
    reader = Reader(os.fspath(filename), tables=TABLES)
    return build_profile(reader, check_fields(reader, data))


def check_fields(reader: Reader, data: object) -> Mapping[Any, Any]:
    """The top-level mapping of a profile file, once the version, the field names and the
    choices are right."""
    required = {"time": "a list of times", "quality_bins": "a list of bin edges"}
    data = reader.header(data, FORMAT, FIELDS, required, "load_profile")
    if "probability" in data and "expected" in data:
        reader.fail("probability", "expected exactly one of probability and expected, got both")
    if "probability" not in data and "expected" not in data:
        reader.fail("probability", "missing field (expected probability or expected, got neither)")
    if "expected" in data and "mean" in data:
        reader.fail(
            "mean",
            "not allowed next to expected, which is the mean"
            " (expected mean only with probability, got both)",
        )
    if "expected" in data and "bin_mean" in data:
        reader.fail(
            "bin_mean",
            "not allowed next to expected, whose point masses stand for their quality"
            " (expected bin_mean only with probability, got both)",
        )
    return data


def build_profile(reader: Reader, data: Mapping[Any, Any]) -> ConditionalPerformanceProfile:
    module = reader.name("module", data.get("module", Path(reader.filename).stem))
    kind = cast(
        ProfileKind, reader.choice("kind", data.get("kind", "interruptible"), PROFILE_KINDS)
    )
    time_unit = cast(Unit, reader.choice("time_unit", data.get("time_unit", "ticks"), UNITS))
    step = read_step(reader, data["step"]) if "step" in data else None
    grids = reader.input_grids(data.get("input_quality", []))
    inputs = reader.inputs(data["inputs"], len(grids)) if "inputs" in data else ()
    time = reader.grid("time", data["time"], minimum=1, quality=False)
    bins = reader.grid("quality_bins", data["quality_bins"], minimum=2, quality=True)

    names = inputs or tuple(f"input_quality[{i}]" for i in range(len(grids)))
    cells = (*(len(g) for g in grids), len(time))
    axes = (*(f"one per {name} quality" for name in names), "one per time")
    if np.prod(cells, dtype=np.float64) * (len(bins) - 1) > MAX_CELLS:
        reader.fail(
            "probability" if "probability" in data else "expected",
            f"expected at most {MAX_CELLS} cells, got shape {[*cells, len(bins) - 1]}",
        )

    def optional(key: str, *, quality: bool = False) -> Array | None:
        return reader.table(key, data[key], cells, axes, quality=quality) if key in data else None

    mean: Array | None
    bin_mean: Array | None = None
    if "expected" in data:
        mean = reader.table("expected", data["expected"], cells, axes, quality=True)
        within_bins(reader, mean, bins)
        probability = point_mass(mean, bins)
    else:
        shape, bin_axes = (*cells, len(bins) - 1), (*axes, "one per quality bin")
        probability = reader.table("probability", data["probability"], shape, bin_axes)
        mean = optional("mean", quality=True)
        if "bin_mean" in data:  # the class checks each against its bin's edges
            bin_mean = reader.table("bin_mean", data["bin_mean"], shape, bin_axes)
    std, samples = optional("std"), optional("samples")
    no_result = optional("no_result")  # the class checks it against the first bin's mass
    try:
        return new_profile(
            input_grids=grids,
            time=time,
            bins=bins,
            probability=probability,
            inputs=inputs,
            mean=mean,
            std=std,
            samples=samples,
            module=module,
            kind=kind,
            time_unit=time_unit,
            step=step,
            no_result_table=no_result,
            bin_mean=bin_mean,
        )
    except ProfileError as exc:  # the class's own invariants: re-prefix with the file
        reader.refile(exc, module or "profile")


def read_step(reader: Reader, value: object) -> float:
    """The module's step: a finite number >= 0 (a file gives no null: leave it out)."""
    expected = "a finite number >= 0 (the module's step, in time_unit)"
    if isinstance(value, bool) or not isinstance(value, int | float):
        hint = ""
        if isinstance(value, str) and EXPONENT.match(value):
            hint = " (YAML reads it as a string: write a dot and a signed exponent, as in 1.0e+3)"
        reader.fail("step", f"expected {expected}, got {describe(value)}{hint}", at_line=True)
    try:
        step = float(value)
    except OverflowError:
        reader.fail("step", f"expected {expected}, got {value}", at_line=True)
    if not np.isfinite(step) or step < 0:
        reader.fail("step", f"expected {expected}, got {format_number(step)}", at_line=True)
    return step


def within_bins(reader: Reader, mean: Array, bins: Array) -> None:
    low, high = format_number(float(bins[0])), format_number(float(bins[-1]))
    outside = (mean < bins[0]) | (mean > bins[-1])
    reader.check("expected", mean, outside, f"a quality within the bins [{low}, {high}]")


# --- writing ---------------------------------------------------------------------------------


def profile_to_dict(profile: ConditionalPerformanceProfile) -> dict[str, Any]:
    """The file's mapping for `profile`: plain lists, floats exact, integral values as ints."""
    header, tables = _split(profile)
    return {**header, **{key: plain(table) for key, table in tables.items()}}


def _split(profile: ConditionalPerformanceProfile) -> tuple[dict[str, Any], dict[str, Array]]:
    """The file's mapping for `profile` without its tables, and the tables, in field order."""
    data: dict[str, Any] = {"format": FORMAT}
    if profile.module:
        data["module"] = profile.module
    data["kind"] = profile.kind
    data["time_unit"] = profile.time_unit
    if profile.step is not None:
        step = float(profile.step)
        data["step"] = int(step) if step.is_integer() and abs(step) < 2**53 else step
    if len(profile.inputs) == profile.n_inputs:  # unnamed input axes are left unnamed
        data["inputs"] = list(profile.inputs)
    data["input_quality"] = [plain(grid) for grid in profile.input_grids]
    data["time"] = plain(profile.time)
    data["quality_bins"] = plain(profile.bins)
    tables: dict[str, Array | None] = {}
    if _is_point_mass(profile):
        tables["expected"] = profile.mean
    else:
        tables["probability"] = profile.probability
        tables["mean"] = profile.mean
    tables["std"] = profile.std
    tables["samples"] = profile.samples
    tables["bin_mean"] = profile.bin_mean
    tables["no_result"] = profile.no_result_table  # never all zeros: the profile keeps None
    return data, {key: table for key, table in tables.items() if table is not None}


def save_profile(
    profile: ConditionalPerformanceProfile,
    path: str | os.PathLike[str],
    extra: Mapping[str, Any] | None = None,
    *,
    companion: bool | None = None,
) -> None:
    """Write `profile` to `path` in the `anytime-profile/1` format, atomically (a temporary
    file renamed over `path`; OSError if it cannot).

    `extra` adds fields a reader of profiles skips (a compiled program's `modules`,
    `allocation` and `compiled`); arrays in it are written like the profile's tables.
    `companion` writes the tables into a binary companion beside `path` (`NAME.npz` for
    `NAME.yaml`), which the file names with its digest; by default, when they hold more than
    `COMPANION_THRESHOLD` numbers. The companion is written (atomically) before the file, so
    an interrupted write leaves the old pair or a file whose digest tells the companion is not
    its own, never a file read with the wrong tables.
    """
    data, tables = _split(profile)
    if companion is None:
        companion = is_large(tables)
    if companion and len(profile.time) > LONG_GRID:  # read as fast as the tables it indexes
        del data["time"]
        tables = {"time": profile.time, **tables}
    place_tables(data, tables, Path(path), companion)
    for key, value in (extra or {}).items():
        if key not in ("modules", "allocation", "compiled"):
            raise ValueError(f"not a field a profile file may carry: {key!r}")
        if key == "allocation":
            data[key] = plain(np.asarray(value))
        else:
            data[key] = dict(value) if key == "compiled" else list(value)
    write_document(data, path)


def _is_point_mass(profile: ConditionalPerformanceProfile) -> bool:
    """Whether the file can say `expected: mean` and be read back as this very profile."""
    mean = profile.mean
    return (
        mean is not None
        and profile.bin_mean is None  # which the `expected` form cannot carry
        and bool(np.all((mean >= profile.bins[0]) & (mean <= profile.bins[-1])))
        and np.array_equal(profile.probability, point_mass(mean, profile.bins))
    )
