"""The monitor against fixed contracts, the MIN/MAX policies and the stopping policy over
seeded worlds.

    .venv/bin/python benchmarks/bench_monitor.py [--worlds 30] [--sizes 64,128] [--quick]

Per world size (the benchmark's worlds are seeds 0 to worlds - 1; the monitor's calibration,
`anytime_navigation.task.calibration`, was measured on seeds from 1000): per policy, mean
utility, mean prediction error |U - predicted| / |predicted|, mean utility ratio U /
clairvoyant bound (defined in `anytime_navigation.task.model`), and the monitored policy's
utility less the policy's, world by world, with the standard error of that mean difference
(positive: the monitor did better). Then, for the monitored
policy, the worlds it predicts worst: what the robot walked and spent there, and the monitor's
prediction of the whole task's utility frame by frame (`FrameRecord.predicted_utility`), which
shows when it found out. For the `stopping` policy (the monitor's contract as an upper bound,
the planner stopped within it by optimal stopping over its dynamic profile; it needs
`find-path.dynamic.yaml`), how often it stopped a planner before the contract and the planning
time that saved. The prediction made when the task is presented is one number for
every world (the robot has sensed nothing yet, and the worlds here share their start, goal
and size), so the mean error of the best single number in hindsight bounds what any such
prediction can reach; it is printed too.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from anytime_navigation.task.calibration import shipped, task_value
from anytime_navigation.task.frame_program import navigation_program
from anytime_navigation.task.frames import run_task
from anytime_navigation.task.model import NavigationTask, TaskReport
from anytime_navigation.world import random_world


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=30)
    parser.add_argument("--sizes", default="128", help="world sides, comma-separated")
    parser.add_argument("--radius", type=int, help="sensor radius (default: a quarter of the side)")
    parser.add_argument("--quick", action="store_true", help="64x64 worlds only")
    parser.add_argument("--worst", type=int, default=5, help="worlds listed by prediction error")
    args = parser.parse_args()
    sizes = [64] if args.quick else [int(s) for s in args.sizes.split(",")]
    compiled, trace = navigation_program(warn=print)
    for i, size in enumerate(sizes):
        if i:
            print()
        bench(compiled, trace, size, args.radius or size // 4, args.worlds, args.worst)


def bench(compiled: Any, trace: Any, size: int, radius: int, worlds: int, worst: int) -> None:
    """One world size: every policy on the same worlds."""
    # Every contract of the grid up to 1000 ticks (where the best fixed policies are), then a
    # few longer ones.
    grid = [float(t) for t in compiled.profile.time if t > 0]
    fixed = [t for t in grid if t <= 1000] + [t for t in grid if t > 1000][1::3]
    stopping = [("stopping", None)] if trace.dynamic else []
    if not stopping:
        print("no dynamic profile of find-path: the stopping policy is left out")
    policies = [("monitored", None), *stopping, ("min", None), ("max", None)]
    policies += [("fixed", t) for t in fixed]
    rows: dict[str, list[tuple[float, float, float]]] = {}
    monitored: list[TaskReport] = []
    stopped: list[TaskReport] = []
    started = time.perf_counter()
    for seed in range(worlds):
        world = random_world(size, seed=seed)
        task = NavigationTask(world, radius=radius, value=task_value(size), seed=seed)
        for policy, contract in policies:
            r = run_task(task, compiled, trace, policy=policy, contract=contract)
            rows.setdefault(r.policy, []).append((r.utility, r.prediction_error, r.utility_ratio))
            if policy == "monitored":
                monitored.append(r)
            if policy == "stopping":
                stopped.append(r)
    calibrated = "calibrated" if shipped(size, radius) else "not calibrated"
    print(
        f"{worlds} worlds {size}x{size}, radius {radius} ({calibrated}), "
        f"{time.perf_counter() - started:.0f} s"
    )
    print(
        f"{'policy':<12}{'utility':>10}{'pred. error':>13}{'utility ratio':>15}"
        f"{'monitored - it':>16}{'se':>6}"
    )
    mine = np.array([u for u, _, _ in rows["monitored"]])
    for name, values in rows.items():
        u, e, q = np.mean(np.array(values), axis=0)
        gain = mine - np.array([v[0] for v in values])
        se = gain.std(ddof=1) / np.sqrt(gain.size) if gain.size > 1 else 0.0
        paired = "" if name == "monitored" else f"{gain.mean():>16.1f}{se:>6.1f}"
        print(f"{name:<12}{u:>10.1f}{100 * e:>12.1f}%{q:>15.3f}{paired}")
    if stopped:
        print_stops(stopped)
    print_worst(monitored, worst)


def print_stops(reports: list[TaskReport]) -> None:
    """How often the stopping policy stopped a planner before its contract, and by how much."""
    frames = [f for r in reports for f in r.records]
    early = [f.contract - f.stopped_at for f in frames if f.stopped_at is not None]
    saved = f", {np.mean(early):.0f} ticks before the contract on average" if early else ""
    print(
        f"\nstopping: {len(early)} of {len(frames)} frames' planners stopped before the"
        f" contract{saved}"
    )


def best_single_prediction(utilities: np.ndarray) -> tuple[float, float]:
    """The one prediction for all worlds of least mean |U - p| / |p|, and that mean error (the
    optimum is one of the utilities: between two of them the mean error is monotone in p)."""
    p = utilities[np.abs(utilities) > 0]
    errors = np.mean(np.abs(utilities[None, :] - p[:, None]) / np.abs(p[:, None]), axis=1)
    i = int(np.argmin(errors))
    return float(p[i]), float(errors[i])


def print_worst(reports: list[TaskReport], n: int) -> None:
    """The monitored policy's `n` worst-predicted worlds, and what bounds its error."""
    worst = sorted(reports, key=lambda r: r.prediction_error, reverse=True)[:n]
    print(f"\nmonitored, the {len(worst)} worlds predicted worst:")
    print(
        f"{'seed':>4}{'predicted':>11}{'utility':>9}{'error':>8}{'route':>7}{'energy':>8}"
        f"{'completion':>12}  prediction frame by frame"
    )
    for r in worst:
        shown = [f"{f.predicted_utility:.0f}" for f in r.records]
        if len(shown) > 10:  # a long run: its start and its end
            shown = [*shown[:7], "...", *shown[-2:]]
        frames = " ".join(shown)
        print(
            f"{r.seed:>4}{r.predicted_utility:>11.1f}{r.utility:>9.1f}"
            f"{100 * r.prediction_error:>7.1f}%{r.route_length:>7.0f}{r.energy:>8.1f}"
            f"{r.completion_time:>12.0f}  {frames}"
        )
    utilities = np.array([r.utility for r in reports])
    best, error = best_single_prediction(utilities)
    running = np.mean(
        [
            np.mean(
                [abs(r.utility - f.predicted_utility) / abs(f.predicted_utility) for f in r.records]
            )
            for r in reports
        ]
    )
    lengths = sorted({r.optimal_length for r in reports})
    shortest = (
        f"{lengths[0]:.0f} cells in every world"
        if len(lengths) == 1
        else f"{lengths[0]:.0f} to {lengths[-1]:.0f} cells"
    )
    print(
        f"(shortest routes: {shortest}; the best single prediction for all worlds, in"
        f" hindsight: {best:.1f}, mean error {100 * error:.1f}%;\n the predictions of every"
        f" frame, averaged over each world's frames: mean error {100 * running:.1f}%)"
    )


if __name__ == "__main__":
    main()
