"""What the compiler promises against what runs deliver, at every budget of the table.

    .venv/bin/python benchmarks/bench_promises.py [--runs 100] [--quick]

Five programs: the navigation plugin's `navigate`, the example plugin's `side-length`
(docs/example-plugin, a plugin that is not the framework's: measure a plot's area with a noisy
sensor, then take its square root, `schemas/side-length.any`, each plot scored against its true
side), and the three schemas of the test plugin tests/plugins/estimation_plugin (another third
party's: estimate a tank's volume by Monte Carlo, or read its label, then the side of its cube;
a chain, a two-input program and a best-of, each tank scored against its true side).

The shipped `navigate` schema (sense with anytime vision, then plan with the ATP) compiled
against the navigation plugin's measured profiles, on the profiles' own setting (random
128x128 worlds, 4-connected). At each total T of the compiled table, fresh worlds (never those
the profiles were measured on) are run through `run_program` on the work clock, and the plan
is scored as the profiles score it: the papers' plan quality on the true map. Columns: the
compiled expectation, the realised mean and its standard error, |difference| / standard error
(within 2 in about 95% of rows when the promise holds; where every run scored the same, so the
standard error is 0, the difference is divided by 1 / runs instead), how many runs used more
than T, and how many ended without a plan. For a program with a best-of, `if dependent`: what
the compiled program says a dependence between its alternatives could make of the promise, at
worst and at best (`CompiledProgram.dependence`).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from anytime_navigation.resources import load_schema_file
from anytime_navigation.task.execution import execute, optimal_length, plan_quality
from anytime_navigation.task.vision import Sensor
from anytime_navigation.world import random_world
from tables import machine, table

from anytime import AnytimeLibrary, CompiledProgram, LibraryEntry, WorkClock, compile_file
from anytime import load_schemas as load_schema_path
from anytime.runtime import Budget, run_program

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "docs" / "example-plugin"))  # the example plugin, as it ships

sys.path.insert(0, str(ROOT / "tests" / "plugins" / "estimation_plugin"))  # the test plugin

import anytime_estimation as estimation  # noqa: E402
from anytime_survey import PLUGIN as SURVEY  # noqa: E402
from anytime_survey import Plot, quality  # noqa: E402

SIZE = 128
SEED_BASE = 10_000  # worlds apart from the profile builder's (which draws from SeedSequence)


#: One run: (compiled program, budget index, run index, total) -> (quality, time used, ran out).
Trial = Callable[[CompiledProgram, int, int, float], tuple[float, float, bool]]


def navigate_trial(
    compiled: CompiledProgram, j: int, i: int, total: float
) -> tuple[float, float, bool]:
    world = random_world(SIZE, seed=SEED_BASE + 1000 * j + i, movement=4)
    sensor = Sensor(world.blocked, seed=SEED_BASE + 1000 * j + i, movement=4)
    record = run_program(
        compiled, [world.start, world.goal, sensor], Budget(total, clock=WorkClock())
    )
    if record.result is None or record.result.value is None:
        return 0.0, record.time_used, True
    executed = execute(record.result.value, world.blocked, movement=4)
    optimal = optimal_length(world.blocked, world.start, world.goal, movement=4)
    return plan_quality(executed.length, optimal), record.time_used, False


def survey_trial(
    compiled: CompiledProgram, j: int, i: int, total: float
) -> tuple[float, float, bool]:
    rng = np.random.default_rng(SEED_BASE + 1000 * j + i)
    area = float(rng.uniform(10, 1000))
    plot = Plot(area, seed=SEED_BASE + 1000 * j + i)
    record = run_program(compiled, [plot], Budget(total, clock=WorkClock()))
    value = record.result.value if record.result is not None else None
    return quality(value, math.sqrt(area)), record.time_used, value is None


def fresh_tanks(schema: str, rng: np.random.Generator) -> tuple[list[estimation.Tank], float]:
    """The test plugin's inputs for one run of `schema` (two tanks for two-tank-side; one
    labelled, readable or not, for labelled-tank-side; else one) and the true side."""

    def tank(labelled: bool = False) -> estimation.Tank:
        volume = float(rng.uniform(*estimation.VOLUMES))
        seed = int(rng.integers(2**32))
        if not labelled:
            return estimation.Tank(volume, seed)
        readable = bool(rng.random() < estimation.READABLE)
        return estimation.Tank(volume, seed, label=volume, label_readable=readable)

    if schema == "two-tank-side":
        tanks = [tank(), tank()]
        return tanks, (tanks[0].volume + tanks[1].volume) ** (1 / 3)
    one = tank(labelled=schema == "labelled-tank-side")
    return [one], one.volume ** (1 / 3)


def estimation_trial(
    compiled: CompiledProgram, j: int, i: int, total: float
) -> tuple[float, float, bool]:
    """A fresh tank (two for two-tank-side; labelled for labelled-tank-side, whose best-of the
    compiler expects with both preconditions holding), scored against its true side."""
    rng = np.random.default_rng([SEED_BASE, len(compiled.name), j, i])
    tanks, truth = fresh_tanks(compiled.name, rng)
    record = run_program(compiled, tanks, Budget(total, clock=WorkClock()))
    value = record.result.value if record.result is not None else None
    return estimation.quality(value, truth), record.time_used, value is None


def promise_table(compiled: CompiledProgram, trial: Trial, runs: int) -> tuple[str, str]:
    rows = []
    worst, within = 0.0, 0
    for j, total in enumerate(compiled.profile.time):
        qualities, over, empty = [], 0, 0
        for i in range(runs):
            q, used, missing = trial(compiled, j, i, float(total))
            qualities.append(q)
            over += used > total + 1e-9
            empty += missing
        mean = float(np.mean(qualities))
        se = float(np.std(qualities, ddof=1) / np.sqrt(runs)) if runs > 1 else 0.0
        promised = float(compiled.expected[j])
        gap = abs(mean - promised)
        ratio = gap / (se if se > 0 else 1.0 / runs)
        worst = max(worst, ratio)
        within += ratio <= 2.0
        bounds = compiled.dependence  # a best-of: what a dependence between alternatives gives
        ranged = [] if bounds is None else [f"{bounds[0][j]:.3f}-{bounds[1][j]:.3f}"]
        rows.append(
            [
                f"{total:g}",
                f"{promised:.3f}",
                *ranged,
                f"{mean:.3f}",
                f"{se:.3f}",
                f"{ratio:.2f}",
                f"{over}/{runs}",
                f"{empty}/{runs}",
            ]
        )
    ranged_header = [] if compiled.dependence is None else ["if dependent"]
    header = ["T (ticks)", "compiled", *ranged_header, "realised", "se", "|diff| / se"]
    header += ["over T", "no result"]
    summary = (
        f"within 2 standard errors at {within} of {len(rows)} budgets; largest |diff| / se:"
        f" {worst:.2f}"
    )
    return table(header, rows), summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100, help="instances per budget")
    parser.add_argument("--quick", action="store_true", help="30 instances per budget")
    args = parser.parse_args()
    runs = 30 if args.quick else args.runs
    print(machine())
    navigation = AnytimeLibrary.default()
    (navigate,) = compile_file(
        load_schema_file("navigation.any"),
        navigation,
        np.arange(0.0, 3001.0, 250.0),
        schema="navigate",
    )
    survey = AnytimeLibrary()
    for module in SURVEY.modules:
        survey.add(LibraryEntry.of_module(module))
    (side_length,) = compile_file(
        load_schema_path(ROOT / "schemas" / "side-length.any"),
        survey,
        range(0, 65, 8),
        resolution=2,
    )
    tanks = AnytimeLibrary()
    for module in estimation.PLUGIN.modules:
        tanks.add(LibraryEntry.of_module(module))
    estimation_programs = compile_file(
        load_schema_path(estimation.SCHEMA_FILE), tanks, range(0, 41, 4), resolution=2
    )
    for title, compiled, trial in (
        ("navigate (navigation plugin), fresh 128x128 worlds", navigate, navigate_trial),
        ("side-length (example plugin), fresh plots", side_length, survey_trial),
        *(
            (f"{p.name} (estimation test plugin), fresh tanks", p, estimation_trial)
            for p in estimation_programs
        ),
    ):
        started = time.perf_counter()
        rows, summary = promise_table(compiled, trial, runs)
        print()
        print(f"{title}, {runs} per budget, {time.perf_counter() - started:.0f} s")
        print()
        print(rows)
        print()
        print(summary)


if __name__ == "__main__":
    main()
