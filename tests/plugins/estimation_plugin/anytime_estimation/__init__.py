"""Estimate a tank's hidden volume, then the side of the cube that holds it.

A third-party plugin of anytime-compose, written against the public API only (`anytime.plugin`).

- `estimate-volume` (contract): the mean of noisy readings of the volume, a batch of readings
  per `BATCH_TICKS` ticks; more time, more readings.
- `read-label` (contract): the alternative for a `best-of`: read the volume printed on the
  tank's label, exact when the label is readable, nothing when it is smudged.
- `cube-side` (interruptible): Newton's method for the cube root of a volume estimate, one step
  per `STEP_TICKS` ticks, registering a result after every step.
- `joint-side` (interruptible, two quality-carrying inputs): the side of a cube holding two
  tanks' volumes, by the same method.
- `has-sensor?`, `has-label?` (elementary): the `best-of`'s preconditions.

Every answer's true quality is `quality(answer, truth)`: 1 - its relative error, clipped to
[0, 1] (0 for no answer). The estimator and the cube roots cannot know the truth, so they
report their own estimate (`reports="estimate"`); the cube roots' is a lower bound of the true
quality whenever their inputs' qualities are true. The label is exact when read, so
`read-label` reports its true quality. How the problem sets make inputs of a given quality:
README.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from anytime.plugin import (
    Context,
    Instance,
    Measurement,
    Plugin,
    ProgramProblems,
    Result,
    contract,
    elementary,
    interruptible,
)

#: The plugin's schemas (package data): tank-side, two-tank-side, labelled-tank-side.
SCHEMA_FILE = Path(str(resources.files(__name__).joinpath("schemas", "estimation.any")))
#: Hidden volumes are drawn uniformly from this range.
VOLUMES = (20.0, 200.0)
#: Readings per batch, and the ticks a batch costs.
BATCH, BATCH_TICKS = 4, 2
#: Ticks one Newton step costs.
STEP_TICKS = 3
#: Ticks reading the label costs.
LABEL_TICKS = 4
#: How often a label is readable (a smudged one is not).
READABLE = 0.6
#: The most batches a run with no contract (infinite allocation) takes.
MAX_BATCHES = 1000
#: The cube root of 2: how much a relative error of a cube root can grow when measured against
#: the true side rather than the input's (a quality-q input is at most twice the truth).
CBRT2 = 2.0 ** (1.0 / 3.0)


def quality(answer: float | None, truth: float) -> float:
    """1 - the relative error of `answer`, clipped to [0, 1]; 0 for no answer."""
    if answer is None:
        return 0.0
    return max(0.0, 1.0 - abs(answer - truth) / truth)


class Tank:
    """A tank of hidden volume: its sensor reads the volume with noise (uniform on [0, 2 V],
    seeded: reproducible), and it may carry a label with the volume printed on it."""

    def __init__(
        self,
        volume: float,
        seed: int = 0,
        *,
        has_sensor: bool = True,
        label: float | None = None,
        label_readable: bool = True,
    ) -> None:
        self.volume = volume
        self.seed = seed
        self.has_sensor = has_sensor
        self.label = label
        self.label_readable = label_readable

    def readings(self) -> Iterator[np.ndarray]:
        """Batches of `BATCH` readings, the same stream every time."""
        rng = np.random.default_rng(self.seed)
        while True:
            yield rng.uniform(0.0, 2.0 * self.volume, size=BATCH)

    def __repr__(self) -> str:
        return f"Tank(volume={self.volume:.3f}, seed={self.seed})"


@contract("estimate-volume", inputs=[], profile="profiles/estimate-volume.yaml", reports="estimate")
def estimate_volume(ctx: Context, tank: Tank) -> Result | None:
    """The mean of as many batches of readings as the allocation pays for; none without a
    sensor or without time for one batch. Its quality is its own estimate: 1 - twice the
    relative standard error of the mean."""
    if not tank.has_sensor:
        return None
    batches = int(min(ctx.allocation, MAX_BATCHES * BATCH_TICKS) // BATCH_TICKS)
    if batches == 0:
        return None
    stream = tank.readings()
    readings = []
    for _ in range(batches):
        ctx.tick(BATCH_TICKS)
        readings.append(next(stream))
    values = np.concatenate(readings)
    mean = float(values.mean())
    se = float(values.std(ddof=1)) / math.sqrt(len(values))
    return Result(mean, min(1.0, max(0.0, 1.0 - 2.0 * se / mean)))


@contract("read-label", inputs=[], profile="profiles/read-label.yaml")
def read_label(ctx: Context, tank: Tank) -> Result | None:
    """The volume printed on the label: exact, when there is one, it is readable and the
    allocation pays for reading it; else nothing."""
    if tank.label is None or ctx.allocation < LABEL_TICKS:
        return None
    ctx.tick(LABEL_TICKS)
    if not tank.label_readable:
        return None
    return Result(tank.label, 1.0)


@elementary("has-sensor?", inputs=[])
def has_sensor(tank: Tank) -> bool:
    return tank.has_sensor


@elementary("has-label?", inputs=[])
def has_label(tank: Tank) -> bool:
    return tank.label is not None


def _cube_root(ctx: Context, volume: float, input_quality: float) -> Iterator[Result]:
    """Newton's method for the cube root of `volume`, from above, a result after every step.

    Every iterate x stays above the root r, and volume / x^2 is below it, so the relative
    error of x is at most b = x^3 / volume - 1. The reported quality is a lower bound of the
    true one when `input_quality` is the input's true quality q: the input is within 1 - q of
    the true volume, so its cube root is within 1 - q of the true side, and x within b of the
    input's cube root, which is at most 2^(1/3) times the true side."""
    x = 1.0 + volume / 3.0  # above the root: (1 + v/3)^3 >= 1 + v
    while True:
        ctx.tick(STEP_TICKS)
        x = (2.0 * x + volume / (x * x)) / 3.0
        bound = max(0.0, x**3 / volume - 1.0)
        yield Result(x, max(0.0, min(1.0, input_quality - CBRT2 * bound)))
        if bound < 1e-12:
            return


