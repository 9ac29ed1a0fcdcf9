"""Compiler benchmarks, printed as side-by-side tables (not a test: nothing here is asserted).

1. Compile time of the papers' 2-module chain (vision conditioned on the sensor's quality ->
   planner conditioned on the map's quality, deterministic tabulated profiles) over 11 input
   qualities x 50 totals, for dp, hill-climbing and exhaustive: the median of several runs of
   `compile_program`, and of the allocator call alone, with the ratio to dp.
2. Random 8-module chains and binary trees (deterministic monotone random profiles): dp
   against hill-climbing, compile time and peak memory on two time lattices, and how much
   expected quality hill-climbing loses (dp is exact on them).
3. Optimality over random programs with n = 2..4 modules (chains and trees, a few totals on a
   small grid): the gap of hill-climbing to the exhaustive optimum, with deterministic and with
   stochastic monotone profiles, and the largest |dp - exhaustive| (deterministic only);
   then the gap by program shape, by total T, and by whether the optimum starves a module.

Every random profile and program comes from a seeded generator, so every run compiles the same
programs. The default run takes about three minutes on two cores; --quick well under one.

Run: .venv/bin/python benchmarks/bench_compiler.py [--quick] [--repeats N] [--resolutions R,R]
[--programs N] [--random-resolutions R,R] [--optimality-programs N] [--seed N]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
import tracemalloc
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
from tables import table  # benchmarks/tables.py: a script's own folder is on sys.path

from anytime.compiler import ALLOCATORS, CompiledProgram, Evaluator, build_model, compile_program
from anytime.dsl import Program, parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.profiles import (
    ConditionalPerformanceProfile,
    Exponential,
    VisionHyperbola,
    default_bins,
    new_profile,
    point_mass,
    tabulate,
)

ORDER = ("dp", "hill-climbing", "exhaustive")
Q11 = np.round(np.linspace(0, 1, 11), 12)  # the default input-quality grid


# --- helpers ------------------------------------------------------------------------------------


def timed(run: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[float, Any]:
    start = time.perf_counter()
    result = run(*args, **kwargs)
    return time.perf_counter() - start, result


def ms(seconds: float) -> str:
    return f"{seconds * 1e3:,.1f}"


def table_rows(
    program: Program, library: AnytimeLibrary, time_grid: np.ndarray, q_grid: np.ndarray, dt: float
) -> tuple[Evaluator, np.ndarray, np.ndarray]:
    """The evaluator and the (input quality, total) rows `compile_program` hands its allocator
    (one quality-carrying program input)."""
    evaluator = Evaluator(build_model(program, library))
    units = np.rint(time_grid / dt).astype(np.int64)
    q_rows = np.repeat(q_grid[:, None], len(time_grid), axis=0)
    u_rows = np.tile(units, len(q_grid))
    return evaluator, q_rows, u_rows


# --- modules and random profiles ----------------------------------------------------------------


def one_input(ctx: Context, a: Result) -> Iterator[Result]:
    """A stand-in body for a random module (only its profile matters to the compiler)."""
    while not ctx.expired:
        ctx.tick(1)
        yield a


def two_inputs(ctx: Context, a: Result, b: Result) -> Iterator[Result]:
    while not ctx.expired:
        ctx.tick(1)
        yield Result(None, min(a.quality, b.quality))


def random_profile(
    rng: np.random.Generator, name: str, inputs: Sequence[str], horizon: float, stochastic: bool
) -> ConditionalPerformanceProfile:
    """A random profile, non-decreasing in time and in every input quality.

    The quality curve saturates at a random fraction of `horizon`, with diminishing returns of
    random strength and random bumps (so it need not be concave), scaled by a random increasing
    function of each input quality and perturbed cell by cell, then made monotone along every
    axis by running maxima. Deterministic: a point mass per cell at that quality (kept exactly
    as the cell mean). Stochastic: a discretised normal around it over 10 bins (its mean moves
    with the quality, so better inputs and more time give stochastically better outputs).
    """
    time_grid = np.round(np.linspace(0, horizon * rng.uniform(0.3, 1.0), 11), 9)
    steps = rng.exponential(size=10) * rng.uniform(0.5, 1.0) ** np.arange(10)
    curve = np.concatenate([[0.0], np.cumsum(steps)])
    curve *= rng.uniform(0.6, 1.0) / curve[-1]
    grids = [np.linspace(0, 1, 6)] * len(inputs)
    mesh = np.meshgrid(*grids, curve, indexing="ij")
    quality = mesh[-1]
    for q in mesh[:-1]:
        floor = rng.uniform(0.0, 0.5)
        quality = quality * (floor + (1 - floor) * q ** rng.uniform(0.5, 2.0))
    quality = quality * rng.uniform(0.85, 1.0, size=quality.shape)
    for axis in range(quality.ndim):
        quality = np.maximum.accumulate(quality, axis=axis)
    quality = np.clip(quality, 0.0, 1.0)
    bins = default_bins(10)
    if stochastic:
        values = (bins[:-1] + bins[1:]) / 2
        sigma = rng.uniform(0.05, 0.15)
        weights = np.exp(-((values - quality[..., None]) ** 2) / (2 * sigma**2))
        probability, mean = weights / weights.sum(axis=-1, keepdims=True), None
    else:
        probability, mean = point_mass(quality, bins), quality
    return new_profile(
        input_grids=grids,
        time=time_grid,
        bins=bins,
        probability=probability,
        mean=mean,
        inputs=tuple(inputs),
        module=name,
    )


def random_parents(rng: np.random.Generator, n: int, shape: str) -> list[int]:
    """parent[i] > i for every module but the root (n - 1): a chain, or a tree in which every
    module has at most two children and some module has two."""
    if shape == "chain":
        return [*range(1, n), -1]
    while True:
        parents, children = [-1] * n, [0] * n
        for i in range(n - 2, -1, -1):
            free = [j for j in range(i + 1, n) if children[j] < 2]
            parents[i] = int(rng.choice(free))
            children[parents[i]] += 1
        if 2 in children:
            return parents


def random_program(
    rng: np.random.Generator, n: int, shape: str, horizon: float, stochastic: bool
) -> tuple[Program, AnytimeLibrary]:
    """A random program of `n` anytime modules and its library. Leaves read the program's one
    quality-carrying input `x`; every other module reads the results of its children."""
    parents = random_parents(rng, n, shape)
    registry = Registry()
    steps = []
    for i in range(n):
        kids = [f"r{j}" for j in range(n) if parents[j] == i]
        args = kids or ["x"]
        names = ("a", "b")[: len(args)]
        profile = random_profile(rng, f"m{i}", names, horizon, stochastic)
        body = one_input if len(args) == 1 else two_inputs
        interruptible(f"m{i}", inputs=list(names), profile=profile, registry=registry)(body)
        steps.append(f"  (setf r{i} (m{i} {' '.join(args)}))")
    text = f"(defschema random (x)\n{chr(10).join(steps)}\n  r{n - 1})\n"
    library = AnytimeLibrary.default(registry=registry, plugins=False)
    return parse_schemas(text, known_functions=library.known_functions())["random"], library


# --- 1. the 2-module chain ----------------------------------------------------------------------


def navigation() -> tuple[Program, AnytimeLibrary]:
    """The papers' program, with vision conditioned on the sensor's quality, so that the
    compiled table has one input-quality axis (the sensor) besides time."""
    registry = Registry()
    t = np.arange(0, 401, 20)
    vision = tabulate(
        lambda t, s: s * VisionHyperbola(t_a=40, q_a=0.6, t_b=200)(t),
        t,
        input_grids=[Q11],
        inputs=["sensor"],
        module="get-domain-description",
        kind="contract",
    )
    planner = tabulate(
        lambda t, q: q**2 * Exponential(rate=0.012)(t),
        t,
        input_grids=[Q11],
        inputs=["domain"],
        module="find-path",
    )

    @contract("get-domain-description", inputs=["sensor"], profile=vision, registry=registry)
    def get_domain_description(ctx: Context, sensor: Result) -> Result:
        return sensor

    @interruptible("find-path", inputs=["domain"], profile=planner, registry=registry)
    def find_path(ctx: Context, start: Any, goal: Any, domain: Result) -> Iterator[Result]:
        yield domain

    text = """
    (defschema navigate (start goal sensor)
      (setf domain (get-domain-description sensor))
      (setf plan (find-path start goal domain))
      plan)
    """
    library = AnytimeLibrary.default(registry=registry, plugins=False)
    return parse_schemas(text, known_functions=library.known_functions())["navigate"], library


def bench_chain(points: int, step: float, resolutions: Sequence[float], repeats: int) -> str:
    program, library = navigation()
    time_grid = step * np.arange(1, points + 1)
    rows = []
    for dt in resolutions:
        compile_s: dict[str, list[float]] = {name: [] for name in ORDER}
        alone_s: dict[str, list[float]] = {name: [] for name in ORDER}
        expected: dict[str, np.ndarray] = {}
        evaluator, q_rows, u_rows = table_rows(program, library, time_grid, Q11, dt)
        for _ in range(repeats):  # round robin, so a busy moment does not favour one side
            for name in ORDER:
                seconds, compiled = timed(
                    compile_program, program, library, time_grid, Q11, allocator=name, resolution=dt
                )
                compile_s[name].append(seconds)
                expected[name] = compiled.expected
                seconds, _ = timed(ALLOCATORS[name]().allocate, evaluator, q_rows, u_rows, dt)
                alone_s[name].append(seconds)
        median = {name: statistics.median(compile_s[name]) for name in ORDER}
        alone = {name: statistics.median(alone_s[name]) for name in ORDER}
        for name in ORDER:
            gap = np.max(np.abs(expected[name] - expected["exhaustive"]))
            rows.append(
                [
                    f"{name}, resolution {dt:g} ({int(time_grid[-1] / dt)} units)",
                    ms(median[name]),
                    f"{median[name] / median['dp']:.2f}x",
                    ms(alone[name]),
                    f"{alone[name] / alone['dp']:.2f}x",
                    f"{gap:.1e}",
                ]
            )
    header = [
        f"2-module chain, table {len(Q11)} x {points}",
        "compile ms",
        "vs dp",
        "allocator ms",
        "vs dp",
        "max abs(E - exhaustive)",
    ]
    note = (
        f"(median of {repeats} round-robin runs; time grid {time_grid[0]:g}..{time_grid[-1]:g}"
        f" step {step:g} ticks; 'compile' is compile_program: allocator, evaluation, baselines"
        " and, for n <= 4, the exhaustive reference behind the reported gap; 'allocator' is"
        " the allocator's call alone on the same rows)"
    )
    return table(header, rows) + "\n" + note


# --- 2. random 8-module chains and trees --------------------------------------------------------


def peak_mib(run: Callable[..., Any], *args: Any, **kwargs: Any) -> float:
    """The peak of memory allocated (numpy arrays included) while `run` runs, in MiB."""
    tracemalloc.start()
    try:
        run(*args, **kwargs)
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def bench_random(
    n: int,
    programs: int,
    repeats: int,
    points: int,
    step: float,
    resolutions: Sequence[float],
    seed: int,
) -> str:
    time_grid = step * np.arange(1, points + 1)
    horizon = 2 * time_grid[-1] / n
    rows = []
    for shape in ("chain", "tree"):
        cases = []
        for k in range(programs):
            rng = np.random.default_rng([seed, 2, k, shape == "tree"])
            cases.append(random_program(rng, n, shape, horizon, stochastic=False))
        for dt in resolutions:
            seconds: dict[str, list[float]] = {"dp": [], "hill-climbing": []}
            peak = {name: 0.0 for name in seconds}
            loss, relative = [], []
            for program, library in cases:
                tables: dict[str, np.ndarray] = {}
                for _ in range(repeats):  # round robin, as above
                    for name in seconds:
                        spent, compiled = timed(
                            compile_program,
                            program,
                            library,
                            time_grid,
                            Q11,
                            allocator=name,
                            resolution=dt,
                        )
                        seconds[name].append(spent)
                        tables[name] = compiled.expected
                gap = (tables["dp"] - tables["hill-climbing"]).ravel()
                optimum = tables["dp"].ravel()
                loss.append(gap)
                relative.append(100 * gap[optimum > 1e-9] / optimum[optimum > 1e-9])
            for name in peak:  # once more, traced: the first program's peak memory
                program, library = cases[0]
                peak[name] = peak_mib(
                    compile_program,
                    program,
                    library,
                    time_grid,
                    Q11,
                    allocator=name,
                    resolution=dt,
                )
            gaps, rel = np.concatenate(loss), np.concatenate(relative)
            dp, hc = (statistics.median(seconds[name]) for name in ("dp", "hill-climbing"))
            rows.append(
                [
                    f"{n}-module {shape}s, {int(time_grid[-1] / dt)} units",
                    ms(dp),
                    ms(hc),
                    f"{hc / dp:.2f}x",
                    f"{peak['dp']:,.0f}",
                    f"{peak['hill-climbing']:,.0f}",
                    f"{gaps.mean():.2e}",
                    f"{gaps.max():.2e}",
                    f"{rel.mean():.3f}%",
                    f"{rel.max():.1f}%",
                    f"{100 * np.mean(gaps <= 1e-9):.1f}%",
                    f"{gaps.min():.0e}",
                ]
            )
    header = [
        f"random programs, table {len(Q11)} x {points}",
        "dp ms",
        "hill ms",
        "hill/dp",
        "dp MiB",
        "hill MiB",
        "mean loss",
        "worst loss",
        "mean rel",
        "worst rel",
        "hill = dp",
        "min loss",
    ]
    note = (
        f"(median compile_program time over {programs} programs x {repeats} runs per row;"
        f" totals {time_grid[0]:g}..{time_grid[-1]:g} ticks on a lattice of"
        f" {', '.join(f'{time_grid[-1] / dt:g}' for dt in resolutions)} units; MiB: peak"
        " traced memory of one compile of the first program; loss = E[dp] - E[hill-climbing]"
        " per cell, dp being exact here; 'rel': the loss over the optimum, cells with"
        " optimum > 0; trees are binary, their leaves read the one program input)"
    )
    return table(header, rows) + "\n" + note


# --- 3. optimality against the exhaustive search ------------------------------------------------


def gap_cells(gap: np.ndarray, optimum: np.ndarray) -> list[str]:
    """Mean and worst gap, absolute and relative (cells with optimum > 0), and the share of
    cells where hill-climbing found the optimum."""
    positive = optimum > 1e-9
    rel = 100 * gap[positive] / optimum[positive]
    return [
        f"{gap.mean():.2e}",
        f"{gap.max():.2e}",
        f"{rel.mean():.3f}%",
        f"{rel.max():.2f}%",
        f"{100 * np.mean(gap <= 1e-9):.1f}%",
    ]


def bench_optimality(programs: int, units: Sequence[int], q_grid: np.ndarray, seed: int) -> str:
    time_grid = np.asarray(units, dtype=np.float64)  # resolution 1: a total of T units
    cases = []
    for k in range(programs):
        n = 2 + k % 3
        shape = "chain" if n == 2 or k % 2 == 0 else "tree"
        cases.append((k, n, shape))
    summary, breakdown = [], []
    where: dict[str, list[str]] = {}
    for kind in ("deterministic", "stochastic"):
        stochastic = kind == "stochastic"
        # Per cell: the gap, the optimum, the program's group, T's index, whether the
        # exhaustive optimum gives some module no time at all.
        gaps, optima, groups, totals, starved = [], [], [], [], []
        dp_error, reported, above = 0.0, 0.0, 0
        for k, n, shape in cases:
            # Same seed for both kinds: the same programs, with point-mass or spread profiles.
            rng = np.random.default_rng([seed, 3, k])
            horizon = 2 * time_grid[-1] / n
            program, library = random_program(rng, n, shape, horizon, stochastic)
            compiled: dict[str, CompiledProgram] = {}
            names = ("hill-climbing", "exhaustive") + (() if stochastic else ("dp",))
            for name in names:
                compiled[name] = compile_program(
                    program, library, time_grid, q_grid, allocator=name, resolution=1
                )
            optimum = compiled["exhaustive"].expected
            gap = optimum - compiled["hill-climbing"].expected
            gaps.append(gap.ravel())
            optima.append(optimum.ravel())
            groups.append(np.full(gap.size, f"{n}-module {shape}s"))
            totals.append(np.broadcast_to(np.arange(len(time_grid)), gap.shape).ravel())
            starved.append((compiled["exhaustive"].allocation == 0).any(axis=-1).ravel())
            above += int(np.sum(gap < -1e-12))
            hc_gap = compiled["hill-climbing"].exhaustive_gap
            reported = max(reported, abs((hc_gap or 0.0) - max(gap.max(), 0.0)))
            if not stochastic:
                dp = compiled["dp"].expected
                dp_error = max(dp_error, float(np.max(np.abs(dp - optimum))))
        gap, optimum = np.concatenate(gaps), np.concatenate(optima)
        group, total, corner = (
            np.concatenate(groups),
            np.concatenate(totals),
            np.concatenate(starved),
        )
        summary.append(
            [
                kind,
                str(len(cases)),
                str(gap.size),
                *gap_cells(gap, optimum),
                str(above),
                "n/a (not exact)" if stochastic else f"{dp_error:.1e}",
                f"{reported:.0e}",
            ]
        )
        for name in sorted(set(group), key=lambda g: (g[0], g)):
            mask = group == name
            programs_in = sum(1 for _, n, shape in cases if f"{n}-module {shape}s" == name)
            breakdown.append(
                [f"{kind}, {name}", str(programs_in), *gap_cells(gap[mask], optimum[mask])]
            )
        positive = optimum > 1e-9
        rel = np.where(positive, 100 * gap / np.where(positive, optimum, 1.0), 0.0)
        slices = [(f"T = {t} units", total == i) for i, t in enumerate(units)]
        slices += [
            ("the optimum gives some module no time", corner),
            ("the optimum gives every module time", ~corner),
        ]
        for label, mask in slices:
            share = 100 * np.mean(mask)
            where.setdefault(label, [label]).append(
                f"{rel[mask & positive].mean():.3f}% ({share:.0f}% of cells)"
            )
    header = [
        "optimality (n = 2..4)",
        "programs",
        "cells",
        "mean gap",
        "worst gap",
        "mean rel",
        "worst rel",
        "hill optimal",
        "hill > exh.",
        "worst abs(dp - exh.)",
        "report check",
    ]
    note = (
        f"(gap = E[exhaustive] - E[hill-climbing] per cell; totals T = {', '.join(map(str, units))}"
        f" units, input qualities {', '.join(f'{q:g}' for q in q_grid)}; 'rel' over cells with"
        " optimum > 0; 'hill > exh.' counts cells where hill-climbing beat the exhaustive"
        " optimum by more than 1e-12; 'report check' is the largest difference between the"
        " compiler's own exhaustive_gap and the worst gap measured here)"
    )
    header_2 = [
        "by shape",
        "programs",
        "mean gap",
        "worst gap",
        "mean rel",
        "worst rel",
        "hill optimal",
    ]
    header_3 = ["where hill-climbing loses: mean rel gap", "deterministic", "stochastic"]
    return "\n\n".join(
        [
            table(header, summary) + "\n" + note,
            table(header_2, breakdown),
            table(header_3, list(where.values())),
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help="few runs and programs (under a minute)"
    )
    parser.add_argument("--repeats", type=int, help="runs per timing (default 7; quick: 2)")
    parser.add_argument("--points", type=int, default=50, help="totals in the time grids")
    parser.add_argument("--step", type=float, default=10, help="step of the time grids, ticks")
    parser.add_argument(
        "--resolutions", default="10,1", help="lattice units of the 2-module table (ticks)"
    )
    parser.add_argument("--modules", type=int, default=8, help="modules of the random programs")
    parser.add_argument("--programs", type=int, help="random programs per shape (default 5)")
    parser.add_argument("--random-resolutions", default="10,5", help="their lattice units (ticks)")
    parser.add_argument(
        "--optimality-programs", type=int, help="programs, n = 2..4 (default 200; quick: 30)"
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    repeats = args.repeats or (2 if args.quick else 7)
    programs = args.programs or (2 if args.quick else 5)
    optimality = args.optimality_programs or (30 if args.quick else 200)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(
        f"Python {platform.python_version()}, numpy {np.__version__},"
        f" {cpus} CPU(s) available, {platform.machine()}; seed {args.seed}"
    )
    resolutions = [float(r) for r in args.resolutions.split(",")]
    sections: list[Callable[[], str]] = [
        lambda: bench_chain(args.points, args.step, resolutions, repeats),
        lambda: bench_random(
            args.modules,
            programs,
            min(repeats, 3),
            args.points,
            args.step,
            [float(r) for r in args.random_resolutions.split(",")],
            args.seed,
        ),
        lambda: bench_optimality(
            optimality, (6, 12, 18, 24), np.array([0.25, 0.5, 0.75, 1.0]), args.seed
        ),
    ]
    for section in sections:
        seconds, text = timed(section)
        print()
        print(text)
        print(f"(this section: {seconds:.0f} s)")


if __name__ == "__main__":
    main()
