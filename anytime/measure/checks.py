"""The catalogue's runs and its checks (`anytime.measure.catalogue` says what each check
requires): the runs of one module at every allocation of the grid and stopped from outside
(`Session`), each answer logged as the executor will see it, and one function per check that
turns those runs into a `Check`.
"""

from __future__ import annotations

import copy
import math
import pickle
import threading
import traceback
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from attrs import frozen

from anytime.clocks import Unit, WorkClock
from anytime.isolation import Lost, calls
from anytime.measure.builder import build_profile
from anytime.measure.trials import Trial, run_trial
from anytime.modules import AnytimeModule, Result
from anytime.problems import Grid, ProblemSet
from anytime.profiles.profile import Array, ConditionalPerformanceProfile
from anytime.runtime.executor import RunRecord, Status
from anytime.runtime.modes import ISOLATED, SOFT, Budget, Isolated, RunMode, Soft
from anytime.runtime.observe import Observer

__all__ = [
    "Check",
    "Run",
    "Session",
    "check_deadline",
    "check_errors",
    "check_interruption",
    "check_pickle",
    "check_profile",
    "check_quality",
    "check_seed",
]


_QUALITY_REFUSED = "ValueError: a Result's quality must be in [0, 1]"


@frozen
class Check:
    """The outcome of one check: `passed` (a skipped check counts as passed) and why."""

    name: str
    passed: bool
    message: str
    skipped: bool = False

    @property
    def status(self) -> str:
        return "skip" if self.skipped else "pass" if self.passed else "FAIL"


# --- running -----------------------------------------------------------------------------------


@frozen
class _Yield:
    """A result the run kept: when it was registered, and whether its value was changed after
    (None: the value could not be copied or compared, so it was not checked)."""

    at: float
    item: Result
    changed: bool | None = None


class _Answers(Observer):
    """The catalogue's view of one run: every result the run keeps, in order, and, with
    `copies`, a copy of each value as it was registered, compared with the value the run
    answers with at its end (by the value's own equality, numpy arrays element by element)."""

    def __init__(self, copies: bool) -> None:
        self.copies = copies
        self.kept: list[tuple[float, Result, Any]] = []

    def registered(self, elapsed: float, result: Result) -> None:
        self.kept.append((elapsed, result, _copy(result.value) if self.copies else _UNCOPIED))
        return None

    def log(self, record: RunRecord) -> tuple[_Yield, ...]:
        return tuple(
            _Yield(at, item, None if copy is _UNCOPIED else not _equal(copy, item.value))
            if item is record.result
            else _Yield(at, item)
            for at, item, copy in self.kept
        )


_UNCOPIED = object()


def _copy(value: Any) -> Any:
    try:
        return copy.deepcopy(value)
    except Exception:  # a value that cannot be copied is not checked
        return _UNCOPIED


def _equal(a: Any, b: Any, seen: set[tuple[int, int]] | None = None) -> bool:
    """Whether `a` and `b` (a value as it was registered, and a copy of it) are equal: by
    their own equality where their class defines one, arrays element by element, and lists,
    tuples, dicts and plain objects (whose equality is identity) part by part."""
    seen = set() if seen is None else seen
    if (id(a), id(b)) in seen:  # a cycle: compared on the way in
        return True
    seen.add((id(a), id(b)))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b, equal_nan=_floating(a) and _floating(b)))
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return (
            type(a) is type(b)
            and len(a) == len(b)
            and all(_equal(x, y, seen) for x, y in zip(a, b, strict=True))
        )
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k], seen) for k in a)
    plain = getattr(type(a), "__eq__", None) is getattr(object, "__eq__", None)
    if type(a) is type(b) and plain and hasattr(a, "__dict__"):
        return _equal(vars(a), vars(b), seen)
    try:
        return bool(a == b)
    except Exception:  # an equality that cannot answer (arrays inside): not checked
        return True


def _floating(value: Any) -> bool:
    return np.asarray(value).dtype.kind in "fc"


@frozen(eq=False)
class Run:
    """One catalogue run: its record, the results it kept, where and at what allocation it
    ran, what its clock saw of its steps, and whether it was skipped (the module was stuck)."""

    record: RunRecord
    log: tuple[_Yield, ...]
    where: str
    allocation: float
    largest_step: float  # the largest tick begun before the deadline (or the first one)
    negative: bool  # a tick of negative work was reported
    skipped: bool = False  # not run: an earlier run of the module hit the watchdog


