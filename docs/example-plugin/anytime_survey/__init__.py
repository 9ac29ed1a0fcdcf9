"""Survey a square plot: average a noisy sensor's readings of its area, then take the square
root of the area with Newton's method. Two interruptible modules, their problem sets (how
`anytime profile` measures them) and the plugin object the entry point names."""

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from anytime.plugin import Context, Instance, Measurement, Plugin, Result, interruptible

NOISE = 0.2  # a reading's standard deviation, relative to the true area


def quality(estimate: float | None, truth: float) -> float:
    """1 for the exact value, falling linearly to 0 at 20% off (or no estimate at all)."""
    if estimate is None:
        return 0.0
    return max(0.0, 1.0 - 5.0 * abs(estimate - truth) / truth)


class Plot:
    """A square plot of land and the sensor that reads its area (seeded: reproducible)."""

    def __init__(self, area: float, seed: int = 0) -> None:
        self.area = area
        self.seed = seed

    def readings(self) -> Iterator[float]:
        rng = np.random.default_rng(self.seed)
        while True:
            yield self.area * (1.0 + NOISE * float(rng.standard_normal()))


@interruptible("measure", inputs=[], profile="profiles/measure.yaml")
def measure(ctx: Context, plot: Plot) -> Iterator[Result]:
    """The mean of the readings so far, one reading a tick. Its quality is what the standard
    error of the mean predicts."""
    total = 0.0
    for n, reading in enumerate(plot.readings(), start=1):
        ctx.tick()
        total += reading
        yield Result(total / n, max(0.0, 1.0 - 4.0 * NOISE / math.sqrt(n)))


@interruptible("square-root", inputs=["area"], profile="profiles/square-root.yaml")
def square_root(ctx: Context, area: Result) -> Iterator[Result]:
    """Newton's method for the square root of an area, one iteration a tick, until it stops
    moving. The root is as good as the area allows, and as the last step suggests."""
    a = area.value
    if a is None or a <= 0:
        return  # nothing to take the root of: no result
    y = (1.0 + a) / 2.0
    while True:
        ctx.tick()
        y, last = (y + a / y) / 2.0, y
        step = abs(y - last) / y
        yield Result(y, min((1.0 + area.quality) / 2.0, max(0.0, 1.0 - 5.0 * step)))
        if step == 0:
            return


class Plots:
    """Problems for `measure`: a plot of 10 to 1000 square units."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        area = float(rng.uniform(10, 1000))
        return Instance(args=(Plot(area, int(rng.integers(2**32))),), reference=area)

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class Areas:
    """Problems for `square-root`: an area of the quality asked for (none at quality 0)."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        area = float(rng.uniform(10, 1000))
        (q,) = input_qualities
        if q == 0:
            return Instance(args=(Result(None, 0.0),), reference=math.sqrt(area))
        error = (1.0 - q) / 5.0 * float(rng.choice([-1.0, 1.0]))
        return Instance(args=(Result(area * (1.0 + error), q),), reference=math.sqrt(area))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


PLUGIN = Plugin(
    name="survey",
    modules=(measure, square_root),
    problem_sets={
        "measure": Measurement.of(Plots(), time=[0, 1, 2, 4, 8, 16, 32, 64]),
        "square-root": Measurement.of(
            Areas(), time=range(13), input_grids=[[0, 0.25, 0.5, 0.75, 1]]
        ),
    },
)
