"""Issue 37, item 10: failures a user can cause are one line, not noise. `check` of a module
whose results do not pickle says so in its verdict, with no child's traceback on stderr; a
module that ends its process in trials that are not isolated, with --workers 2, is a one-line
error saying that no profile was made (not "internal error ... a bug"); an unreachable
--scheduler is reported after a short connect timeout (`DASK_CONNECT_SECONDS`), not Dask's
30 s."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import Cli

from anytime.cli import main
from anytime.measure.builder import register_problems
from anytime.modules import Context, Registry, Result, interruptible
from anytime.problems import Instance

MODULES = Registry()


@interruptible("ends-its-process", registry=MODULES, inputs=())
def ends_its_process(ctx: Context, how: str) -> Iterator[Result]:
    ctx.tick(1)
    yield Result(0.5, 0.5)
    os._exit(3)


@interruptible("unpicklable", registry=MODULES, inputs=())
def unpicklable(ctx: Context, how: str) -> Iterator[Result]:
    ctx.tick(1)
    yield Result(lambda: 0, 0.5)


class Exits:
    def instance(self, rng: np.random.Generator, qualities: tuple[float, ...]) -> Instance:
        return Instance(("exit",))

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


@pytest.fixture
def ends(monkeypatch: pytest.MonkeyPatch) -> str:
    fresh = Registry()
    monkeypatch.setattr("anytime.library.REGISTRY", fresh)
    monkeypatch.setattr("anytime.problems._MEASUREMENTS", {})
    for module in MODULES:
        fresh.add(module)
    register_problems("ends-its-process", Exits(), time=[1, 2, 3])
    register_problems("unpicklable", Exits(), time=[1, 2, 3])
    return "ends-its-process"


def test_check_of_a_module_whose_results_do_not_pickle_prints_no_traceback(
    ends: str, capfd: pytest.CaptureFixture[str]
) -> None:
    # capfd, not the cli fixture: the children write to the file descriptor, not sys.stderr
    code = main(["check", "unpicklable", "--trials", "5", "--quiet", "--no-plugins"])
    stdout, stderr = capfd.readouterr()
    assert (code, stderr) == (
        1,
        "anytime: error: module 'unpicklable' fails 1 of 6 checks: errors\n",
    )
    assert (
        "  FAIL  errors        what its process answered does not pickle: AttributeError: Can't"
        " pickle local object 'unpicklable.<locals>.<lambda>' (allocation 1, trial 0); 18 of 20"
        " runs failed\n"
    ) in stdout


def test_a_worker_ended_by_a_trial_not_isolated_is_one_line(
    cli: Cli, ends: str, tmp_path: Path
) -> None:
    out = tmp_path / "out.yaml"
    code, stdout, stderr = cli(
        "profile", ends, "--trials", "20", "--workers", "2", "--isolation", "none", "--quiet",
        "--no-plugins", "-o", str(out),
    )  # fmt: skip
    assert (code, stdout) == (1, "")
    assert stderr == (
        "anytime: error: a worker process died: a trial ended the process it ran in (trials not"
        " isolated take their worker with them; isolated, it is a failed trial); no profile was"
        " made\n"
    )
    assert not out.exists()


def test_an_unreachable_scheduler_is_reported_after_a_short_timeout(
    cli: Cli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    pytest.importorskip("distributed")
    monkeypatch.setattr("anytime.measure.builder.DASK_CONNECT_SECONDS", 1.0)
    code, stdout, stderr = cli(
        "profile", "find-path", "--trials", "2", "--scheduler", "tcp://127.0.0.1:1", "--quiet",
        "-o", str(tmp_path / "out.yaml"),
    )  # fmt: skip
    assert (code, stdout) == (1, "")
    assert stderr == (
        "anytime: error: cannot connect to the Dask scheduler at tcp://127.0.0.1:1: Timed out"
        " trying to connect to tcp://127.0.0.1:1 after 1 s\n"
    )