@interruptible(
    "cube-side", inputs=["volume"], profile="profiles/cube-side.yaml", reports="estimate"
)
def cube_side(ctx: Context, volume: Result) -> Iterator[Result]:
    """The side of the cube of the estimated volume, improved step by step."""
    if volume.value is None or volume.value <= 0:
        return  # nothing to take the root of: no result
    yield from _cube_root(ctx, float(volume.value), volume.quality)


@interruptible(
    "joint-side",
    inputs=["volume_a", "volume_b"],
    profile="profiles/joint-side.yaml",
    reports="estimate",
)
def joint_side(ctx: Context, volume_a: Result, volume_b: Result) -> Iterator[Result]:
    """The side of a cube holding both estimated volumes, improved step by step."""
    if volume_a.value is None or volume_b.value is None:
        return
    total = float(volume_a.value) + float(volume_b.value)
    if total <= 0:
        return
    yield from _cube_root(ctx, total, min(volume_a.quality, volume_b.quality))


# --- problem sets: how `anytime profile` measures each module ------------------------------


def _tank(rng: np.random.Generator, **kwargs: Any) -> Tank:
    return Tank(float(rng.uniform(*VOLUMES)), int(rng.integers(2**32)), **kwargs)


def estimate_of(rng: np.random.Generator, volume: float, q: float) -> Result:
    """What `estimate-volume` produces at true quality `q`, distributed as it is (README.md):
    at 0 no result; else the volume off by exactly 1 - q, above or below with equal chance."""
    if q == 0:
        return Result(None, 0.0)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    return Result(volume * (1.0 + sign * (1.0 - q)), q)


class Tanks:
    """Problems for `estimate-volume`: a tank with a sensor, of a volume in `VOLUMES`."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        tank = _tank(rng)
        return Instance(args=(tank,), reference=tank.volume)

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class LabelledTanks:
    """Problems for `read-label`: a labelled tank (its precondition holds), the label readable
    with probability `READABLE`."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        volume = float(rng.uniform(*VOLUMES))
        tank = Tank(volume, label=volume, label_readable=bool(rng.random() < READABLE))
        return Instance(args=(tank,), reference=volume)

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class VolumeEstimates:
    """Problems for `cube-side`: a volume estimate of the quality asked for (`estimate_of`),
    scored against the true volume's cube root."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (q,) = input_qualities
        volume = float(rng.uniform(*VOLUMES))
        return Instance(args=(estimate_of(rng, volume, q),), reference=volume ** (1 / 3))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class VolumeEstimatePairs:
    """Problems for `joint-side`: two independent tanks' volume estimates of the qualities
    asked for, scored against the cube root of the true total."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        qa, qb = input_qualities
        a, b = (float(v) for v in rng.uniform(*VOLUMES, size=2))
        args = (estimate_of(rng, a, qa), estimate_of(rng, b, qb))
        return Instance(args=args, reference=(a + b) ** (1 / 3))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


