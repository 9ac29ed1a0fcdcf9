"""A toy anytime plugin: one interruptible module with an analytic profile.

Written the old way: importing it registers `toy-count` in the process-wide registry
(`registry=REGISTRY`); the library attributes it to the plugin whose entry point names this
package.
It also registers the module's problem set, so that `anytime profile toy-count` can measure it.
"""

from collections.abc import Iterator
from typing import Any

import numpy as np

from anytime import REGISTRY, Context, Result, interruptible
from anytime.measure.builder import Instance, register_problems
from anytime.profiles import tabulate

LIMITS = np.arange(50, 150)  # the problem set draws the count's limit uniformly from these


def expected_quality(t: Any, q: Any) -> Any:
    """E[q * min(1, t / limit)] over the limits: what counting up to the limit gives."""
    fraction = np.minimum(1.0, np.asarray(t)[..., None] / LIMITS).mean(axis=-1)
    return q * fraction


PROFILE = tabulate(
    expected_quality,
    time=[0, 50, 100, 200],
    bins=[0.0, 0.25, 0.5, 0.75, 1.0],
    input_grids=[[0.5, 1.0]],
    inputs=["data"],
    module="toy-count",
)


@interruptible("toy-count", inputs=["data"], profile=PROFILE, registry=REGISTRY)
def toy_count(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Count up to `limit`, one tick a step; the quality is the fraction counted, scaled by the
    quality of the data it counts on."""
    for done in range(1, limit + 1):
        ctx.tick()
        yield Result(done, data.quality * done / limit)
        if ctx.expired:
            return


class CountingProblems:
    """Problems for `toy-count`: a random limit; the true quality is the fraction counted times
    the input quality."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        limit = int(rng.choice(LIMITS))
        return Instance(args=(None, limit), reference=(limit, input_qualities[0]))

    def score(self, instance: Instance, value: Any) -> float:
        limit, quality = instance.reference
        return float(quality * value / limit)


register_problems(
    toy_count, CountingProblems(), time=[0, 25, 50, 100, 150, 200], input_grids=[[0.5, 1.0]]
)
