"""What process isolation costs: soft, hard and process runs side by side (not a test: nothing
here is asserted).

1. Per-run overhead: a trivial interruptible module (three results, a tick each, then it
   returns) run many times on the work clock in each mode, the modes interleaved run by run so
   that a busy moment of the machine does not favour one; the median and p99 wall time of a
   call of `run`, and their ratios to soft mode. Process isolation's extra is a fork, a pipe
   with a pickled message per result, and ending the child's process group (SIGTERM to the
   group, the child awaited and reaped); a row with a bare `Child` (fork, pipe, end; no module, no
   executor) shows how much of it is the process alone.
2. Interruption latency on the wall clock: how late `run` answers after the deadline (the
   time the call returned minus the call's start plus the allocation), median, p99 and worst,
   for a module that yields every ~1 ms (a short `time.sleep`), one that yields once and then
   blocks (sleeps on a lock for up to 10 s, the GIL released) and one that yields once and
   then spins in pure Python (holding the GIL in-process), at two allocations. Soft mode
   cannot interrupt a module that does not yield, so the blocking and spinning modules are run
   only in hard and process mode; in hard mode the abandoned thread is released and joined
   after each run, in process mode the child is ended at the deadline.
3. Answering after a failure: the time from a module's failure (it yields a first result,
   then raises, or ends its own process with `os._exit(1)` or SIGKILL) to the answer; a raise
   in all three modes, the other two in process mode only (in-process they would end the
   benchmark). The failure's time is written by the module into shared memory just before it
   fails (`time.perf_counter` is the system-wide monotonic clock on Linux).

Run: .venv/bin/python benchmarks/bench_isolation.py [--quick] [--runs N] [--overhead-runs N]
"""

from __future__ import annotations

import argparse
import math
import mmap
import os
import signal
import struct
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from tables import machine, table  # benchmarks/tables.py: a script's own folder is on sys.path

from anytime.clocks import Clock, WallClock, WorkClock
from anytime.isolation import Channel, Child, processes
from anytime.modules import AnytimeModule, Context, Registry, Result, interruptible
from anytime.runtime import Budget, Hard, Isolated, RunRecord, Soft, run

BENCH = Registry()
MODES = ("soft", "hard", "process")
ALLOCATIONS = (0.02, 0.05)
BLOCK = 10.0  # seconds a blocking or spinning module would go on for without its deadline


@interruptible("trivial", inputs=[], registry=BENCH)
def trivial(ctx: Context) -> Iterator[Result]:
    """Three results, a tick before each, then it returns."""
    for i in range(3):
        ctx.tick(1)
        yield Result(i, (i + 1) / 3)


@interruptible("yielding", inputs=[], registry=BENCH)
def yielding(ctx: Context, period: float) -> Iterator[Result]:
    """A slightly better result every `period` seconds (sleeping between them), forever."""
    i = 0
    while True:
        time.sleep(period)
        i += 1
        yield Result(i, 1 - 1 / (i + 1))


@interruptible("blocking", inputs=[], registry=BENCH)
def blocking(ctx: Context, release: threading.Event, how: str) -> Iterator[Result]:
    """Yields once, then goes on for up to BLOCK seconds without looking at its context:
    blocked on `release` ("blocks", the GIL released) or spinning on it in Python ("spins").
    In a child process nobody sets `release`: it goes on until its process is ended."""
    yield Result("first", 0.5)
    if how == "blocks":
        release.wait(BLOCK)
    else:
        end = time.perf_counter() + BLOCK
        while not release.is_set() and time.perf_counter() < end:
            pass
    yield Result("late", 1.0)


@interruptible("failing", inputs=[], registry=BENCH)
def failing(ctx: Context, when: mmap.mmap, how: str) -> Iterator[Result]:
    """Yields once, notes the time in `when` (shared with the caller) and fails: raises, exits
    its process with code 1, or kills it with SIGKILL."""
    yield Result("first", 0.5)
    struct.pack_into("d", when, 0, time.perf_counter())
    if how == "raises":
        raise RuntimeError("the module failed")
    if how == "exits":
        os._exit(1)
    os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(BLOCK)  # the signal is on its way


