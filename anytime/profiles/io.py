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

Files are read by a safe loader only, libyaml's (`yaml.CSafeLoader`) where PyYAML has it, else
the pure one: a tag that would construct a Python object is refused, never run. A file the fast
loader refuses is read again by the pure one, so a message is the same with either. Every
problem is a `ProfileError` saying `FILE: field: what is wrong (expected ..., got ...)`; YAML
syntax errors add the line and column (`FILE:LINE:COL: ...`). YAML 1.1 reads `1e-3` and `1.0e3`
as strings: give such numbers a dot and a signed exponent, `1.0e-3` and `1.0e+3`.

Large tables go into a binary companion beside the file (`NAME.npz` for `NAME.yaml`, numpy's
uncompressed archive, read with pickles refused); the file then has `tables: {file, sha256,
shapes}` in their place, and a companion whose digest or shapes are not the header's is an
error, as is a table given in both. Writers add it when the tables hold more than
`COMPANION_THRESHOLD` numbers: a million-cell table loads in under a second, not a minute.

Writing uses repr precision for floats (integral values as integers), so save -> load gives
back an equal profile. A profile whose probabilities are exactly the point masses of its `mean`
is written as `expected:`, so a hand-written `expected:` file keeps its form. A profile without
a module name takes the file's name when loaded back; a profile without input axes comes back
as a `PerformanceProfile`.

The formats of dynamic profiles and quality traces (`anytime.profiles.dynamic_io`) are of the
same family: they share this module's reader (`read_document`, `_Reader.header`), companion
(`place_tables`) and writer (`write_document`).
"""

from __future__ import annotations

import errno
import hashlib
import io
import os
import re
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn, cast

import numpy as np
import yaml
from numpy.typing import NDArray

from anytime.errors import ProfileError
from anytime.files import MAX_PROFILE_BYTES, OutputFileError, read_input, write_atomic
from anytime.profiles.profile import (
    Array,
    ConditionalPerformanceProfile,
    Kind,
    TimeUnit,
    new_profile,
    point_mass,
)
from anytime.profiles.yaml_limits import YAMLLimitError, check_document
from anytime.text import did_you_mean

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

KINDS = ("interruptible", "contract")
TIME_UNITS = ("ticks", "seconds")

#: The tables of a profile, in the order they are written; a companion can hold any of them,
#: and the time grid when it is longer than `LONG_GRID`.
TABLES = ("probability", "expected", "mean", "std", "samples", "bin_mean", "no_result")
LONG_GRID = 1_000

#: A profile whose tables hold more numbers than this is written with a binary companion.
COMPANION_THRESHOLD = 100_000
#: The largest companion read: every table and the time grid at the largest size a file may
#: describe.
MAX_COMPANION_BYTES = (len(TABLES) + 1) * 8 * 10_000_000 + (1 << 20)

#: libyaml's loader where PyYAML was built with it (ten times faster), else the pure one; both
#: construct plain data only (the safe constructor).
FAST_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: A file describing more cells than this is refused before its tables are read: YAML aliases
#: can make a small file stand for an enormous table.
MAX_CELLS = 10_000_000

#: Numbers YAML 1.1 reads as strings: an exponent without a dot, or without a sign.
_EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")
_TAG = re.compile(r"could not determine a constructor for the tag '([^']*)'")


# --- reading ---------------------------------------------------------------------------------


def load_profile(path: str | os.PathLike[str]) -> ConditionalPerformanceProfile:
    """Read and validate a profile file; every problem is a `ProfileError` naming the file."""
    return read_profile_file(path)[0]


def read_profile_file(
    path: str | os.PathLike[str],
) -> tuple[ConditionalPerformanceProfile, Mapping[Any, Any]]:
    """The validated profile of a file and the file's mapping, the tables of its companion (if
    it has one) in it as arrays: what a reader of the fields beyond the profile's needs."""
    reader, data = read_document(path)
    fields = reader.fields(data)
    return reader.profile(fields), fields


