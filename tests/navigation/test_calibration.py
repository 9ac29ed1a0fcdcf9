"""The task's calibration: the frame program's profile measured in the task, and the monitor's
model of the task when it plans with it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from anytime_navigation.task.calibration import (
    BINS,
    TaskCalibration,
    measure,
    shipped,
    task_value,
)
from anytime_navigation.task.frame_program import navigation_program
from anytime_navigation.task.frames import run_task
from anytime_navigation.task.model import FrameState, NavigationTask, TaskModel
from anytime_navigation.world import random_world
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.plugin.compose import DeadlineValue


@pytest.fixture(scope="module")
def program():
    return navigation_program()


def small_calibration() -> TaskCalibration:
    return TaskCalibration(
        32, 8, 4, [100, 300], [[0.8, 0.9, 1.0, 1.0], [0.95, 1.0, 1.0, 1.0]], [0.5, 0.7, 0.6, 0.8]
    )


def test_the_profile_is_the_samples_distribution_per_contract():
    calibration = small_calibration()
    profile = calibration.profile()
    assert profile.time.tolist() == [0.0, 100.0, 300.0]
    assert profile.bins.tolist() == BINS.tolist()
    assert profile.mean.tolist() == pytest.approx([0.0, 0.925, 0.9875])
    assert profile.probability[0, 0] == 1.0  # no plan before any time
    counts = profile.probability[1:] * 4
    assert np.allclose(counts, np.round(counts))
    assert counts[0, -1] == 2 and counts[1, -1] == 3  # 1.0 falls in the last bin
    assert calibration.progress_ratio == pytest.approx(0.65)
    assert calibration.worlds == 4


def test_a_calibration_reads_back_as_written():
    calibration = small_calibration()
    assert TaskCalibration.from_json(calibration.as_json()) == calibration


@pytest.mark.parametrize("size", [64, 128])
def test_the_benchmarks_sizes_are_calibrated(size):
    calibration = shipped(size, size // 4)
    assert calibration is not None
    assert (calibration.size, calibration.radius, calibration.movement) == (size, size // 4, 4)
    assert calibration.worlds >= 150
    quality = np.asarray(calibration.quality)
    assert quality.shape == (len(calibration.contracts), calibration.worlds)
    assert np.all((quality > 0) & (quality <= 1))
    assert 0 < calibration.progress_ratio <= 1


def test_no_calibration_where_none_was_measured():
    assert shipped(32, 8) is None
    assert shipped(64, 8) is None  # another sensor radius


def test_measuring_gives_a_calibration_of_the_task(program):
    calibration = measure(16, 2, contracts=[200.0, 400.0])
    assert (calibration.size, calibration.radius, calibration.worlds) == (16, 4, 2)
    assert np.all(np.asarray(calibration.quality) <= 1)
    assert calibration.profile().time.tolist() == [0.0, 200.0, 400.0]


def test_a_calibrated_task_plans_with_the_calibrations_contracts(program):
    compiled, trace = program
    world = random_world(64, seed=5)
    task = NavigationTask(world, radius=16, value=task_value(64), seed=5)
    calibrated = run_task(task, compiled, trace)
    grid = set(shipped(64, 16).contracts)
    assert {r.contract for r in calibrated.records} <= grid
    plain = run_task(task, compiled, trace, calibrated=False)
    assert {r.contract for r in plain.records} <= set(compiled.profile.time.tolist())
    assert calibrated.reached and plain.reached


# --- the model with a route quality ----------------------------------------------------------


def route_model(later=None, value=None) -> TaskModel:
    calibration = shipped(64, 16)
    task = NavigationTask(random_world(64, seed=0), radius=16, value=value or task_value(64))
    return TaskModel(
        task,
        calibration.profile(),
        progress=calibration.progress_ratio,
        route_quality=True,
        later=later,
    )


@settings(max_examples=40, deadline=None)
@given(
    remaining=st.floats(1.0, 300.0),
    step=st.floats(1.0, 40.0),
    contract=st.sampled_from([200.0, 400.0, 700.0]),
)
def test_a_routes_quality_stretches_the_whole_route(remaining, step, contract):
    # Without a deadline the robot walks at the slowest speed, so the energy is the route.
    model = route_model(value=DeadlineValue(1000.0, 0.0, 0.0))
    state = FrameState(0.0, remaining, 0.05, step, waiting=True)
    cost = np.asarray(model.cost(state, np.array([[contract]]), np.array([[1.0, 0.5]])))
    slowest = float(model.task.energy(0.05))
    assert cost.reshape(-1) == pytest.approx([slowest * remaining, 2 * slowest * remaining])


def test_later_frames_choose_their_own_contract():
    fixed, free = route_model(), route_model(later=shipped(64, 16).contracts)
    state = FrameState(0.0, 126.0, 0.05, 22.0, waiting=True)
    c, q = np.array([[100.0], [400.0]]), np.full((2, 1), 0.95)
    u_fixed = np.asarray(fixed.value(state, c, q) - fixed.cost(state, c, q)).reshape(-1)
    u_free = np.asarray(free.value(state, c, q) - free.cost(state, c, q)).reshape(-1)
    assert np.all(u_free >= u_fixed - 1e-9)  # choosing later can only help
    assert u_free[0] > u_fixed[0]  # a short first contract need not be kept


@settings(max_examples=60, deadline=None)
@given(
    remaining=st.floats(10.0, 300.0),
    step=st.floats(5.0, 40.0),
    now=st.floats(0.0, 2500.0),
    quality=st.floats(0.6, 1.0),
)
def test_the_speeds_mix_is_no_worse_than_any_one_speed(remaining, step, now, quality):
    model = route_model()
    state = FrameState(now, remaining, 0.05, step, waiting=True)
    c, q = np.array([[400.0]]), np.array([[quality]])
    best = (model.value(state, c, q) - model.cost(state, c, q)).item()
    x = max(1.0, remaining / step)
    frames = math.ceil(x)
    path = remaining / quality
    for v in model.task.speeds:
        e = path / x / v
        completion = now + 400.0 + (frames - 1) * max(400.0, e) + (x - frames + 1) * e
        single = float(model.task.value(completion)) - float(model.task.energy(v)) * path
        assert best >= single - 1e-6
