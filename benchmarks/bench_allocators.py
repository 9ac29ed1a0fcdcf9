"""The allocators side by side on random programs of every shape, printed as tables (not a
test: nothing here is asserted).

Programs: chains and binary trees, DAGs with 1-3 shared results (a result read once more by a
later module), with and without a best-of or an if, deterministic and stochastic monotone
profiles (benchmarks/bench_compiler.py's `random_profile`), 2-12 modules, lattices of 50 and
100 units. Every program comes from a seeded generator.

1. Optimality (n <= 5, where the exhaustive search is computable): the gap of multi-start and
   of hill-climbing to the exhaustive optimum, relative to it, per cell (input quality, total);
   dp's where it is exact; the allocators' own times on the same rows and multi-start's speed-up
   over exhaustive (targets: mean gap <= 0.1%, worst <= 1%, >= 100x faster at 4-5 modules).
   The exhaustive reference is let evaluate up to 20 million allocations a program, so that 5
   modules at 100 units are measured too (on a third as many programs: about 8 s each).
2. Scale: DAGs of 6-12 modules with 3 shared results, the default input-quality grid and 50
   totals, compiled whole (`compile_program`) with multi-start and hill-climbing: time, peak
   traced memory and what multi-start gains over hill-climbing (target: 12 modules at 100
   units in <= 10 s and <= 1 GB).

Run: .venv/bin/python benchmarks/bench_allocators.py [--quick] [--programs N] [--seed N]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator
from functools import partial

import numpy as np
from bench_compiler import (
    one_input,
    peak_mib,
    random_parents,
    random_profile,
    timed,
    two_inputs,
)
from tables import machine, table

from anytime.compiler import ALLOCATORS, Evaluator, compile_program, dp_obstacle
from anytime.compiler.allocators import Exhaustive
from anytime.dsl import Program, parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, elementary, interruptible


def three_inputs(ctx: Context, a: Result, b: Result, c: Result) -> Iterator[Result]:
    while not ctx.expired:
        ctx.tick(1)
        yield Result(None, min(a.quality, b.quality, c.quality))


BODIES = {1: one_input, 2: two_inputs, 3: three_inputs}


def _condition(x: Result) -> bool:
    return True


def random_general(
    rng: np.random.Generator,
    n: int,
    shape: str,
    shared: int,
    choice: str,
    horizon: float,
    stochastic: bool,
) -> tuple[Program, AnytimeLibrary]:
    """A random program of `n` nodes that get time (modules, or an if of two): a chain or a
    binary tree (`shape`), `shared` of whose results are read once more by a later module (a
    DAG), with `choice` "best-of" (a module reads the best of two of its inputs), "if" (a leaf is
    an if of two modules) or "none". Leaves read the program's one input `x`."""
    parents = random_parents(rng, n, shape if n >= 3 else "chain")  # a tree needs 3 modules
    reads: list[list[str]] = [[f"r{j}" for j in range(n) if parents[j] == i] for i in range(n)]
    for _ in range(shared):
        options = [
            (i, j)
            for i in range(n - 1)
            for j in range(i + 1, n)
            if j != parents[i] and f"r{i}" not in reads[j] and len(reads[j]) < 2
        ]
        if not options:  # every later module reads two results already
            break
        i, j = options[int(rng.integers(len(options)))]
        reads[j].append(f"r{i}")
    registry = Registry()
    steps = []
    best_of = choice == "best-of" and any(len(r) >= 2 for r in reads)
    leaves = [i for i in range(n) if not reads[i]]
    branch = int(rng.choice(leaves)) if choice == "if" else -1
    for i in range(n):
        args = reads[i] or ["x"]
        if best_of and len(args) >= 2:
            steps.append(f"  (setf b{i} (best-of {args[0]} {args[1]}))")
            args = [f"b{i}", *args[2:]]
            best_of = False
        names = ("a", "b", "c")[: len(args)]
        for name in (f"m{i}", f"m{i}e") if i == branch else (f"m{i}",):
            profile = random_profile(rng, name, names, horizon, stochastic)
            body = BODIES[len(args)]
            interruptible(name, inputs=list(names), profile=profile, registry=registry)(body)
        call = f"(m{i} {' '.join(args)})"
        if i == branch:
            call = f"(if (ok? x) {call} (m{i}e {' '.join(args)}) :p 0.4)"
        steps.append(f"  (setf r{i} {call})")
    elementary("ok?", registry=registry)(_condition)
    text = f"(defschema random (x)\n{chr(10).join(steps)}\n  r{n - 1})\n"
    library = AnytimeLibrary.default(registry=registry, plugins=False)
    return parse_schemas(text, known_functions=library.known_functions())["random"], library


