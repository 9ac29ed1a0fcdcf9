"""The callable form of a plugin: a function that returns the plugin's modules."""

from anytime import AnytimeModule, Context, Registry, Result, contract
from anytime.profiles import Step, tabulate

# Kept out of the process-wide registry: the entry point's callable is how they are found.
_REGISTRY = Registry()


@contract(
    "toy-halve",
    inputs=[],
    registry=_REGISTRY,
    # Below 20 ticks it answers roughly (0.5), from 20 exactly (1.0).
    profile=tabulate(Step([(0, 0.5), (20, 1.0)]), time=[0, 10, 20], kind="contract"),
)
def toy_halve(ctx: Context, x: float) -> Result:
    """Half of `x`, exactly when given 20 ticks, roughly when given 10."""
    ctx.tick(min(ctx.allocation, 20))
    return Result(x / 2, 1.0 if ctx.allocation >= 20 else 0.5)


def modules() -> list[AnytimeModule]:
    return [toy_halve]
