"""A toy anytime plugin: one interruptible module with an analytic profile.

Importing it registers `toy-count` in the process-wide registry, as any module defined with the
decorators does; the library attributes it to the plugin whose entry point names this package.
"""

from collections.abc import Iterator
from typing import Any

from anytime import Context, Result, interruptible
from anytime.profiles import Exponential, tabulate

#: Expected quality `q * (1 - exp(-t / 50))` for input quality q after t ticks.
PROFILE = tabulate(
    lambda t, q: q * Exponential(rate=0.02)(t),
    time=[0, 50, 100, 200],
    bins=[0.0, 0.25, 0.5, 0.75, 1.0],
    input_grids=[[0.5, 1.0]],
    inputs=["data"],
    module="toy-count",
)


@interruptible("toy-count", inputs=["data"], profile=PROFILE)
def toy_count(ctx: Context, data: Any, limit: int) -> Iterator[Result]:
    """Count up to `limit`, one tick a step; the quality is the fraction counted."""
    for done in range(1, limit + 1):
        ctx.tick()
        yield Result(done, done / limit)
        if ctx.expired:
            return
