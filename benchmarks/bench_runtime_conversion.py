"""Acceleration ratios of contract algorithms made interruptible, measured against theory.

Schedules: round-robin with the optimal b = (m+1)^(1/m) on m = 1..4 workers (m = 1 is the
geometric schedule with r = 2), geometric with r = 1.5 and r = 3 on one worker (both 4.5: r = 2
is the optimum), and randomised with b = e and b = 2 on one worker. Columns, side by side:

- theory: b^(m+1)/(b^m - 1), which is (m+1)^((m+1)/m)/m for the optimal round-robin; for a
  randomised schedule its expected ratio b / ln b.
- schedule, long: from the schedule alone (t0 = 1, horizon 2^20): the exact sup of
  needed(t)/t; for a randomised one the mean of needed(t)/t at a fixed t over 10^5 draws of U.
- work clock, long: running `make_interruptible(toy)` on a `WorkClock` (one worker; the toy
  contract ticks exactly its allocation), the same quantity from the observed (length,
  completion) pairs; for a randomised one the mean over 2,000 runs.
- schedule, window: what the schedule itself gives on the short wall-clock runs' window
  (t0 = 20 ms, 2.5 s): a finite schedule approaches the limit from below, so the wall clock
  is compared with this.
- wall clock: running it on the wall clock with m worker processes (m = 1: in the caller's
  process), the toy contract busy-waiting through its allocation; the sup over the observed
  pairs (median of the runs). For a randomised schedule, the mean of needed(t)/t over t
  log-uniform on whole periods of b from 4 t0 on: for one draw of U that is the expectation
  over U (log_b(L/t) of the first length L >= t is uniform whatever U is).
- start-up: how late the first contract completes (the process pool starting);
  less start-up: the wall-clock ratio with that delay taken off every completion;
  hand-off: the median extra delay of a worker's contract over its previous one (the result's
  trip back to the caller and the next contract's trip out).

Run: .venv/bin/python benchmarks/bench_runtime_conversion.py [--quick] [--seed N]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tables import table  # benchmarks/tables.py: a script's own folder is on sys.path

from anytime.clocks import Clock, WallClock, WorkClock
from anytime.modules import AnytimeModule, Context, Registry, Result, contract
from anytime.runtime.conversion import make_interruptible
from anytime.runtime.schedules import (
    Contracts,
    Schedule,
    geometric,
    randomised,
    round_robin,
    worst_ratio,
)

Array = NDArray[np.float64]
TOYS = Registry()
HORIZON = 2.0**20  # the long runs, in units of t0
T0 = 0.02  # the wall-clock runs' first contract, seconds


@contract("toy", registry=TOYS)
def toy(ctx: Context, problem: Any) -> Result:
    """A contract that spends its allocation: one tick on the work clock, a busy wait on the
    wall clock. Its value is the allocation it got."""
    ctx.tick(ctx.allocation)
    if ctx.clock.unit == "seconds":
        while not ctx.expired:
            pass
    return Result(ctx.allocation, 1.0 - math.exp(-ctx.allocation))


class Run:
    """One run of the interruptible module to its end: the lengths of the contracts it
    completed and when, next to the schedule's plan for the same draw of U."""

    def __init__(self, module: AnytimeModule, schedule: Schedule, clock: Clock, total: float):
        ctx = Context(allocation=total, clock=clock)
        pairs = [(result.value, ctx.elapsed) for result in module(ctx, None)]
        self.length, self.finish = (np.array(x, dtype=np.float64) for x in zip(*pairs, strict=True))
        u = math.log(self.length[0] / schedule.unit, schedule.base) if schedule.randomised else 0.0
        plan = schedule.contracts(total, u)
        done = plan.finish <= total
        self.plan = Contracts(
            length=plan.length[done], finish=plan.finish[done], worker=plan.worker[done]
        )
        self.k = np.abs(plan.length[None, :] - self.length[:, None]).argmin(axis=1)
        self.late = self.finish - plan.finish[self.k]

    def contracts(self, shift: float = 0.0) -> Contracts:
        return Contracts(
            length=self.length, finish=self.finish - shift, worker=np.zeros(len(self.length), int)
        )

    def hand_off(self, m: int) -> list[float]:
        """Extra delay of each contract over the same worker's previous one."""
        late = dict(zip(self.k.tolist(), self.late.tolist(), strict=True))
        return [late[k] - late[k - m] for k in late if k - m in late]