# --- 1. optimality against the exhaustive search --------------------------------------------

REFERENCE = 20_000_000  # allocations the exhaustive reference may evaluate for one program
SHAPES = (("chain", 0), ("tree", 0), ("tree", 1), ("tree", 2), ("tree", 3))
CHOICES = ("none", "best-of", "if")


def shape_name(shape: str, shared: int) -> str:
    return f"DAG, {shared} shared" if shared else shape


def rows_of(
    program: Program, library: AnytimeLibrary, units: int, totals: int, quality: np.ndarray
) -> tuple[Evaluator, np.ndarray, np.ndarray]:
    """The evaluator (its ifs' branches compiled on the lattice) and the rows (input quality,
    total in units) of a table of `totals` totals up to `units`."""
    grid = np.unique(np.rint(np.linspace(0, units, totals + 1)[1:]))
    model = compile_program(program, library, grid, quality, allocator="proportional").model
    q_rows = np.repeat(quality[:, None], len(grid), axis=0)
    u_rows = np.tile(grid.astype(np.int64), len(quality))
    return Evaluator(model), q_rows, u_rows


def relative_gap(optimum: np.ndarray, value: np.ndarray) -> np.ndarray:
    """100 (optimum - value) / optimum, over cells with optimum > 0."""
    positive = optimum > 1e-9
    gap: np.ndarray = 100 * (optimum[positive] - value[positive]) / optimum[positive]
    return gap