def read_document(
    path: str | os.PathLike[str], tables: Sequence[str] = TABLES, kind: str = "profile files"
) -> tuple[_Reader, object]:
    """The parsed YAML document of a file of this format's family (a profile, a dynamic
    profile, traces), with the arrays of its companion, which may hold `tables`, read into it;
    and the reader that names the file (and the lines of its fields) in messages."""
    filename = os.fspath(path)
    try:
        data = read_input(path, limit=MAX_PROFILE_BYTES, kind=kind)
        text = data.decode("utf-8-sig").replace("\r\n", "\n").replace("\r", "\n")
    except UnicodeDecodeError as exc:
        bad = exc.object[exc.start : exc.start + 1].hex()
        raise ProfileError(
            f"{filename}: cannot read the file: expected UTF-8 text, got byte 0x{bad}"
            f" at offset {exc.start}"
        ) from None
    except OSError as exc:
        raise ProfileError(f"{filename}: cannot read the file: {exc.strerror or exc}") from None
    reader = _Reader(filename, text, tables)
    return reader, reader.with_companion(_parse_yaml(text, filename))


def _parse_yaml(text: str, filename: str) -> object:
    """The document, read by the fast loader; a document it refuses is read again by the pure
    one, whose messages (and marks) are the ones the format documents. What the document may
    expand to (aliases, nesting, integers) and duplicate keys are checked before either loads."""
    try:
        check_document(text, FAST_LOADER)
    except YAMLLimitError as exc:
        raise ProfileError(f"{filename}:{exc.line}:{exc.column}: {exc}") from None
    try:
        return yaml.load(text, Loader=FAST_LOADER)  # a safe loader: plain data only
    except yaml.YAMLError:
        pass
    try:
        return yaml.safe_load(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{filename}:{mark.line + 1}:{mark.column + 1}" if mark else filename
        tag = _TAG.match(exc.problem or "")
        if isinstance(exc, yaml.constructor.ConstructorError) and tag:
            name = tag.group(1).replace("tag:yaml.org,2002:", "!!")
            field = _field_at(text, mark.index) if mark else "top level"
            what = "a tag that would construct a Python object" if "python/" in name else "a tag"
            raise ProfileError(
                f"{where}: {field}: refused YAML tag {name!r} (expected plain data: numbers,"
                f" strings, lists and mappings, got {what})"
            ) from None
        problem = ", ".join(part for part in (exc.context, exc.problem) if part)
        raise ProfileError(f"{where}: not YAML: {problem}") from None
    except yaml.reader.ReaderError as exc:  # a character YAML does not allow
        line = text.count("\n", 0, exc.position) + 1
        column = exc.position - text.rfind("\n", 0, exc.position)
        raise ProfileError(
            f"{filename}:{line}:{column}: not YAML: unacceptable character"
            f" #x{exc.character:04x}: {exc.reason}"
        ) from None
    except yaml.YAMLError as exc:  # not raised by the loaders today; kept as a safety net
        raise ProfileError(f"{filename}: not YAML: {exc}") from None


def _field_at(text: str, index: int) -> str:
    """The top-level field whose value holds character `index` (composing builds no objects)."""
    root = yaml.compose(text, Loader=yaml.SafeLoader)  # the marks of the pure loader's message
    if isinstance(root, yaml.MappingNode):
        for key, value in root.value:
            if value.start_mark.index <= index <= value.end_mark.index:
                return str(key.value)
    return "top level"


def profile_from_dict(
    data: object, filename: str | os.PathLike[str]
) -> ConditionalPerformanceProfile:
    """Validate the parsed contents of a profile file and build the profile.

    `filename` prefixes every message, and its stem is the module name when none is given.
    """
    return _Reader(os.fspath(filename)).read(data)


class _Reader:
    """Reads one file's mapping, field by field, failing at the first problem."""

    def __init__(
        self, filename: str, text: str | None = None, tables: Sequence[str] = TABLES
    ) -> None:
        self.filename = filename
        self.text = text  # the file's text, when there is one: messages can then say where
        self.tables = tuple(tables)  # the tables a companion may hold (and the time grid)

    def fail(self, field: str, problem: str, *, at_line: bool = False) -> NoReturn:
        """Raise the `ProfileError`; with `at_line`, at the line and column of the value of the
        top-level `field` when the text is known."""
        where = self.filename
        if at_line and self.text is not None:
            mark = _value_mark(self.text, field)
            if mark is not None:
                where = f"{where}:{mark.line + 1}:{mark.column + 1}"
        raise ProfileError(f"{where}: {field}: {problem}")

    def read(self, data: object) -> ConditionalPerformanceProfile:
        return self.profile(self.fields(data))

    def with_companion(self, data: object) -> object:
        """`data` with the tables of the companion its `tables` field names read into it as
        arrays, once the companion is the one this header was written with."""
        if not isinstance(data, Mapping) or "tables" not in data:
            return data
        header = data["tables"]
        if not isinstance(header, Mapping) or sorted(header) != ["file", "sha256", "shapes"]:
            self.fail(
                "tables",
                "expected a mapping of file, sha256 and shapes (the companion written with"
                f" the profile), got {_describe(header)}",
            )
        name, shapes = header["file"], header["shapes"]
        if not isinstance(name, str) or not name.endswith(".npz") or Path(name).name != name:
            self.fail(
                "tables.file",
                f"expected the name of a .npz file beside this one, got {_describe(name)}",
            )
        if not isinstance(shapes, Mapping) or not shapes:
            self.fail(
                "tables.shapes", f"expected a mapping of table -> shape, got {_describe(shapes)}"
            )
        for key, shape in shapes.items():
            if key not in (*self.tables, "time"):
                self.fail(
                    f"tables.shapes.{key}",
                    f"expected one of {', '.join(self.tables)}, time; got {_describe(key)}",
                )
            if key in data:
                self.fail(key, "given both in this file and in its companion (expected one)")
            if not isinstance(shape, list) or not all(_is_count(n) for n in shape):
                self.fail(
                    f"tables.shapes.{key}",
                    f"expected a list of axis lengths, got {_describe(shape)}",
                )
        arrays = self.companion(name, str(header["sha256"]))
        if sorted(arrays) != sorted(shapes):
            self.fail(
                "tables.shapes",
                f"expected the companion '{name}' to hold {', '.join(sorted(shapes))},"
                f" got {', '.join(sorted(arrays)) or 'nothing'}",
            )
        for key, array in arrays.items():
            if list(array.shape) != shapes[key] or array.dtype.kind not in "fiu":
                self.fail(
                    f"tables.shapes.{key}",
                    f"expected numbers of shape {shapes[key]} (the header's), got"
                    f" {array.dtype} of shape {list(array.shape)} in the companion '{name}'",
                )
        rest = {key: value for key, value in data.items() if key != "tables"}
        return {**rest, **{key: a.astype(np.float64) for key, a in arrays.items()}}

    def companion(self, name: str, sha256: str) -> dict[str, Array]:
        """The arrays of the companion `name` beside the file, if its digest is `sha256`."""
        path = Path(self.filename).parent / name
        try:
            raw = read_input(path, limit=MAX_COMPANION_BYTES, kind="profile companions")
        except OSError as exc:
            self.fail("tables.file", f"cannot read the companion '{name}': {exc.strerror or exc}")
        digest = hashlib.sha256(raw).hexdigest()
        if digest != sha256:
            self.fail(
                "tables.sha256",
                f"the companion '{name}' is not the one this file was written with (expected"
                f" sha256 {sha256}, got {digest}): write the profile again",
            )
        try:
            with np.load(io.BytesIO(raw), allow_pickle=False) as archive:
                return {key: archive[key] for key in archive.files}
        except (OSError, ValueError, zipfile.BadZipFile) as exc:
            self.fail("tables.file", f"the companion '{name}' is not an archive of arrays: {exc}")

    def header(
        self,
        data: object,
        version: str,
        fields: Sequence[str],
        required: Mapping[str, str],
        loader: str,
    ) -> Mapping[Any, Any]:
        """The top-level mapping, once its format is `version`, every field one of `fields` and
        every field of `required` (name -> what it holds) given; `loader` is the function that
        reads such a file with its companion."""
        if not isinstance(data, Mapping):
            self.fail("top level", f"expected a mapping of fields, got {_describe(data)}")
        if "format" not in data:
            self.fail("format", f"missing field (expected {version!r}, got nothing)")
        if data["format"] != version:
            self.fail(
                "format",
                f"unknown format version (expected {version!r}, got {_describe(data['format'])})",
            )
        if "tables" in data:  # `with_companion` reads them into the mapping
            self.fail("tables", f"a companion is read with its file ({loader}), not here")
        for key in data:
            if key not in fields:
                hint = did_you_mean(str(key), fields, separator=", ")
                self.fail(
                    str(key),
                    f"unknown field{hint} (expected one of {', '.join(fields)};"
                    f" got {_describe(key)})",
                )
        for key, what in required.items():
            if key not in data:
                self.fail(key, f"missing field (expected {what}, got nothing)")
        return data

    def fields(self, data: object) -> Mapping[Any, Any]:
        """The top-level mapping, once the version, the field names and the choices are right."""
        required = {"time": "a list of times", "quality_bins": "a list of bin edges"}
        data = self.header(data, FORMAT, FIELDS, required, "load_profile")
        if "probability" in data and "expected" in data:
            self.fail("probability", "expected exactly one of probability and expected, got both")
        if "probability" not in data and "expected" not in data:
            self.fail(
                "probability", "missing field (expected probability or expected, got neither)"
            )
        if "expected" in data and "mean" in data:
            self.fail(
                "mean",
                "not allowed next to expected, which is the mean"
                " (expected mean only with probability, got both)",
            )
        if "expected" in data and "bin_mean" in data:
            self.fail(
                "bin_mean",
                "not allowed next to expected, whose point masses stand for their quality"
                " (expected bin_mean only with probability, got both)",
            )
        return data

    def profile(self, data: Mapping[Any, Any]) -> ConditionalPerformanceProfile:
        module = self.name("module", data.get("module", Path(self.filename).stem))
        kind = cast(Kind, self.choice("kind", data.get("kind", "interruptible"), KINDS))
        time_unit = cast(
            TimeUnit, self.choice("time_unit", data.get("time_unit", "ticks"), TIME_UNITS)
        )
        step = self.step(data["step"]) if "step" in data else None
        grids = self.input_grids(data.get("input_quality", []))
        inputs = self.inputs(data["inputs"], len(grids)) if "inputs" in data else ()
        time = self.grid("time", data["time"], minimum=1, quality=False)
        bins = self.grid("quality_bins", data["quality_bins"], minimum=2, quality=True)

        names = inputs or tuple(f"input_quality[{i}]" for i in range(len(grids)))
        cells = (*(len(g) for g in grids), len(time))
        axes = (*(f"one per {name} quality" for name in names), "one per time")
        if np.prod(cells, dtype=np.float64) * (len(bins) - 1) > MAX_CELLS:
            self.fail(
                "probability" if "probability" in data else "expected",
                f"expected at most {MAX_CELLS} cells, got shape {[*cells, len(bins) - 1]}",
            )

        def optional(key: str, *, quality: bool = False) -> Array | None:
            return self.table(key, data[key], cells, axes, quality=quality) if key in data else None

        mean: Array | None
        bin_mean: Array | None = None
        if "expected" in data:
            mean = self.table("expected", data["expected"], cells, axes, quality=True)
            self.within_bins(mean, bins)
            probability = point_mass(mean, bins)
        else:
            shape, bin_axes = (*cells, len(bins) - 1), (*axes, "one per quality bin")
            probability = self.table("probability", data["probability"], shape, bin_axes)
            mean = optional("mean", quality=True)
            if "bin_mean" in data:  # the class checks each against its bin's edges
                bin_mean = self.table("bin_mean", data["bin_mean"], shape, bin_axes)
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
            self.refile(exc, module or "profile")

    def refile(self, error: ProfileError, name: str) -> NoReturn:
        """Raise `error`, an invariant of a class named `name` in its messages, as this file's."""
        message = str(error).removeprefix(f"{name}: ")
        raise ProfileError(f"{self.filename}: {message}") from None

    # --- scalars -------------------------------------------------------------------------

    def name(self, field: str, value: object) -> str:
        if not isinstance(value, str) or not value:
            self.fail(field, f"expected a name (a non-empty string), got {_describe(value)}")
        return value

    def choice(self, field: str, value: object, options: Sequence[str]) -> str:
        if not isinstance(value, str) or value not in options:
            expected = " or ".join(repr(option) for option in options)
            self.fail(field, f"expected {expected}, got {_describe(value)}")
        return value

    def step(self, value: object) -> float:
        """The module's step: a finite number >= 0 (a file gives no null: leave it out)."""
        expected = "a finite number >= 0 (the module's step, in time_unit)"
        if isinstance(value, bool) or not isinstance(value, int | float):
            hint = ""
            if isinstance(value, str) and _EXPONENT.match(value):
                hint = (
                    " (YAML reads it as a string: write a dot and a signed exponent, as in 1.0e+3)"
                )
            self.fail("step", f"expected {expected}, got {_describe(value)}{hint}", at_line=True)
        try:
            step = float(value)
        except OverflowError:
            self.fail("step", f"expected {expected}, got {value}", at_line=True)
        if not np.isfinite(step) or step < 0:
            self.fail("step", f"expected {expected}, got {_format(step)}", at_line=True)
        return step

    def inputs(self, value: object, n_grids: int) -> tuple[str, ...]:
        if not isinstance(value, list):
            self.fail("inputs", f"expected a list of names, got {_describe(value)}")
        names = tuple(self.name(f"inputs[{i}]", item) for i, item in enumerate(value))
        for i, name in enumerate(names):
            if name in names[:i]:
                self.fail(f"inputs[{i}]", f"expected distinct names, got {name!r} twice")
        if len(names) != n_grids:
            self.fail(
                "inputs",
                f"expected {_count(n_grids, 'name')} (one per input_quality grid),"
                f" got {len(names)}",
            )
        return names

    # --- arrays --------------------------------------------------------------------------

    def number(self, field: str, value: object) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            hint = ""
            if isinstance(value, str) and _EXPONENT.match(value):
                hint = (
                    " (YAML reads it as a string: write a dot and a signed exponent, as in 1.0e+3)"
                )
            self.fail(field, f"expected a number, got {_describe(value)}{hint}")
        try:
            return float(value)
        except OverflowError:
            self.fail(field, f"expected a finite number, got {value}")

    def input_grids(self, value: object) -> list[Array]:
        if not isinstance(value, list):
            self.fail(
                "input_quality", f"expected a list of grids (one per input), got {_describe(value)}"
            )
        return [
            self.grid(f"input_quality[{i}]", grid, minimum=1, quality=True)
            for i, grid in enumerate(value)
        ]

    def grid(self, field: str, value: object, *, minimum: int, quality: bool) -> Array:
        """A 1-D list of numbers (or a companion's array); the class checks that it increases."""
        if isinstance(value, np.ndarray) and value.ndim == 1 and len(value) >= minimum:
            return self.checked(field, value, quality)
        if not isinstance(value, list) or len(value) < minimum:
            self.fail(
                field,
                f"expected a list of at least {_count(minimum, 'number')}, got {_describe(value)}",
            )
        grid = np.array([self.number(f"{field}[{i}]", x) for i, x in enumerate(value)])
        return self.checked(field, grid, quality)

    def table(
        self,
        field: str,
        value: object,
        shape: tuple[int, ...],
        axes: Sequence[str],
        *,
        quality: bool = False,
    ) -> Array:
        """A nested list of exactly `shape` (or a companion's array); the first deviation is
        named by its index."""
        if isinstance(value, np.ndarray):  # from the companion, whose shapes the header gave
            if value.shape != shape:
                self.fail(
                    field,
                    f"expected shape {list(shape)} ({', '.join(axes)}), got {list(value.shape)}"
                    " in the companion",
                )
            return self.checked(field, value, quality)
        fast = _plain_table(value, shape)
        if fast is not None:
            return self.checked(field, fast, quality)
        flat: list[float] = []

        def walk(node: object, depth: int, where: str) -> None:
            if depth == len(shape):
                flat.append(self.number(where, node))
                return
            n = shape[depth]
            what = f"a list of {_count(n, 'number') if depth == len(shape) - 1 else n}"
            if not isinstance(node, list) or len(node) != n:
                self.fail(where, f"expected {what} ({axes[depth]}), got {_describe(node)}")
            for i, item in enumerate(node):
                walk(item, depth + 1, f"{where}[{i}]")

        walk(value, 0, field)
        return self.checked(field, np.array(flat, dtype=np.float64).reshape(shape), quality)

    def checked(self, field: str, table: Array, quality: bool) -> Array:
        self.non_negative(field, table)
        if quality:
            self.in_unit_interval(field, table)
        return table

    # --- values (vectorised; the first offending cell is named) --------------------------

    def check(self, field: str, array: Array, bad: NDArray[np.bool_], expected: str) -> None:
        if np.any(bad):
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            where = field + "".join(f"[{i}]" for i in index)
            self.fail(where, f"expected {expected}, got {_format(float(array[index]))}")

    def non_negative(self, field: str, array: Array) -> None:
        self.check(field, array, ~np.isfinite(array), "a finite number")
        self.check(field, array, array < 0, "a number >= 0")

    def in_unit_interval(self, field: str, array: Array) -> None:
        self.check(field, array, (array < 0) | (array > 1), "a quality in [0, 1]")

    def within_bins(self, mean: Array, bins: Array) -> None:
        low, high = _format(float(bins[0])), _format(float(bins[-1]))
        outside = (mean < bins[0]) | (mean > bins[-1])
        self.check("expected", mean, outside, f"a quality within the bins [{low}, {high}]")


def _value_mark(text: str, field: str) -> yaml.Mark | None:
    """Where the value of the top-level `field` starts (composing builds no objects)."""
    try:
        root = yaml.compose(text, Loader=FAST_LOADER)
    except yaml.YAMLError:  # cannot happen for text that loaded; kept as a safety net
        return None
    if isinstance(root, yaml.MappingNode):
        for key, value in root.value:
            if isinstance(key, yaml.ScalarNode) and key.value == field:
                return cast(yaml.Mark, value.start_mark)
    return None


def _plain_table(value: object, shape: tuple[int, ...]) -> Array | None:
    """`value` as an array when it is a nested list of exactly `shape` whose cells are all
    plain numbers, in a few passes over the cells instead of a walk; None when it is not, for
    the walk to name the first problem."""
    if not isinstance(value, list):
        return None
    try:
        cells = np.array(value, dtype=object)
    except ValueError:  # ragged
        return None
    if cells.shape != shape or not {type(x) for x in cells.flat} <= {int, float}:
        return None
    try:
        return cells.astype(np.float64)
    except OverflowError:  # an integer beyond float
        return None


def _is_count(n: object) -> bool:
    return isinstance(n, int) and not isinstance(n, bool) and n >= 0


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _format(x: float) -> str:
    """A number as YAML would show it: `.nan`, `-.inf`, integers without `.0`."""
    if np.isnan(x):
        return ".nan"
    if np.isinf(x):
        return ".inf" if x > 0 else "-.inf"
    if x.is_integer() and abs(x) < 2**53:
        return str(int(x))
    return repr(x)


def _describe(value: object) -> str:
    """What a parsed YAML value is, for a message."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return _format(value)
    if isinstance(value, int | str):
        return repr(value)
    if isinstance(value, list):
        return f"a list of {len(value)}" if value else "an empty list"
    if isinstance(value, Mapping):
        return "a mapping"
    return f"{value} (a {type(value).__name__})"


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


def is_large(tables: Mapping[str, Array]) -> bool:
    """Whether `tables` hold more numbers than `COMPANION_THRESHOLD`: a companion's job."""
    return sum(table.size for table in tables.values()) > COMPANION_THRESHOLD


def place_tables(
    data: dict[str, Any], tables: Mapping[str, Array], path: Path, companion: bool
) -> None:
    """Add `tables` to the mapping `data` of the file `path`: as plain lists, or (`companion`)
    written into the binary companion beside it, which `data` then names with its digest."""
    if companion:
        data["tables"] = _write_companion(tables, path)
    else:
        data.update((key, plain(table)) for key, table in tables.items())


def write_document(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Write the mapping `data` to `path` as YAML, atomically, in the order of its keys."""
    text = yaml.dump(
        dict(data),
        Dumper=_Dumper,
        sort_keys=False,
        default_flow_style=False,
        allow_unicode=True,
        width=1_000_000,  # one row of a table per line, however many bins
    )
    write_atomic(path, text)


def _write_companion(tables: Mapping[str, Array], path: Path) -> dict[str, Any]:
    """Write `tables` as the companion of the file `path`; the file's `tables` field."""
    target = path.with_name(f"{path.stem}.npz")
    if target.name == path.name:  # the header would overwrite its own companion
        raise OutputFileError(
            errno.EINVAL, "a profile with a companion cannot itself be named .npz", str(path)
        )
    buffer = io.BytesIO()
    arrays = {key: np.asarray(table, dtype=np.float64) for key, table in tables.items()}
    cast(Any, np.savez)(buffer, **arrays)  # numpy's stubs take the names for its keywords
    raw = buffer.getvalue()
    write_atomic(target, raw)
    return {
        "file": target.name,
        "sha256": hashlib.sha256(raw).hexdigest(),
        "shapes": {key: list(table.shape) for key, table in tables.items()},
    }


def _is_point_mass(profile: ConditionalPerformanceProfile) -> bool:
    """Whether the file can say `expected: mean` and be read back as this very profile."""
    mean = profile.mean
    return (
        mean is not None
        and profile.bin_mean is None  # which the `expected` form cannot carry
        and bool(np.all((mean >= profile.bins[0]) & (mean <= profile.bins[-1])))
        and np.array_equal(profile.probability, point_mass(mean, profile.bins))
    )


def plain(array: Array) -> Any:
    """Nested lists of Python numbers; floats keep full precision, integral ones print as ints."""

    def number(x: Any) -> Any:
        if isinstance(x, list):
            return [number(item) for item in x]
        return int(x) if x.is_integer() and abs(x) < 2**53 else x

    return number(array.tolist())


class _Dumper(yaml.SafeDumper):
    """The safe dumper, indenting lists under their key and writing the innermost ones inline."""

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        super().increase_indent(flow, False)


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.SequenceNode:
    inline = not any(isinstance(item, list) for item in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=inline)


_Dumper.add_representer(list, _represent_list)
