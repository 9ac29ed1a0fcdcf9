"""The motion plugin (domains/motion, OMPL): what compiling buys, whether the compiled promise
holds, and its planners' quality over time.

1. For `move` (sense -> BIT* -> shorten) and `move-best` (one sensed map, a best-of of RRT*
   and BIT*, shorten), at every budget of the compiled table, on fresh problems (mean +-
   standard error): the compiled expectation against the realised quality of the compiled
   split, and beside it MoveIt's even split (the budget divided evenly among the modules),
   all of it to the planners, and the best single fixed split (the one set of fractions,
   chosen among a few on separate tuning problems, that does best over all the budgets), with
   the most time any compiled run used.
   Targets (issue 39): the compiled split >= 10% above the even split where the split
   matters, never below it by more than a standard error; |realised - compiled| <=
   max(0.01, 2 se) at every budget; no run over its budget.
2. Each planner's true quality over its validity checks, on the true obstacles' map (coverage
   1) and on maps sensed with 500 rays, from the same problems.
3. The time to measure a profile with `anytime profile`'s builder, 1 and 2 worker processes
   and a local Dask cluster of 2 workers, and whether the three give the same profile.

    .venv/bin/python benchmarks/bench_motion.py [--quick] [--problems N]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from anytime_motion.domain import OccupancyMap, Sensor, path_quality
from anytime_motion.modules import PROBLEM_SETS
from anytime_motion.planners import OmplPlanner
from anytime_motion.program import (
    SCHEMAS,
    Problem,
    compiled_program,
    draw_problem,
    fixed_split,
    move,
)
from profile_timing import profile_times as timing_table
from tables import machine, table

from anytime import Budget, run_program
from anytime.plugin import WorkClock

SEED = 20_261_205  # fresh problems, apart from the profile builder's seeds and the tests'
#: Candidate fixed splits (fractions of the budget: sensing, shortening; the planners get the
#: rest, evenly between a best-of's two).
CANDIDATES = [(s, h) for s in (0.125, 0.25, 0.375, 0.5) for h in (0.0, 0.125)]


def _problems(seed: int, count: int) -> list[Problem]:
    rng = np.random.default_rng([SEED, seed])
    return [draw_problem(rng) for _ in range(count)]


def _fractions(modules: tuple[str, ...], sense: float, shorten: float) -> np.ndarray:
    planners = [m in ("rrt-star", "bit-star") for m in modules]
    share = (1.0 - sense - shorten) / sum(planners)
    return np.array(
        [
            sense if m == "sense-obstacles" else shorten if m == "shorten-path" else share
            for m in modules
        ]
    )


def _fixed_quality(program, problem: Problem, fractions: np.ndarray, total: float) -> float:  # type: ignore[no-untyped-def]
    runnable = fixed_split(program, fractions * total)
    record = run_program(
        runnable, [problem.sensor, problem.query], Budget(total, clock=WorkClock())
    )
    path = record.result.value if record.result is not None else None
    return path_quality(path, problem.world, problem.reference.cost)


def _cell(q: list[float]) -> tuple[float, float, str]:
    a = np.asarray(q, dtype=float)
    se = float(a.std(ddof=1) / math.sqrt(len(a)))
    return float(a.mean()), se, f"{a.mean():.3f} ± {se:.3f}"


def promises(count: int, tuning: int) -> None:
    for index, schema in enumerate(SCHEMAS):
        program = compiled_program(schema)
        totals = [float(t) for t in program.profile.time]
        tune = _problems(100 + index, tuning)
        best, best_mean = CANDIDATES[0], -1.0
        for sense, shorten in CANDIDATES:
            fractions = _fractions(program.modules, sense, shorten)
            mean = float(
                np.mean([_fixed_quality(program, p, fractions, t) for t in totals for p in tune])
            )
            if mean > best_mean:
                best, best_mean = (sense, shorten), mean
        fixed = _fractions(program.modules, *best)
        problems = _problems(index, count)
        rows = []
        met = wins = splits_matter = 0
        for j, total in enumerate(totals):
            runs = [move(program, p, total) for p in problems]
            compiled = [r.quality for r in runs]
            even = [move(program, p, total, "even").quality for p in problems]
            planner = [move(program, p, total, "planner").quality for p in problems]
            best_fixed = [_fixed_quality(program, p, fixed, total) for p in problems]
            used = max(r.record.time_used for r in runs)
            c_mean, c_se, c_text = _cell(compiled)
            e_mean, e_se, e_text = _cell(even)
            diff = c_mean - float(program.expected[j])
            ok = abs(diff) <= max(0.01, 2 * c_se) and used <= total
            met += ok
            matters = abs(c_mean - e_mean) > 2 * math.hypot(c_se, e_se)
            splits_matter += matters
            wins += matters and c_mean >= 1.1 * e_mean
            rows.append(
                [
                    f"{total:g}",
                    f"{program.expected[j]:.3f}",
                    c_text,
                    f"{diff:+.3f}",
                    f"{used:g}",
                    e_text,
                    _cell(planner)[2],
                    _cell(best_fixed)[2],
                    "yes" if matters else "",
                ]
            )
        split = ", ".join(f"{m} {f:.3g}" for m, f in zip(program.modules, fixed, strict=True))
        print(
            f"**{schema}** ({count} fresh problems per budget; {program.allocator}; the best"
            f" fixed split, chosen on {tuning} other problems: {split}):\n"
        )
        header = [
            "T (ticks)", "compiled", "realised", "diff", "max used", "even (MoveIt)",
            "all to planners", "best fixed", "split matters",
        ]  # fmt: skip
        print(table(header, rows))
        print(
            f"\nwithin max(0.01, 2 se) and no overrun at {met} of {len(rows)} budgets; where"
            f" the split matters (compiled and even more than 2 se apart: {splits_matter}"
            f" budgets), the compiled split >= 1.1x the even split at {wins}\n"
        )


CHECKS = [500, 1000, 2000, 3000, 4000, 6000]


def planners(count: int) -> None:
    problems = _problems(7, count)
    rows = []
    for sensed in (False, True):
        for name in ("rrt-star", "bit-star"):
            quality = np.zeros((count, len(CHECKS)))
            for i, problem in enumerate(problems):
                if sensed:
                    map = OccupancyMap(problem.world.dimension)
                    sensor = Sensor(problem.world, problem.sensor.seed)
                    for hits, _ in zip(sensor.scans(), range(500 // sensor.rays), strict=False):
                        map.mark(hits)
                else:
                    map = OccupancyMap.of_world(problem.world)
                solver = OmplPlanner(name, map, problem.query)
                for k, checks in enumerate(CHECKS):
                    while solver.checks < checks and solver.advance(100) > 0:
                        pass
                    found = solver.best()
                    path = found.value if found is not None else None
                    quality[i, k] = path_quality(path, problem.world, problem.reference.cost)
            where = "sensed, 500 rays" if sensed else "true obstacles"
            se = quality.std(axis=0, ddof=1) / math.sqrt(count)
            rows.append(
                [
                    f"{name} ({where})",
                    *(f"{m:.3f} ± {s:.3f}" for m, s in zip(quality.mean(axis=0), se, strict=True)),
                ]
            )
    print(f"**Each planner's true quality over its validity checks** ({count} problems):\n")
    print(table(["planner (map)", *(f"{c} checks" for c in CHECKS)], rows))
    print()


TIMING_TRIALS = {"sense-obstacles": 40, "rrt-star": 4, "shorten-path": 2}


def profile_times() -> None:
    print(timing_table(TIMING_TRIALS, PROBLEM_SETS))
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="30 problems per budget")
    parser.add_argument("--problems", type=int, default=100, help="fresh problems (100)")
    args = parser.parse_args()
    count = 30 if args.quick else args.problems
    promises(count, tuning=10 if args.quick else 30)
    planners(count)
    profile_times()
    print(machine())


if __name__ == "__main__":
    main()
