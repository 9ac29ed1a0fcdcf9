"""Issue 37, item 6: `kill -9` of `anytime profile --workers 2` leaves no process behind: its
pool workers die with it (a parent-death signal), and their isolated trial children with them."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from anytime.isolation import processes


def _session(session: int) -> list[int]:
    """The live processes of session `session` (zombies are not alive)."""
    return [p.pid for p in processes() if p.session == session and p.state not in ("Z", "X")]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
@pytest.mark.parametrize("isolation", ["process", "none"])
def test_kill_9_of_profile_with_workers_orphans_no_worker(tmp_path: Path, isolation: str) -> None:
    argv = ["profile", "find-path", "--trials", "5000", "--workers", "2", "--quiet"]
    argv += ["--isolation", isolation, "-o", str(tmp_path / "out.yaml")]
    code = (
        "import sys; from anytime.cli import main; print('ready', flush=True);"
        f" sys.exit(main({argv!r}))"
    )
    command = subprocess.Popen(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        start_new_session=True,  # its session holds it and everything it starts
    )
    try:
        assert command.stdout is not None
        assert command.stdout.readline() == "ready\n"
        deadline = time.monotonic() + 60  # only a hang of the test machine reaches it
        while time.monotonic() < deadline:
            workers = [p for p in processes() if p.parent == command.pid]
            if len(workers) >= 2:
                break
            time.sleep(0.05)
        assert len(workers) >= 2, "the pool's workers never started"
        os.kill(command.pid, signal.SIGKILL)
        command.wait(timeout=60)
        left = _session(command.pid)
        while left and time.monotonic() < deadline:
            time.sleep(0.1)
            left = _session(command.pid)
        assert left == []
    finally:
        for pid in _session(command.pid):
            with_suppressed_kill(pid)
        if command.poll() is None:
            command.kill()
            command.wait()


def with_suppressed_kill(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
