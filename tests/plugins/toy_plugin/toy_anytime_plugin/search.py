"""A plugin whose module stalls: a randomised local search that improves often at first and
rarely after about 40 ticks, and registers a result only when it improves (as a tabu search
does). Written against the public plugin API only (`anytime.plugin`); the stopping benchmark
(benchmarks/bench_stopping.py) records its traces with the profile builder.

The problem: find the highest point of a rugged landscape, `POINTS` values on a ring (a few
broad hills, each with a rough top). The search climbs from a random point, one neighbour
tried a tick (a step of 1 to `REACH` points either way); after `PATIENCE` tries without a
better neighbour it starts again from a random point. Its answer is the best point seen; the
true quality is the landscape's value there, scaled so that its lowest point is 0 and its
highest 1 (the search knows the values it sees, so `reports="true"`).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from anytime.plugin import Context, Instance, Measurement, Plugin, Result, interruptible

#: Points of the ring, hills on it, and the size of the roughness on the hills' tops.
POINTS, HILLS, ROUGHNESS = 300, 6, 0.2
#: The farthest neighbour a climb tries, and how many failed tries end a climb.
REACH, PATIENCE = 8, 8


class Landscape:
    """The values of a ring of `POINTS` points, lowest 0 and highest 1: a sum of `HILLS`
    Gaussian hills of random heights and widths with rough tops (seeded: reproducible)."""

    def __init__(self, seed: int) -> None:
        rng = np.random.default_rng(seed)
        points = np.arange(POINTS)
        centres = rng.integers(POINTS, size=HILLS)
        distance = np.abs(points[:, None] - centres)
        distance = np.minimum(distance, POINTS - distance)  # on a ring
        widths = rng.uniform(8.0, 40.0, size=HILLS)
        heights = rng.uniform(0.3, 1.0, size=HILLS)
        hills = (heights * np.exp(-0.5 * (distance / widths) ** 2)).sum(axis=1)
        rough = hills + ROUGHNESS * rng.random(POINTS) * hills / hills.max()
        self.values = (rough - rough.min()) / (rough.max() - rough.min())
        self.seed = seed

    def __repr__(self) -> str:
        return f"Landscape(seed={self.seed})"


@interruptible("toy-search", inputs=[])
def toy_search(ctx: Context, landscape: Landscape, seed: int) -> Iterator[Result]:
    """Random-restart hill climbing for the highest point, one point tried a tick; a result
    (the best point so far) only when it improves."""
    rng = np.random.default_rng(seed)
    values = landscape.values
    best = -1.0
    while True:
        here = int(rng.integers(POINTS))  # a climb starts at a random point
        failed = 0
        while failed < PATIENCE:
            ctx.tick()
            if values[here] > best:
                best = float(values[here])
                yield Result(here, best)
            if ctx.expired:
                return
            step = int(rng.integers(1, REACH + 1)) * (1 if rng.random() < 0.5 else -1)
            there = (here + step) % POINTS
            if values[there] > values[here]:
                here, failed = there, 0
            else:
                failed += 1


class Landscapes:
    """Problems for `toy-search`: a random landscape and the search's seed; the true quality
    is the landscape's value at the answer."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        landscape = Landscape(int(rng.integers(2**32)))
        return Instance(args=(landscape, int(rng.integers(2**32))), reference=landscape)

    def score(self, instance: Instance, value: Any) -> float:
        return 0.0 if value is None else float(instance.reference.values[value])


#: The grid its traces are recorded on: every 2 ticks up to 100.
TIMES = list(range(0, 101, 2))

PLUGIN = Plugin(
    name="toy-search",
    modules=(toy_search,),
    problem_sets={"toy-search": Measurement.of(Landscapes(), time=TIMES)},
)
