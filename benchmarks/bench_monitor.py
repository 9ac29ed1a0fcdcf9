"""The monitor against fixed contracts, the MIN/MAX policies and the stopping policy over
seeded worlds.

    .venv/bin/python benchmarks/bench_monitor.py [--worlds 400] [--sizes 64,128] [--quick]
        [--workers 2]

Per world size, every policy on the same worlds (seeds 0 to worlds - 1; the monitor's
calibration, `anytime_navigation.task.calibration`, was measured on seeds from 1000, so these
are held out): the monitored policy, the stopping policy, MIN and MAX (the compiled program's
shortest and longest contract), and a fixed contract at every contract the monitor chooses
among (its calibration's grid, 100 to 1000 ticks) and at a few longer ones of the compiled
program's grid. Per policy: mean utility, mean prediction error |U - predicted| / |predicted|,
mean utility ratio U / clairvoyant bound (defined in `anytime_navigation.task.model`), and the
monitored policy's utility less the policy's, world by world, with the standard error of that
mean difference (positive: the monitor did better; paired on the same worlds, the worlds'
own spread cancels). Then whether the monitored policy is above every fixed contract and MIN,
and its prediction: the mean predicted and realised utility (the prediction's bias, with its
standard error; the prediction is the median of the monitor's model at its first decision,
not the mean, so a bias is expected where a few worlds wander, `anytime_navigation.task.model`),
the mean error, and the mean error of the best single number in hindsight:
the prediction made when the task is presented is one number for every world (the robot has
sensed nothing yet, and the worlds share their start, goal and size), so that error bounds
what any prediction made then can reach on these worlds. Then the worlds the monitor predicts
worst: what the robot walked and spent there, and the monitor's prediction of the whole task's
utility frame by frame (`FrameRecord.predicted_utility`), which shows when it found out. For the
`stopping` policy (the monitor's contract as an upper bound, the planner stopped within it by
optimal stopping over its dynamic profile; it needs `find-path.dynamic.yaml`), how often it
stopped a planner before the contract and the planning time that saved. Utilities are on the
work clock: the same on any machine and with any number of `--workers`.
"""

from __future__ import annotations

import argparse
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
from anytime_navigation.task.calibration import CONTRACTS, FIRST_SEED, shipped, task_value
from anytime_navigation.task.frame_program import navigation_program
from anytime_navigation.task.frames import run_task
from anytime_navigation.task.model import NavigationTask, TaskReport
from anytime_navigation.world import random_world


