"""`anytime.files`: the safe reader and the atomic writer every command's files go through."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from anytime.files import (
    InputFileError,
    OutputFileError,
    atomic_path,
    format_size,
    read_input,
    write_atomic,
)


def test_read_input_reads_a_regular_file_within_the_limit(tmp_path: Path) -> None:
    path = tmp_path / "a.txt"
    path.write_bytes(b"12345")
    assert read_input(path, limit=5) == b"12345"
    with pytest.raises(InputFileError) as caught:
        read_input(path, limit=4, kind="test files")
    assert str(caught.value) == (
        f"cannot read '{path}': larger than the 4 bytes limit for test files (5 bytes)"
    )
    assert caught.value.filename == str(path) and isinstance(caught.value, OSError)


def test_read_input_passes_on_a_missing_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        read_input(tmp_path / "missing", limit=10)


def test_format_size() -> None:
    assert [format_size(n) for n in (5, 1024, 1 << 20, 64 << 20, 1536)] == [
        "5 bytes",
        "1 KiB",
        "1 MiB",
        "64 MiB",
        "1.5 KiB",
    ]


def test_write_atomic_replaces_the_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    path = tmp_path / "out.yaml"
    path.write_text("old\n")
    path.chmod(0o640)
    write_atomic(path, "new\n")
    assert path.read_text() == "new\n"
    assert (path.stat().st_mode & 0o777) == 0o640
    assert os.listdir(tmp_path) == ["out.yaml"]


def test_an_interrupted_write_leaves_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "out.png"
    path.write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_path(path) as temp:
        assert temp.parent == tmp_path and temp.suffix == ".png"
        temp.write_text("half")
        raise KeyboardInterrupt
    assert path.read_text() == "old"
    assert os.listdir(tmp_path) == ["out.png"]
    with pytest.raises(KeyboardInterrupt), atomic_path(tmp_path / "new.png") as temp:
        temp.write_text("half")
        raise KeyboardInterrupt
    assert os.listdir(tmp_path) == ["out.png"]


def test_a_write_goes_through_a_symbolic_link(tmp_path: Path) -> None:
    real = tmp_path / "real.txt"
    real.write_text("old")
    link = tmp_path / "link.txt"
    link.symlink_to(real)
    write_atomic(link, "new")
    assert link.is_symlink() and real.read_text() == "new"


def test_a_device_is_written_in_place_and_a_directory_refused(tmp_path: Path) -> None:
    write_atomic("/dev/null", "nothing")
    assert Path("/dev/null").is_char_device()
    with pytest.raises(OutputFileError) as caught:
        write_atomic(tmp_path, "x")
    assert str(caught.value) == f"cannot write '{tmp_path}': Is a directory"
    with pytest.raises(OutputFileError) as caught:
        write_atomic(tmp_path / "no" / "such.txt", "x")
    assert str(caught.value) == (
        f"cannot write '{tmp_path / 'no' / 'such.txt'}': No such file or directory"
    )
