"""The task's calibration: the frame program's profile measured in the task, and the monitor's
model of the task when it plans with it."""

from __future__ import annotations

import math

import attrs
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


# --- the first frame apart from the later ones ---------------------------------------------------


def first_frame_calibration() -> TaskCalibration:
    quality = [[0.8, 0.9, 1.0, 1.0], [0.95, 1.0, 1.0, 1.0]]
    walked = [[20, 24, 30, 22], [22, 22, 25, 22]]
    left = [[0.75, 0.7, 0.68, 0.72], [0.65, 0.66, 0.62, 0.65]]
    stretch = [[1.2, 1.1, 1.0, 1.3], [1.05, 1.0, 1.1, 1.0]]
    return TaskCalibration(
        32, 8, 4, [100, 300], quality, [0.5, 0.7, 0.6, 0.8], 1000, walked, left, stretch
    )


def test_the_first_frame_reads_back_as_written():
    calibration = first_frame_calibration()
    assert TaskCalibration.from_json(calibration.as_json()) == calibration
    first = calibration.first_frame()
    assert first is not None
    assert first.walked.shape == first.left.shape == first.stretch.shape == (2, 4)
    assert small_calibration().first_frame() is None  # measured without it
    assert "first_walked" not in small_calibration().as_json()


@pytest.mark.parametrize("size", [64, 128])
def test_the_benchmarks_sizes_have_their_first_frame(size):
    calibration = shipped(size, size // 4)
    first = calibration.first_frame()
    assert first is not None
    assert first.walked.shape == (len(calibration.contracts), calibration.worlds)
    prior = 2.0 * (size - 1)  # the start's distance on the prior map: nothing known
    assert np.all(first.walked >= prior * (1 - first.left) - 1e-9)  # progress is walked
    assert np.all(first.left > 0)
    assert np.all(first.stretch >= 1.0 - 1e-9)  # the rest is at least its shortest route


def test_measuring_gives_the_first_frame(program):
    calibration = measure(16, 2, contracts=[200.0, 400.0])
    first = calibration.first_frame()
    assert first is not None and first.walked.shape == (2, 2)
    assert np.all(first.walked >= 1) and np.all((first.left > 0) & (first.left < 1))


def first_model(later=None, value=None) -> TaskModel:
    calibration = first_frame_calibration()
    task = NavigationTask(random_world(32, seed=0), radius=8, value=value or task_value(32))
    return TaskModel(
        task,
        calibration.profile(),
        progress=calibration.progress_ratio,
        route_quality=True,
        later=later,
        first=calibration.first_frame(),
    )


def test_the_first_frames_route_is_its_own_and_the_later_frames_stretch():
    # Without a deadline the robot walks at the slowest speed: the energy is the route's.
    model = first_model(value=DeadlineValue(1000.0, 0.0, 0.0))
    state = FrameState(0.0, 62.0, 0.05, 20.0, waiting=True)
    decision = model.first_choice(state, np.array([100.0, 300.0]))
    first = model.first
    route = first.walked + 62.0 * first.left * first.stretch  # later at the same contract
    cost = float(model.task.energy(0.05)) * route.mean(axis=1)
    assert decision.contract == 300.0 and decision.grid.tolist() == [100.0, 300.0]
    assert decision.expected_cost == pytest.approx(cost[1])
    assert decision.utility_curve.tolist() == pytest.approx((1000.0 - cost).tolist())
    assert decision.expected_utility == pytest.approx(1000.0 - cost[1])


def test_a_first_contract_that_buys_nothing_is_not_waited_for():
    model = first_model()
    first = model.first
    same = attrs.evolve(
        first,
        walked=np.repeat(first.walked[:1], 2, axis=0),
        left=np.repeat(first.left[:1], 2, axis=0),
        stretch=np.repeat(first.stretch[:1], 2, axis=0),
    )
    model = attrs.evolve(model, first=same, later=(100.0,))
    state = FrameState(0.0, 62.0, 0.05, 20.0, waiting=True)
    decision = model.first_choice(state, np.array([100.0, 300.0]))
    assert decision.contract == 100.0
    assert decision.utility_curve[0] >= decision.utility_curve[1]


def test_the_first_choice_is_only_the_first_frames():
    model = first_model(later=(100.0, 300.0))
    waiting = FrameState(0.0, 62.0, 0.05, 20.0, waiting=True)
    walking = FrameState(400.0, 40.0, 0.05, 20.0, waiting=False, current=20.0)
    assert model.first_choice(walking, np.array([100.0, 300.0])) is None
    assert model.first_choice(waiting, np.array([100.0, 200.0])) is None  # 200 not measured
    assert attrs.evolve(model, first=None).first_choice(waiting, np.array([100.0])) is None
    assert attrs.evolve(model, later=(500.0,)).first_choice(waiting, np.array([100.0])) is None


def test_a_calibrated_tasks_first_frame_is_the_first_choice(program):
    compiled, trace = program
    world = random_world(64, seed=5)
    task = NavigationTask(world, radius=16, value=task_value(64), seed=5)
    report = run_task(task, compiled, trace)
    calibration = shipped(64, 16)
    model = TaskModel(
        task,
        calibration.profile(),
        progress=calibration.progress_ratio,
        route_quality=True,
        later=calibration.contracts,
        first=calibration.first_frame(),
    )
    prior = float(2 * (64 - 1))  # nothing known: the Manhattan distance
    state = FrameState(0.0, prior, 0.05, model.first_step(world.start), waiting=True)
    decision = model.first_choice(state, np.asarray(calibration.contracts))
    assert report.records[0].contract == decision.contract
    assert report.log.of_kind("contract")[0].data["expected_utility"] == pytest.approx(
        decision.expected_utility
    )
    assert report.predicted_utility == pytest.approx(decision.median_utility)
    assert report.records[0].expected_completion == pytest.approx(decision.expected_completion)


@pytest.mark.slow
@pytest.mark.parametrize("size", [64, 128])
def test_the_prediction_is_calibrated_on_held_out_worlds(program, size):
    # Worlds apart from the calibration's (seeds from 1000) and the benchmark's (0 to 99): the
    # expected utility when the task is presented is the mean of what the robot realises within
    # 2% (on 100 of them: 853.2 against 857.0 at 64, 720.2 against 720.1 at 128), and the
    # prediction, the median, errs less on the mean than the expected utility would.
    compiled, trace = program
    expected, predicted, realised = [], [], []
    for seed in range(2000, 2040):
        world = random_world(size, seed=seed)
        task = NavigationTask(world, radius=size // 4, value=task_value(size), seed=seed)
        report = run_task(task, compiled, trace)
        expected.append(report.log.of_kind("contract")[0].data["expected_utility"])
        predicted.append(report.predicted_utility)
        realised.append(report.utility)
    mean, u, p = np.mean(expected), np.array(realised), np.array(predicted)
    assert abs(np.mean(u) - mean) <= 0.02 * abs(mean)
    assert np.mean(np.abs(u - p) / np.abs(p)) < np.mean(np.abs(u - mean) / abs(mean))
