"""The robot keeps its best reading of each cell: a frame whose contract leaves vision no time
to read (under `T_A`) plans on the robot's map of its window, not on the prior (every cell
free), and a poorer reading does not replace a better one read there before."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from anytime_navigation.task.calibration import task_value
from anytime_navigation.task.frame_program import navigation_program
from anytime_navigation.task.frames import _TaskRun
from anytime_navigation.task.model import NavigationTask
from anytime_navigation.task.vision import fraction_correct
from anytime_navigation.world import random_world


@pytest.fixture(scope="module")
def program():
    return navigation_program()


def _run(program, seed: int = 3) -> _TaskRun:
    compiled, trace = program
    world = random_world(64, seed=seed)
    task = NavigationTask(world, radius=16, value=task_value(64), seed=seed)
    return _TaskRun(task, compiled, trace, "fixed", 400.0, "work", (), None)


def _plan(run: _TaskRun, known: np.ndarray, contract: float, index: int):
    decision = SimpleNamespace(contract=contract)
    return run.plan(run.world.start, known, decision, None, index)


def test_no_reading_keeps_the_robots_map_of_the_window(program):
    run = _run(program)
    x0, y0, x1, y1 = run.task.window(run.world.start)
    read = _plan(run, np.zeros_like(run.truth), 1000.0, 0).known  # vision reads at 400 ticks
    assert read[y0:y1, x0:x1].any()
    kept = _plan(run, read, 200.0, 1)  # vision gets 0 ticks: no reading
    assert (kept.known == read).all()  # was the prior, every cell of the window free


def test_a_poorer_reading_does_not_replace_a_better_one(program):
    run = _run(program)
    x0, y0, x1, y1 = run.task.window(run.world.start)
    truth = run.truth[y0:y1, x0:x1]

    def correct(known: np.ndarray) -> float:
        return fraction_correct(known[y0:y1, x0:x1], truth)

    good = _plan(run, np.zeros_like(run.truth), 1000.0, 0).known
    after = _plan(run, good, 300.0, 1).known  # vision's 100 ticks: quality 0.85
    assert (after == good).all()
    poor = _plan(_run(program), np.zeros_like(run.truth), 300.0, 1).known
    assert correct(poor) < correct(good)
    better = _plan(_run(program), poor, 1000.0, 2).known  # a better reading does replace it
    assert correct(better) > correct(poor)
