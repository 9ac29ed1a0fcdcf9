"""The profile builder: measure a module's conditional performance profile empirically.

A domain says how to make problems for a module with a `ProblemSet`: `instance(rng, q)` builds
one problem whose quality-carrying inputs have the qualities `q`, and `score(instance, value)`
is the domain's quality function for an output. The builder runs the module on `trials`
instances at every point of the input-quality grid and time grid, scores each output, and
returns the measured profile: the histogram of scored qualities per cell, with its sample mean,
standard deviation and sample count, the mean quality of the trials in each bin (`bin_mean`)
and the fraction of trials that had no result (`no_result_table`; they score 0).

How time is measured (see docs/plugins.md): by default with a `WorkClock`, so a profile counts
the ticks a module reports and does not depend on how busy the machine is.

- An **interruptible** module runs once per instance, up to the largest time on the grid. At
  grid time t it is credited with the last `Result` it yielded at or before t (a result yielded
  once the clock has passed t does not count for t); before its first result it has no result,
  quality 0.
- A **contract** module runs once per instance and grid time, with `ctx.allocation = t`.
- The profile's `step` is measured too, as the maximum over all runs: for an interruptible
  module the largest gap between successive yields, counting from its start to the first and
  from the last to the end of its run (the yield past the largest grid time that ends a run
  counts; a run that returns by itself right after the `ctx.tick` that spent that time
  watches its time between ticks, and its last stretch counts as its longest tick there); for
  a contract module the most a run used past its allocation (0 if none did). It is as
  reproducible as the profile: on the work clock, the same for any workers and chunks.
- A module that raises (`SystemExit` too), or yields something that is not a `Result`, is a
  failed run, and so is an isolated run whose process dies or that the watchdog ends (see
  `build_profile`'s `mode`). It is
  scored by what `anytime.runtime.run` keeps of such a run: an interruptible run the last
  result it registered up to each grid time (after the failure, the last one before it; none
  if it failed before its first), a contract run none. Failures are counted and the first
  one's traceback is kept; they never stop the build. A contract run that uses more than its
  allocation keeps its result and is counted as an overrun.

With `traces=True` the build also keeps what the profile is tabulated from, every trial's
scored quality at every grid time and whether it had a result there, and for a module that
reports an estimate (`reports="estimate"`) the `Result.quality` of its result there
(`ProfileBuild.traces`, a `QualityTraces`): a dynamic profile is derived from them.

Reproducibility: trial i at input-quality cell c draws from `SeedSequence(seed, spawn_key=(c,
i))`, the stream `SeedSequence(seed).spawn(...)` would hand it, whichever worker runs it and in
whatever order chunks come back. The same instance (same seed) is used at every time of the
grid, so a cell's curve over time compares like with like. With the work clock the profile
(and its traces) is therefore identical for any number of workers, any chunk size and any
executor.
"""

from __future__ import annotations

import importlib
import math
import secrets
import time as _time
from collections.abc import Iterator, Mapping, Sequence
from concurrent.futures import Executor
from contextlib import contextmanager
from typing import Any, Literal

import numpy as np
from attrs import field, frozen
from numpy.typing import ArrayLike, NDArray

from anytime.errors import AnytimeError, ProfileError
from anytime.isolation import counting_interrupts
from anytime.measure.chunks import measure_chunk, measure_chunks
from anytime.measure.progress import ProgressBar
from anytime.measure.trials import CLOCKS, Chunk, ClockName, Done
from anytime.modules import AnytimeModule
from anytime.pool import WorkerDied, spread
from anytime.problems import (
    BuildError,
    Grid,
    Instance,
    Measurement,
    ProblemSet,
    register_problems,
    registered_measurements,
    registered_problems,
)
from anytime.profiles.dynamic import QualityTraces
from anytime.profiles.profile import (
    Array,
    ConditionalPerformanceProfile,
    default_bins,
    new_profile,
)
from anytime.runtime.modes import ISOLATED, Hard, Isolated, RunMode, Soft
from anytime.vocabulary import PROFILE_KINDS

__all__ = [
    "BuildError",
    "Grid",
    "Instance",
    "Measurement",
    "MissingExtraError",
    "ProblemSet",
    "ProfileBuild",
    "ProfileRequest",
    "build_profile",
    "dask_executor",
    "profile_module",
    "register_problems",
    "registered_measurements",
    "registered_problems",
]