@dataclass(frozen=True)
class Outcome:
    """What the benchmark keeps of one run (light enough to come back from a worker)."""

    seed: int
    policy: str
    utility: float
    predicted: float
    error: float
    ratio: float
    route: float
    optimal: float
    energy: float
    completion: float
    frames: tuple[float, ...]  # the whole task's utility predicted at each frame
    stops: tuple[tuple[float, float | None], ...]  # (contract, stopped at) per frame

    @classmethod
    def of(cls, r: TaskReport) -> Outcome:
        return cls(
            r.seed,
            r.policy,
            r.utility,
            r.predicted_utility,
            r.prediction_error,
            r.utility_ratio,
            r.route_length,
            r.optimal_length,
            r.energy,
            r.completion_time,
            tuple(f.predicted_utility for f in r.records),
            tuple((f.contract, f.stopped_at) for f in r.records),
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=400)
    parser.add_argument("--sizes", default="128", help="world sides, comma-separated")
    parser.add_argument("--radius", type=int, help="sensor radius (default: a quarter of the side)")
    parser.add_argument("--quick", action="store_true", help="64x64 worlds only")
    parser.add_argument("--worst", type=int, default=5, help="worlds listed by prediction error")
    parser.add_argument(
        "--workers",
        type=int,
        default=min(2, os.cpu_count() or 1),
        help="processes running the worlds (default: 2, or 1 on one core)",
    )
    args = parser.parse_args()
    sizes = [64] if args.quick else [int(s) for s in args.sizes.split(",")]
    if args.worlds > FIRST_SEED:  # the calibration's training worlds are seeds from FIRST_SEED
        parser.error(f"--worlds at most {FIRST_SEED}: the worlds must be held out")
    for i, size in enumerate(sizes):
        if i:
            print()
        bench(size, args.radius or size // 4, args.worlds, args.worst, args.workers)


def policies_of(compiled: Any, trace: Any) -> list[tuple[str, float | None]]:
    """The monitored policy, the stopping policy (with the planner's dynamic profile), MIN,
    MAX, and a fixed contract at every contract the monitor chooses among (the calibration's
    grid) and at a few longer ones of the compiled program's grid (where the best fixed
    contracts are not: they are late)."""
    grid = [float(t) for t in compiled.profile.time if t > 0]
    fixed = sorted({*CONTRACTS, *[t for t in grid if t <= 1000]})
    fixed += [t for t in grid if t > 1000][1::3]
    stopping: list[tuple[str, float | None]] = [("stopping", None)] if trace.dynamic else []
    policies: list[tuple[str, float | None]] = [("monitored", None), *stopping]
    policies += [("min", None), ("max", None)]
    return policies + [("fixed", t) for t in fixed]


_PROGRAM: Any = None


def world(size: int, radius: int, seed: int) -> list[Outcome]:
    """Every policy on the world of `seed`."""
    global _PROGRAM
    if _PROGRAM is None:
        _PROGRAM = navigation_program()
    compiled, trace = _PROGRAM
    task = NavigationTask(
        random_world(size, seed=seed), radius=radius, value=task_value(size), seed=seed
    )
    return [
        Outcome.of(run_task(task, compiled, trace, policy=policy, contract=contract))
        for policy, contract in policies_of(compiled, trace)
    ]


def bench(size: int, radius: int, worlds: int, worst: int, workers: int) -> None:
    """One world size: every policy on the same worlds."""
    compiled, trace = navigation_program(warn=print)
    if not trace.dynamic:
        print("no dynamic profile of find-path: the stopping policy is left out")
    started = time.perf_counter()
    run = partial(world, size, radius)
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            outcomes = [o for w in pool.map(run, range(worlds)) for o in w]
    else:
        outcomes = [o for seed in range(worlds) for o in run(seed)]
    rows: dict[str, list[Outcome]] = {}
    for o in outcomes:
        rows.setdefault(o.policy, []).append(o)
    calibrated = "calibrated" if shipped(size, radius) else "not calibrated"
    print(
        f"{worlds} worlds {size}x{size} (seeds 0-{worlds - 1}), radius {radius} ({calibrated}),"
        f" {time.perf_counter() - started:.0f} s"
    )
    print(
        f"{'policy':<12}{'utility':>10}{'pred. error':>13}{'utility ratio':>15}"
        f"{'monitored - it':>16}{'se':>6}"
    )
    mine = np.array([o.utility for o in rows["monitored"]])
    below = []
    for name, values in rows.items():
        u = np.array([o.utility for o in values])
        e = np.mean([o.error for o in values])
        q = np.mean([o.ratio for o in values])
        gain = mine - u
        se = gain.std(ddof=1) / np.sqrt(gain.size) if gain.size > 1 else 0.0
        paired = "" if name == "monitored" else f"{gain.mean():>16.1f}{se:>6.1f}"
        print(f"{name:<12}{u.mean():>10.1f}{100 * e:>12.1f}%{q:>15.3f}{paired}")
        if name == "min" or name.startswith("fixed:"):
            below.append((gain.mean(), se, name))
    print_verdict(below)
    print_prediction(rows["monitored"])
    if "stopping" in rows:
        print_stops(rows["stopping"])
    print_worst(rows["monitored"], worst)


def print_verdict(gains: list[tuple[float, float, str]]) -> None:
    """Whether the monitored policy is above every fixed contract and MIN, and by how little."""
    least, se, name = min(gains)
    beaten = sum(g > 0 for g, _, _ in gains)
    clear = sum(g > s for g, s, _ in gains)
    print(
        f"\nmonitored above {beaten} of {len(gains)} fixed contracts and MIN"
        f" ({clear} by more than a standard error); the closest: {name},"
        f" monitored - it {least:.1f} +- {se:.1f}"
    )


def print_prediction(reports: list[Outcome]) -> None:
    """The prediction made when the task is presented against what was realised."""
    u = np.array([r.utility for r in reports])
    p = np.array([r.predicted for r in reports])
    bias = u - p
    se = bias.std(ddof=1) / np.sqrt(bias.size) if bias.size > 1 else 0.0
    best, floor = best_single_prediction(u)
    error = np.mean([r.error for r in reports])
    print(
        f"monitored's prediction when the task is presented: {p.mean():.1f} (realised"
        f" {u.mean():.1f}: bias {bias.mean():+.1f} +- {se:.1f}); mean error {100 * error:.1f}%,"
        f"\n the best single number for these worlds in hindsight {best:.1f}: mean error"
        f" {100 * floor:.1f}%"
    )


def print_stops(reports: list[Outcome]) -> None:
    """How often the stopping policy stopped a planner before its contract, and by how much."""
    frames = [f for r in reports for f in r.stops]
    early = [c - t for c, t in frames if t is not None]
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


def print_worst(reports: list[Outcome], n: int) -> None:
    """The monitored policy's `n` worst-predicted worlds, and the later frames' predictions."""
    worst = sorted(reports, key=lambda r: r.error, reverse=True)[:n]
    print(f"\nmonitored, the {len(worst)} worlds predicted worst:")
    print(
        f"{'seed':>4}{'predicted':>11}{'utility':>9}{'error':>8}{'route':>7}{'energy':>8}"
        f"{'completion':>12}  prediction frame by frame"
    )
    for r in worst:
        shown = [f"{p:.0f}" for p in r.frames]
        if len(shown) > 10:  # a long run: its start and its end
            shown = [*shown[:7], "...", *shown[-2:]]
        frames = " ".join(shown)
        print(
            f"{r.seed:>4}{r.predicted:>11.1f}{r.utility:>9.1f}"
            f"{100 * r.error:>7.1f}%{r.route:>7.0f}{r.energy:>8.1f}"
            f"{r.completion:>12.0f}  {frames}"
        )
    running = np.mean([np.mean([abs(r.utility - p) / abs(p) for p in r.frames]) for r in reports])
    lengths = sorted({r.optimal for r in reports})
    shortest = (
        f"{lengths[0]:.0f} cells in every world"
        if len(lengths) == 1
        else f"{lengths[0]:.0f} to {lengths[-1]:.0f} cells"
    )
    print(
        f"(shortest routes: {shortest}; the predictions of every frame, averaged over each"
        f" world's frames: mean error {100 * running:.1f}%)"
    )
    print_residuals(reports)


def print_residuals(reports: list[Outcome], first: int = 8) -> None:
    """The monitor's prediction by the frame it was made at: its bias, the mean of realised
    less predicted over predicted, with its standard error (a model that is calibrated is
    unbiased at every frame, not only on average), and its mean error |realised - predicted|
    / |predicted| (the prediction updated as the frames come: frame 0's is the one made when
    the task is presented), for the first frames."""
    cells, errors = [], []
    for i in range(first):
        r = np.array(
            [(o.utility - o.frames[i]) / abs(o.frames[i]) for o in reports if len(o.frames) > i]
        )
        if r.size < 2:
            break
        se = r.std(ddof=1) / np.sqrt(r.size)
        cells.append(f"{i}: {100 * r.mean():+.1f} +- {100 * se:.1f}% ({r.size})")
        errors.append(f"{i}: {100 * np.abs(r).mean():.1f}%")
    print("monitored, (realised - predicted) / predicted by the frame of the prediction:")
    print(" " + ", ".join(cells[:4]) + (",\n " + ", ".join(cells[4:]) if cells[4:] else ""))
    print("monitored, mean error of the prediction by the frame it was made at:")
    print(" " + ", ".join(errors))


if __name__ == "__main__":
    main()
