"""best-of: the compiled split against Romanenko's proportional split and an equal split.

Each situation is a `(best-of (when (always) (a)) (when (always) (b)) ...)` whose alternatives
have known profiles; for the same decision time T_d, the table gives the expected quality of
the chosen alternative (the best result: E[max]) under the split the compiler finds (auto: dp
for deterministic profiles, exhaustive search for stochastic ones), under Romanenko's
proportional split (T_i = T_d * T_i* / sum T_j*, T_i* the first time a module's expected quality
rises) and under an equal split. Then seeded random situations (2-3 alternatives drawn from
exponential, hyperbola, discrete-variant and two-outcome stochastic shapes): how often the
compiled split is at least as good, the mean and the largest gain, and the worst case.

Run: .venv/bin/python benchmarks/bench_choices.py [--random N] [--seed N]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from tables import table  # noqa: E402

from anytime.compiler import compile_program  # noqa: E402
from anytime.dsl import parse_schemas  # noqa: E402
from anytime.library import AnytimeLibrary, RegistrySource  # noqa: E402
from anytime.modules import Context, Registry, Result, contract, elementary  # noqa: E402
from anytime.profiles import (  # noqa: E402
    DiscreteVariants,
    Exponential,
    VisionHyperbola,
    new_profile,
    tabulate,
)
from anytime.profiles.profile import ConditionalPerformanceProfile  # noqa: E402

HORIZON = 40
LATTICE = np.arange(HORIZON + 1, dtype=np.float64)
BINS = np.linspace(0, 1, 11)


def curve(shape: object) -> ConditionalPerformanceProfile:
    return tabulate(shape, LATTICE, kind="contract")


def gamble(start: float, p: float, high: float) -> ConditionalPerformanceProfile:
    """After `start`: quality `high` with probability p, else 0 (a risky method)."""
    k = min(int(high * 10), 9)
    row = np.zeros(10)
    row[0], row[k] = 1 - p, p
    first = np.eye(10)[0]
    probability = np.where((LATTICE >= start)[:, None], row, first)
    return new_profile(
        input_grids=[], time=LATTICE, bins=BINS, probability=probability, kind="contract"
    )


def library(profiles: Sequence[ConditionalPerformanceProfile]) -> AnytimeLibrary:
    registry = Registry()

    @elementary("always", inputs=[], registry=registry)
    def always() -> bool:
        return True

    for i, profile in enumerate(profiles):

        def run(ctx: Context) -> Result:
            return Result(None, 0.0)

        run.__name__ = run.__qualname__ = f"alt{i}"
        contract(f"alt{i}", inputs=[], profile=profile, registry=registry)(run)
    return AnytimeLibrary([RegistrySource(registry)])


def compare(
    profiles: Sequence[ConditionalPerformanceProfile], totals: Sequence[float]
) -> dict[str, np.ndarray]:
    whens = " ".join(f"(when (always) (alt{i}))" for i in range(len(profiles)))
    program = parse_schemas(f"(defschema s () (best-of {whens}))")["s"]
    lib = library(profiles)
    out = {}
    for name in ("auto", "proportional"):
        compiled = compile_program(program, lib, totals, allocator=name, resolution=1.0)
        out[name] = compiled.expected
        if name == "auto":
            out["equal"] = compiled.baselines["equal"]
            out["chosen"] = np.array(compiled.allocator)
    return out


SITUATIONS = {
    "same shape: 2 x exp(0.1)": [curve(Exponential(0.1)), curve(Exponential(0.1))],
    "fast exp vs slow hyperbola": [
        curve(Exponential(0.3, 0.6)),
        curve(VisionHyperbola(t_a=8, q_a=0.5, t_b=30)),
    ],
    "discrete variants": [
        DiscreteVariants([(2, 0.3), (5, 0.5)]).profile(1.0, HORIZON),
        DiscreteVariants([(6, 0.4), (15, 0.9)]).profile(1.0, HORIZON),
    ],
    "steady vs risky (stochastic)": [
        curve(Exponential(0.05)),
        gamble(start=4, p=0.5, high=1.0),
    ],
    "3 alternatives, mixed": [
        curve(Exponential(0.2, 0.7)),
        DiscreteVariants([(10, 0.6), (25, 1.0)]).profile(1.0, HORIZON),
        gamble(start=3, p=0.4, high=0.9),
    ],
}


def random_profile(rng: np.random.Generator) -> ConditionalPerformanceProfile:
    kind = rng.integers(4)
    if kind == 0:
        return curve(Exponential(float(rng.uniform(0.02, 0.5)), float(rng.uniform(0.3, 1.0))))
    if kind == 1:
        t_a = float(rng.integers(0, 15))
        return curve(VisionHyperbola(t_a, float(rng.uniform(0.1, 0.7)), t_a + rng.integers(5, 25)))
    if kind == 2:
        times = np.sort(rng.choice(np.arange(1, HORIZON), size=3, replace=False))
        qualities = np.sort(rng.uniform(0.1, 1.0, size=3))
        return DiscreteVariants(list(zip(times, qualities, strict=True))).profile(1.0, HORIZON)
    return gamble(float(rng.integers(1, 15)), float(rng.uniform(0.2, 0.8)), rng.uniform(0.3, 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--random", type=int, default=60, help="random situations (60)")
    parser.add_argument("--seed", type=int, default=8)
    args = parser.parse_args()

    totals = [5.0, 10.0, 20.0, 40.0]
    rows = []
    for name, profiles in SITUATIONS.items():
        result = compare(profiles, totals)
        for i, t in enumerate(totals):
            rows.append(
                [
                    name if i == 0 else "",
                    f"{t:g}",
                    f"{result['auto'][i]:.3f}",
                    f"{result['proportional'][i]:.3f}",
                    f"{result['equal'][i]:.3f}",
                    str(result["chosen"]),
                ]
            )
    print("Expected quality of the chosen alternative, E[max], for the same T_d:\n")
    header = ["situation", "T_d", "compiled", "proportional", "equal", "allocator"]
    print(table(header, rows))

    rng = np.random.default_rng(args.seed)
    gains: dict[str, list[float]] = {"proportional": [], "equal": []}
    for _ in range(args.random):
        profiles = [random_profile(rng) for _ in range(int(rng.integers(2, 4)))]
        result = compare(profiles, totals)
        for other in gains:
            gains[other].extend(result["auto"] - result[other])
    rows = []
    for other, values in gains.items():
        g = np.array(values)
        rows.append(
            [
                f"compiled - {other}",
                f"{len(g)}",
                f"{np.mean(g >= -1e-12):.0%}",
                f"{g.mean():.3f}",
                f"{g.max():.3f}",
                f"{g.min():.2e}",
            ]
        )
    print(f"\n{args.random} random situations x {len(totals)} T_d (seed {args.seed}):\n")
    print(table(["gap", "cases", "never worse", "mean gain", "max gain", "worst"], rows))


if __name__ == "__main__":
    main()
