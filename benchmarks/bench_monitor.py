"""The monitor against fixed contracts and the MIN/MAX policies over seeded worlds.

    .venv/bin/python benchmarks/bench_monitor.py [--worlds 30] [--size 128] [--quick]

Per policy: mean utility, mean prediction error |U - predicted| / |predicted| and mean utility
ratio U / clairvoyant bound (definitions in `anytime_navigation.task`).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from anytime_navigation.frame_program import navigation_program
from anytime_navigation.frames import run_task
from anytime_navigation.task import NavigationTask
from anytime_navigation.world import random_world

from anytime.runtime.monitor import DeadlineValue


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=30)
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--radius", type=int, help="sensor radius (default: a quarter of the side)")
    parser.add_argument("--quick", action="store_true", help="64x64 worlds")
    args = parser.parse_args()
    size = 64 if args.quick else args.size
    radius = args.radius or size // 4
    compiled, trace = navigation_program(warn=print)
    # Every contract of the grid up to 1000 ticks (where the best fixed policies are), then a
    # few longer ones.
    grid = [float(t) for t in compiled.profile.time if t > 0]
    fixed = [t for t in grid if t <= 1000] + [t for t in grid if t > 1000][1::3]
    policies = [("monitored", None), ("min", None), ("max", None)] + [("fixed", t) for t in fixed]
    rows: dict[str, list[tuple[float, float, float]]] = {}
    started = time.perf_counter()
    for seed in range(args.worlds):
        world = random_world(size, seed=seed)
        value = DeadlineValue(1000.0, 6000.0 * size / 128, 0.25 * 128 / size)
        task = NavigationTask(world, radius=radius, value=value, seed=seed)
        for policy, contract in policies:
            r = run_task(task, compiled, trace, policy=policy, contract=contract)
            rows.setdefault(r.policy, []).append((r.utility, r.prediction_error, r.utility_ratio))
    print(
        f"{args.worlds} worlds {size}x{size}, radius {radius}, "
        f"{time.perf_counter() - started:.0f} s"
    )
    print(f"{'policy':<12}{'utility':>10}{'pred. error':>13}{'utility ratio':>15}")
    for name, values in rows.items():
        u, e, q = np.mean(np.array(values), axis=0)
        print(f"{name:<12}{u:>10.1f}{100 * e:>12.1f}%{q:>15.3f}")


if __name__ == "__main__":
    main()