class MissingExtraError(AnytimeError, ImportError):
    """An optional dependency is needed and not installed; the message names the extra."""


@frozen
class ProfileBuild:
    """A measured profile and how the measurement went.

    Attributes:
        profile: the measured conditional performance profile.
        trials: instances per cell (the profile's `samples`).
        runs: module runs in all (one per trial for interruptible, one per trial and time for
            contract modules).
        failures: runs that raised or yielded something other than a `Result`, or (isolated)
            whose process died or that took longer than the watchdog.
        overruns: contract runs that used more than their allocation (their results count).
        first_failure: the first failed run (in trial order) and its traceback, or None.
        reasons: why runs failed: each reason (an error's first line, or how an isolated
            trial's process died or that it hung) and how many runs it failed.
        seed: the seed the trials' random streams derive from (pass it again to reproduce).
        seconds: wall time of the whole build.
        traces: every trial's quality at every grid time, when asked for (`traces=True`), else
            None: what `DynamicProfile.from_traces` derives a dynamic profile from.
    """

    profile: ConditionalPerformanceProfile
    trials: int
    runs: int
    failures: int
    overruns: int
    first_failure: str | None
    seed: int
    seconds: float
    traces: QualityTraces | None = None
    reasons: Mapping[str, int] = field(factory=dict)

    @property
    def rate(self) -> float:
        """Trials per second."""
        total = self.trials * math.prod(self.profile.cell_shape[:-1])
        return total / self.seconds if self.seconds > 0 else math.inf

    def to_dict(self) -> dict[str, Any]:
        """The counts of the build as plain JSON values (`anytime profile --json`)."""
        return {
            "trials": int(self.trials),
            "runs": int(self.runs),
            "failures": int(self.failures),
            "overruns": int(self.overruns),
            "failure_reasons": dict(self.reasons),
            "seed": int(self.seed),
            "seconds": round(float(self.seconds), 3),
        }

    def summary(self) -> str:
        """A few lines for a terminal: what was measured, and failures if any."""
        cells = "x".join(str(n) for n in self.profile.cell_shape)
        lines = [
            f"{self.profile.module}: {self.trials} trials per cell over {cells} cells,"
            f" {self.runs} runs in {self.seconds:.1f} s ({self.rate:.1f} trials/s), seed"
            f" {self.seed}"
        ]
        if self.failures:
            head = (self.first_failure or "").splitlines()[0]
            lines.append(f"{self.failures} of {self.runs} runs failed; first: {head}")
            common = sorted(self.reasons.items(), key=lambda kv: (-kv[1], kv[0]))
            for reason, count in common[:_REASONS_SHOWN]:
                lines.append(f"  {count} x {reason}")
            if len(common) > _REASONS_SHOWN:
                lines.append(f"  and {len(common) - _REASONS_SHOWN} other reasons")
        if self.overruns:
            lines.append(f"{self.overruns} contract runs used more than their allocation")
        return "\n".join(lines)


_REASONS_SHOWN = 5  # the most common reasons for failed runs a summary lists


@frozen
class ProfileRequest:
    """The options of `anytime profile MODULE` (see `profile_module`).

    Attributes:
        trials: instances per cell of the grid.
        seed: the root seed (None: fresh entropy, reported in the build).
        workers: local worker processes (1: run in this process).
        scheduler: address of a Dask distributed scheduler to run the trials on instead.
        clock: "work" (ticks the module reports; reproducible) or "wall" (seconds).
        quiet: no progress bar even on a terminal.
        chunk_size: trials per task (default: enough tasks to keep every worker busy).
        traces: keep every trial's quality trace (`ProfileBuild.traces`).
        mode: how the trials run (see `build_profile`): `Isolated(watchdog=...)` (the
            default: each trial in a child process; a crash or hang is a failed run), `SOFT`
            or `Hard()`.
    """

    trials: int = 100
    seed: int | None = 0
    workers: int = 1
    scheduler: str | None = None
    clock: ClockName = "work"
    quiet: bool = False
    chunk_size: int | None = None
    traces: bool = False
    mode: RunMode = ISOLATED


