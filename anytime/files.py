"""Reading input files safely and writing output files atomically.

`read_input` reads a file the user named (a schema, a profile, a map...) only if it is a
regular file no larger than a stated limit: a FIFO, a device such as `/dev/zero` or a directory
is refused after an `os.stat`, before it is opened, so it can neither hang the reader nor fill
its memory. The refusal is an `InputFileError`, an `OSError` whose `strerror` says what is wrong
in a few words (callers that report `cannot read 'FILE': STRERROR` need nothing more).

`write_atomic` and `atomic_path` write an output file through a temporary file in the same
directory, renamed over the target with `os.replace` once it is complete: an interrupted run
leaves the old file or none, never half of a new one.
"""

from __future__ import annotations

import errno
import os
import secrets
import stat
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from anytime.errors import AnytimeError

__all__ = [
    "MAX_PROFILE_BYTES",
    "MAX_SCHEMA_BYTES",
    "InputFileError",
    "OutputFileError",
    "atomic_path",
    "format_size",
    "read_input",
    "write_atomic",
]

#: The largest schema file read (schemas are a few kilobytes).
MAX_SCHEMA_BYTES = 1 << 20
#: The largest profile file read (a measured profile of the shipped modules is about 25 KiB).
MAX_PROFILE_BYTES = 64 << 20

_KINDS = {
    stat.S_IFIFO: "a FIFO",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
    stat.S_IFLNK: "a symbolic link",
}


class InputFileError(AnytimeError, OSError):
    """An input file refused unread: not a regular file, or over its size limit.

    `filename` is the path as given; `strerror` says what is wrong ("not a regular file (a
    FIFO)"); the message is `cannot read 'FILE': STRERROR`."""

    def __init__(self, filename: str, problem: str) -> None:
        super().__init__(errno.EINVAL, problem, filename)

    def __str__(self) -> str:
        return f"cannot read '{self.filename}': {self.strerror}"


class OutputFileError(AnytimeError, OSError):
    """An output file could not be written (`atomic_path`, `write_atomic`); the file that was
    there, if any, is unchanged. The message is `cannot write 'FILE': STRERROR`."""

    def __str__(self) -> str:
        return f"cannot write '{self.filename}': {self.strerror}"


def format_size(n: int) -> str:
    """A byte count for messages: '512 bytes', '1 MiB', '5.2 GiB'."""
    if n < 1024:
        return f"{n} bytes"
    value = float(n)
    for unit in ("KiB", "MiB", "GiB", "TiB"):
        value /= 1024
        if value < 1024 or unit == "TiB":
            break
    return f"{value:.0f} {unit}" if value == int(value) else f"{value:.1f} {unit}"


def _refuse_unless_regular(filename: str, mode: int) -> None:
    if stat.S_ISDIR(mode):  # as the system says it
        raise InputFileError(filename, os.strerror(errno.EISDIR))
    if not stat.S_ISREG(mode):
        kind = _KINDS.get(stat.S_IFMT(mode), "not a file")
        raise InputFileError(filename, f"not a regular file ({kind})")


def _refuse_if_larger(filename: str, size: int, limit: int, kind: str) -> None:
    if size > limit:
        raise InputFileError(
            filename, f"larger than the {format_size(limit)} limit for {kind} ({size:,} bytes)"
        )


def read_input(path: str | os.PathLike[str], *, limit: int, kind: str = "input files") -> bytes:
    """The bytes of the regular file `path`, at most `limit` of them.

    Args:
        limit: the largest size accepted, in bytes.
        kind: what such files are called in the message ("schema files").

    Raises:
        InputFileError: `path` is not a regular file (a FIFO, a device, a directory...) or is
            larger than `limit`; it is not read (a FIFO is never opened).
        OSError: it cannot be read (missing, no permission...).
    """
    filename = os.fspath(path)
    info = os.stat(filename)  # before opening: opening a FIFO would wait for a writer
    _refuse_unless_regular(filename, info.st_mode)
    _refuse_if_larger(filename, info.st_size, limit, kind)
    # Non-blocking, in case the file was swapped for a FIFO since the stat; checked again.
    fd = os.open(filename, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    with open(fd, "rb", closefd=True) as stream:
        info = os.fstat(stream.fileno())
        _refuse_unless_regular(filename, info.st_mode)
        data = stream.read(limit + 1)
    _refuse_if_larger(filename, max(len(data), info.st_size), limit, kind)
    return data


def _temporary(target: Path) -> Path:
    """A new empty file next to `target`, named after it and keeping its suffix (writers such
    as image libraries read the format from it)."""
    for _ in range(100):
        token = secrets.token_hex(4)
        temp = target.with_name(f".{target.stem}.{token}.partial{target.suffix}")
        try:
            fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return temp
    raise FileExistsError(errno.EEXIST, "no free temporary name", os.fspath(target))


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path to write `path`'s new content to; renamed over `path` when the block
    ends without an exception, removed when it raises (KeyboardInterrupt included).

    The temporary file is in the same directory (so the rename is atomic), with the same
    suffix. An existing file's permissions are kept. A target that exists and is not a regular
    file (`/dev/null`, a FIFO) is written in place; a directory is refused.

    Raises:
        OutputFileError: an OSError writing the file (an `OSError` naming `path`, not the
            temporary file, with what went wrong in `strerror`).
    """
    filename = os.fspath(path)
    target = Path(os.path.realpath(filename))  # write through a symbolic link, not over it
    try:
        info: os.stat_result | None = os.stat(target)
    except FileNotFoundError:
        info = None
    if info is not None and stat.S_ISDIR(info.st_mode):
        raise OutputFileError(errno.EISDIR, os.strerror(errno.EISDIR), filename)
    if info is not None and not stat.S_ISREG(info.st_mode):
        yield Path(filename)
        return
    try:
        temp = _temporary(target)
    except OSError as error:
        raise OutputFileError(error.errno, error.strerror, filename) from None
    try:
        if info is not None:
            os.chmod(temp, stat.S_IMODE(info.st_mode))
        yield temp
        os.replace(temp, target)
    except BaseException as error:
        with suppress(OSError):
            os.unlink(temp)
        if isinstance(error, OSError) and not isinstance(error, AnytimeError):
            if error.filename in (None, os.fspath(temp), os.fspath(target)):
                raise OutputFileError(error.errno, error.strerror or str(error), filename) from None
        raise


def write_atomic(path: str | os.PathLike[str], data: str | bytes) -> None:
    """Write `data` (text as UTF-8) to `path` through a temporary file (see `atomic_path`).

    Raises:
        OutputFileError: it cannot be written; the file at `path`, if any, is unchanged.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else data
    with atomic_path(path) as temp, open(temp, "wb") as stream:
        stream.write(raw)
        stream.flush()
        if stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
            os.fsync(stream.fileno())
