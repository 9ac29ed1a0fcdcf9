"""The routing plugin (domains/routing): its compiled schemas' promises, and its tour
improvement on TSPLIB instances against their optimal lengths.

1. For `deliver` (the chain), `deliver-best` (the DAG with a best-of) and `deliver-each` (the
   chain with a loop, a `plan-tour` per depot), at every budget of the compiled table: the
   compiled expectation against the mean true quality of runs on fresh problems (mean +-
   standard error), fixed and adaptive, and the most time any run used.
   Target: |realised - compiled| <= max(0.01, 2 se) at every budget, no run over its budget.
2. The time to measure each module's profile with `anytime profile`'s builder, the plugin's own
   problem sets on their full grids with a few trials per cell: 1 worker process, 2, and a
   local Dask cluster of 2 single-threaded worker processes (started beforehand, not timed);
   and whether the three give the same profile (the seed fixes it, whatever runs the trials).
3. `plan-tours` (nearest neighbour, then best-improvement 2-opt / Or-opt, one tick a batch of
   moves) on TSPLIB instances with one depot: optimal length / length after so many ticks, and
   at convergence. Target: within 5% of the optimum.

    .venv/bin/python benchmarks/bench_routing.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from anytime_routing.domain import Clustering
from anytime_routing.modules import PROBLEM_SETS, plan_tours
from anytime_routing.program import (
    SCHEMAS,
    compiled_program,
    deliver,
    fresh_problems,
)
from profile_timing import profile_times as timing_table
from tables import machine, table

from anytime import Context, Result

DATA = Path(__file__).resolve().parent / "data" / "tsplib"
#: (instance, optimal length): TSPLIB's published optima (data/tsplib/README.md).
TSPLIB = (
    ("berlin52", 7542),
    ("st70", 675),
    ("kroA100", 21282),
    ("pr152", 73682),
    ("rat195", 2323),
)
SEED = 20_250_115  # fresh problems, apart from the profile builder's seeds and the tests'


def promises(worlds: int) -> None:
    for schema in SCHEMAS:
        program = compiled_program(schema)
        rng = np.random.default_rng([SEED, SCHEMAS.index(schema)])
        problems = fresh_problems(rng, worlds)
        rows = []
        met = 0
        for j, total in enumerate(program.profile.time):
            cells = [f"{total:g}", f"{program.expected[j]:.3f}"]
            ok = True
            for adaptive in (False, True):
                runs = [deliver(program, w, float(total), adaptive, r) for w, r in problems]
                q = np.array([run.quality for run in runs], dtype=float)
                used = max(run.record.time_used for run in runs)
                se = float(q.std(ddof=1) / math.sqrt(len(q)))
                diff = float(q.mean() - program.expected[j])
                ok = ok and abs(diff) <= max(0.01, 2 * se) and used <= total
                cells += [f"{q.mean():.3f} ± {se:.3f}", f"{diff:+.3f}", f"{used:g}"]
            met += ok
            rows.append(cells)
        print(f"**{schema}** ({worlds} fresh problems per budget; {program.allocator}):\n")
        header = ["T (ticks)", "compiled", "fixed", "diff", "max used"]
        print(table([*header, "adaptive", "diff", "max used"], rows))
        print(f"\nwithin max(0.01, 2 se) and no overrun at {met} of {len(rows)} budgets\n")


#: Trials per cell for the timing (the shipped profiles use 300-2000).
TIMING_TRIALS = {"estimate-demand": 40, "cluster-stops": 8, "plan-tours": 3, "insert-tours": 3}


def profile_times() -> None:
    print(timing_table(TIMING_TRIALS, PROBLEM_SETS))
    print()


def read_tsplib(name: str) -> np.ndarray:
    lines = (DATA / f"{name}.tsp").read_text().splitlines()
    start = [line.strip() for line in lines].index("NODE_COORD_SECTION") + 1
    coords = [line.split()[1:3] for line in lines[start:] if line.strip() not in ("", "EOF")]
    return np.array(coords, dtype=float)


def nint_length(cities: np.ndarray, order: list[int]) -> int:
    route = cities[order + order[:1]]
    return int(np.rint(np.sqrt(((route[1:] - route[:-1]) ** 2).sum(axis=1))).sum())


def tsplib() -> None:
    rows = []
    marks = (1, 25, 50, 100, 200, 400)
    for name, optimum in TSPLIB:
        cities = read_tsplib(name)
        clustering = Clustering(cities[1:], cities[:1], np.zeros(len(cities) - 1, dtype=np.int64))
        ctx = Context()
        started = time.perf_counter()
        trace = []
        for result in plan_tours(ctx, Result(clustering, 1.0)):
            order = [0, *(int(c) + 1 for c in result.value.orders[0])]
            trace.append((ctx.elapsed, nint_length(cities, order)))
        seconds = time.perf_counter() - started
        cells = [name, str(optimum)]
        for mark in marks:
            best = [length for at, length in trace if at <= mark]
            cells.append(f"{optimum / best[-1]:.3f}" if best else "-")
        final = trace[-1][1]
        cells += [f"{optimum / final:.3f} ({final}, {trace[-1][0]:g} ticks)", f"{seconds:.2f}"]
        rows.append(cells)
    print("**plan-tours on TSPLIB** (one depot, the first city; optimal / length, TSPLIB's")
    print("rounded distances):\n")
    header = ["instance", "optimum", *(f"{m} ticks" for m in marks), "converged", "seconds"]
    print(table(header, rows))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="100 problems per budget (400)")
    args = parser.parse_args()
    promises(100 if args.quick else 400)
    profile_times()
    tsplib()
    print(f"\n{machine()}")


if __name__ == "__main__":
    main()
