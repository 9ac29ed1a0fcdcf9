"""The binary companion of a file of the profile family: its large tables in numpy's
uncompressed archive beside it (`NAME.npz` for `NAME.yaml`, read with pickles refused).

The file then has `tables: {file, sha256, shapes}` in their place, and a companion whose digest
or shapes are not the header's is an error, as is a table given in both. Writers add it when the
tables hold more than `COMPANION_THRESHOLD` numbers: a million-cell table loads in under a
second, not a minute.

A companion is judged before it is decompressed (`read_archive`): every declared shape has at
most `MAX_CELLS` cells, the zip directory lists at most `MAX_MEMBERS` members, and each member's
`.npy` header, read alone, must declare its table's shape and numbers of at most 8 bytes, and
its size in the directory must be the one that header implies. A zip bomb, or a header that
lies, is a `ProfileError` naming the file, the field and the member, not "out of memory".
"""

from __future__ import annotations

import errno
import hashlib
import io
import math
import zipfile
import zlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import IO, Any, NoReturn, cast

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
        if math.prod(shape) > MAX_CELLS:  # refused before the companion is opened
            fail(
                f"tables.shapes.{key}",
                f"expected at most {MAX_CELLS} cells, got shape {shape}"
                f" ({math.prod(shape):,} cells)",
            )
    arrays = read_archive(filename, name, str(header["sha256"]), shapes, fail)
    rest = {key: value for key, value in data.items() if key != "tables"}
    return {**rest, **{key: a.astype(np.float64) for key, a in arrays.items()}}


def read_archive(
    filename: str, name: str, sha256: str, shapes: Mapping[str, list[int]], fail: Fail
) -> dict[str, Array]:
    """The arrays of the companion `name` beside the file `filename`, if its digest is
    `sha256` and it holds the tables `shapes` declares (table -> shape), each of that shape.

    A member is judged before it is decompressed: its `.npy` header (read alone, a few hundred
    bytes) must declare the shape of `shapes` and numbers, and the member's uncompressed size
    in the zip directory must be the one that header implies. The zip reader decompresses no
    more than that size (a longer stream fails its CRC), so a small archive that would expand
    to gigabytes (a zip bomb) costs what its declared table costs, at most `MAX_CELLS` cells.
    """
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

    def damaged(exc: object) -> NoReturn:
        fail("tables.file", f"the companion '{name}' is not an archive of arrays: {exc}")

    try:
        listed = _listed(raw)
    except _ARCHIVE_ERRORS as exc:
        damaged(exc)
    if listed is not None and listed > MAX_MEMBERS:  # before a ZipInfo is made for each
        damaged(f"its directory lists {listed:,} members (at most {MAX_MEMBERS})")
    try:
        archive = zipfile.ZipFile(io.BytesIO(raw))
        infos = archive.infolist()
    except _ARCHIVE_ERRORS as exc:
        damaged(exc)
    members: dict[str, tuple[zipfile.ZipInfo, _Header]] = {}
    for info in infos:
        key = info.filename.removesuffix(".npy")
        if key in members:
            damaged(f"it holds '{info.filename}' twice")
        try:  # the header alone: a few hundred bytes, whatever the member expands to
            with archive.open(info) as member:
                header = _npy_header(member)
        except _ARCHIVE_ERRORS as exc:
            damaged(exc)
        if header[2].hasobject:
            damaged("Object arrays cannot be loaded when allow_pickle=False")
        members[key] = info, header
    if sorted(members) != sorted(shapes):
        fail(
            "tables.shapes",
            f"expected the companion '{name}' to hold {', '.join(sorted(shapes))},"
            f" got {', '.join(sorted(members)) or 'nothing'}",
        )
    arrays = {}
    for key, (info, (shape, fortran, dtype, start)) in members.items():
        if list(shape) != shapes[key] or dtype.kind not in "fiu" or dtype.itemsize > 8:
            fail(
                f"tables.shapes.{key}",
                f"expected numbers of shape {shapes[key]} (the header's), got"
                f" {dtype} of shape {list(shape)} in the companion '{name}'",
            )
        size = start + math.prod(shape) * dtype.itemsize
        if info.file_size != size:  # a header that lies about what follows it
            fail(
                "tables.file",
                f"the companion '{name}' is damaged or forged: its member '{info.filename}'"
                f" holds {info.file_size:,} bytes, where its header ({dtype} of shape"
                f" {list(shape)}) says {size:,}",
            )
        try:
            with archive.open(info) as member:
                member.read(start)  # the header, read above
                body = member.read(size - start)  # the CRC is checked at the member's end
        except _ARCHIVE_ERRORS as exc:
            damaged(exc)
        if len(body) != size - start:  # cannot happen once the CRC held; kept as a net
            damaged(f"its member '{info.filename}' ends early")
        array = np.frombuffer(body, dtype=dtype)
        arrays[key] = array.reshape(shape, order="F" if fortran else "C")
    return arrays


#: The most members a companion's zip directory may list (it holds at most the seven tables and
#: the time grid): millions of tiny entries would cost gigabytes of directory objects.
MAX_MEMBERS = 64


def _listed(raw: bytes) -> int | None:
    """How many members the zip directory of `raw` says it lists (its end record, zip64
    included), read without listing them; None when it cannot tell (ZipFile then says why)."""
    end_record = getattr(zipfile, "_EndRecData", None)  # the one zipfile reads itself
    record = end_record(io.BytesIO(raw)) if end_record is not None else None
    return int(record[4]) if record else None  # zipfile._ECD_ENTRIES_TOTAL


#: What reading a damaged archive raises (a bad CRC, a truncated or unknown stream, a bad header).
_ARCHIVE_ERRORS = (
    OSError,
    EOFError,
    ValueError,
    RuntimeError,  # an encrypted member
    NotImplementedError,  # an unknown compression method
    zipfile.BadZipFile,
    zlib.error,
)


#: What a `.npy` header declares: shape, Fortran order, dtype, and where the data starts.
_Header = tuple[tuple[int, ...], bool, np.dtype[Any], int]


def _npy_header(member: IO[bytes]) -> _Header:
    """The shape, order and dtype a `.npy` stream declares, and where its data starts; only the
    header is read (numpy bounds its length)."""
    version = np.lib.format.read_magic(member)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(member)
    elif version == (2, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(member)
    else:
        raise ValueError(f"unsupported .npy format version {version[0]}.{version[1]}")
    return shape, fortran, dtype, member.tell()


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