def profile_module(
    module: AnytimeModule,
    request: ProfileRequest | None = None,
    *,
    measurement: Measurement | None = None,
) -> ProfileBuild:
    """Measure `module` with its registered problem set (or `measurement`) as `request` says."""
    request = request if request is not None else ProfileRequest()
    plan = measurement if measurement is not None else registered_problems(module.name)
    with _request_executor(request) as executor:
        return build_profile(
            module,
            plan.problems,
            time=plan.grid.time,
            input_grids=plan.grid.input_grids,
            bins=plan.grid.bins,
            trials=request.trials,
            seed=request.seed,
            executor=executor,
            workers=request.workers,
            clock=request.clock,
            progress=False if request.quiet else None,
            chunk_size=request.chunk_size,
            traces=request.traces,
            mode=request.mode,
        )


@contextmanager
def _request_executor(request: ProfileRequest) -> Iterator[Executor | None]:
    if request.scheduler is None:
        yield None
    else:
        with dask_executor(request.scheduler) as executor:
            yield executor


#: Seconds given to connecting to a Dask scheduler before it is reported unreachable.
DASK_CONNECT_SECONDS = 5.0


@contextmanager
def dask_executor(address: Any) -> Iterator[Executor]:
    """The `concurrent.futures` executor of a Dask distributed cluster, closed on exit.

    `address` is a scheduler address ("tcp://host:8786") or a cluster object. Its workers must
    be able to import the module and the problem set's class (both travel by reference).
    """
    try:
        distributed: Any = importlib.import_module("distributed")
    except ImportError as exc:
        raise MissingExtraError(
            f"running trials on a Dask scheduler needs Dask distributed ({exc}); install the"
            " extra: pip install 'anytime-compose[dask]'"
        ) from exc
    try:
        # Dask's own connect timeout (30 s) made a wrong address take 34 s to be reported.
        client = distributed.Client(address, timeout=DASK_CONNECT_SECONDS)
    except (OSError, TimeoutError, ValueError) as exc:
        raise BuildError(f"cannot connect to the Dask scheduler at {address}: {exc}") from exc
    try:
        # pure=False: every chunk is its own task, whatever Dask makes of its arguments' hash.
        yield client.get_executor(pure=False)
    finally:
        client.close()