def call(
    mode: str,
    module: AnytimeModule,
    args: tuple[Any, ...],
    clock: Clock,
    allocation: float = float("inf"),
) -> RunRecord:
    if mode == "process":
        return run(module, args, budget=Budget(allocation, clock=clock), mode=Isolated())
    return run(
        module,
        args,
        budget=Budget(allocation, clock=clock),
        mode=Hard() if mode == "hard" else Soft(),
    )


def percentiles(values: list[float]) -> tuple[float, float, float]:
    """Median, p99 and worst."""
    array = np.array(values)
    return float(np.median(array)), float(np.percentile(array, 99)), float(array.max())


def answers(records: list[RunRecord]) -> str:
    """The statuses of the runs (with exit codes of crashed ones) and how many had a result."""
    statuses = Counter(
        str(r.status) + (f" ({r.exit_code})" if r.exit_code is not None else "") for r in records
    )
    shown = ", ".join(f"{s} x{n}" if len(statuses) > 1 else s for s, n in sorted(statuses.items()))
    with_result = sum(r.result is not None for r in records)
    return f"{shown}; {with_result}/{len(records)} with a result"


def leftovers() -> list[int]:
    """Child processes of this process, live or unreaped (after every run has answered there
    should be none)."""
    mine = os.getpid()
    return [p.pid for p in processes() if p.parent == mine]


