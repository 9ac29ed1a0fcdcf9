"""The catalogue every anytime module must pass.

`check_module(module, problems)` runs a module on instances of its problem set (a
`ProblemSet`, as the profile builder takes) under the work clock and reports named checks, each
passed, failed or skipped, with a message that says what was seen and where:

- **pickle**: the module pickles (by reference, or by value when it is not importable by its
  name) and its problem set pickles, as worker processes
  (`anytime profile --workers`, Dask) need;
- **quality**: every answer is a `Result`, of quality in [0, 1] (`Result` refuses others: a
  module that tries fails here, not with a bare traceback);
- **errors**: no run raises;
- **deadline**: at every allocation of the time grid, a run never registers a result after its
  allocation and uses at most one of its own steps (the largest single `ctx.tick(n)` it began
  before the deadline) past it, and at most its declared `step` if it declares one (what the
  compiler reserves for it); a contract module does not overrun its contract at all;
- **interruption**: stopped from outside at a random tick, a run answers with the best result
  the module registered before the stop (its latest, for a module that does not report its
  true quality), never with none once one was registered, and that
  result's value has not changed since it was registered; a contract module, given a random
  allocation, answers with the result it returned;
- **profile**: the profile measured with `build_profile` (`trials` fresh instances per
  input-quality cell, independent of those a profile built with the same seed was measured on,
  the declared profile's own bins) agrees with the declared one at every cell:
  `|measured - declared| <= q * se + tolerance`, where `se` combines the measured standard
  error and the declared one (a measured declared profile has one), and `q` is the Student
  t quantile that makes the chance of a false alarm over all cells at most `1 - confidence`
  (Bonferroni). Its message warns when the step measured then (the largest gap between
  results) is larger than the module's declared `step`: the declaration is right only if the
  module stops on `ctx.expired` between its results (the deadline check tests that). Skipped
  for a module without a profile or with one in seconds.

The time grid is the declared profile's (so the profile is compared at its own cells, without
interpolation), else the grid registered with the problem set; `time=` and `input_grids=`
override it. A module that neither ticks nor yields hangs the catalogue as it would hang a run.

In a domain plugin's tests, run every module of the library that has a registered problem set::

    import pytest
    from anytime import AnytimeLibrary
    from anytime.testing import assert_module_passes, catalogue_cases

    CASES = catalogue_cases(AnytimeLibrary.default())

    @pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
    def test_catalogue(case):
        assert_module_passes(case.module, case.problems, trials=10)

`assert_module_passes` raises `AssertionError` with the whole report. From the command line:
`anytime check MODULE [--trials N]`.
"""

from __future__ import annotations

import math
import pickle
import threading
import traceback
from collections.abc import Callable, Iterator, Sequence
from contextlib import suppress
from typing import Any, cast

import attrs
import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.clocks import Unit, WorkClock
from anytime.errors import AnytimeError, ProfileError
from anytime.isolation import WATCHDOG, Isolation, Lost, calls
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.measure.builder import build_profile
from anytime.measure.progress import ProgressBar
from anytime.measure.trials import Trial
from anytime.modules import AnytimeModule, Context, Result
from anytime.problems import BuildError, Grid, ProblemSet, registered_problems
from anytime.profiles.profile import Array, ConditionalPerformanceProfile
from anytime.runtime.executor import RunRecord, Status, run

__all__ = [
    "CHECKS",
    "CatalogueCase",
    "CatalogueError",
    "CatalogueReport",
    "Check",
    "assert_module_passes",
    "catalogue_cases",
    "check_module",
]

#: The checks, in the order they are reported.
CHECKS = ("pickle", "quality", "errors", "deadline", "interruption", "profile")

#: How `Result` refuses a quality outside [0, 1] (the message of its converter).
_QUALITY_REFUSED = "ValueError: a Result's quality must be in [0, 1]"


class CatalogueError(AnytimeError, ValueError):
    """The catalogue cannot run as asked (no grid to run on, an elementary module...)."""


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


@frozen
class CatalogueReport:
    """Every check of one module. `passed` when none failed."""

    module: str
    kind: str
    checks: tuple[Check, ...]
    trials: int
    seed: int
    runs: int

    @property
    def passed(self) -> bool:
        return all(check.passed for check in self.checks)

    @property
    def failed(self) -> tuple[Check, ...]:
        return tuple(check for check in self.checks if not check.passed)

    def __getitem__(self, name: str) -> Check:
        for check in self.checks:
            if check.name == name:
                return check
        raise KeyError(name)

    def format(self) -> str:
        """A headline and one line per check."""
        failed = len(self.failed)
        verdict = (
            f"all {len(self.checks)} checks passed"
            if not failed
            else f"{failed} of {len(self.checks)} checks failed"
        )
        lines = [
            f"module '{self.module}' ({self.kind}): {verdict} ({self.runs} runs, {self.trials}"
            f" trials per cell, seed {self.seed})"
        ]
        width = max(len(name) for name in CHECKS)
        for check in self.checks:
            lines.append(f"  {check.status}  {check.name.ljust(width)}  {check.message}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {
            "module": self.module,
            "kind": self.kind,
            "passed": self.passed,
            "trials": self.trials,
            "seed": self.seed,
            "runs": self.runs,
            "checks": [
                {"name": c.name, "status": c.status.lower(), "message": c.message}
                for c in self.checks
            ],
        }