def bench_optimality(programs: int, seed: int) -> str:
    """Each case: n, units, stochastic; the programs cycle through shapes and choices."""
    # 5 modules at 100 units is past the exhaustive search's default limit (about 15 million
    # allocations a program here): its reference is raised for it, on a third of the programs.
    cases = [(n, 50, False, programs) for n in (2, 3, 4, 5)]
    cases += [(n, 100, False, programs) for n in (2, 3, 4)] + [(5, 100, False, programs // 3)]
    cases += [(n, 50, True, programs) for n in (2, 3)]
    quality = np.array([0.5, 1.0])
    rows = []
    everything: list[np.ndarray] = []
    for n, units, stochastic, count in cases:
        gaps: dict[str, list[np.ndarray]] = {"multi-start": [], "hill-climbing": [], "dp": []}
        seconds = {name: 0.0 for name in ("multi-start", "hill-climbing", "exhaustive")}
        shapes_seen = set()
        for k in range(count):
            shape, shared = SHAPES[k % len(SHAPES)]
            choice = CHOICES[(k // len(SHAPES)) % len(CHOICES)]
            rng = np.random.default_rng([seed, 1, n, units, stochastic, k])
            program, library = random_general(
                rng, n, shape, min(shared, n - 1), choice, 2.0 * units / n, stochastic
            )
            totals = 2 if stochastic else 5
            evaluator, q_rows, u_rows = rows_of(program, library, units, totals, quality)
            shapes_seen.add(evaluator.model.graph.shape)
            values = {}
            for name in seconds:
                search = ALLOCATORS[name]() if name != "exhaustive" else Exhaustive(limit=REFERENCE)
                spent, (_, value) = timed(search.allocate, evaluator, q_rows, u_rows, 1.0)
                seconds[name] += spent
                values[name] = value
            optimum = values["exhaustive"]
            for name in ("multi-start", "hill-climbing"):
                gaps[name].append(relative_gap(optimum, values[name]))
            if dp_obstacle(evaluator.model) is None:
                _, dp = ALLOCATORS["dp"]().allocate(evaluator, q_rows, u_rows, 1.0)
                gaps["dp"].append(relative_gap(optimum, dp))
        ms, hc = (np.concatenate(gaps[name]) for name in ("multi-start", "hill-climbing"))
        everything.append(ms)
        dp = np.concatenate(gaps["dp"]) if gaps["dp"] else None
        rows.append(
            [
                f"{n} modules, {units} units, {'stochastic' if stochastic else 'deterministic'}",
                str(count),
                str(ms.size),
                f"{ms.mean():.4f}%",
                f"{ms.max():.3f}%",
                f"{hc.mean():.3f}%",
                f"{hc.max():.2f}%",
                "n/a" if dp is None else f"{np.abs(dp).max():.1e}% ({len(gaps['dp'])})",
                f"{seconds['multi-start']:.2f}",
                f"{seconds['hill-climbing']:.2f}",
                f"{seconds['exhaustive']:.2f}",
                f"{seconds['exhaustive'] / seconds['multi-start']:.1f}x",
            ]
        )
    whole = np.concatenate(everything)
    header = [
        "programs of every shape",
        "programs",
        "cells",
        "multi-start mean gap",
        "worst",
        "hill mean gap",
        "worst",
        "dp worst (programs)",
        "multi-start s",
        "hill s",
        "exhaustive s",
        "exh. / multi-start",
    ]
    note = (
        f"(gap = 100 (E[exhaustive] - E[allocator]) / E[exhaustive] per cell with E > 0; each"
        f" row's programs cycle through chains, trees and DAGs with 1-3 shared results, each"
        f" without a choice, with a best-of and with an if; totals: 5 evenly up to the lattice"
        f" (2 for stochastic profiles), input qualities 0.5 and 1; dp only where it is exact;"
        f" times: the allocators' own calls on the same rows, summed over the programs. Over"
        f" all {whole.size} cells: multi-start mean gap {whole.mean():.4f}%, worst"
        f" {whole.max():.3f}%)"
    )
    return table(header, rows) + "\n" + note


# --- 2. scale: 6 to 12 modules ----------------------------------------------------------------


def bench_scale(sizes: list[int], programs: int, seed: int) -> str:
    q11 = np.round(np.linspace(0, 1, 11), 12)
    grid = 10.0 * np.arange(1, 51)
    rows = []
    for n in sizes:
        for choice in ("none", "best-of"):
            for resolution in (10.0, 5.0):
                seconds = {"multi-start": 0.0, "hill-climbing": 0.0}
                peak = {name: 0.0 for name in seconds}
                gains = []
                for k in range(programs):
                    rng = np.random.default_rng([seed, 2, n, k, choice == "best-of"])
                    program, library = random_general(
                        rng, n, "tree", 3, choice, 2 * grid[-1] / n, False
                    )
                    tables = {}
                    for name in seconds:
                        run = partial(compile_program, program, library, grid, q11, allocator=name)
                        spent, compiled = timed(run, resolution=resolution)
                        seconds[name] = max(seconds[name], spent)
                        tables[name] = compiled.expected
                        if k == 0:  # once more, traced: the first program's peak memory
                            peak[name] = peak_mib(run, resolution=resolution)
                    gains.append(relative_gap(tables["multi-start"], tables["hill-climbing"]))
                gain = np.concatenate(gains)
                rows.append(
                    [
                        f"{n} modules, 3 shared, {choice}, {grid[-1] / resolution:g} units",
                        f"{seconds['multi-start']:.2f}",
                        f"{seconds['hill-climbing']:.2f}",
                        f"{peak['multi-start']:,.0f}",
                        f"{peak['hill-climbing']:,.0f}",
                        f"{gain.mean():.3f}%",
                        f"{gain.max():.2f}%",
                        f"{np.mean(gain > 1e-9):.1%}",
                        f"{np.mean(gain < -1e-9):.1%}",
                    ]
                )
    header = [
        f"DAGs, table {len(q11)} x {len(grid)}",
        "multi-start s",
        "hill s",
        "multi-start MiB",
        "hill MiB",
        "gain over hill, mean",
        "largest",
        "cells above hill",
        "below",
    ]
    note = (
        f"(compile_program, slowest of {programs} programs per row; MiB: peak traced memory of"
        " one compile of the first program; gain = 100 (E[multi-start] - E[hill-climbing]) /"
        " E[multi-start] per cell; deterministic profiles; exhaustive is not computable here)"
    )
    return table(header, rows) + "\n" + note


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer programs (a few minutes)")
    parser.add_argument("--programs", type=int, help="programs per row (default 30; quick 15)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    programs = args.programs or (15 if args.quick else 30)
    print(machine())
    sections: list[Callable[[], str]] = [
        lambda: bench_optimality(programs, args.seed),
        lambda: bench_scale([6, 9, 12], 1 if args.quick else 3, args.seed),
    ]
    for section in sections:
        seconds, text = timed(section)
        print()
        print(text)
        print(f"(this section: {seconds:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