def ratio(schedule: Schedule, contracts: Contracts, t_min: float) -> float:
    """The sup of needed(t)/t for a deterministic schedule; for a randomised one its mean over
    t log-uniform on whole periods of b from t_min to the longest length / the worst case."""
    if not schedule.randomised:
        return float(worst_ratio(contracts.length, contracts.finish))
    top = float(contracts.length[-1])
    periods = math.floor(math.log(top / t_min, schedule.base))
    t = t_min * schedule.base ** (np.arange(periods * 200) / 200)
    return float(contracts.ratio(t).mean())


def measure(schedule: Schedule, args: argparse.Namespace, rng: np.random.Generator) -> list[str]:
    m = schedule.workers
    long, short = with_unit(schedule, 1.0), with_unit(schedule, T0)
    cells = [str(m), f"{schedule.base:.4f}", f"{schedule.theory_ratio:.4f}"]
    work = make_interruptible(toy, schedule=long, seed=rng)
    if schedule.randomised:
        t = HORIZON / schedule.worst_case_ratio / 2
        cells.append(f"{long.contracts(HORIZON, rng.random(100_000)).ratio(t).mean():.4f}")
        assert m == 1
        runs = [Run(work, long, WorkClock(), HORIZON) for _ in range(args.work_runs)]
        cells.append(f"{statistics.fmean(float(r.contracts().ratio(t)) for r in runs):.4f}")
    else:
        cells.append(f"{float(long.contracts(HORIZON).worst_ratio(HORIZON)):.4f}")
        if m == 1:  # a work clock cannot see other processes' ticks
            run = Run(work, long, WorkClock(), HORIZON)
            cells.append(f"{ratio(long, run.contracts(), 1):.4f}")
        else:
            cells.append("-")
    wall = make_interruptible(toy, schedule=short, seed=rng)
    runs = [Run(wall, short, WallClock(), args.total) for _ in range(args.wall_runs)]
    t_min = 4 * T0
    hand_off = [d for r in runs for d in r.hand_off(m)]
    cells += [
        f"{statistics.median(ratio(short, r.plan, t_min) for r in runs):.4f}",
        f"{statistics.median(ratio(short, r.contracts(), t_min) for r in runs):.4f}",
        f"{statistics.median(float(r.late[0]) for r in runs) * 1e3:.1f} ms",
        f"{statistics.median(ratio(short, r.contracts(r.late[0]), t_min) for r in runs):.4f}",
        f"{statistics.median(hand_off) * 1e3:.2f} ms" if hand_off else "-",
    ]
    return cells


def with_unit(schedule: Schedule, t0: float) -> Schedule:
    return Schedule(
        unit=t0,
        base=schedule.base,
        workers=schedule.workers,
        randomised=schedule.randomised,
        name=schedule.name,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer and shorter runs")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    args.total = 1.0 if args.quick else 2.5
    args.wall_runs = 1 if args.quick else 5
    args.work_runs = 200 if args.quick else 2000
    rng = np.random.default_rng(args.seed)
    print(
        f"# Contract -> interruptible: acceleration ratios (Python {platform.python_version()},"
        f" {os.cpu_count()} cores; wall clock: t0 = {T0 * 1e3:g} ms, {args.total:g} s per run,"
        f" median of {args.wall_runs})\n"
    )
    schedules = [
        *((f"round-robin m={m}", round_robin(m)) for m in (1, 2, 3, 4)),
        ("geometric r=1.5", geometric(1.0, 1.5)),
        ("geometric r=3", geometric(1.0, 3.0)),
        ("randomised b=e (expected)", randomised(math.e)),
        ("randomised b=2 (expected)", randomised(2.0)),
    ]
    start = time.perf_counter()
    rows = [[label, *measure(schedule, args, rng)] for label, schedule in schedules]
    header = [
        "schedule",
        "m",
        "b",
        "theory",
        "schedule, long",
        "work clock, long",
        "schedule, window",
        "wall clock",
        "start-up",
        "less start-up",
        "hand-off",
    ]
    print(table(header, rows))
    print(f"\n({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