class _ProbeClock:
    """A work clock that measures the module's steps and can stop it after `stop_at` ticks."""

    unit: Unit = "ticks"

    def __init__(self, deadline: float, stop: threading.Event, stop_at: float = math.inf):
        self.ticks = 0.0
        self.deadline = deadline
        self.largest = 0.0
        self.steps = 0
        self.negative = False
        self._stop, self._stop_at = stop, stop_at
        self._lock = threading.Lock()

    def now(self) -> float:
        return self.ticks

    def advance(self, n: float) -> None:
        with self._lock:
            if self.ticks < self.deadline or self.steps == 0:
                self.largest = max(self.largest, n)
            self.negative |= n < 0
            self.steps += 1
            self.ticks += n
            if self.ticks >= self._stop_at:
                self._stop.set()


def check_seed(seed: int) -> int:
    """The root seed of the catalogue's streams for user seed `seed`: a different stream from
    the one `build_profile(seed=seed)` draws its instances from."""
    state = np.random.SeedSequence([seed, _CATALOGUE_STREAM]).generate_state(4)
    return int.from_bytes(state.tobytes(), "little")


#: Mixed into the catalogue's seeds (the bytes of "check"), so its instances are its own.
_CATALOGUE_STREAM = 0x636865636B


#: One catalogue run: cell, instance, input qualities, where (for messages), allocation, and
#: the tick to stop it at.
_Spec = tuple[int, int, tuple[float, ...], str, float, float]


class Session:
    """The instances of one catalogue run, and the runs made on them."""

    def __init__(
        self, module: AnytimeModule, problems: ProblemSet, grid: Grid, trials: int, seed: int
    ) -> None:
        self.module, self.problems, self.grid = module, problems, grid
        self.trials, self.seed = trials, seed
        self.cells = [
            tuple(float(g[i]) for g, i in zip(grid.input_grids, index, strict=True))
            for index in np.ndindex(*grid.cell_shape)
        ]
        self.done: Callable[[], object] = lambda: None  # called after every run (progress)
        self.mode: Soft | Isolated = ISOLATED  # every run in a child process, or here
        # The first run that hit the watchdog ("REASON, WHERE"): the module is stuck, and the
        # runs after it are skipped rather than each wait the watchdog again.
        self.stuck: str | None = None

    def _instances(self) -> Iterator[tuple[int, int, tuple[float, ...], str]]:
        for cell, qualities in enumerate(self.cells):
            for instance in range(self.trials):
                at = f" at input qualities {list(qualities)}" if qualities else ""
                yield cell, instance, qualities, f"trial {instance}{at}"

    def _run(
        self,
        cell: int,
        instance: int,
        qualities: tuple[float, ...],
        where: str,
        allocation: float,
        stop_at: float = math.inf,
    ) -> Run:
        trial = Trial(
            self.module,
            self.problems,
            qualities,
            np.random.SeedSequence(self.seed, spawn_key=(cell, instance)),
            WorkClock,  # unused: the trial only makes the problem
            where,
        )
        _, args = trial.problem()  # made afresh for every run: a module may change its arguments
        stop = threading.Event()
        clock = _ProbeClock(allocation, stop, stop_at)
        answers = _Answers(copies=stop_at < math.inf)
        budget = Budget(allocation, clock=clock, stop=stop)
        record = run_trial(self.module, args, budget, SOFT, answers)
        return Run(record, answers.log(record), where, allocation, clock.largest, clock.negative)

    def deadline_runs(self) -> list[Run]:
        """Every instance at every allocation of the grid."""
        return self._runs(
            [
                (cell, i, q, f"allocation {float(a):g}, {where}", float(a), math.inf)
                for cell, i, q, where in self._instances()
                for a in self.grid.time
            ]
        )

    def interruption_runs(self) -> list[Run]:
        """Every instance, stopped at a random tick (interruptible) or given a random
        allocation (contract), up to the grid's largest time."""
        longest = float(self.grid.time[-1])
        specs: list[_Spec] = []
        for cell, i, q, where in self._instances():
            rng = np.random.default_rng(np.random.SeedSequence(self.seed, spawn_key=(cell, i, 1)))
            point = float(rng.uniform(0, longest))
            if self.module.kind == "contract":
                specs.append((cell, i, q, f"allocation {point:.6g}, {where}", point, math.inf))
            else:
                label = f"stopped at tick {point:.6g}, {where}"
                specs.append((cell, i, q, label, math.inf, point))
        return self._runs(specs)

    def _runs(self, specs: list[_Spec]) -> list[Run]:
        """The runs of `specs`, isolated in child processes unless the session says not: a
        run whose process dies or hangs is a run that crashed (or failed, on the watchdog).
        One process makes the runs in turn; with the mode's limits, each has its own."""
        mode = self.mode

        def call(spec: _Spec) -> Run:
            return self._run(*spec)

        if not isinstance(mode, Isolated):
            outcomes: Iterator[Run | Lost] = (call(spec) for spec in specs)
        elif mode.limits is None:
            outcomes = calls(call, specs, watchdog=mode.watchdog)
        else:
            outcomes = (
                outcome
                for spec in specs
                for outcome in calls(call, [spec], watchdog=mode.watchdog, limits=mode.limits)
            )
        runs = []
        for spec in specs:
            if self.stuck is not None:
                runs.append(self._skipped(spec))
            else:
                outcome = next(outcomes)
                runs.append(self._lost(spec, outcome) if isinstance(outcome, Lost) else outcome)
                if isinstance(outcome, Lost) and outcome.exit_code is None:  # the watchdog
                    self.stuck = f"{outcome.reason}, {spec[3]}"
                    close = getattr(outcomes, "close", None)
                    if close is not None:
                        close()  # ends the process that would go on with the next runs
            self.done()
        return runs

    def _skipped(self, spec: _Spec) -> Run:
        """The run of `spec`, not made: an earlier run hit the watchdog."""
        *_, where, allocation, _ = spec
        record = RunRecord(
            self.module.name, Status.FAILED, None, 0.0, allocation, error="not run: stuck"
        )
        return Run(record, (), where, allocation, 0.0, False, skipped=True)

    def _lost(self, spec: _Spec, lost: Lost) -> Run:
        """The run of `spec` whose process did not come back."""
        *_, where, allocation, _ = spec
        hung = lost.exit_code is None
        record = RunRecord(
            self.module.name,
            Status.FAILED if hung else Status.CRASHED,
            None,
            0.0,
            allocation,
            error=lost.reason,
            exit_code=lost.exit_code,
        )
        return Run(record, (), where, allocation, 0.0, False)