def build_profile(
    module: AnytimeModule,
    problems: ProblemSet,
    *,
    time: ArrayLike,
    input_grids: Sequence[ArrayLike] = (),
    bins: ArrayLike | None = None,
    trials: int = 100,
    seed: int | None = 0,
    executor: Executor | None = None,
    workers: int = 1,
    clock: ClockName = "work",
    progress: bool | None = None,
    chunk_size: int | None = None,
    traces: bool = False,
    mode: RunMode = ISOLATED,
) -> ProfileBuild:
    """Measure `module`'s conditional performance profile on `problems`.

    Args:
        module: an interruptible or contract module.
        problems: makes instances and scores outputs (see `ProblemSet`).
        time: the time grid (ticks for the work clock, seconds for the wall clock).
        input_grids: one grid of qualities per quality-carrying input, in `module.inputs` order.
        bins: K+1 quality-bin edges of the histogram (default: 10 equal bins).
        trials: instances per input-quality cell.
        seed: the root seed; None draws fresh entropy (reported as `ProfileBuild.seed`).
        executor: where to run the trials (any `concurrent.futures.Executor`; left running).
        workers: without an executor, a process pool of this many workers (1: in this process).
        clock: "work" (default, reproducible) or "wall".
        progress: draw a progress bar on standard error (None: only on a terminal).
        chunk_size: trials per task; it changes the overhead, never the result.
        traces: also keep every trial's scored quality at every grid time, and for a module
            that reports an estimate its `Result.quality` there (`ProfileBuild.traces`).
        mode: how the trials run (`anytime.runtime.modes`). `Isolated(watchdog=...,
            limits=...)` (the default) runs them in child processes (`anytime.isolation`),
            one making a worker's trials in turn: a run that crashes its process, or takes
            longer than `watchdog` seconds of wall time (an interruptible module's trial, or
            one time of a contract module's), is a failed run that keeps what it had
            registered before (see above), and the build goes on; with `limits`, every run has
            a process of its own (a fork per run) and the limits are each run's. `SOFT` runs
            them in the worker itself (a little faster, and a module that crashes or hangs
            takes the build with it). `Hard(poll=...)` runs them there too, each trial's run
            hard, as `anytime.runtime.run(mode=Hard())` runs it: the profile is what hard runs
            answer with (a contract run still working at its allocation answers with none;
            an interruptible run ends at the tick that passes the largest grid time), and the
            measured step is how late a run answered, not how long the module went on.
    """
    started = _time.perf_counter()
    grid = _check(module, time, input_grids, bins, trials, seed, workers, clock, chunk_size)
    if not isinstance(mode, Soft | Hard | Isolated):
        raise BuildError(f"mode: expected Soft(), Hard() or Isolated(), got {mode!r}")
    entropy = int(seed) if seed is not None else secrets.randbits(128)  # as SeedSequence() does
    total = trials * math.prod(grid.cell_shape)
    if chunk_size is None:
        chunk_size = max(1, min(256, math.ceil(total / max(64, 8 * workers))))
    chunks = [
        Chunk(
            module,
            problems,
            grid,
            clock,
            entropy,
            trials,
            start,
            min(start + chunk_size, total),
            mode,
        )
        for start in range(0, total, chunk_size)
    ]
    quality = np.zeros((total, len(grid.time)))
    scored = np.ones(quality.shape, dtype=np.bool_)
    # The module's reports are kept only where they are traces' estimates (a "true" report is
    # the score itself, and "none" says nothing).
    estimate = np.zeros(quality.shape) if traces and module.reports == "estimate" else None
    finished = np.full(total, float(grid.time[-1]))
    failures = overruns = 0
    step = 0.0
    first: tuple[int, str] | None = None
    reasons: dict[str, int] = {}
    # Counted: a KeyboardInterrupt a trial's module raises itself is a failed trial, the
    # user's Ctrl-C stops the build (see `anytime.measure.trials.run_trial`).
    with counting_interrupts(), ProgressBar(total, label=module.name, enabled=progress) as bar:
        for done in _run(chunks, executor, workers):
            quality[done.start : done.start + len(done.quality)] = done.quality
            rows = slice(done.start, done.start + len(done.quality))
            if done.scored is not None:
                scored[rows] = done.scored
            if estimate is not None and done.reported is not None:
                estimate[rows] = done.reported
            if done.finished is not None:
                finished[rows] = done.finished
            failures += done.failures
            overruns += done.overruns
            for reason, count in done.reasons.items():
                reasons[reason] = reasons.get(reason, 0) + count
            step = max(step, done.step)
            if done.first_failure is not None and (first is None or done.first_failure < first):
                first = done.first_failure
            bar.update(len(done.quality))
    shape = (*grid.cell_shape, trials, len(grid.time))
    quality, scored = quality.reshape(shape), scored.reshape(shape)
    return ProfileBuild(
        profile=_tabulate(module, grid, quality, ~scored, clock, step),
        trials=trials,
        runs=total * (len(grid.time) if module.kind == "contract" else 1),
        failures=failures,
        overruns=overruns,
        first_failure=None if first is None else first[1],
        reasons=dict(sorted(reasons.items())),
        seed=entropy,
        seconds=_time.perf_counter() - started,
        traces=_traces(module, grid, quality, scored, estimate, finished, clock)
        if traces
        else None,
    )


def _traces(
    module: AnytimeModule,
    grid: Grid,
    quality: Array,
    scored: NDArray[np.bool_],
    estimate: Array | None,
    finished: Array,
    clock: str,
) -> QualityTraces:
    """The build's tables as traces; `estimate` (flat, one row per trial) is 0 where a run had
    no result."""
    return QualityTraces(
        module=module.name,
        time=grid.time,
        quality=quality,
        scored=scored,
        estimate=None if estimate is None else estimate.reshape(quality.shape),
        finished=finished.reshape(quality.shape[:-1]),
        reports=module.reports,
        input_grids=grid.input_grids,
        inputs=module.inputs,
        time_unit=CLOCKS[clock][1],
    )


