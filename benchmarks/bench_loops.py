"""map over K items: the run-time split of a loop's time against the best split by exhaustive
search over the K calls.

A loop's quality is the mean of its calls'; at run time its time is split among the calls from
the per-call profile at each item's own quality (equal shares for identical concave curves,
the marginal-value rule for concave ones, dynamic programming over the calls otherwise:
`anytime.compiler.loops`). For calls conditioned on item quality
q (the call's curve is q * f(t)), with f of several shapes (concave, S-shaped, steps), K = 1..4
items at seeded random qualities and several budgets (lattice units), the table gives the mean
expected quality under the run-time split, under the best split of the lattice (every
composition of the budget into K parts) and under an equal split, and the gap. Then seeded
random situations: the mean and the worst gap, how often it is within 0.5% (the target: always),
the same for the marginal-value rule used everywhere (why it is not used on non-concave
curves), and the time of one run-time split against one exhaustive search.

Run: .venv/bin/python benchmarks/bench_loops.py [--random N] [--seed N]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from tables import table  # benchmarks/tables.py: a script's own folder is on sys.path

from anytime.compiler.allocators import compositions
from anytime.compiler.loops import (
    call_curves,
    concave,
    identical_concave,
    marginal_units,
    run_time_split,
)
from anytime.compiler.model import ModuleNode
from anytime.profiles import Exponential, VisionHyperbola, tabulate

HORIZON = 40
LATTICE = np.arange(HORIZON + 1, dtype=np.float64)
BUDGETS = (4, 10, 20, 40, 100)


def steps(points: list[tuple[float, float]]) -> Callable[[np.ndarray], np.ndarray]:
    """Discrete variants: quality q_k from time t_k on (Romanenko's concretization tasks)."""

    def f(t: np.ndarray) -> np.ndarray:
        out = np.zeros(np.shape(t))
        for start, quality in points:
            out = np.where(np.asarray(t) >= start, quality, out)
        return out

    return f


SHAPES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "concave: exp(0.1)": Exponential(0.1),
    "S-shaped: hyperbola after 8": VisionHyperbola(t_a=8, q_a=0.3, t_b=20),
    "steps: 0.3@4, 0.6@9, 1@18": steps([(4, 0.3), (9, 0.6), (18, 1.0)]),
}


def call_of(shape: Callable[[np.ndarray], np.ndarray]) -> ModuleNode:
    """A module whose curve is q * shape(t), q the quality of its item."""
    profile = tabulate(
        lambda t, q: np.asarray(q) * shape(t), LATTICE, input_grids=[[0.0, 1.0]], inputs=["item"]
    )
    return ModuleNode(0, "call", (), profile, True, 0)


def rule(curves: np.ndarray) -> str:
    """Which rule the run-time split uses for these curves (1, K, U+1)."""
    if identical_concave(curves)[0]:
        return "equal"
    return "marginal" if concave(curves)[0] else "dp"


def compare(call: ModuleNode, qualities: np.ndarray, total: int) -> tuple[float, float, float, str]:
    """Mean expected quality: run-time split, exhaustive optimum, equal split; the rule."""
    k = len(qualities)
    shares = run_time_split(call, qualities, float(total), 1.0)
    split = float(call.profile.expected(qualities, call.run_time(shares)).mean())
    curves = call_curves(call, qualities[None], total, 1.0)[0]
    best = float(curves[np.arange(k), compositions(total, k)].mean(axis=1).max())
    equal = float(call.profile.expected(qualities, np.full(k, total / k)).mean())
    return split, best, equal, rule(curves[None])


def gap(split: float, best: float) -> float:
    return (best - split) / best if best > 0 else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--random", type=int, default=40, help="random situations (40)")
    parser.add_argument("--seed", type=int, default=15)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)

    rows = []
    for name, shape in SHAPES.items():
        call = call_of(shape)
        for k in range(1, 5):
            qualities = np.round(rng.uniform(0.3, 1.0, size=(k, 1)), 2)
            for i, total in enumerate(BUDGETS):
                split, best, equal, used = compare(call, qualities, total)
                rows.append(
                    [
                        name if k == 1 and i == 0 else "",
                        str(k) if i == 0 else "",
                        f"{total}",
                        f"{split:.4f}",
                        f"{best:.4f}",
                        f"{equal:.4f}",
                        f"{gap(split, best):.2%}",
                        used,
                    ]
                )
    print("Mean expected quality of K calls (items at random qualities), per budget:\n")
    header = [
        "per-call curve",
        "K",
        "T (units)",
        "run-time split",
        "exhaustive",
        "equal",
        "gap",
        "rule",
    ]
    print(table(header, rows))

    gaps, greedy_gaps, split_time, search_time = [], [], 0.0, 0.0
    makers = list(SHAPES.values())
    for _ in range(args.random):
        shape: Callable[[np.ndarray], np.ndarray]
        if rng.random() < 0.5:
            shape = makers[int(rng.integers(len(makers)))]
        else:  # random variants
            times = np.sort(rng.choice(np.arange(1, HORIZON), size=3, replace=False))
            levels = np.sort(rng.uniform(0.1, 1.0, size=3))
            shape = steps(list(zip(times.tolist(), levels.tolist(), strict=True)))
        call = call_of(shape)
        k = int(rng.integers(1, 5))
        qualities = rng.uniform(0.2, 1.0, size=(k, 1))
        for total in BUDGETS:
            start = time.perf_counter()
            shares = run_time_split(call, qualities, float(total), 1.0)
            split_time += time.perf_counter() - start
            split = float(call.profile.expected(qualities, call.run_time(shares)).mean())
            start = time.perf_counter()
            curves = call_curves(call, qualities[None], total, 1.0)[0]
            best = float(curves[np.arange(k), compositions(total, k)].mean(axis=1).max())
            search_time += time.perf_counter() - start
            gaps.append(gap(split, best))
            greedy = marginal_units(curves[None])[0, total]
            greedy_gaps.append(gap(float(curves[np.arange(k), greedy].mean()), best))
    g, greedy_g = np.array(gaps), np.array(greedy_gaps)
    n = len(g)
    print(f"\n{args.random} random situations x {len(BUDGETS)} budgets (seed {args.seed}):\n")
    print(
        table(
            [
                "split",
                "cases",
                "mean gap",
                "worst gap",
                "within 0.5%",
                "split (ms)",
                "exhaustive (ms)",
                "ratio",
            ],
            [
                [
                    "run-time rule",
                    str(n),
                    f"{g.mean():.3%}",
                    f"{g.max():.3%}",
                    f"{np.mean(g <= 0.005):.0%}",
                    f"{1e3 * split_time / n:.2f}",
                    f"{1e3 * search_time / n:.2f}",
                    f"{search_time / split_time:.1f}x",
                ],
                [
                    "marginal-value rule alone",
                    str(n),
                    f"{greedy_g.mean():.3%}",
                    f"{greedy_g.max():.3%}",
                    f"{np.mean(greedy_g <= 0.005):.0%}",
                    "",
                    "",
                    "",
                ],
            ],
        )
    )


if __name__ == "__main__":
    main()
