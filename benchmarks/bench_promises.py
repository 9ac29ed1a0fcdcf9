"""What the compiler promises against what runs deliver, at every budget of the table.

    .venv/bin/python benchmarks/bench_promises.py [--runs 30] [--quick]

The shipped `navigate` schema (sense with anytime vision, then plan with the ATP) compiled
against the navigation plugin's measured profiles, on the profiles' own setting (random
128x128 worlds, 4-connected). At each total T of the compiled table, fresh worlds (never those
the profiles were measured on) are run through `run_program` on the work clock, and the plan
is scored as the profiles score it: the papers' plan quality on the true map. Columns: the
compiled expectation, the realised mean and its standard error, |difference| / standard error
(within 2 in about 95% of rows when the promise holds; where every run scored the same, so the
standard error is 0, the difference is divided by 1 / runs instead), how many runs used more
than T, and how many ended without a plan.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from anytime_navigation.execution import execute, optimal_length, plan_quality
from anytime_navigation.resources import load_schema_file
from anytime_navigation.vision import Sensor
from anytime_navigation.world import random_world
from tables import machine, table

from anytime import AnytimeLibrary, WorkClock, compile_file
from anytime.runtime import run_program

SIZE = 128
SEED_BASE = 10_000  # worlds apart from the profile builder's (which draws from SeedSequence)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100, help="worlds per budget")
    parser.add_argument("--quick", action="store_true", help="30 worlds per budget")
    args = parser.parse_args()
    runs = 30 if args.quick else args.runs
    started = time.perf_counter()
    schemas = load_schema_file("navigation.any")
    library = AnytimeLibrary.default()
    grid = np.arange(0.0, 3001.0, 250.0)
    (compiled,) = [c for c in compile_file(schemas, library, grid, schema="navigate")]
    rows = []
    worst, within = 0.0, 0
    for j, total in enumerate(compiled.profile.time):
        qualities, over, empty = [], 0, 0
        for i in range(runs):
            world = random_world(SIZE, seed=SEED_BASE + 1000 * j + i, movement=4)
            sensor = Sensor(world.blocked, seed=SEED_BASE + 1000 * j + i, movement=4)
            clock = WorkClock()
            record = run_program(compiled, [world.start, world.goal, sensor], total, clock=clock)
            over += record.time_used > total + 1e-9
            if record.result is None or record.result.value is None:
                empty += 1
                qualities.append(0.0)
                continue
            executed = execute(record.result.value, world.blocked, movement=4)
            optimal = optimal_length(world.blocked, world.start, world.goal, movement=4)
            qualities.append(plan_quality(executed.length, optimal))
        mean = float(np.mean(qualities))
        se = float(np.std(qualities, ddof=1) / np.sqrt(runs)) if runs > 1 else 0.0
        promised = float(compiled.expected[j])
        gap = abs(mean - promised)
        ratio = gap / (se if se > 0 else 1.0 / runs)
        worst = max(worst, ratio)
        within += ratio <= 2.0
        rows.append(
            [
                f"{total:g}",
                f"{promised:.3f}",
                f"{mean:.3f}",
                f"{se:.3f}",
                f"{ratio:.2f}",
                f"{over}/{runs}",
                f"{empty}/{runs}",
            ]
        )
    print(machine())
    print(
        f"navigate compiled for T = 0..3000 ticks, {runs} fresh worlds per budget,"
        f" {time.perf_counter() - started:.0f} s"
    )
    print()
    header = ["T (ticks)", "compiled", "realised", "se", "|diff| / se", "over T", "no plan"]
    print(table(header, rows))
    print()
    print(
        f"within 2 standard errors at {within} of {len(rows)} budgets; largest |diff| / se:"
        f" {worst:.2f}"
    )


if __name__ == "__main__":
    main()