def _check(
    module: AnytimeModule,
    time: ArrayLike,
    input_grids: Sequence[ArrayLike],
    bins: ArrayLike | None,
    trials: int,
    seed: int | None,
    workers: int,
    clock: str,
    chunk_size: int | None,
) -> Grid:
    """The build's grid, once every argument is known to be usable."""
    where = f"profile of module '{module.name}'"
    if module.kind not in PROFILE_KINDS:
        raise BuildError(
            f"{where}: only interruptible and contract modules have a profile to measure"
            f" (this one is {module.kind})"
        )
    if len(input_grids) != len(module.inputs):
        names = ", ".join(module.inputs) or "none"
        raise BuildError(
            f"{where}: expected {len(module.inputs)} input-quality grid(s) (one per"
            f" quality-carrying input: {names}), got {len(input_grids)}"
        )
    for name, value, least in (
        ("trials", trials, 1),
        ("workers", workers, 1),
        ("chunk_size", 1 if chunk_size is None else chunk_size, 1),
        ("seed", 0 if seed is None else seed, 0),
    ):
        if not isinstance(value, int | np.integer) or isinstance(value, bool) or value < least:
            raise BuildError(f"{where}: {name}: expected an integer >= {least}, got {value!r}")
    if clock not in CLOCKS:
        raise BuildError(f"{where}: clock: expected 'work' or 'wall', got {clock!r}")
    grid = Grid(time, input_grids, default_bins() if bins is None else bins)
    sizes = (*(g.size for g in grid.input_grids), grid.time.size, max(1, grid.bins.size - 1))
    try:  # a profile's own validation names the offending grid
        new_profile(
            input_grids=grid.input_grids,
            time=grid.time,
            bins=grid.bins,
            probability=np.full(sizes, 1 / sizes[-1]),
            module=where,
        )
    except ProfileError as exc:
        raise BuildError(str(exc)) from exc
    return grid


def _tabulate(
    module: AnytimeModule,
    grid: Grid,
    quality: Array,
    missing: NDArray[np.bool_],
    clock: str,
    step: float,
) -> ConditionalPerformanceProfile:
    """The profile of a (*cells, trials, times) table of scored qualities (0 where `missing`,
    a trial without a result at that time), and measured `step`."""
    axis = quality.ndim - 2
    n_bins = len(grid.bins) - 1
    # The bin holding each quality, as `point_mass` finds it (1.0 falls in the last bin).
    index = np.clip(np.searchsorted(grid.bins, quality, side="right") - 1, 0, n_bins - 1)
    inside = [index == k for k in range(n_bins)]  # one mask per bin, over every cell at once
    counts = np.stack([mask.sum(axis=axis) for mask in inside], axis=-1)
    sums = np.stack([np.where(mask, quality, 0.0).sum(axis=axis) for mask in inside], axis=-1)
    trials = quality.shape[axis]
    probability = counts / trials
    # Each bin's mean quality (its midpoint where no trial fell in it), kept inside the bin as
    # the profile checks it: the first bin reaches down to 0, the last up to 1.
    midpoints = np.round((grid.bins[:-1] + grid.bins[1:]) / 2, 12)  # 0.15, not 0.15000000000000002
    bin_mean = np.divide(
        sums, counts, out=np.broadcast_to(midpoints, sums.shape).copy(), where=counts > 0
    )
    lower = np.concatenate(([0.0], grid.bins[1:-1]))
    upper = np.concatenate((grid.bins[1:-1], [1.0]))
    bin_mean = np.clip(bin_mean, lower, upper)
    std = quality.std(axis=axis, ddof=1) if trials > 1 else np.zeros(probability.shape[:-1])
    kind: Literal["interruptible", "contract"] = (
        "contract" if module.kind == "contract" else "interruptible"
    )
    return new_profile(
        input_grids=grid.input_grids,
        time=grid.time,
        bins=grid.bins,
        probability=probability,
        inputs=module.inputs,
        mean=np.clip(quality.mean(axis=axis), 0.0, 1.0),
        samples=np.full(probability.shape[:-1], float(trials)),
        std=std,
        module=module.name,
        kind=kind,
        time_unit=CLOCKS[clock][1],
        step=step,
        no_result_table=missing.mean(axis=axis),
        bin_mean=bin_mean,
    )


def _run(chunks: list[Chunk], executor: Executor | None, workers: int) -> Iterator[Done]:
    """Finished chunks as they come back, in any order: here, all in one (isolated) process
    of trials, or spread over local workers or an executor (`anytime.pool.spread`)."""
    if executor is None and workers == 1:
        yield from measure_chunks(chunks)
        return
    try:
        yield from spread(measure_chunk, chunks, executor=executor, workers=workers)
    except WorkerDied:  # a trial ended its worker: the trials measured are lost with it
        raise BuildError(
            "a worker process died: a trial ended the process it ran in (trials not isolated"
            " take their worker with them; isolated, it is a failed trial); no profile was made"
        ) from None
    except ImportError as error:  # raised where an executor's worker unpickled a chunk
        if executor is None:
            raise
        module = chunks[0].module.name if chunks else "the module"
        raise BuildError(
            f"the executor's workers cannot import what the trials of '{module}' need"
            f" ({type(error).__name__}: {error}): install its package where the workers run"
            " (a module defined in a script or notebook does not travel); no profile was made"
        ) from None
