"""The file formats of dynamic profiles and quality traces: reading (validated) and writing
(exact).

Both are YAML mappings of the same family as `anytime-profile/1` (docs/profiles.md says more):
the same safe loader, the same messages (`FILE: field: what is wrong (expected ..., got ...)`,
`FILE:LINE:COL` for YAML syntax), floats written at repr precision so that save -> load gives
back an equal object, and the same binary companion (`NAME.npz` beside `NAME.yaml`, named with
its digest in `tables:`) when the tables hold more than `COMPANION_THRESHOLD` numbers.

A dynamic profile, `anytime-dynamic-profile/1` (`DynamicProfile`; K states, m times)::

    format: anytime-dynamic-profile/1   # required
    module: approach                    # default: the file's name without .dynamic.yaml
    observed: true                      # what the state is: true, estimate or none (true)
                                        # (a bare YAML true is read as the word)
    time_unit: ticks                    # or seconds (ticks)
    samples: 60                         # trials behind each cell (0)
    inputs: [x]                         # the input axes' names, as in a profile
    input_quality: [[0.4, 1.0]]         # one grid per input; may be empty
    time: [0, 10, 20]                   # required: the grid times
    quality_bins: [0, 0.5, 1]           # required: B+1 edges from 0 to 1
    ends: true                          # one more state per bin, absorbing, for runs that
                                        # ended by themselves (false)
    entered: [0, 1, 2, 3]               # edges over grid indices 0..m of the classes of the
                                        # time a run entered its bin (C classes; optional:
                                        # without it the state is the bin, K = B, C = 1)
    occupancy: ...                      # required: (*cells, m, K) P(state), K = B * C
    transition: ...                     # required: (*cells, m - 1, K, K) P(next state | state)
    quality_mean: ...                   # required: (*cells, m, B) mean true quality per bin
                                        # ((*cells, m, K, B): per state and bin, with entered
                                        # or ends)
    observation: ...                    # (*cells, m, K, B) P(true bin | state), exactly when
                                        # the state is not the true quality (observed is not
                                        # true, or entered or ends is given)


Quality traces, `anytime-traces/1` (`QualityTraces`; N trials)::

    format: anytime-traces/1            # required
    module: approach                    # default: the file's name without .traces.yaml
    reports: estimate                   # what Result.quality is: true, estimate or none (true)
    time_unit: ticks
    trials: 60                          # required: N
    inputs: [x]
    input_quality: [[0.4, 1.0]]
    time: [0, 10, 20]                   # required
    quality: ...                        # required: (*cells, N, m) scored quality
    scored: ...                         # required: (*cells, N, m) 1 where the run had a result
    estimate: ...                       # (*cells, N, m) reported quality, exactly when reports
                                        # is estimate
    finished: ...                       # (*cells, N) when each run ended: by itself, or at
                                        # the last grid time (optional: not known)

Traces follow the profile's companion rule rather than always going to a companion: the traces
of a small measurement (tens of trials on a few cells) stay one readable file that a review
can diff, and a large one (the threshold is 100,000 numbers) loads as fast as a profile's
companion. The classes check their own invariants (rows summing to 1, shapes of
`observation` and `estimate` against `observed` and `reports`); their messages name the file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, cast

import numpy as np

from anytime.errors import ProfileError
from anytime.profiles.dynamic import (
    OBSERVED,
    DynamicProfile,
    Observed,
    QualityTraces,
    check_entered,
)
from anytime.profiles.io import (
    MAX_CELLS,
    Reader,
    describe,
    is_large,
    place_tables,
    plain,
    read_document,
    write_document,
)
from anytime.profiles.profile import Array
from anytime.vocabulary import UNITS, Unit

__all__ = [
    "DYNAMIC_FORMAT",
    "DYNAMIC_SUFFIX",
    "TRACES_FORMAT",
    "TRACES_SUFFIX",
    "dynamic_profile_path",
    "load_dynamic_profile",
    "load_traces",
    "save_dynamic_profile",
    "save_traces",
]

DYNAMIC_FORMAT = "anytime-dynamic-profile/1"
TRACES_FORMAT = "anytime-traces/1"

#: A module's dynamic profile is `NAME.dynamic.yaml` beside its profile `NAME.yaml`; traces
#: are best named `NAME.traces.yaml`. A profile directory reads neither as a profile.
DYNAMIC_SUFFIX = ".dynamic.yaml"
TRACES_SUFFIX = ".traces.yaml"

#: The fields of each file, in the order they are written, and the tables among them (which a
#: companion may hold).
DYNAMIC_TABLES = ("occupancy", "transition", "quality_mean", "observation")
DYNAMIC_FIELDS = (
    "format",
    "module",
    "observed",
    "time_unit",
    "samples",
    "inputs",
    "input_quality",
    "time",
    "quality_bins",
    "ends",
    "entered",
    *DYNAMIC_TABLES,
)
TRACES_TABLES = ("quality", "scored", "estimate", "finished")
TRACES_FIELDS = (
    "format",
    "module",
    "reports",
    "time_unit",
    "trials",
    "inputs",
    "input_quality",
    "time",
    *TRACES_TABLES,
)


def dynamic_profile_path(profile_path: str | os.PathLike[str]) -> Path:
    """Where the dynamic profile of the profile file `NAME.yaml` is: `NAME.dynamic.yaml`."""
    path = Path(profile_path)
    return path.with_name(f"{path.stem}.dynamic{path.suffix or '.yaml'}")


# --- reading ---------------------------------------------------------------------------------


def load_dynamic_profile(path: str | os.PathLike[str]) -> DynamicProfile:
    """Read and validate an `anytime-dynamic-profile/1` file; every problem is a
    `ProfileError` naming the file."""
    reader, document = read_document(path, DYNAMIC_TABLES, kind="dynamic profile files")
    required = {
        "time": "a list of times",
        "quality_bins": "a list of bin edges",
        **{key: "a table" for key in DYNAMIC_TABLES[:-1]},
    }
    data = reader.header(document, DYNAMIC_FORMAT, DYNAMIC_FIELDS, required, "load_dynamic_profile")
    axes = _Axes.read(reader, data, DYNAMIC_SUFFIX)
    observed = cast(Observed, reader.choice("observed", _word(data, "observed"), OBSERVED))
    samples = _whole(reader, "samples", data.get("samples", 0), least=0)
    bins = reader.grid("quality_bins", data["quality_bins"], minimum=2, quality=True)
    entered = None
    if "entered" in data:
        entered = reader.grid("entered", data["entered"], minimum=2, quality=False)
        check_entered(entered, len(axes.time), reader.fail)
    ends = data.get("ends", False)
    if not isinstance(ends, bool):
        reader.fail("ends", f"expected true or false, got {describe(ends)}")
    m, kb = len(axes.time), len(bins) - 1
    # Running states (bin, entry class), then with ends one ended state per bin.
    k = kb * (1 if entered is None else len(entered) - 1) + (kb if ends else 0)
    _check_size(reader, "transition", (*axes.cells, max(m, 1), k, k))
    state, step = (*axes.names, "one per time", "one per state"), "one per time step"
    per_state, per_bin = (*axes.cells, m, k), (*axes.cells, m, kb)
    by_bin = (*axes.names, "one per time", "one per quality bin")
    pair = (*axes.names, step, "one per state", "one per next state")
    occupancy = reader.table("occupancy", data["occupancy"], per_state, state, quality=True)
    transition = reader.table(
        "transition", data["transition"], (*axes.cells, m - 1, k, k), pair, quality=True
    )
    if entered is not None or ends:  # per state and true bin
        per_bin, by_bin = (*per_state, kb), (*state, "one per true-quality bin")
    quality_mean = reader.table("quality_mean", data["quality_mean"], per_bin, by_bin, quality=True)
    observation = None
    if "observation" in data:
        true_bin = (*axes.names, "one per time", "one per state", "one per true-quality bin")
        observation = reader.table(
            "observation", data["observation"], (*per_state, kb), true_bin, quality=True
        )
    try:
        return DynamicProfile(
            module=axes.module,
            time=axes.time,
            bins=bins,
            occupancy=occupancy,
            transition=transition,
            quality_mean=quality_mean,
            observation=observation,
            observed=observed,
            samples=samples,
            input_grids=axes.grids,
            inputs=axes.inputs,
            time_unit=axes.time_unit,
            entered=entered,
            ends=ends,
        )
    except ProfileError as exc:  # the class's own invariants: re-prefix with the file
        reader.refile(exc, axes.module)


def load_traces(path: str | os.PathLike[str]) -> QualityTraces:
    """Read and validate an `anytime-traces/1` file; every problem is a `ProfileError` naming
    the file."""
    reader, document = read_document(path, TRACES_TABLES, kind="trace files")
    required = {
        "time": "a list of times",
        "trials": "the number of trials",
        "quality": "a table",
        "scored": "a table",
    }
    data = reader.header(document, TRACES_FORMAT, TRACES_FIELDS, required, "load_traces")
    axes = _Axes.read(reader, data, TRACES_SUFFIX)
    reports = cast(Observed, reader.choice("reports", _word(data, "reports"), OBSERVED))
    trials = _whole(reader, "trials", data["trials"], least=1)
    shape = (*axes.cells, trials, len(axes.time))
    _check_size(reader, "quality", shape)
    names = (*axes.names, "one per trial", "one per time")
    quality = reader.table("quality", data["quality"], shape, names, quality=True)
    scored = reader.table("scored", data["scored"], shape, names)
    reader.check("scored", scored, (scored != 0) & (scored != 1), "0 or 1 (a result or none)")
    estimate = None
    if "estimate" in data:
        estimate = reader.table("estimate", data["estimate"], shape, names, quality=True)
    finished = None
    if "finished" in data:
        finished = reader.table("finished", data["finished"], shape[:-1], names[:-1], quality=False)
    try:
        return QualityTraces(
            module=axes.module,
            time=axes.time,
            quality=quality,
            scored=scored.astype(np.bool_),
            estimate=estimate,
            finished=finished,
            reports=reports,
            input_grids=axes.grids,
            inputs=axes.inputs,
            time_unit=axes.time_unit,
        )
    except ProfileError as exc:
        reader.refile(exc, axes.module)


class _Axes:
    """The fields both files share: the module's name, the time unit, the input-quality grids
    and their names, and the time grid."""

    def __init__(
        self,
        module: str,
        time_unit: Unit,
        grids: list[Array],
        inputs: tuple[str, ...],
        time: Array,
    ) -> None:
        self.module, self.time_unit, self.time = module, time_unit, time
        self.grids, self.inputs = tuple(grids), inputs
        self.cells = tuple(len(grid) for grid in grids)
        labels = inputs or tuple(f"input_quality[{i}]" for i in range(len(grids)))
        self.names = tuple(f"one per {name} quality" for name in labels)

    @classmethod
    def read(cls, reader: Reader, data: Mapping[Any, Any], suffix: str) -> _Axes:
        name = Path(reader.filename).name
        default = name.removesuffix(suffix) if name.endswith(suffix) else Path(name).stem
        module = reader.name("module", data.get("module", default))
        time_unit = reader.choice("time_unit", data.get("time_unit", "ticks"), UNITS)
        grids = reader.input_grids(data.get("input_quality", []))
        inputs = reader.inputs(data["inputs"], len(grids)) if "inputs" in data else ()
        time = reader.grid("time", data["time"], minimum=1, quality=False)
        return cls(module, cast(Unit, time_unit), grids, inputs, time)


def _word(data: Mapping[Any, Any], field: str) -> object:
    """The value of `observed` or `reports` ("true" when not given): YAML 1.1 reads a bare
    `true` as a boolean, which here stands for the word."""
    value = data.get(field, "true")
    return "true" if value is True else value


def _whole(reader: Reader, field: str, value: object, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        reader.fail(field, f"expected an integer >= {least}, got {describe(value)}")
    return value


def _check_size(reader: Reader, field: str, shape: tuple[int, ...]) -> None:
    """Refuse a file describing a table larger than `MAX_CELLS` before reading its tables."""
    if np.prod(shape, dtype=np.float64) > MAX_CELLS:
        reader.fail(field, f"expected at most {MAX_CELLS} cells, got shape {list(shape)}")


# --- writing ---------------------------------------------------------------------------------


def save_dynamic_profile(
    profile: DynamicProfile, path: str | os.PathLike[str], *, companion: bool | None = None
) -> None:
    """Write `profile` to `path` in the `anytime-dynamic-profile/1` format, atomically; the
    tables go into a companion beside it when `companion` says so, by default when they hold
    more than `COMPANION_THRESHOLD` numbers (as `save_profile`)."""
    data = _header(
        DYNAMIC_FORMAT,
        profile,
        {"observed": profile.observed, "time_unit": profile.time_unit, "samples": profile.samples},
    )
    data["quality_bins"] = plain(profile.bins)
    if profile.entered is not None:
        data["entered"] = [int(e) for e in profile.entered]
    if profile.ends:
        data["ends"] = True
    tables = {
        "occupancy": profile.occupancy,
        "transition": profile.transition,
        "quality_mean": profile.quality_mean,
    }
    if profile.observation is not None:
        tables["observation"] = profile.observation

    _write(data, tables, path, companion)


def save_traces(
    traces: QualityTraces, path: str | os.PathLike[str], *, companion: bool | None = None
) -> None:
    """Write `traces` to `path` in the `anytime-traces/1` format, atomically; the tables go
    into a companion as `save_dynamic_profile` says."""
    data = _header(
        TRACES_FORMAT,
        traces,
        {"reports": traces.reports, "time_unit": traces.time_unit, "trials": traces.trials},
    )
    tables = {"quality": traces.quality, "scored": traces.scored.astype(np.float64)}
    if traces.estimate is not None:
        tables["estimate"] = traces.estimate
    if traces.finished is not None:
        tables["finished"] = traces.finished
    _write(data, tables, path, companion)


def _header(
    version: str, tables: DynamicProfile | QualityTraces, fields: Mapping[str, Any]
) -> dict[str, Any]:
    """The fields before the tables: the format, the module, `fields`, the axes."""
    data: dict[str, Any] = {"format": version}
    if tables.module:
        data["module"] = tables.module
    data.update(fields)
    if len(tables.inputs) == len(tables.input_grids):  # unnamed input axes are left unnamed
        data["inputs"] = list(tables.inputs)
    data["input_quality"] = [plain(grid) for grid in tables.input_grids]
    data["time"] = plain(tables.time)
    return data


def _write(
    data: dict[str, Any],
    tables: dict[str, Array],
    path: str | os.PathLike[str],
    companion: bool | None,
) -> None:
    place_tables(data, tables, Path(path), is_large(tables) if companion is None else companion)
    write_document(data, path)
