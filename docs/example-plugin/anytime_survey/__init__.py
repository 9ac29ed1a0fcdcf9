"""Survey a square plot: average a noisy sensor's readings of its area, then take the square
root of the area with Newton's method. Two interruptible modules, their problem sets (how
`anytime profile` measures them), a subcommand, and the plugin object the entry point names."""

import argparse
import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from anytime import AnytimeLibrary, compile_file, load_schemas, run_program
from anytime.plugin import (
    Context,
    Instance,
    Measurement,
    Plugin,
    ProgramProblems,
    Result,
    interruptible,
)
from anytime.plugin.cli import EXIT_OK, CommandGroup, positive_float, positive_int

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
    """Problems for `square-root`: an area of the quality asked for, as `measure` gives it. Its
    error is symmetric, so an area of quality q > 0 is off by (1 - q) / 5 of the truth, above
    or below; quality 0 is any error of 20% or more, drawn like one reading's (the worst
    `measure` gives). No result is not a quality: the module is not called without one."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        area = float(rng.uniform(10, 1000))
        (q,) = input_qualities
        error = (1.0 - q) / 5.0 * float(rng.choice([-1.0, 1.0]))
        while q == 0 and abs(error) <= 0.2:
            error = NOISE * float(rng.standard_normal())
        return Instance(args=(Result(area * (1.0 + error), q),), reference=math.sqrt(area))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


class Surveys:
    """The problems the schema side-length is promised for (`anytime verify`): a plot of 10 to
    1000 square units; a result is scored against its true side."""

    def instance(self, rng: np.random.Generator) -> Instance:
        area = float(rng.uniform(10, 1000))
        return Instance(args=(Plot(area, int(rng.integers(2**32))),), reference=math.sqrt(area))

    def score(self, instance: Instance, value: Any) -> float:
        return quality(value, instance.reference)


def survey(args: argparse.Namespace) -> int:
    """`anytime survey`: compile the schema for the time given and run it on one plot."""
    library = AnytimeLibrary.default()
    schemas = load_schemas(args.file, library.known_functions())
    (program,) = compile_file(schemas, library, [0, args.time], schema=args.schema, resolution=1)
    result = run_program(program, [Plot(args.area)], args.time).result
    if result is None:  # the program registered no result in that time
        print(f"{args.schema} in {args.time} ticks: no result")
        return EXIT_OK
    split = ", ".join(
        f"{m} {t:g}" for m, t in zip(program.modules, program.allocation[-1], strict=True)
    )
    side = math.sqrt(args.area)
    print(f"{args.schema} in {args.time} ticks ({split}): side {result.value:.3f},", end=" ")
    print(f"true {side:.3f}, quality {quality(result.value, side):.3f}", end=" ")
    print(f"(expected {program.expected[-1]:.3f})")
    return EXIT_OK


def add_commands(commands: CommandGroup) -> None:
    parser = commands.add_command(
        "survey", help="survey one plot with a compiled schema", run=survey
    )
    parser.add_argument("file", metavar="FILE", help="a schema file (.any)")
    parser.add_argument("--schema", default="side-length", help="the schema (side-length)")
    parser.add_argument("--area", type=positive_float, default=400.0, help="true area (400)")
    parser.add_argument("--time", type=positive_int, default=32, help="total ticks (32)")


PLUGIN = Plugin(
    name="survey",
    modules=(measure, square_root),
    problem_sets={
        "measure": Measurement.of(Plots(), time=[0, 1, 2, 4, 8, 16, 32, 64]),
        "square-root": Measurement.of(
            Areas(), time=range(13), input_grids=[[0, 0.25, 0.5, 0.75, 1]]
        ),
    },
    add_commands=add_commands,
    program_problems={
        "side-length": ProgramProblems.of(Surveys(), time_grid=range(0, 65, 8), resolution=2)
    },
)
