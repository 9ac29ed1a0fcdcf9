"""The compiled promise on every program shape, against simulated runs.

    .venv/bin/python benchmarks/bench_shapes.py [--runs 20000] [--seed 0]

Programs over one uncertain shared result, a sensed map of quality 0.15 or 0.95 (the good one
more likely the longer it senses), read by two planners: a best-of of the two plans, a
diamond whose join is product-like, and a join reading the map twice; each with deterministic
planners and with stochastic ones (half the time only half as good). At every total of the
table, `runs` simulated runs, in which each module draws its output from its own profile given
the qualities its inputs had in that run (tests/compiler/program_sampler.py, code apart from
the compiler's), against the compiled promise, and against what the same allocation was
promised when the readers' inputs were taken as independent (the evaluation before shared
results were conditioned on). Then a called schema and an `if` branch that read the map,
compiled with the input-quality grid {1} and with the default grid: their tables against the
brute-force optimum over every split (they were clamped to quality 1 and over-claimed).

Columns: z = (promised - realised) / se; within 2 in about 95% of rows when the promise is
exact (a row where every run gave the one quality promised has z = 0).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from tables import machine, table

from anytime.compiler import compile_file, compile_program, evaluate
from anytime.dsl import parse_schemas

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "compiler"))
from program_sampler import simulate  # noqa: E402
from test_shared_results import SHAPES, TOTALS, _library, brute_force  # noqa: E402

BRANCHES = """
(defschema sub (a) (plan1 a))
(defschema call (x) (setf m (sense-x x)) (sub m))
(defschema branch (x) (setf m (sense-x x)) (if (ok m) (plan1 m) (plan2 m) :p 0.25))
"""


def independent_compile(text: str, library: object) -> object:
    """The program compiled as before: a shared result's readers taken as independent (the
    evaluator told that no result is shared), for the allocation and the promise it made."""
    real = evaluate.shared_nodes
    evaluate.shared_nodes = lambda model: frozenset()  # type: ignore[assignment]
    try:
        return compile_program(parse_schemas(text)["p"], library, TOTALS)  # type: ignore[arg-type]
    finally:
        evaluate.shared_nodes = real


def shapes(runs: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    rows = []
    for stochastic in (False, True):
        library = _library(stochastic)
        for name, text in SHAPES.items():
            compiled = compile_program(parse_schemas(text)["p"], library, TOTALS)
            before = independent_compile(text, library)
            for j, total in enumerate(TOTALS):
                if total == 0 or total % 20:
                    continue
                old = simulate(before, [], total, runs, rng).mean()
                realised = simulate(compiled, [], total, runs, rng)
                mean, se = realised.mean(), realised.std(ddof=1) / np.sqrt(runs)
                gap = compiled.expected[j] - mean
                z = gap / se if se > 1e-12 else 0.0
                rows.append(
                    [
                        name,
                        "stochastic" if stochastic else "deterministic",
                        f"{total:g}",
                        f"{before.expected[j]:.3f}",  # type: ignore[attr-defined]
                        f"{old:.3f}",
                        f"{compiled.expected[j]:.4f}",
                        f"{mean:.4f} ± {se:.4f}",
                        f"{z:+.2f}",
                    ]
                )
    print(f"Shared results: promised against {runs:,} simulated runs (seed {seed})")
    print()
    print(
        table(
            [
                "program",
                "planners",
                "T",
                "before: promised",
                "realised",
                "now: promised",
                "realised ± se",
                "z",
            ],
            rows,
        )
    )


def branches() -> None:
    library = _library(stochastic_planners=False)
    schemas = parse_schemas(BRANCHES)
    rows = []
    for schema in ("call", "branch"):
        optimum = brute_force(library, schema)
        for grid in ([1.0], list(np.linspace(0, 1, 11))):
            compiled = compile_file(schemas, library, TOTALS, grid, schema=schema)[-1]
            over = compiled.expected[-1] - optimum
            rows.append(
                [
                    "a called schema" if schema == "call" else "an if branch",
                    "{1}" if len(grid) == 1 else "0, 0.1, ..., 1",
                    compiled.allocator,
                    str(compiled.exact),
                    f"{np.max(over):+.1e}",
                    f"{optimum[-1]:.4f}",
                    f"{compiled.expected[-1, -1]:.4f}",
                ]
            )
    print("Branches and callees on a computed result: the table against the brute-force optimum")
    print()
    print(
        table(
            [
                "program",
                "input grid",
                "allocator",
                "exact",
                "most above optimum",
                "optimum at 80",
                "table at 80",
            ],
            rows,
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(machine())
    print()
    shapes(args.runs, args.seed)
    print()
    branches()


if __name__ == "__main__":
    main()
