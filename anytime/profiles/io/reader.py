"""Reading a file of the profile family field by field: the first problem is a `ProfileError`
saying `FILE: field: what is wrong (expected ..., got ...)`, with the line and column of the
field's value where it helps (`FILE:LINE:COL: ...`). YAML 1.1 reads `1e-3` and `1.0e3` as
strings: such a number gets a hint to write a dot and a signed exponent, `1.0e-3`, `1.0e+3`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray

from anytime.errors import ProfileError
from anytime.files import MAX_PROFILE_BYTES, read_input
from anytime.profiles.io.companion import with_companion
from anytime.profiles.io.document import (
    EXPONENT,
    count,
    describe,
    format_number,
    parse_yaml,
    value_mark,
)
from anytime.profiles.profile import Array
from anytime.text import did_you_mean


def read_document(
    path: str | os.PathLike[str], tables: Sequence[str], kind: str
) -> tuple[Reader, object]:
    """The parsed YAML document of a file of the profile family (a profile, a dynamic profile,
    traces; `kind` names them in messages), with the arrays of its companion, which may hold
    `tables`, read into it; and the reader that names the file (and the lines of its fields)
    in messages."""
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
    reader = Reader(filename, text, tables)
    return reader, reader.with_companion(parse_yaml(text, filename))


class Reader:
    """Reads one file's mapping, field by field, failing at the first problem."""

    def __init__(self, filename: str, text: str | None = None, tables: Sequence[str] = ()) -> None:
        self.filename = filename
        self.text = text  # the file's text, when there is one: messages can then say where
        self.tables = tuple(tables)  # the tables a companion may hold (and the time grid)

    def fail(self, field: str, problem: str, *, at_line: bool = False) -> NoReturn:
        """Raise the `ProfileError`; with `at_line`, at the line and column of the value of the
        top-level `field` when the text is known."""
        where = self.filename
        if at_line and self.text is not None:
            mark = value_mark(self.text, field)
            if mark is not None:
                where = f"{where}:{mark.line + 1}:{mark.column + 1}"
        raise ProfileError(f"{where}: {field}: {problem}")

    def with_companion(self, data: object) -> object:
        """`data` with the tables of the companion its `tables` field names read into it."""
        return with_companion(data, self.filename, self.tables, self.fail)

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
            self.fail("top level", f"expected a mapping of fields, got {describe(data)}")
        if "format" not in data:
            self.fail("format", f"missing field (expected {version!r}, got nothing)")
        if data["format"] != version:
            self.fail(
                "format",
                f"unknown format version (expected {version!r}, got {describe(data['format'])})",
            )
        if "tables" in data:  # `with_companion` reads them into the mapping
            self.fail("tables", f"a companion is read with its file ({loader}), not here")
        for key in data:
            if key not in fields:
                hint = did_you_mean(str(key), fields, separator=", ")
                self.fail(
                    str(key),
                    f"unknown field{hint} (expected one of {', '.join(fields)};"
                    f" got {describe(key)})",
                )
        for key, what in required.items():
            if key not in data:
                self.fail(key, f"missing field (expected {what}, got nothing)")
        return data

    def refile(self, error: ProfileError, name: str) -> NoReturn:
        """Raise `error`, an invariant of a class named `name` in its messages, as this file's."""
        message = str(error).removeprefix(f"{name}: ")
        raise ProfileError(f"{self.filename}: {message}") from None

    # --- scalars -------------------------------------------------------------------------

    def name(self, field: str, value: object) -> str:
        if not isinstance(value, str) or not value:
            self.fail(field, f"expected a name (a non-empty string), got {describe(value)}")
        return value

    def choice(self, field: str, value: object, options: Sequence[str]) -> str:
        if not isinstance(value, str) or value not in options:
            expected = " or ".join(repr(option) for option in options)
            self.fail(field, f"expected {expected}, got {describe(value)}")
        return value

    def inputs(self, value: object, n_grids: int) -> tuple[str, ...]:
        if not isinstance(value, list):
            self.fail("inputs", f"expected a list of names, got {describe(value)}")
        names = tuple(self.name(f"inputs[{i}]", item) for i, item in enumerate(value))
        for i, name in enumerate(names):
            if name in names[:i]:
                self.fail(f"inputs[{i}]", f"expected distinct names, got {name!r} twice")
        if len(names) != n_grids:
            self.fail(
                "inputs",
                f"expected {count(n_grids, 'name')} (one per input_quality grid), got {len(names)}",
            )
        return names

    # --- arrays --------------------------------------------------------------------------

    def number(self, field: str, value: object) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            hint = ""
            if isinstance(value, str) and EXPONENT.match(value):
                hint = (
                    " (YAML reads it as a string: write a dot and a signed exponent, as in 1.0e+3)"
                )
            self.fail(field, f"expected a number, got {describe(value)}{hint}")
        try:
            return float(value)
        except OverflowError:
            self.fail(field, f"expected a finite number, got {value}")

    def input_grids(self, value: object) -> list[Array]:
        if not isinstance(value, list):
            self.fail(
                "input_quality", f"expected a list of grids (one per input), got {describe(value)}"
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
                f"expected a list of at least {count(minimum, 'number')}, got {describe(value)}",
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
        fast = plain_table(value, shape)
        if fast is not None:
            return self.checked(field, fast, quality)
        flat: list[float] = []

        def walk(node: object, depth: int, where: str) -> None:
            if depth == len(shape):
                flat.append(self.number(where, node))
                return
            n = shape[depth]
            what = f"a list of {count(n, 'number') if depth == len(shape) - 1 else n}"
            if not isinstance(node, list) or len(node) != n:
                self.fail(where, f"expected {what} ({axes[depth]}), got {describe(node)}")
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
            self.fail(where, f"expected {expected}, got {format_number(float(array[index]))}")

    def non_negative(self, field: str, array: Array) -> None:
        self.check(field, array, ~np.isfinite(array), "a finite number")
        self.check(field, array, array < 0, "a number >= 0")

    def in_unit_interval(self, field: str, array: Array) -> None:
        self.check(field, array, (array < 0) | (array > 1), "a quality in [0, 1]")


def plain_table(value: object, shape: tuple[int, ...]) -> Array | None:
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
