"""`owned_directory`: a command's `--out DIR` holds exactly one run's output."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from anytime.files import OutputFileError
from anytime.outdir import owned_directory

OWNS = ("frame-*.png", "run.gif", "events.jsonl")


def test_earlier_outputs_are_deleted_and_other_files_kept(tmp_path: Path) -> None:
    for name in ("frame-001.png", "frame-099.png", "run.gif", "notes.txt", "frame.png.txt"):
        (tmp_path / name).write_text("x")
    (tmp_path / "frame-dir.png").mkdir()  # a directory of a matching name is the user's
    with owned_directory(tmp_path, OWNS) as out:
        assert (tmp_path / "run.gif").exists()  # until the run writes, nothing is deleted
        assert out.fresh() == tmp_path
        left = sorted(p.name for p in tmp_path.iterdir())
        (tmp_path / "frame-000.png").write_text("this run's")
        out.fresh()  # once only: this run's outputs stay
        assert (tmp_path / "frame-000.png").exists()
    assert left == ["frame-dir.png", "frame.png.txt", "notes.txt"]  # and no lock file


def test_a_missing_directory_is_made(tmp_path: Path) -> None:
    with owned_directory(tmp_path / "a" / "b", OWNS) as out:
        assert out.path.is_dir()


def test_a_second_run_into_the_directory_is_refused_while_the_first_writes(
    tmp_path: Path,
) -> None:
    with owned_directory(tmp_path, OWNS):
        (tmp_path / "frame-000.png").write_text("first run's")
        with pytest.raises(OutputFileError) as caught, owned_directory(tmp_path, OWNS):
            pass
        assert str(caught.value) == (
            f"cannot write '{tmp_path}': another run (process {os.getpid()}) is writing there;"
            " wait for it or choose another directory"
        )
        assert (tmp_path / "frame-000.png").read_text() == "first run's"  # nothing deleted
    with owned_directory(tmp_path, OWNS) as out:  # released: the next run takes it
        out.fresh()
        assert not (tmp_path / "frame-000.png").exists()


def test_a_run_that_died_leaves_nothing_locked_and_nothing_behind(tmp_path: Path) -> None:
    """The lock is the directory's own, released by the kernel when its holder dies: a run
    killed while it held it does not lock the next one out, and leaves no file."""
    import signal
    import subprocess
    import sys

    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom anytime.outdir import owned_directory\n"
         f"with owned_directory({str(tmp_path)!r}, ['x']):\n    print('held', flush=True)\n"
         "    time.sleep(60)"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert holder.stdout is not None and holder.stdout.readline() == "held\n"
    with pytest.raises(OutputFileError) as caught, owned_directory(tmp_path, OWNS):
        pass
    assert str(caught.value) == (
        f"cannot write '{tmp_path}': another run (process {holder.pid}) is writing there;"
        " wait for it or choose another directory"
    )
    holder.send_signal(signal.SIGKILL)
    holder.wait()
    with owned_directory(tmp_path, OWNS):
        pass
    assert list(tmp_path.iterdir()) == []


def test_a_file_where_the_directory_should_be(tmp_path: Path) -> None:
    target = tmp_path / "file"
    target.write_text("x")
    with pytest.raises(OutputFileError, match=f"^cannot write '{target}': File exists$"):
        with owned_directory(target, OWNS):
            pass