@frozen(eq=False)
class CatalogueCase:
    """A module of a library with the problem set registered for it."""

    module: AnytimeModule
    problems: ProblemSet
    grid: Grid

    @property
    def id(self) -> str:
        return self.module.name


def catalogue_cases(library: AnytimeLibrary | None = None) -> list[CatalogueCase]:
    """The interruptible and contract modules of `library` (default: the installed plugins and
    the in-process registry) that have a registered problem set, by name."""
    library = library if library is not None else AnytimeLibrary.default()
    cases = []
    for entry in library:
        if entry.module is None or entry.kind not in ("interruptible", "contract"):
            continue
        try:
            measurement = library.measurement(entry.name)
        except BuildError:
            continue
        cases.append(CatalogueCase(entry.module, measurement.problems, measurement.grid))
    return cases


def assert_module_passes(
    module: AnytimeModule, problems: ProblemSet, **options: Any
) -> CatalogueReport:
    """`check_module(module, problems, **options)`, raising `AssertionError` with the report
    when a check fails."""
    report = check_module(module, problems, **options)
    if not report.passed:
        raise AssertionError(report.format())
    return report


def check_module(
    module: AnytimeModule,
    problems: ProblemSet,
    *,
    trials: int = 20,
    seed: int = 0,
    time: ArrayLike | None = None,
    input_grids: Sequence[ArrayLike] | None = None,
    registered: Grid | None = None,
    tolerance: float = 0.02,
    confidence: float = 0.99,
    workers: int = 1,
    progress: bool | None = False,
    isolation: Isolation = "process",
    watchdog: float = WATCHDOG,
) -> CatalogueReport:
    """Run the catalogue on `module` (see the module docstring).

    Args:
        trials: instances per input-quality cell, for every check.
        seed: the root of the catalogue's own streams: its instances are independent of the
            ones `build_profile` (and `anytime profile`) makes with the same seed, so that
            "measured agrees with declared" is tested on instances the profile never saw.
        time: allocations (ticks) to run at (default: the declared profile's grid, else the
            registered one).
        input_grids: one grid of input qualities per quality-carrying input (default: as time).
        registered: the grid of the module's problem set (default: the one registered with
            `register_problems`, if any), used when it declares no profile.
        tolerance: the absolute slack of the profile check, on top of sampling error.
        confidence: the profile check's family-wise confidence over all cells.
        workers: processes for the profile check's measurement (its result does not depend
            on how many).
        progress: draw progress bars on standard error (the runs, then the profile's trials);
            None: only on a terminal.
        isolation: "process" (default) makes every run, and every trial of the profile check,
            in a child process (`anytime.isolation`): a run that crashes its process fails the
            errors check with how it died, and the catalogue goes on; "none" runs them here.
        watchdog: wall-clock seconds one isolated run may take before it counts as failed.

    Raises:
        CatalogueError: an elementary module, or no grid to run on.
        BuildError: the problem set breaks its contract (as the profile builder reports it).
    """
    if module.kind not in ("interruptible", "contract"):
        raise CatalogueError(
            f"module '{module.name}' is {module.kind}: the catalogue checks interruptible and"
            " contract modules"
        )
    if not isinstance(trials, int) or trials < 1:
        raise CatalogueError(f"trials: expected an integer >= 1, got {trials!r}")
    if not 0 < confidence < 1:
        raise CatalogueError(f"confidence: expected a number between 0 and 1, got {confidence!r}")
    declared, verdict = _declared(module)
    grid = _grid(module, declared, time, input_grids, registered)
    own = check_seed(seed)
    session = _Session(module, problems, grid, trials, own)
    session.isolation, session.watchdog = isolation, watchdog
    checks = [_check_pickle(module, problems)]
    total = len(session.cells) * trials * (len(grid.time) + 1)
    with ProgressBar(total, label=f"{module.name} checks", unit="runs", enabled=progress) as bar:
        session.done = bar.update
        deadline = session.deadline_runs()
        interruption = session.interruption_runs()
    runs = deadline + interruption
    checks.append(_check_quality(runs))
    checks.append(_check_errors(runs))
    checks.append(_check_deadline(module, deadline))
    checks.append(_check_interruption(module, interruption))
    if declared is not None:
        verdict = _check_profile(
            module,
            problems,
            declared,
            grid,
            trials,
            own,
            tolerance,
            confidence,
            workers,
            progress,
            isolation,
            watchdog,
        )
    assert verdict is not None
    checks.append(verdict)
    return CatalogueReport(module.name, module.kind, tuple(checks), trials, seed, len(runs))


