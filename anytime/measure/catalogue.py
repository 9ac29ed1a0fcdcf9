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
  result's value has not changed since it was registered (by the value's own equality, arrays
  element by element, objects without one part by part); a contract module, given a random
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
override it. Isolated (the default), a module that neither ticks nor yields fails its run on
the watchdog, and is then taken to be stuck: the runs after it are skipped (each would wait the
watchdog again; the errors check says how many), and so are the checks left without a run and
the profile check. Run in-process (`SOFT`), such a module hangs the catalogue as it hangs a run.

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

from collections.abc import Callable, Sequence
from contextlib import suppress
from functools import partial
from typing import Any, cast

from attrs import frozen
from numpy.typing import ArrayLike

from anytime.errors import AnytimeError, ProfileError
from anytime.isolation import counting_interrupts
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.measure.checks import (
    MIN_PROFILE_TRIALS,
    Check,
    Run,
    Session,
    check_deadline,
    check_errors,
    check_interruption,
    check_pickle,
    check_profile,
    check_quality,
    check_seed,
)
from anytime.measure.progress import ProgressBar
from anytime.modules import AnytimeModule
from anytime.problems import BuildError, Grid, ProblemSet, registered_problems
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.runtime.modes import ISOLATED, Hard, Isolated, RunMode, Soft
from anytime.vocabulary import PROFILE_KINDS

__all__ = [
    "CHECKS",
    "CatalogueCase",
    "CatalogueError",
    "CatalogueReport",
    "Check",
    "assert_module_passes",
    "catalogue_cases",
    "check_module",
    "check_seed",
]

#: The checks, in the order they are reported.
CHECKS = ("pickle", "quality", "errors", "deadline", "interruption", "profile")


#: How `Result` refuses a quality outside [0, 1] (the message of its converter).
class CatalogueError(AnytimeError, ValueError):
    """The catalogue cannot run as asked (no grid to run on, an elementary module...)."""


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
        if entry.module is None or entry.kind not in PROFILE_KINDS:
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
    mode: RunMode = ISOLATED,
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
        mode: `Isolated(watchdog=..., limits=...)` (the default) makes every run, and every
            trial of the profile check, in a child process (`anytime.isolation`): a run that
            crashes its process fails the errors check with how it died, and one that takes
            more than `watchdog` seconds of wall time fails it too, and the runs after it
            are skipped (see above); the catalogue goes on.
            With `limits`, every run has a process of its own and the limits are each run's.
            `SOFT` runs them here. `Hard()` is refused: a hard run answers at its deadline
            whatever the module does, which would hide what the deadline and interruption
            checks are there to see.

    Raises:
        CatalogueError: an elementary module, no grid to run on, or a mode that is not
            `Soft()` or `Isolated()`.
        BuildError: the problem set breaks its contract (as the profile builder reports it).
    """
    if module.kind not in PROFILE_KINDS:
        raise CatalogueError(
            f"module '{module.name}' is {module.kind}: the catalogue checks interruptible and"
            " contract modules"
        )
    if not isinstance(trials, int) or trials < 1:
        raise CatalogueError(f"trials: expected an integer >= 1, got {trials!r}")
    if not 0 < confidence < 1:
        raise CatalogueError(f"confidence: expected a number between 0 and 1, got {confidence!r}")
    if isinstance(mode, Hard):
        raise CatalogueError(
            "mode: Hard() is not for the catalogue: a hard run answers at its deadline whatever"
            " the module does, which would hide what the deadline and interruption checks test;"
            " give Soft() or Isolated()"
        )
    if not isinstance(mode, Soft | Isolated):
        raise CatalogueError(f"mode: expected Soft() or Isolated(), got {mode!r}")
    declared, verdict = _declared(module)
    grid = _grid(module, declared, time, input_grids, registered)
    own = check_seed(seed)
    session = Session(module, problems, grid, trials, own)
    session.mode = mode
    checks = [check_pickle(module, problems)]
    total = len(session.cells) * trials * (len(grid.time) + 1)
    bar = ProgressBar(total, label=f"{module.name} checks", unit="runs", enabled=progress)
    with counting_interrupts(), bar:  # a module's own KeyboardInterrupt is a failed run
        session.done = bar.update
        deadline = session.deadline_runs()
        interruption = session.interruption_runs()
    runs = deadline + interruption
    made = [r for r in runs if not r.skipped]
    checks.append(_unless_none_ran("quality", made, session, check_quality))
    checks.append(check_errors(runs))
    deadline_made = [r for r in deadline if not r.skipped]
    interruption_made = [r for r in interruption if not r.skipped]
    checks.append(
        _unless_none_ran("deadline", deadline_made, session, partial(check_deadline, module))
    )
    checks.append(
        _unless_none_ran(
            "interruption", interruption_made, session, partial(check_interruption, module)
        )
    )
    if session.stuck is not None:  # measuring its profile would wait the watchdog per trial
        verdict = Check("profile", True, f"skipped: the module is stuck ({session.stuck})", True)
    elif declared is not None and trials < MIN_PROFILE_TRIALS:
        verdict = Check(
            "profile",
            True,
            f"skipped: judging a profile needs at least {MIN_PROFILE_TRIALS} trials per cell,"
            f" got {trials} (one shows no spread, and with two any gap is within the bound)",
            True,
        )
    elif declared is not None:
        verdict = check_profile(
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
            mode,
        )
    assert verdict is not None
    checks.append(verdict)
    return CatalogueReport(module.name, module.kind, tuple(checks), trials, seed, len(runs))


def _unless_none_ran(
    name: str, runs: list[Run], session: Session, check: Callable[[list[Run]], Check]
) -> Check:
    """`check(runs)`, or a skipped check when the session skipped every one of its runs."""
    if not runs and session.stuck is not None:
        return Check(name, True, f"skipped: the module is stuck ({session.stuck})", True)
    return check(runs)


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