# --- the checks --------------------------------------------------------------------------------


def _qualified(module: AnytimeModule) -> str:
    return f"{module.function.__module__}.{module.function.__qualname__}"


def _headline(exc: BaseException) -> str:
    return "".join(traceback.format_exception_only(exc)).strip().splitlines()[-1]


def check_pickle(module: AnytimeModule, problems: ProblemSet) -> Check:
    name = _qualified(module)
    try:
        restored = pickle.loads(pickle.dumps(module))
    except Exception as exc:
        return Check(
            "pickle",
            False,
            f"does not pickle: {name} cannot be imported by a worker process, nor its function"
            f" pickled by value ({_headline(exc)}); define the module at the top level of a"
            " Python module",
        )
    by_reference = restored is module
    if not by_reference and (restored.name, restored.kind) != (module.name, module.kind):
        return Check("pickle", False, f"{name} unpickles as {restored!r}, not as {module!r}")
    kind = type(problems).__qualname__
    try:
        pickle.loads(pickle.dumps(problems))
    except Exception as exc:
        return Check(
            "pickle",
            False,
            f"the module pickles, but its problem set ({kind}) does not: {_headline(exc)}",
        )
    how = f"by reference ({name})" if by_reference else "by value (not importable by its name)"
    return Check("pickle", True, f"pickles {how}; its problem set pickles")


def _not_a_result(error: str) -> bool:
    """Whether a run failed because the module gave something that is not a `Result` (the
    executor's words for it)."""
    return error.startswith(("yielded ", "returned ")) and error.endswith(", not a Result")


def _first(bad: list[tuple[Run, str]], total: int, what: str) -> str:
    run_, problem = bad[0]
    return f"{problem} ({run_.where}); {len(bad)} of {total} runs {what}"