# --- the grid and the declared profile ---------------------------------------------------------


def _declared(module: AnytimeModule) -> tuple[ConditionalPerformanceProfile | None, Check | None]:
    """The declared profile in ticks (loaded and checked against the module as the library
    does it), or the profile check's verdict when there is none to compare with."""
    if module.profile_source is None:
        return None, Check("profile", True, "no declared profile to compare with", skipped=True)
    try:
        profile = LibraryEntry.of_module(module).profile
    except ProfileError as error:
        return None, Check("profile", False, f"the declared profile cannot be used: {error}")
    assert profile is not None
    if profile.time_unit != "ticks":
        message = (
            f"the declared profile is in {profile.time_unit}: convert it to ticks"
            f" (anytime calibrate {module.name} --profile FILE --to ticks -o OUT) to compare it"
        )
        return None, Check("profile", True, message, skipped=True)
    return profile, None


def _grid(
    module: AnytimeModule,
    declared: ConditionalPerformanceProfile | None,
    time: ArrayLike | None,
    input_grids: Sequence[ArrayLike] | None,
    registered: Grid | None,
) -> Grid:
    """The explicit grids, else the declared profile's, else the registered ones."""
    source: Grid | None = registered
    if declared is not None:
        source = Grid(declared.time, declared.input_grids)
    elif source is None:
        with suppress(BuildError):
            source = registered_problems(module.name).grid
    if source is None and (time is None or (input_grids is None and module.inputs)):
        raise CatalogueError(
            f"module '{module.name}': no grid to run it on (no declared profile in ticks, no"
            " registered problem set): give time= and input_grids="
        )
    grid = Grid(
        time if time is not None else cast(Grid, source).time,
        input_grids if input_grids is not None else source.input_grids if source else (),
    )
    if len(grid.input_grids) != len(module.inputs) or grid.time.ndim != 1 or not grid.time.size:
        raise CatalogueError(
            f"module '{module.name}': expected a time grid and {len(module.inputs)} input-quality"
            f" grid(s) (inputs: {', '.join(module.inputs) or 'none'}), got"
            f" {len(grid.input_grids)}"
        )
    return grid


# --- running -----------------------------------------------------------------------------------


@frozen
class _Yield:
    """One answer the module gave: when, what, whether the executor could register it, and
    the pickled value at that moment (None when it does not pickle)."""

    at: float
    item: Any
    eligible: bool
    snapshot: bytes | None


@frozen(eq=False)
class _Run:
    record: RunRecord
    log: tuple[_Yield, ...]
    where: str
    allocation: float
    largest_step: float  # the largest tick begun before the deadline (or the first one)
    negative: bool  # a tick of negative work was reported


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


def _snapshot(value: Any) -> bytes | None:
    try:
        return pickle.dumps(value)
    except Exception:
        return None


def _recorded(module: AnytimeModule, log: list[_Yield], snapshots: bool) -> AnytimeModule:
    """`module` with every answer it gives logged, as the executor will see it (with a pickled
    copy of each registered value if `snapshots`)."""
    inner = module.function
    contract = module.kind == "contract"

    def entry(ctx: Context, item: Any) -> _Yield:
        if contract:  # registered unless it was stopped before its allocation ran out
            eligible = not (ctx.stop.is_set() and ctx.elapsed < ctx.allocation)
        else:
            eligible = not ctx.stop.is_set() and ctx.elapsed <= ctx.allocation
        eligible &= isinstance(item, Result)
        value = item.value if isinstance(item, Result) else None
        snapshot = _snapshot(value) if eligible and snapshots else None
        return _Yield(ctx.elapsed, item, eligible, snapshot)

    def generator(ctx: Context, *args: Any, **kwargs: Any) -> Iterator[Any]:
        items = inner(ctx, *args, **kwargs)
        try:
            for item in items:
                log.append(entry(ctx, item))
                yield item
        finally:
            items.close()

    def call(ctx: Context, *args: Any, **kwargs: Any) -> Any:
        item = inner(ctx, *args, **kwargs)
        log.append(entry(ctx, item))
        return item

    function: Callable[..., Any] = call if contract else generator
    return attrs.evolve(module, function=function)


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


