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

The lock is an advisory `flock` on the directory itself: the kernel releases it when the holder
exits, however it exits, so a crashed run never leaves the directory locked, and nothing of the
lock is left in the directory. Where the system lists its locks (Linux: /proc/locks) the refusal
names the process that holds it.
"""

from __future__ import annotations

import errno
import fnmatch
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from anytime.files import OutputFileError

__all__ = ["OwnedDirectory", "owned_directory"]

#: Where Linux lists the file locks held (to name the process holding a directory).
PROC_LOCKS = Path("/proc/locks")

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
        handle = os.open(out, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
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
        holder = _holder(os.fstat(handle))
        who = "another run" if holder is None else f"another run (process {holder})"
        raise OutputFileError(
            errno.EBUSY,
            f"{who} is writing there; wait for it or choose another directory",
            str(out),
        ) from None


def _holder(stat: os.stat_result) -> int | None:
    """The process holding a flock on the file of `stat`, from the system's list of locks
    (None: not listed, or no list to read)."""
    device = f"{os.major(stat.st_dev):02x}:{os.minor(stat.st_dev):02x}:{stat.st_ino}"
    try:
        lines = PROC_LOCKS.read_text(encoding="ascii", errors="replace").splitlines()
    except OSError:
        return None
    for line in lines:  # "1: FLOCK  ADVISORY  WRITE 4242 08:01:1234567 0 EOF"
        fields = line.split()
        if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5] == device:
            return int(fields[4]) if fields[4].isdigit() else None
    return None


def _clear(out: Path, owns: Sequence[str]) -> None:
    for entry in out.iterdir():
        if not any(fnmatch.fnmatchcase(entry.name, p) for p in owns):
            continue
        if not entry.is_file() or entry.is_symlink():
            continue  # a directory or link of that name is the user's, not an output of ours
        try:
            entry.unlink(missing_ok=True)  # gone meanwhile is as good as deleted
        except OSError as error:
            raise OutputFileError(
                error.errno, f"cannot delete the earlier output '{entry.name}'", str(out)
            ) from None