def resident_mb() -> float:
    pages = int(Path("/proc/self/statm").read_text().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def us(seconds: float) -> str:
    return f"{seconds * 1e6:,.0f}"


def ms(seconds: float) -> str:
    return f"{seconds * 1e3:.2f}"


# --- 1. per-run overhead ----------------------------------------------------------------------


def in_blocks(
    kinds: dict[str, Callable[[], tuple[float, RunRecord | None]]], runs: int, block: int
) -> dict[str, list[tuple[float, RunRecord | None]]]:
    """`runs` measurements of each kind, taken in blocks of `block` runs of one kind, the kinds
    taking turns block by block (so that a busy moment of the machine does not favour one);
    the first run of each block is not kept: after a fork the caller's next run pays for the
    pages it writes that it shares with the child (copy-on-write), which is the fork's cost,
    not the next mode's (the row "right after a process run" shows it)."""
    taken: dict[str, list[tuple[float, RunRecord | None]]] = {name: [] for name in kinds}
    while any(len(v) < runs for v in taken.values()):
        for name, measure in kinds.items():
            measure()
            for _ in range(min(block, runs - len(taken[name]))):
                taken[name].append(measure())
    return taken


def timed(function: Callable[[], RunRecord | None]) -> tuple[float, RunRecord | None]:
    start = time.perf_counter()
    record = function()
    return time.perf_counter() - start, record


def bare_child() -> None:
    """Fork a child that sends one message and exits; read it; end the child's group."""

    def target(channel: Channel) -> None:
        channel.send(("done",))

    child = Child(target)
    while not child.receive(1.0) and not child.gone:
        pass
    child.end()


def soft_after_process() -> tuple[float, RunRecord | None]:
    """A soft run timed right after an (untimed) process run."""
    call("process", trivial, (), WorkClock())
    return timed(lambda: call("soft", trivial, (), WorkClock()))


def bench_overhead(runs: int, block: int) -> str:
    kinds: dict[str, Callable[[], tuple[float, RunRecord | None]]] = {
        mode: lambda mode=mode: timed(lambda: call(mode, trivial, (), WorkClock()))
        for mode in MODES
    }
    kinds["bare Child"] = lambda: timed(bare_child)
    kinds["soft after process"] = soft_after_process
    taken = in_blocks(kinds, runs, block)
    labels = {
        "soft": "soft (caller's thread)",
        "hard": "hard (worker thread)",
        "process": "process (mode=Isolated())",
        "bare Child": "the process alone: a bare Child (fork, pipe, end)",
        "soft after process": "soft, right after a process run",
    }
    soft50, soft99, _ = percentiles([t for t, _ in taken["soft"]])
    rows = []
    for name, measured in taken.items():
        p50, p99, worst = percentiles([t for t, _ in measured])
        records = [r for _, r in measured if r is not None]
        rows.append(
            [
                labels[name],
                str(len(measured)),
                us(p50),
                us(p99),
                us(worst),
                f"{p50 / soft50:,.1f}x",
                f"{p99 / soft99:,.1f}x",
                answers(records) if records else "-",
            ]
        )
    header = [
        "per-run overhead (trivial module, work clock)",
        "runs",
        "median us",
        "p99 us",
        "max us",
        "median / soft",
        "p99 / soft",
        "answers",
    ]
    left = leftovers()
    note = (
        "(wall time of one call of `run` for a module that ticks and yields 3 results and"
        " returns. Process isolation adds a fork, a pipe carrying each result pickled, and"
        " ending the child's process group: SIGTERM to the group, waiting for the child to"
        " exit and reaping it; the bare-Child row is the fork, one message and the"
        " ending, without the executor. The last row is a soft run timed right after an"
        " untimed process run: the caller pays again for the pages it shares with the forked"
        " child (copy-on-write faults), so the fork costs more than its own row shows."
        f" Runs in blocks of {block} per mode, the modes taking turns, the first run of each"
        " block not kept. A fork's cost grows with the caller's memory: this process has"
        f" {resident_mb():.0f} MB resident, numpy loaded. Child processes left after the"
        f" table: {len(left)}{' ' + str(left) if left else ''})"
    )
    return table(header, rows) + "\n" + note


# --- 2. interruption latency ------------------------------------------------------------------


def overshoot(
    mode: str, module: AnytimeModule, args: tuple[Any, ...], allocation: float
) -> tuple[float, RunRecord]:
    """Wall time from calling `run` to its answer, minus the allocation (seconds)."""
    start = time.perf_counter()
    record = call(mode, module, args, WallClock(), allocation)
    return time.perf_counter() - start - allocation, record


def blocked_run(mode: str, how: str, allocation: float) -> tuple[float, RunRecord]:
    """One run of the blocking module; a hard run's abandoned thread is released and joined
    afterwards, so that it does not take the CPU from (or stay around for) the next run."""
    release = threading.Event()
    before = set(threading.enumerate())
    measured = overshoot(mode, blocking, (release, how), allocation)
    release.set()
    for worker in set(threading.enumerate()) - before:
        worker.join()
    return measured


def bench_latency(runs: int, period: float, block: int) -> str:
    cases: list[tuple[str, tuple[str, ...], Callable[[str, float], tuple[float, RunRecord]]]] = [
        (
            f"yields every {period * 1e3:g} ms",
            MODES,
            lambda mode, allocation: overshoot(mode, yielding, (period,), allocation),
        ),
        (
            f"blocks {BLOCK:g} s after a first result",
            ("hard", "process"),
            lambda mode, allocation: blocked_run(mode, "blocks", allocation),
        ),
        (
            f"spins in Python {BLOCK:g} s after a first result",
            ("hard", "process"),
            lambda mode, allocation: blocked_run(mode, "spins", allocation),
        ),
    ]
    rows = []
    for allocation in ALLOCATIONS:
        for name, modes, measure in cases:
            kinds: dict[str, Callable[[], tuple[float, RunRecord | None]]] = {
                mode: partial(measure, mode, allocation) for mode in modes
            }
            taken = in_blocks(kinds, runs, block)
            late = {mode: [t for t, _ in taken[mode]] for mode in modes}
            soft = float(np.median(late["soft"])) if "soft" in modes else None
            hard = float(np.median(late["hard"]))
            if soft is None:
                rows.append(
                    [f"{name}, soft", f"{allocation * 1e3:g}", "-", "-", "-", "-", "-"]
                    + [f"not interruptible: it would answer after its {BLOCK:g} s (not run)"]
                )
            for mode in modes:
                p50, p99, worst = percentiles(late[mode])
                rows.append(
                    [
                        f"{name}, {mode}",
                        f"{allocation * 1e3:g}",
                        ms(p50),
                        ms(p99),
                        ms(worst),
                        "-" if soft is None else f"{p50 / soft:.1f}x",
                        "-" if mode == "soft" else f"{p50 / hard:.1f}x",
                        answers([r for _, r in taken[mode] if r is not None]),
                    ]
                )
    header = [
        "interruption latency (wall clock)",
        "allocation ms",
        "median ms",
        "p99 ms",
        "max ms",
        "median / soft",
        "median / hard",
        f"answers ({runs} runs each)",
    ]
    left = leftovers()
    note = (
        "(latency = the time the call returned minus its deadline, the call's start plus the"
        " allocation; in process mode it includes ending the child's group: SIGTERM, the"
        f" child's exit, reaping it. Runs in blocks of {block} per mode, the modes taking"
        " turns, the first run of each block not kept; with fewer than 100 runs the p99 is"
        " close to the max. In soft mode the module yielding every millisecond answers at its"
        " first yield past the deadline, in the others at the deadline. The blocking module"
        " sleeps on a lock with the GIL released; the spinning one holds the GIL in-process,"
        f" which the caller must win back, every {sys.getswitchinterval() * 1e3:g} ms at most."
        f" Child processes left after the table: {len(left)}{' ' + str(left) if left else ''})"
    )
    return table(header, rows) + "\n" + note


# --- 3. answering after a failure -------------------------------------------------------------


def failed_run(mode: str, how: str) -> tuple[float, RunRecord]:
    """Seconds from the module's failure to the answer (a wall-clock allocation of 10 s, so
    that the deadline plays no part)."""
    when = mmap.mmap(-1, 8)  # anonymous and shared with a forked child
    record = call(mode, failing, (when, how), WallClock(), BLOCK)
    answered = time.perf_counter()
    failed = struct.unpack_from("d", when, 0)[0]
    when.close()
    return answered - failed, record


def bench_failures(runs: int, block: int) -> str:
    cases = [
        ("raises RuntimeError", MODES, "raises"),
        ("os._exit(1)", ("process",), "exits"),
        ("SIGKILL to itself", ("process",), "kills"),
    ]
    rows = []
    soft = math.nan
    for name, modes, how in cases:
        kinds: dict[str, Callable[[], tuple[float, RunRecord | None]]] = {
            mode: partial(failed_run, mode, how) for mode in modes
        }
        taken = in_blocks(kinds, runs, block)
        if "soft" in modes:
            soft = float(np.median([t for t, _ in taken["soft"]]))
        for mode in modes:
            p50, p99, worst = percentiles([t for t, _ in taken[mode]])
            rows.append(
                [
                    f"{name}, {mode}",
                    ms(p50),
                    ms(p99),
                    ms(worst),
                    f"{p50 / soft:,.1f}x",
                    answers([r for _, r in taken[mode] if r is not None]),
                ]
            )
    header = [
        "answer after a failure (after a first result)",
        "median ms",
        "p99 ms",
        "max ms",
        "median / soft",
        f"answers ({runs} runs each)",
    ]
    left = leftovers()
    note = (
        "(from the moment the module fails, noted by it in shared memory, to the moment the"
        " call returned; the record keeps the first result. Ending its own process is run"
        " in process mode only: in-process it would end this benchmark. For a raise the"
        " executor builds the traceback (in process mode in the child, which sends it over"
        " the pipe); a dead child is noticed through its pidfd. Child processes left after"
        f" the table: {len(left)}{' ' + str(left) if left else ''})"
    )
    return table(header, rows) + "\n" + note


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help="fewer runs (30 latency, 200 overhead)"
    )
    parser.add_argument("--runs", type=int, help="runs per latency row (default 60; quick 30)")
    parser.add_argument(
        "--overhead-runs", type=int, help="runs per overhead row (default 500; quick 200)"
    )
    parser.add_argument("--period", type=float, default=0.001, help="seconds between yields")
    parser.add_argument("--block", type=int, default=10, help="runs of a mode in a row")
    args = parser.parse_args()
    runs = args.runs or (30 if args.quick else 60)
    overhead_runs = args.overhead_runs or (200 if args.quick else 500)
    print(machine())
    print()
    print(bench_overhead(overhead_runs, 5 * args.block))
    print()
    print(bench_latency(runs, args.period, args.block))
    print()
    print(bench_failures(runs, args.block))


if __name__ == "__main__":
    main()
