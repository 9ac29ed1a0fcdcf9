"""The binary companion of a file of the profile family: its large tables in numpy's
uncompressed archive beside it (`NAME.npz` for `NAME.yaml`, read with pickles refused).

The file then has `tables: {file, sha256, shapes}` in their place, and a companion whose digest
or shapes are not the header's is an error, as is a table given in both. Writers add it when the
tables hold more than `COMPANION_THRESHOLD` numbers: a million-cell table loads in under a
second, not a minute.
"""

from __future__ import annotations

import errno
import hashlib
import io
import zipfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn, cast

import numpy as np

from anytime.files import OutputFileError, read_input, write_atomic
from anytime.profiles.io.document import MAX_CELLS, describe, is_count, plain
from anytime.profiles.profile import Array

#: How a reader reports a problem with a field (it names the file): `Reader.fail`.
Fail = Callable[[str, str], NoReturn]

#: A profile whose tables hold more numbers than this is written with a binary companion.
COMPANION_THRESHOLD = 100_000
#: The largest companion read: every table of a profile (seven, the most of any file of the
#: family) and the time grid at the largest size a file may describe.
MAX_COMPANION_BYTES = (7 + 1) * 8 * MAX_CELLS + (1 << 20)


# --- reading ---------------------------------------------------------------------------------


def with_companion(data: object, filename: str, tables: Sequence[str], fail: Fail) -> object:
    """`data`, the mapping of the file `filename`, with the tables of the companion its `tables`
    field names read into it as arrays, once the companion is the one this header was written
    with; the companion may hold `tables` and the time grid."""
    if not isinstance(data, Mapping) or "tables" not in data:
        return data
    header = data["tables"]
    if not isinstance(header, Mapping) or sorted(header) != ["file", "sha256", "shapes"]:
        fail(
            "tables",
            "expected a mapping of file, sha256 and shapes (the companion written with"
            f" the profile), got {describe(header)}",
        )
    name, shapes = header["file"], header["shapes"]
    if not isinstance(name, str) or not name.endswith(".npz") or Path(name).name != name:
        fail(
            "tables.file",
            f"expected the name of a .npz file beside this one, got {describe(name)}",
        )
    if not isinstance(shapes, Mapping) or not shapes:
        fail("tables.shapes", f"expected a mapping of table -> shape, got {describe(shapes)}")
    for key, shape in shapes.items():
        if key not in (*tables, "time"):
            fail(
                f"tables.shapes.{key}",
                f"expected one of {', '.join(tables)}, time; got {describe(key)}",
            )
        if key in data:
            fail(key, "given both in this file and in its companion (expected one)")
        if not isinstance(shape, list) or not all(is_count(n) for n in shape):
            fail(
                f"tables.shapes.{key}",
                f"expected a list of axis lengths, got {describe(shape)}",
            )
    arrays = read_archive(filename, name, str(header["sha256"]), fail)
    if sorted(arrays) != sorted(shapes):
        fail(
            "tables.shapes",
            f"expected the companion '{name}' to hold {', '.join(sorted(shapes))},"
            f" got {', '.join(sorted(arrays)) or 'nothing'}",
        )
    for key, array in arrays.items():
        if list(array.shape) != shapes[key] or array.dtype.kind not in "fiu":
            fail(
                f"tables.shapes.{key}",
                f"expected numbers of shape {shapes[key]} (the header's), got"
                f" {array.dtype} of shape {list(array.shape)} in the companion '{name}'",
            )
    rest = {key: value for key, value in data.items() if key != "tables"}
    return {**rest, **{key: a.astype(np.float64) for key, a in arrays.items()}}


def read_archive(filename: str, name: str, sha256: str, fail: Fail) -> dict[str, Array]:
    """The arrays of the companion `name` beside the file `filename`, if its digest is
    `sha256`."""
    path = Path(filename).parent / name
    try:
        raw = read_input(path, limit=MAX_COMPANION_BYTES, kind="profile companions")
    except OSError as exc:
        fail("tables.file", f"cannot read the companion '{name}': {exc.strerror or exc}")
    digest = hashlib.sha256(raw).hexdigest()
    if digest != sha256:
        fail(
            "tables.sha256",
            f"the companion '{name}' is not the one this file was written with (expected"
            f" sha256 {sha256}, got {digest}): write the profile again",
        )
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as archive:
            return {key: archive[key] for key in archive.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        fail("tables.file", f"the companion '{name}' is not an archive of arrays: {exc}")


# --- writing ---------------------------------------------------------------------------------


def is_large(tables: Mapping[str, Array]) -> bool:
    """Whether `tables` hold more numbers than `COMPANION_THRESHOLD`: a companion's job."""
    return sum(table.size for table in tables.values()) > COMPANION_THRESHOLD


def place_tables(
    data: dict[str, Any], tables: Mapping[str, Array], path: Path, companion: bool
) -> None:
    """Add `tables` to the mapping `data` of the file `path`: as plain lists, or (`companion`)
    written into the binary companion beside it, which `data` then names with its digest."""
    if companion:
        data["tables"] = write_companion(tables, path)
    else:
        data.update((key, plain(table)) for key, table in tables.items())


def write_companion(tables: Mapping[str, Array], path: Path) -> dict[str, Any]:
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