def check_quality(runs: list[Run]) -> Check:
    bad: list[tuple[Run, str]] = []
    for r in runs:
        error = r.record.error or ""
        if _not_a_result(error):
            bad.append((r, error))
        elif error.startswith(_QUALITY_REFUSED):
            bad.append((r, f"tried to build a Result of quality outside [0, 1]: {error}"))
        elif r.record.result is not None and not (
            isinstance(r.record.result, Result) and 0.0 <= r.record.result.quality <= 1.0
        ):
            bad.append((r, f"answered with {r.record.result!r}"))
    if bad:
        return Check("quality", False, _first(bad, len(runs), "broke the Result protocol"))
    answers = sum(len(r.log) for r in runs)
    return Check(
        "quality",
        True,
        f"all {answers} answers of {len(runs)} runs were Results of quality in [0, 1]",
    )


def skipped_note(runs: list[Run]) -> str:
    """What a message says of the runs skipped after one hit the watchdog ("" if none)."""
    skipped = sum(r.skipped for r in runs)
    if not skipped:
        return ""
    return (
        f"; the other {skipped} runs were skipped: a module whose run hits the watchdog is taken"
        " to be stuck (each further run would wait the watchdog again)"
    )


def check_errors(runs: list[Run]) -> Check:
    note = skipped_note(runs)
    runs = [r for r in runs if not r.skipped]
    bad = [
        (r, r.record.error or "failed")
        for r in runs
        if r.record.status in (Status.FAILED, Status.CRASHED)
        and not _not_a_result(r.record.error or "")
        and not (r.record.error or "").startswith(_QUALITY_REFUSED)
    ]
    if bad:
        crashed = any(r.record.status is Status.CRASHED for r, _ in bad)
        hung = any(r.record.error.startswith("watchdog") for r, _ in bad if r.record.error)
        what = "failed" if crashed or hung else "raised"
        return Check("errors", False, _first(bad, len(runs), what) + note)
    return Check("errors", True, f"none of {len(runs)} runs raised")


def check_deadline(module: AnytimeModule, runs: list[Run]) -> Check:
    bad: list[tuple[Run, str]] = []
    worst = 0.0
    for r in runs:
        record = r.record
        over = record.time_used - r.allocation
        worst = max(worst, over)
        if r.negative:
            bad.append((r, "reported negative work (ctx.tick(n) with n < 0)"))
        elif module.kind == "contract":
            if record.status is Status.CONTRACT_EXPIRED:
                bad.append((r, f"overran its contract: used {_ticks(record.time_used)}"))
        elif module.step is not None and over > module.step + 1e-9 * max(1.0, r.allocation):
            bad.append(
                (
                    r,
                    f"used {_ticks(record.time_used)}, {over:g} past the allocation, more than"
                    f" its declared step ({_ticks(module.step)})",
                )
            )
        elif over > r.largest_step + 1e-9 * max(1.0, r.allocation):
            bad.append(
                (
                    r,
                    f"used {_ticks(record.time_used)}, {over:g} past the allocation; its largest"
                    f" step before the deadline was {r.largest_step:g}",
                )
            )
    if bad:
        return Check("deadline", False, _first(bad, len(runs), "missed the deadline"))
    allowed = "within one step of" if module.kind == "interruptible" else "within"
    return Check(
        "deadline",
        True,
        f"{len(runs)} runs at allocations {_numbers(runs)} all ended {allowed} their allocation"
        f" (the most past it: {_ticks(max(worst, 0.0))})",
    )


def _ticks(n: float) -> str:
    return f"{n:g} tick{'' if n == 1 else 's'}"


def _numbers(runs: list[Run]) -> str:
    return ", ".join(f"{a:g}" for a in sorted({r.allocation for r in runs}))


