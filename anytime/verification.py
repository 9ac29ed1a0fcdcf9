"""`anytime.verify`: the compiled promise, checked by running the program.

A compiled program promises, for every total T of its table and every input quality, the
expected quality of its result (`CompiledProgram.expected`). `verify` runs the program as the
runtime runs it (`run_program`, fixed allocation, on the work clock) on fresh problems drawn by
its program-level problem set (`anytime.problems.ProgramProblems`) at every total of the table,
the smallest included, and compares the realised mean quality with the promise at each
problem's input qualities:

- realised: the problem set's score of the program's result where it declares `score`, else
  the quality the result reports (0 without a result);
- se: sqrt(se_runs^2 + se_promise^2), the standard error of the realised mean and the table's
  own standard error where its cell is estimated by sampling
  (`CompiledProgram.standard_error`, 0 where it is exact; 0 when the program has none);
- a total fails when |realised - promised| > max(0.01, 3 se), or when any run used more than
  T on the work clock (beyond the executor's rounding, 1e-9 relative).

Run i at the table's total j draws its problem from `SeedSequence(seed, spawn_key=(j, i))`:
the same seed gives the same problems and the same result for any number of workers, any chunk
size and any executor, and a total checked alone (`budgets=`) meets the problems it meets in a
full check.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import Executor
from typing import Any

import numpy as np
from attrs import asdict, cmp_using, field, frozen

from anytime.clocks import WorkClock
from anytime.compiler.compile import CompiledProgram, declared_dependence
from anytime.errors import AnytimeError
from anytime.measure.progress import ProgressBar
from anytime.modules import Result
from anytime.pool import spread
from anytime.problems import Instance, ProgramProblems, ProgramProblemSet
from anytime.profiles.profile import Array
from anytime.runtime.executor import Status
from anytime.runtime.modes import SOFT, Budget, Hard, Isolated, RunMode, Soft
from anytime.runtime.program import ExecutionError, bind_inputs, run_program
from anytime.vocabulary import read_only

__all__ = [
    "SIGMAS",
    "TOLERANCE",
    "BudgetCheck",
    "DependenceFit",
    "Verification",
    "VerifyError",
    "format_verification",
    "verification_to_dict",
    "verify",
]

#: Runs whose scores differ by at most this scored alike (the rest is rounding).
ALIKE = 1e-12
#: The least difference between realised and promised that fails a total.
TOLERANCE = 0.01
#: Standard errors a difference may reach before it fails a total.
SIGMAS = 3.0
#: Relative rounding of the work clock tolerated before a run counts as over its budget (the
#: executor's own, `anytime.runtime.executor`).
_SLACK = 1e-9


class VerifyError(AnytimeError, ValueError):
    """A verification cannot run as asked: bad options, or a problem set that breaks its
    contract (the message names it and the run)."""


@frozen
class BudgetCheck:
    """The promise at one total of the table against the runs there.

    Attributes:
        total: the total T (in the table's time unit).
        promised: the mean over the runs of the compiled expectation at each run's input
            qualities.
        realised: the mean realised quality of the runs.
        se: the standard error of the difference, sqrt(se_runs^2 + se_promise^2).
        se_runs: the standard error of the realised mean (sample deviation / sqrt(runs)).
        se_promise: the table's own standard error there (0 where the table is exact).
        z: (realised - promised) / se; where se is 0 (every run scored alike, an exact
            table), the difference over 1 / runs.
        tolerance: max(0.01, 3 se), the most |realised - promised| may be.
        runs: how many runs.
        over_budget: runs that used more than T on the work clock.
        no_result: runs whose program ended without a result.
        failed: runs in which a module failed or crashed (their results still count).
        passed: within the tolerance, and no run over budget.
        qualities: each run's realised quality, in run order.
        time_used: each run's time used, in run order.
        dependence: for a program with a best-of, the promise if its alternatives depended
            on each other as unfavourably, and as favourably, as their profiles allow
            (`CompiledProgram.dependence`, at the runs' input qualities); None without one.
    """

    total: float
    promised: float
    realised: float
    se: float
    se_runs: float
    se_promise: float
    z: float
    tolerance: float
    runs: int
    over_budget: int
    no_result: int
    failed: int
    passed: bool
    qualities: Array = field(converter=read_only, eq=cmp_using(eq=np.array_equal), repr=False)
    time_used: Array = field(converter=read_only, eq=cmp_using(eq=np.array_equal), repr=False)
    dependence: tuple[float, float] | None = None


@frozen
class DependenceFit:
    """The `:dependence` of a program's best-of that best explains the runs.

    With one best-of judged by quality, the promise at `:dependence D` is linear in D:
    `(1 - D) * independent + D * least` at each total, `least` the comonotone bound
    (`BudgetCheck.dependence`). The estimate is the weighted least-squares D of the realised
    means (weights 1 / se^2 per total), unclipped: below 0, the alternatives do better together
    than independent ones, which `:dependence` cannot say. It is fitted at the table's
    allocations; a schema given it is compiled again, so check it on another seed.

    Attributes:
        declared: the schema's `:dependence` (0: independent).
        estimate: the fitted D.
        se: its standard error.
    """

    declared: float
    estimate: float
    se: float


@frozen
class Verification:
    """What `verify` found: one `BudgetCheck` per total checked, and how it was run.

    Attributes:
        schema: the program's name.
        time_unit: the table's time unit.
        problems: the problem set's name.
        scored: whether runs were scored by the problem set (else by their reported quality).
        runs: runs per total.
        seed: the root seed (pass it again to reproduce).
        budgets: the checks, by increasing total.
        tolerance, sigmas: a total failed when |realised - promised| > max(tolerance,
            sigmas * se).
        seconds: wall time of the whole verification.
        dependence_fit: for a program with one best-of (judged by quality), the
            `:dependence` that best explains the runs; None otherwise.
    """

    schema: str
    time_unit: str
    problems: str
    scored: bool
    runs: int
    seed: int
    budgets: tuple[BudgetCheck, ...]
    tolerance: float = TOLERANCE
    sigmas: float = SIGMAS
    seconds: float = field(default=0.0, eq=False)
    dependence_fit: DependenceFit | None = None

    @property
    def passed(self) -> bool:
        """Every total within its tolerance, and no run over its budget."""
        return all(check.passed for check in self.budgets)

    @property
    def failed(self) -> tuple[BudgetCheck, ...]:
        """The totals that failed."""
        return tuple(check for check in self.budgets if not check.passed)


# --- the work: runs spread over workers --------------------------------------------------------


@frozen(eq=False)
class _Job:
    """What every run of one verification shares (handed to local workers once, at fork)."""

    compiled: CompiledProgram
    problems: ProgramProblems
    totals: tuple[tuple[int, float], ...]  # (index in the table's time grid, total) per check
    runs: int
    entropy: int
    mode: RunMode


@frozen(eq=False)
class _Chunk:
    """Runs `start` to `stop` (flat index `check * runs + run`); `job` is None where the worker
    was handed the job when it started."""

    job: _Job | None
    start: int
    stop: int


@frozen(eq=False)
class _Ran:
    """One run: its realised quality, time used, input qualities and how it ended."""

    flat: int
    quality: float
    used: float
    qualities: tuple[float, ...]
    no_result: bool
    failed: bool


_WORKER_JOB: list[_Job] = []  # the job a local worker was handed when it started


def _install(job: _Job) -> None:
    _WORKER_JOB[:] = [job]


@frozen(eq=False)
class _Done:
    """A chunk's runs, up to the first whose problem set failed (its index and message)."""

    ran: list[_Ran]
    error: tuple[int, str] | None = None


def _run_chunk(chunk: _Chunk) -> _Done:
    job = chunk.job if chunk.job is not None else _WORKER_JOB[0]
    ran = []
    for flat in range(chunk.start, chunk.stop):
        try:
            ran.append(_run_one(job, flat))
        except VerifyError as error:  # reported once every chunk is in: the first, by run
            return _Done(ran, (flat, str(error)))
    return _Done(ran)


def _run_one(job: _Job, flat: int) -> _Ran:
    check, run = divmod(flat, job.runs)
    j, total = job.totals[check]
    where = f"run {run} at T = {total:g}"
    problems = job.problems
    rng = np.random.default_rng(np.random.SeedSequence(job.entropy, spawn_key=(j, run)))
    try:
        instance = problems.problems.instance(rng)
    except Exception as exc:
        raise VerifyError(f"{problems.name}.instance failed ({where}): {_headline(exc)}") from exc
    if not isinstance(instance, Instance):
        raise VerifyError(
            f"{problems.name}.instance: expected an Instance, got {type(instance).__name__}"
            f" ({where})"
        )
    compiled = job.compiled
    try:
        values = bind_inputs(compiled.name, compiled.model.program.inputs, instance.args)
    except ExecutionError as exc:
        raise VerifyError(
            f"{problems.name}.instance: its problem does not fit the program ({where}): {exc}"
        ) from exc
    try:
        record = run_program(
            compiled,
            instance.args,
            Budget(total, clock=WorkClock()),
            mode=job.mode,
        )
    except ExecutionError as exc:
        raise VerifyError(f"schema '{compiled.name}' cannot run ({where}): {exc}") from exc
    qualities = tuple(
        float(values[name].quality) if isinstance(values[name], Result) else 1.0
        for name in compiled.model.quality_inputs
    )
    result = record.result
    if problems.scored:
        quality = _score(problems, instance, None if result is None else result.value, where)
    else:
        quality = 0.0 if result is None else float(result.quality)
    return _Ran(
        flat,
        quality,
        float(record.time_used),
        qualities,
        result is None,
        record.status is Status.FAILED,
    )


def _score(problems: ProgramProblems, instance: Instance, value: Any, where: str) -> float:
    scorer: ProgramProblemSet = problems.problems
    try:
        quality = scorer.score(instance, value)  # type: ignore[attr-defined]  # it has one
    except Exception as exc:
        raise VerifyError(f"{problems.name}.score failed ({where}): {_headline(exc)}") from exc
    try:
        q = float(quality)
    except (TypeError, ValueError):
        q = math.nan
    if not 0.0 <= q <= 1.0:  # NaN too
        raise VerifyError(
            f"{problems.name}.score: expected a quality in [0, 1], got {quality!r} ({where})"
        )
    return q


def _headline(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


# --- verify ------------------------------------------------------------------------------------


def verify(
    compiled: CompiledProgram,
    problems: ProgramProblems | ProgramProblemSet,
    *,
    runs: int = 100,
    budgets: Iterable[float] | None = None,
    workers: int = 1,
    seed: int = 0,
    executor: Executor | None = None,
    progress: bool | None = None,
    chunk_size: int | None = None,
    mode: RunMode = SOFT,
    tolerance: float = TOLERANCE,
    sigmas: float = SIGMAS,
) -> Verification:
    """Run `compiled` on `runs` fresh problems of `problems` at every total of its table (or
    those of `budgets`, each a total of the table) and compare the realised mean quality with
    the promise (see the module's docstring).

    Args:
        compiled: the compiled program.
        problems: its program-level problem set (a `ProgramProblems`, or the problem set
            itself).
        runs: runs per total.
        budgets: the totals to check (default: every total of the table).
        workers: local worker processes (1: run here).
        seed: the root seed of the problems.
        executor: where to run them instead (any `concurrent.futures.Executor`, such as a Dask
            cluster's, `anytime.measure.builder.dask_executor`; left running): the program
            and the problem set travel with every chunk of runs, so they must pickle.
        progress: draw a progress bar on standard error (None: only on a terminal).
        chunk_size: runs per task; it changes the overhead, never the result.
        mode: how each module call of a run is run (`Soft()`, the default, `Hard()` or
            `Isolated()`; see `run_program`).
        tolerance: a total fails when |realised - promised| > max(tolerance, sigmas * se).
        sigmas: see `tolerance`.

    Raises:
        VerifyError: bad arguments, or the problem set fails or breaks its contract.
    """
    started = _time.perf_counter()
    plan = problems if isinstance(problems, ProgramProblems) else _wrap(problems)
    totals = _totals(compiled, budgets)
    _check_counts(runs=runs, workers=workers, seed=seed, chunk_size=chunk_size)
    if not isinstance(mode, Soft | Hard | Isolated):
        raise VerifyError(f"mode: expected Soft(), Hard() or Isolated(), got {mode!r}")
    if not (tolerance >= 0 and sigmas >= 0):
        raise VerifyError(
            f"tolerance and sigmas: expected numbers >= 0, got {tolerance!r} and {sigmas!r}"
        )
    job = _Job(compiled, plan, totals, runs, int(seed), mode)
    count = runs * len(totals)
    if chunk_size is None:
        chunk_size = max(1, min(64, math.ceil(count / max(16, 8 * workers))))
    local = executor is None
    chunks = [
        _Chunk(None if local else job, start, min(start + chunk_size, count))
        for start in range(0, count, chunk_size)
    ]
    ran: list[_Ran | None] = [None] * count
    errors: list[tuple[int, str]] = []
    try:
        with ProgressBar(count, label=compiled.name, unit="runs", enabled=progress) as bar:
            for done in spread(
                _run_chunk,
                chunks,
                executor=executor,
                workers=workers,
                initializer=_install if local else None,
                initargs=(job,) if local else (),
            ):
                for one in done.ran:
                    ran[one.flat] = one
                if done.error is not None:
                    errors.append(done.error)
                bar.update(len(done.ran))
    finally:
        _WORKER_JOB.clear()  # a verification run here must not keep its job
    if errors:  # the first in run order, whichever worker met it first
        raise VerifyError(min(errors)[1])
    checks = tuple(
        _check(compiled, total, _complete(ran[k * runs : (k + 1) * runs]), tolerance, sigmas)
        for k, (_, total) in enumerate(totals)
    )
    return Verification(
        schema=compiled.name,
        time_unit=compiled.profile.time_unit,
        problems=plan.name,
        scored=plan.scored,
        runs=runs,
        seed=int(seed),
        budgets=checks,
        tolerance=float(tolerance),
        sigmas=float(sigmas),
        seconds=_time.perf_counter() - started,
        dependence_fit=_fit_dependence(compiled, checks),
    )


def _fit_dependence(
    compiled: CompiledProgram, checks: Sequence[BudgetCheck]
) -> DependenceFit | None:
    """The `:dependence` that best explains the realised means (see `DependenceFit`)."""
    declared = declared_dependence(compiled.model)
    ranged = [check for check in checks if check.dependence is not None and check.runs]
    if declared is None or declared >= 1 or not ranged:
        return None  # at 1 the promise no longer says what independent alternatives give
    promised = np.array([check.promised for check in ranged])
    realised = np.array([check.realised for check in ranged])
    least = np.array([check.dependence[0] for check in ranged if check.dependence is not None])
    se = np.array([c.se if c.se > 0 else 1.0 / c.runs for c in ranged])
    independent = (promised - declared * least) / (1 - declared)
    slope, residual, weight = least - independent, realised - independent, se**-2.0
    information = float(np.sum(weight * slope**2))
    if information <= 1e-12:  # the bound and the promise agree everywhere: no dependence shows
        return None
    estimate = float(np.sum(weight * slope * residual)) / information
    return DependenceFit(declared, estimate, 1 / math.sqrt(information))


def _wrap(problems: ProgramProblemSet) -> ProgramProblems:
    try:
        return ProgramProblems.of(problems)
    except TypeError as exc:
        raise VerifyError(
            f"problems: expected ProgramProblems or a problem set with an instance(rng)"
            f" method, got {type(problems).__name__}"
        ) from exc


def _complete(ran: Sequence[_Ran | None]) -> list[_Ran]:
    out = [one for one in ran if one is not None]
    assert len(out) == len(ran), "every run reports back"
    return out


def _totals(
    compiled: CompiledProgram, budgets: Iterable[float] | None
) -> tuple[tuple[int, float], ...]:
    """(index in the time grid, total) of each total to check, by increasing total."""
    grid = [float(t) for t in compiled.profile.time]
    if budgets is None:
        return tuple(enumerate(grid))
    chosen: dict[int, float] = {}
    for budget in budgets:
        value = float(budget)
        matches = [j for j, t in enumerate(grid) if abs(t - value) <= _SLACK * max(1.0, abs(t))]
        if not matches:
            raise VerifyError(
                f"budget {value:g} is not a total of the compiled table of schema"
                f" '{compiled.name}' ({_grid_text(grid)})"
            )
        chosen[matches[0]] = grid[matches[0]]
    if not chosen:
        raise VerifyError("budgets: expected at least one total of the compiled table")
    return tuple(sorted(chosen.items()))


def _grid_text(grid: Sequence[float]) -> str:
    if len(grid) <= 6:
        return ", ".join(f"{t:g}" for t in grid)
    return f"{grid[0]:g}, {grid[1]:g}, ..., {grid[-1]:g}"


def _check_counts(**values: int | None) -> None:
    for name, value in values.items():
        if value is None and name == "chunk_size":
            continue
        least = 0 if name == "seed" else 1
        if not isinstance(value, int | np.integer) or isinstance(value, bool) or value < least:
            raise VerifyError(f"{name}: expected an integer >= {least}, got {value!r}")


def _check(
    compiled: CompiledProgram, total: float, ran: list[_Ran], tolerance: float, sigmas: float
) -> BudgetCheck:
    qualities = np.array([one.quality for one in ran])
    used = np.array([one.used for one in ran])
    n = len(ran)
    profile = compiled.profile
    at = np.array([one.qualities for one in ran], dtype=np.float64).reshape(n, profile.n_inputs)
    times = np.full(n, total)
    promised = float(profile.interpolate(compiled.expected, at, times).mean())
    table = getattr(compiled, "standard_error", None)  # 0 where the table is exact
    se_promise = 0.0
    if table is not None:
        own = profile.interpolate(np.asarray(table, dtype=np.float64), at, times)
        se_promise = float(own.mean())
    # No spread but rounding's (scores computed alike on different problems differ in their
    # last bits): the std would be rounding, and z its quotient.
    alike = bool(np.ptp(qualities) <= ALIKE) if n else True
    realised = float(qualities.mean()) if n else 0.0
    se_runs = 0.0 if alike or n < 2 else float(qualities.std(ddof=1) / math.sqrt(n))
    se = math.hypot(se_runs, se_promise)
    difference = realised - promised
    # Where every run scored alike and the table is exact, se is 0: the difference is measured
    # in 1 / runs instead, the resolution of a mean of `runs` scores.
    z = difference / (se if se > 0 else 1.0 / n)
    limit = max(tolerance, sigmas * se)
    over = int(np.sum(used > total + _SLACK * max(1.0, abs(total))))
    bounds = getattr(compiled, "dependence", None)
    dependence = None
    if bounds is not None:
        least, most = (float(profile.interpolate(bound, at, times).mean()) for bound in bounds)
        dependence = (least, most)
    return BudgetCheck(
        total=total,
        promised=promised,
        realised=realised,
        se=se,
        se_runs=se_runs,
        se_promise=se_promise,
        z=z,
        tolerance=limit,
        runs=n,
        over_budget=over,
        no_result=sum(one.no_result for one in ran),
        failed=sum(one.failed for one in ran),
        passed=abs(difference) <= limit and over == 0,
        qualities=qualities,
        time_used=used,
        dependence=dependence,
    )


# --- reports -----------------------------------------------------------------------------------


def verification_to_dict(verification: Verification) -> dict[str, Any]:
    """The verification as JSON-ready data, as `anytime verify --json` prints it (docs/cli.md,
    "JSON output"): one row per budget, with the names `compile --json` and `deliver --json`
    give the same things."""
    return {
        "schema": verification.schema,
        "time_unit": verification.time_unit,
        "problem_set": verification.problems,
        "scored": verification.scored,
        "runs_per_budget": verification.runs,
        "seed": verification.seed,
        "passed": verification.passed,
        "min_tolerance": verification.tolerance,
        "sigmas": verification.sigmas,
        "budgets": [
            {
                "budget": check.total,
                "expected_quality": check.promised,
                "realised_quality": check.realised,
                "se": check.se,
                "realised_quality_se": check.se_runs,
                "expected_quality_se": check.se_promise,
                "z": check.z,
                "tolerance": check.tolerance,
                "runs": check.runs,
                "overruns": check.over_budget,
                "no_result": check.no_result,
                "failures": check.failed,
                "passed": check.passed,
                "expected_quality_if_dependent": (
                    None if check.dependence is None else list(check.dependence)
                ),
            }
            for check in verification.budgets
        ],
        "dependence_fit": (
            None if verification.dependence_fit is None else asdict(verification.dependence_fit)
        ),
        "seconds": round(verification.seconds, 3),
    }


def format_verification(verification: Verification) -> str:
    """The promise against the runs, one row per total, and the verdict."""
    name = verification.problems
    how = f"{name}.score" if verification.scored else "the quality each result reports"
    lines = [
        f"schema {verification.schema}: {verification.runs} runs per budget on {name} problems,"
        f" seed {verification.seed}, scored by {how}"
    ]
    ranged = any(check.dependence is not None for check in verification.budgets)
    header = [
        f"T ({verification.time_unit})",
        "promised",
        *(["if dependent"] if ranged else []),
        "realised ± se",
        "z",
        "over budget",
        "ok",
    ]
    rows = [header]
    for check in verification.budgets:
        rows.append(
            [
                f"{check.total:g}",
                f"{check.promised:.3f}",
                *([_range(check.dependence)] if ranged else []),
                f"{check.realised:.3f} ± {check.se:.3f}",
                _z(check.z),
                f"{check.over_budget}/{check.runs}",
                "yes" if check.passed else "NO",
            ]
        )
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    for row in rows:
        cells = [cell.rjust(width) for cell, width in zip(row, widths, strict=True)]
        lines.append("  " + "  ".join(cells).rstrip())
    lines.extend(_verdict(verification))
    return "\n".join(lines) + "\n"


def _range(bounds: tuple[float, float] | None) -> str:
    return "-" if bounds is None else f"{bounds[0]:.3f}-{bounds[1]:.3f}"


def _z(z: float) -> str:
    return f"{z:+.2f}"


def _verdict(verification: Verification) -> Iterator[str]:
    checks = verification.budgets
    rule = (
        f"|realised - promised| <= max({verification.tolerance:g}, {verification.sigmas:g} se),"
        " no run over its budget"
    )
    failed = verification.failed
    ranged = [check for check in checks if check.dependence is not None]
    if ranged:
        inside = sum(
            c.dependence[0] - verification.sigmas * c.se
            <= c.realised
            <= c.dependence[1] + verification.sigmas * c.se
            for c in ranged
            if c.dependence is not None
        )
        yield (
            "  the promise takes a best-of's alternatives as independent, or as its :dependence"
            " says; 'if dependent' is what it would be were they as dependent as their"
            " profiles allow, either way: realised within it"
            f" ({verification.sigmas:g} se) at {inside} of {len(ranged)} budgets"
        )
    fit = verification.dependence_fit
    if fit is not None:
        yield (
            f"  the runs fit :dependence {fit.estimate:.2f} ± {fit.se:.2f} (the schema's:"
            f" {fit.declared:g}), the probability that one draw decides every alternative"
            + (
                " (below 0: they do better together than independent ones)"
                if fit.estimate < 0
                else ""
            )
        )
    if not failed:
        yield f"  passed at all {len(checks)} budgets ({rule})"
        return
    yield f"  FAILED at {len(failed)} of {len(checks)} budgets ({rule}):"
    for check in failed:
        reasons = []
        difference = check.realised - check.promised
        if abs(difference) > check.tolerance:
            side = "above" if difference > 0 else "below"
            reasons.append(
                f"realised {abs(difference):.3f} {side} the promise (tolerance"
                f" {check.tolerance:.3f})"
            )
        if check.over_budget:
            reasons.append(f"{check.over_budget} of {check.runs} runs over budget")
        yield f"    T = {check.total:g}: {'; '.join(reasons)}"