class _Session:
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
        self.isolation: Isolation = "process"
        self.watchdog = WATCHDOG

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
    ) -> _Run:
        trial = Trial(
            self.module,
            self.problems,
            qualities,
            np.random.SeedSequence(self.seed, spawn_key=(cell, instance)),
            WorkClock,  # unused: the trial only makes the problem
            where,
        )
        _, args = trial.problem()  # made afresh for every run: a module may change its arguments
        log: list[_Yield] = []
        stop = threading.Event()
        clock = _ProbeClock(allocation, stop, stop_at)
        recorded = _recorded(self.module, log, snapshots=stop_at < math.inf)
        record = run(recorded, args, allocation=allocation, clock=clock, stop=stop)
        return _Run(record, tuple(log), where, allocation, clock.largest, clock.negative)

    def deadline_runs(self) -> list[_Run]:
        """Every instance at every allocation of the grid."""
        return self._runs(
            [
                (cell, i, q, f"allocation {float(a):g}, {where}", float(a), math.inf)
                for cell, i, q, where in self._instances()
                for a in self.grid.time
            ]
        )

    def interruption_runs(self) -> list[_Run]:
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

    def _runs(self, specs: list[_Spec]) -> list[_Run]:
        """The runs of `specs`, isolated in child processes unless the session says not: a
        run whose process dies or hangs is a run that crashed (or failed, on the watchdog)."""
        if self.isolation == "none":
            outcomes: Iterator[_Run | Lost] = (self._run(*spec) for spec in specs)
        else:
            outcomes = calls(lambda spec: self._run(*spec), specs, watchdog=self.watchdog)
        runs = []
        for spec, outcome in zip(specs, outcomes, strict=True):
            runs.append(self._lost(spec, outcome) if isinstance(outcome, Lost) else outcome)
            self.done()
        return runs

    def _lost(self, spec: _Spec, lost: Lost) -> _Run:
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
        return _Run(record, (), where, allocation, 0.0, False)


# --- the checks --------------------------------------------------------------------------------


def _qualified(module: AnytimeModule) -> str:
    return f"{module.function.__module__}.{module.function.__qualname__}"


def _headline(exc: BaseException) -> str:
    return "".join(traceback.format_exception_only(exc)).strip().splitlines()[-1]


def _check_pickle(module: AnytimeModule, problems: ProblemSet) -> Check:
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


def _first(bad: list[tuple[_Run, str]], total: int, what: str) -> str:
    run_, problem = bad[0]
    return f"{problem} ({run_.where}); {len(bad)} of {total} runs {what}"


def _check_quality(runs: list[_Run]) -> Check:
    bad: list[tuple[_Run, str]] = []
    for r in runs:
        strange = [y.item for y in r.log if not isinstance(y.item, Result)]
        error = r.record.error or ""
        if strange:
            bad.append((r, error or f"gave {type(strange[0]).__name__}, not a Result"))
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


def _check_errors(runs: list[_Run]) -> Check:
    bad = [
        (r, r.record.error or "failed")
        for r in runs
        if r.record.status in (Status.FAILED, Status.CRASHED)
        and all(isinstance(y.item, Result) for y in r.log)
        and not (r.record.error or "").startswith(_QUALITY_REFUSED)
    ]
    if bad:
        crashed = any(r.record.status is Status.CRASHED for r, _ in bad)
        return Check("errors", False, _first(bad, len(runs), "failed" if crashed else "raised"))
    return Check("errors", True, f"none of {len(runs)} runs raised")


def _check_deadline(module: AnytimeModule, runs: list[_Run]) -> Check:
    bad: list[tuple[_Run, str]] = []
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
        else:
            late = [y for y in r.log if y.item is record.result and y.at > r.allocation]
            if record.result is not None and late:
                bad.append((r, f"registered a result at tick {late[0].at:g}"))
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


def _numbers(runs: list[_Run]) -> str:
    return ", ".join(f"{a:g}" for a in sorted({r.allocation for r in runs}))


def _check_interruption(module: AnytimeModule, runs: list[_Run]) -> Check:
    # A module that does not report its true quality answers with its latest result (the
    # executor cannot rank its results by what it says of them).
    latest = module.kind == "interruptible" and module.reports != "true"
    bad: list[tuple[_Run, str]] = []
    for r in runs:
        result = r.record.result
        registered = [y for y in r.log if y.eligible]
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
        elif mine[-1].snapshot is not None and _snapshot(result.value) != mine[-1].snapshot:
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


def _check_profile(
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
    isolation: Isolation = "process",
    watchdog: float = WATCHDOG,
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
        isolation=isolation,
        watchdog=watchdog,
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