def check_interruption(module: AnytimeModule, runs: list[Run]) -> Check:
    # A module that does not report its true quality answers with its latest result (the
    # executor cannot rank its results by what it says of them).
    latest = module.kind == "interruptible" and module.reports != "true"
    bad: list[tuple[Run, str]] = []
    for r in runs:
        result = r.record.result
        registered = list(r.log)
        if result is None:
            if registered:
                bad.append((r, f"answered with no result after registering {len(registered)}"))
            continue
        mine = [y for y in registered if y.item is result]
        if not mine:
            bad.append((r, f"answered with a result it had not registered: {result!r}"))
            continue
        if latest and registered[-1].item is not result:
            bad.append((r, "answered with an earlier result than the latest it registered"))
        elif not latest and result.quality < (best := max(y.item.quality for y in registered)):
            bad.append((r, f"answered with quality {result.quality:g}, having registered {best:g}"))
        elif mine[-1].changed:
            bad.append((r, "changed the value of a result after registering it"))
    if bad:
        which = "latest" if latest else "best"
        what = f"did not answer with their {which} registered result"
        return Check("interruption", False, _first(bad, len(runs), what))
    how = "given random allocations" if module.kind == "contract" else "stopped at random ticks"
    which = "latest" if latest else "best"
    return Check(
        "interruption",
        True,
        f"{len(runs)} runs {how} all answered with the {which} result registered before",
    )


#: The fewest trials per cell `check_profile` judges a declared profile on: with one the spread
#: is unknown (a bound of zero width), with two the t quantile is so wide anything passes.
MIN_PROFILE_TRIALS = 5


def check_profile(
    module: AnytimeModule,
    problems: ProblemSet,
    declared: ConditionalPerformanceProfile,
    grid: Grid,
    trials: int,
    seed: int,
    tolerance: float,
    confidence: float,
    workers: int,
    progress: bool | None = False,
    mode: RunMode = ISOLATED,
) -> Check:
    build = build_profile(
        module,
        problems,
        time=grid.time,
        input_grids=grid.input_grids,
        bins=declared.bins,
        trials=trials,
        seed=seed,
        workers=workers,
        progress=progress,
        mode=mode,
    )
    measured = build.profile
    exact = declared.mean is not None  # else compare what both say with bin representatives
    ours: Array
    if exact:
        assert measured.mean is not None
        ours = measured.mean
    else:
        ours = measured.probability @ declared.values
    mesh = np.meshgrid(*grid.input_grids, grid.time, indexing="ij")
    q = np.stack(mesh[:-1], axis=-1) if grid.input_grids else np.zeros((*mesh[-1].shape, 0))
    theirs = declared.expected(q, mesh[-1])
    std = measured.std if measured.std is not None else np.zeros(ours.shape)
    se = np.sqrt(std**2 / trials + declared.standard_error(q, mesh[-1]) ** 2)
    factor = _quantile(1 - (1 - confidence) / (2 * ours.size), trials - 1)
    allowed = factor * se + tolerance
    gap = np.abs(ours - theirs)
    cell = np.unravel_index(int(np.argmax(gap - allowed)), gap.shape)
    qualities = [float(g[i]) for g, i in zip(grid.input_grids, cell[:-1], strict=True)]
    at = f"input qualities {qualities}, " if qualities else ""
    worst = (
        f"{at}time {grid.time[cell[-1]]:g}: measured {ours[cell]:.3f} (n={trials}, se"
        f" {se[cell]:.3f}), declared {theirs[cell]:.3f}, allowed {allowed[cell]:.3f}"
    )
    failures = f"; {build.failures} of {build.runs} runs failed" if build.failures else ""
    declared_step, measured_step = module.step, measured.step
    if declared_step is not None and measured_step is not None and measured_step > declared_step:
        apart = "past its allocation" if module.kind == "contract" else "without a result"
        failures += (
            f"; warning: a run went {_ticks(measured_step)} {apart}, more than its declared"
            f" step ({_ticks(declared_step)}): right only if it stops on ctx.expired in"
            " between"
        )
    if gap[cell] > allowed[cell]:
        n_bad = int(np.sum(gap > allowed))
        return Check(
            "profile",
            False,
            f"the measured profile disagrees with the declared one at {n_bad} of {gap.size}"
            f" cells; worst at {worst}{failures}",
        )
    return Check(
        "profile",
        True,
        f"the measured profile agrees with the declared one at all {gap.size} cells; closest"
        f" to the limit at {worst}{failures}",
    )


def _quantile(p: float, df: int) -> float:
    """The Student t quantile (the normal one for df < 1)."""
    # Imported here: scipy.stats takes most of a second to import, which every `anytime`
    # command would otherwise pay at start-up (the CLI imports this module).
    from scipy import stats

    if df < 1:
        return float(stats.norm.ppf(p))
    return float(stats.t.ppf(p, df))
