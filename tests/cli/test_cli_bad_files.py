"""Input files that are not regular files, or are too large, are refused unread: one line naming
the file, exit status 1, at once (a FIFO is never opened, /dev/zero never read)."""

from __future__ import annotations

import contextlib
import os
import stat
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from anytime_navigation.movingai import MAX_MAP_BYTES, MAX_SCENARIO_BYTES
from anytime_navigation.resources import data_file

from anytime.files import MAX_PROFILE_BYTES, MAX_SCHEMA_BYTES

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

ARENA = str(Path(str(data_file("maps"))) / "arena.map")

#: Each kind of bad input: (a function making it in a directory, what the message says).
Maker = Callable[[Path, str], Path]


@pytest.fixture
def unblock(tmp_path: Path) -> Iterator[None]:
    """A guard, not part of what is tested: should a reader open a FIFO of the test after all,
    a writer opens and closes it after 10 s, so that the test fails instead of hanging."""
    stop = threading.Event()

    def release() -> None:
        if stop.wait(10):
            return
        for path in tmp_path.iterdir():
            if stat.S_ISFIFO(path.lstat().st_mode):
                with contextlib.suppress(OSError):
                    os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))

    threading.Thread(target=release, daemon=True).start()
    yield
    stop.set()


def fifo(directory: Path, name: str) -> Path:
    path = directory / name
    os.mkfifo(path)
    return path


def dev_zero(directory: Path, name: str) -> Path:
    return Path("/dev/zero")


def a_directory(directory: Path, name: str) -> Path:
    path = directory / name
    path.mkdir()
    return path


def too_large(limit: int) -> Maker:
    def make(directory: Path, name: str) -> Path:
        path = directory / name
        with open(path, "wb") as stream:
            stream.truncate(limit + 1)  # sparse: nothing is written, the size is what counts
        return path

    return make


def kinds(limit: int, what: str) -> list[object]:
    return [
        pytest.param(fifo, "not a regular file (a FIFO)", id="fifo"),
        pytest.param(dev_zero, "not a regular file (a character device)", id="dev-zero"),
        pytest.param(a_directory, "Is a directory", id="directory"),
        pytest.param(
            too_large(limit), f"larger than the {what} ({limit + 1:,} bytes)", id="over-the-limit"
        ),
    ]


pytestmark = [
    pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs"),
    pytest.mark.usefixtures("unblock"),
]


@pytest.mark.parametrize("command", ["parse", "compile", "plot"])
@pytest.mark.parametrize(
    ("make", "problem"), kinds(MAX_SCHEMA_BYTES, "1 MiB limit for schema files")
)
def test_schema_files(cli: Cli, tmp_path: Path, command: str, make: Maker, problem: str) -> None:
    path = make(tmp_path, "bad.any")
    if path.name == "zero" and command == "plot":
        pytest.skip("/dev/zero has no .any suffix: plot reads it as a profile (tested below)")
    code, out, err = cli(command, str(path), "--no-plugins")
    assert (code, out) == (1, "")
    assert err == f"anytime: error: cannot read '{path}': {problem}\n"


@pytest.mark.parametrize(
    ("make", "problem"), kinds(MAX_PROFILE_BYTES, "64 MiB limit for profile files")
)
def test_profile_files(cli: Cli, tmp_path: Path, make: Maker, problem: str) -> None:
    path = make(tmp_path, "bad.yaml")
    code, out, err = cli("plot", str(path), "-o", str(tmp_path / "out.png"))
    assert (code, out) == (1, "")
    assert err == f"anytime: error: {path}: cannot read the file: {problem}\n"
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize(("make", "problem"), kinds(MAX_MAP_BYTES, "64 MiB limit for map files"))
def test_map_files(cli: Cli, tmp_path: Path, make: Maker, problem: str) -> None:
    path = make(tmp_path, "bad.map")
    code, out, err = cli("plan", "--map", str(path), "--start", "1,1", "--goal", "2,2")
    assert (code, out) == (1, "")
    assert err == f"anytime: error: cannot read '{path}': {problem}\n"
    code, out, err = cli("navigate", "--map", str(path))
    assert (code, out) == (1, "")
    assert err == f"anytime: error: cannot read '{path}': {problem}\n"


@pytest.mark.parametrize(
    ("make", "problem"),
    kinds(MAX_SCENARIO_BYTES, "64 MiB limit for scenario files"),
)
def test_scenario_files(cli: Cli, tmp_path: Path, make: Maker, problem: str) -> None:
    path = make(tmp_path, "bad.scen")
    code, out, err = cli("plan", "--map", ARENA, "--scen", str(path))
    assert (code, out) == (1, "")
    assert err == f"anytime: error: cannot read '{path}': {problem}\n"
