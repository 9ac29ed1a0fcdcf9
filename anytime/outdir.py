"""An output directory a command owns for the length of its run.

A command that writes many files into `--out DIR` (frame pictures, an animation, a log) must not
mix its files with another run's: two runs into one directory would interleave their frames, and a
later, shorter run would leave the earlier run's extra frames behind as if they were its own.
`owned_directory` makes the directory and takes an exclusive lock on it for as long as the
command runs (a second run into the same directory is refused at once, naming the process that
holds it); `OwnedDirectory.fresh()`, called when the command has its results and starts writing,
deletes the files this command wrote there before (those matching its patterns), so what the
directory holds afterwards is exactly one run's output, and a run interrupted before it had
anything to write leaves the earlier run's output as it was. Other files are left alone.

The lock is an advisory `flock` on a hidden file `DIR/.anytime.lock`: the kernel releases it when
the holder exits, however it exits, so a crashed run never leaves the directory locked.
"""

from __future__ import annotations

import errno
import fnmatch
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from anytime.files import OutputFileError

__all__ = ["LOCK_NAME", "OwnedDirectory", "owned_directory"]

#: The lock file `owned_directory` keeps in the directory (left there: deleting it would race).
LOCK_NAME = ".anytime.lock"

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: the directory is cleared but not locked
    fcntl = None  # type: ignore[assignment]


class OwnedDirectory:
    """A directory locked by `owned_directory`; `owns` are the glob patterns of the command's
    outputs (e.g. `"frame-*.png"`)."""

    def __init__(self, path: Path, owns: Sequence[str]) -> None:
        self.path = path
        self.owns = tuple(owns)
        self._cleared = False

    def fresh(self) -> Path:
        """Delete the earlier runs' outputs (on the first call only) and return the path."""
        if not self._cleared:
            _clear(self.path, self.owns)
            self._cleared = True
        return self.path


@contextmanager
def owned_directory(path: str | os.PathLike[str], owns: Sequence[str]) -> Iterator[OwnedDirectory]:
    """Make `path` a directory this process alone writes into while the block runs; the earlier
    runs' outputs matching the glob patterns `owns` go when the block calls `fresh()`.

    Raises `OutputFileError` (`cannot write 'DIR': ...`) when the directory cannot be made, is
    being written by another run, or an earlier output cannot be deleted."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
        handle = os.open(out / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as error:
        raise OutputFileError(error.errno, error.strerror, str(out)) from None
    try:
        _lock(handle, out)
        yield OwnedDirectory(out, owns)
    finally:
        os.close(handle)  # closing the descriptor releases the lock


def _lock(handle: int, out: Path) -> None:
    if fcntl is None:  # pragma: no cover
        return
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(handle, 32, 0).decode("ascii", "replace").strip() or "unknown"
        raise OutputFileError(
            errno.EBUSY,
            f"another run (process {holder}) is writing there; wait for it or choose another"
            " directory",
            str(out),
        ) from None
    os.ftruncate(handle, 0)
    os.pwrite(handle, f"{os.getpid()}\n".encode("ascii"), 0)


def _clear(out: Path, owns: Sequence[str]) -> None:
    for entry in out.iterdir():
        if entry.name == LOCK_NAME or not any(fnmatch.fnmatchcase(entry.name, p) for p in owns):
            continue
        if not entry.is_file() or entry.is_symlink():
            continue  # a directory or link of that name is the user's, not an output of ours
        try:
            entry.unlink(missing_ok=True)  # gone meanwhile is as good as deleted
        except OSError as error:
            raise OutputFileError(
                error.errno, f"cannot delete the earlier output '{entry.name}'", str(out)
            ) from None