# --- program problem sets: how `anytime verify` checks each schema's promise ----------------


class TankSideProblems:
    """Problems for `tank-side`: a fresh tank with a sensor, scored against its true side."""

    def instance(self, rng: np.random.Generator) -> Instance:
        tank = _tank(rng)
        return Instance(args=(tank,), reference=tank.volume ** (1 / 3))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class TwoTankProblems:
    """Problems for `two-tank-side`: two fresh tanks, scored against the side of the cube that
    holds both."""

    def instance(self, rng: np.random.Generator) -> Instance:
        a, b = _tank(rng), _tank(rng)
        return Instance(args=(a, b), reference=(a.volume + b.volume) ** (1 / 3))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class LabelledTankProblems:
    """Problems for `labelled-tank-side`: a fresh tank with a sensor and a label (both
    preconditions hold, as the compiler assumes), readable with probability `READABLE`."""

    def instance(self, rng: np.random.Generator) -> Instance:
        volume = float(rng.uniform(*VOLUMES))
        seed = int(rng.integers(2**32))
        readable = bool(rng.random() < READABLE)
        tank = Tank(volume, seed, label=volume, label_readable=readable)
        return Instance(args=(tank,), reference=volume ** (1 / 3))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


#: The time grids: every even tick (the compiled programs allocate on a lattice of 2 ticks, so
#: the compiler never interpolates a profile between grid times, where a module's quality is a
#: step function of time).
TIMES = list(range(0, 41, 2))
JOINT_TIMES = list(range(0, 27, 2))
#: The totals the schemas are compiled for and checked at (on a lattice of 2 ticks).
PROGRAM_TIMES = list(range(0, 41, 4))
#: Input-quality grids, finest where the estimator's qualities lie.
QUALITIES = [0.0, 0.25, 0.5, 0.75, 0.85, 0.9, 0.95, 1.0]
JOINT_QUALITIES = [0.0, 0.25, 0.5, 0.75, 0.9, 1.0]
#: Bins: the estimator's finest where its qualities lie; the label's two outcomes (nothing or
#: exact) each in a bin of its own; coarse ones for the outputs of the programs.
VOLUME_BINS = [0.0, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.925, 0.95, 0.975, 1.0]
LABEL_BINS = [0.0, 0.001, 0.999, 1.0]
SIDE_BINS = [0.0, 0.6, 0.8, 0.9, 0.95, 1.0]
JOINT_BINS = [0.0, 0.8, 0.9, 1.0]

PLUGIN = Plugin(
    name="estimation",
    modules=(estimate_volume, read_label, has_sensor, has_label, cube_side, joint_side),
    problem_sets={
        "estimate-volume": Measurement.of(Tanks(), time=TIMES, bins=VOLUME_BINS),
        "read-label": Measurement.of(LabelledTanks(), time=[0, 2, 4, 40], bins=LABEL_BINS),
        "cube-side": Measurement.of(
            VolumeEstimates(), time=TIMES, input_grids=[QUALITIES], bins=SIDE_BINS
        ),
        "joint-side": Measurement.of(
            VolumeEstimatePairs(),
            time=JOINT_TIMES,
            input_grids=[JOINT_QUALITIES, JOINT_QUALITIES],
            bins=JOINT_BINS,
        ),
    },
    program_problems={
        name: ProgramProblems.of(problems, time_grid=PROGRAM_TIMES, resolution=2)
        for name, problems in (
            ("tank-side", TankSideProblems()),
            ("two-tank-side", TwoTankProblems()),
            ("labelled-tank-side", LabelledTankProblems()),
        )
    },
)
