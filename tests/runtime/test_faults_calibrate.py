"""Issue 37, item 4: `calibrate` isolated and bounded. A module that loops or sleeps without
reporting work is ended by a watchdog (the budget plus `GRACE`), one that crashes its process or
raises is a `CalibrationError` saying how, and `anytime calibrate` says so in one line."""

from __future__ import annotations

import ctypes
import faulthandler
import os
import sys
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from conftest import Cli

from anytime.measure.builder import Instance, Measurement
from anytime.measure.calibrate import GRACE, CalibrationError, calibrate
from anytime.modules import Context, Registry, Result, interruptible
from anytime.problems import Grid
from anytime.runtime import Isolated
from anytime.runtime.modes import SOFT

MODULES = Registry()


@interruptible("misbehaves", inputs=[], registry=MODULES)
def misbehaves(ctx: Context, how: str) -> Iterator[Result]:
    for i in range(1, 1_000_000):
        ctx.tick()
        yield Result(i, min(1.0, i / 1000))
        if i == 10:
            if how == "loop":
                while True:
                    pass
            elif how == "sleep":
                time.sleep(600)
            elif how == "segfault":
                faulthandler.disable()
                ctypes.string_at(0)
            elif how == "os-exit":
                os._exit(3)
            elif how == "exit":
                sys.exit(3)
            elif how == "keyboard-interrupt":
                raise KeyboardInterrupt


class Problems:
    def __init__(self, how: str) -> None:
        self.how = how

    def instance(self, rng: np.random.Generator, qualities: tuple[float, ...]) -> Instance:
        return Instance((self.how,))

    def score(self, instance: Instance, value: Any) -> float:
        return 0.5


def _plan(how: str) -> Measurement:
    return Measurement(Problems(how), Grid([0, 1e9]))


WHERE = "module 'misbehaves' {} while being calibrated (trial 0): "
ERRORS = {
    "loop": WHERE.format("did not answer")
    + f"watchdog: no answer after {0.5 + GRACE:g} s of wall time (the budget was 0.5 s: it must"
    " report its work with ctx.tick(n) often enough to be stopped)",
    "segfault": WHERE.format("crashed") + "its process was killed by SIGSEGV (signal 11)",
    "os-exit": WHERE.format("crashed") + "its process exited with code 3 before it answered",
    "exit": WHERE.format("failed") + "SystemExit: 3",
    "keyboard-interrupt": WHERE.format("failed") + "KeyboardInterrupt",
}
ERRORS["sleep"] = ERRORS["loop"]


@pytest.mark.parametrize("how", list(ERRORS))
def test_a_misbehaving_module_is_a_calibration_error(how: str) -> None:
    module = MODULES.get("misbehaves")
    assert module is not None
    started = time.monotonic()
    with pytest.raises(CalibrationError) as caught:
        calibrate(module, 0.5, measurement=_plan(how))
    assert str(caught.value) == ERRORS[how]
    assert time.monotonic() - started < 60  # bounded: only a hang reaches this


def test_the_watchdog_is_the_modes_when_it_is_shorter() -> None:
    module = MODULES.get("misbehaves")
    assert module is not None
    with pytest.raises(CalibrationError, match=r"watchdog: no answer after 0\.3 s of wall time"):
        calibrate(module, 5.0, measurement=_plan("sleep"), mode=Isolated(0.3))


@pytest.mark.parametrize("mode", [Isolated(), SOFT], ids=["isolated", "soft"])
def test_a_module_that_behaves_is_calibrated_in_either_mode(mode: Any) -> None:
    module = MODULES.get("misbehaves")
    assert module is not None
    calibration = calibrate(module, 0.2, measurement=_plan("none"), mode=mode)
    assert calibration.runs >= 1 and calibration.ticks_per_second > 0


@pytest.mark.parametrize("how", ["loop", "segfault"])
def test_anytime_calibrate_says_it_in_one_line(
    cli: Cli, monkeypatch: pytest.MonkeyPatch, how: str
) -> None:
    fresh = Registry()
    for module in MODULES:
        fresh.add(module)
    monkeypatch.setattr("anytime.library.REGISTRY", fresh)
    monkeypatch.setattr("anytime.problems._MEASUREMENTS", {"misbehaves": _plan(how)})
    code, stdout, stderr = cli(
        "calibrate", "misbehaves", "--seconds", "0.5", "--quiet", "--no-plugins"
    )
    assert (code, stdout, stderr) == (1, "", f"anytime: error: {ERRORS[how]}\n")
