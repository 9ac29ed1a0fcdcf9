"""The catalogue every module must pass (`anytime.testing`, `anytime check`): a well-behaved
module passes every check, and each broken one fails exactly the check for what it breaks."""

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
from conftest import Cli

import anytime.library
from anytime import AnytimeLibrary, RegistrySource
from anytime.isolation import Limits
from anytime.measure.builder import Instance, build_profile, register_problems
from anytime.modules import AnytimeModule, Context, Registry, Result, contract, interruptible
from anytime.profiles import tabulate
from anytime.profiles.io import save_profile
from anytime.runtime.modes import SOFT, Hard, Isolated, RunMode
from anytime.testing import (
    CHECKS,
    CatalogueError,
    assert_module_passes,
    catalogue_cases,
    check_module,
)

#: Instances count up to a limit drawn uniformly from these.
LIMITS = np.arange(80, 121)
TIME = [0, 25, 50, 100, 150]
QUALITIES = [0.5, 1.0]


def counted(t: Any, q: Any, speed: float = 1.0) -> Any:
    """The exact expected quality of counting at `speed` steps a tick for `t` ticks."""
    t = np.asarray(t, dtype=float)[..., None]
    return q * np.mean(np.minimum(speed * t, LIMITS) / LIMITS, axis=-1)


#: The true profile of every counting toy below (their limits are uniform on LIMITS).
COUNTING = tabulate(counted, TIME, input_grids=[QUALITIES], inputs=["data"])
#: A profile that claims twice the speed.
BOASTFUL = tabulate(
    lambda t, q: counted(t, q, speed=2.0), TIME, input_grids=[QUALITIES], inputs=["data"]
)


class Counting:
    """A random limit; the true quality is the fraction counted times the input quality."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        limit = int(rng.integers(LIMITS[0], LIMITS[-1] + 1))
        return Instance(args=(None, limit), reference=(limit, input_qualities[0]))

    def score(self, instance: Instance, value: Any) -> float:
        limit, quality = instance.reference
        count = value[0] if isinstance(value, list) else value  # `rewriter` answers in a list
        return float(quality * count / limit)


GOOD = Registry()
BROKEN = Registry()


@interruptible("catalogue-good", inputs=["data"], profile=COUNTING, registry=GOOD)
def good(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Count to `limit`, one tick a step, registering the fraction counted."""
    for done in range(1, limit + 1):
        ctx.tick()
        yield Result(done, data.quality * done / limit)


@interruptible("catalogue-overrun", inputs=["data"], profile=COUNTING, registry=BROKEN)
def overrun(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`, but once its time is up it makes a long last pass regardless."""
    for done in range(1, limit + 1):
        ctx.tick()
        if ctx.expired:
            ctx.tick(1000)
        yield Result(done, data.quality * done / limit)


@interruptible("catalogue-bare", inputs=["data"], profile=COUNTING, registry=BROKEN)
def bare(ctx: Context, data: Result, limit: int) -> Iterator[Any]:
    """Counts like `good`, but forgets to wrap its last answer in a Result."""
    for done in range(1, limit + 1):
        ctx.tick()
        quality = data.quality * done / limit
        yield (done, quality) if done == limit else Result(done, quality)


@interruptible("catalogue-overjoyed", inputs=["data"], profile=COUNTING, registry=BROKEN)
def overjoyed(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`, but rates its last answer a little above what a quality can be."""
    for done in range(1, limit + 1):
        ctx.tick()
        bonus = 1.01 if done == limit else 1.0
        yield Result(done, data.quality * done / limit * bonus)


@interruptible("catalogue-crashing", inputs=["data"], profile=COUNTING, registry=BROKEN)
def crashing(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`, then trips over its own end."""
    for done in range(1, limit + 1):
        ctx.tick()
        yield Result(done, data.quality * done / limit)
    raise RuntimeError("counted past the end")


@interruptible("catalogue-boastful", inputs=["data"], profile=BOASTFUL, registry=BROKEN)
def boastful(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`; its declared profile claims twice the speed."""
    for done in range(1, limit + 1):
        ctx.tick()
        yield Result(done, data.quality * done / limit)


@interruptible("catalogue-rewriter", inputs=["data"], profile=COUNTING, registry=BROKEN)
def rewriter(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`, but keeps writing into the list it registered."""
    counted = [0]
    for done in range(1, limit + 1):
        ctx.tick()
        counted[0] = done
        yield Result(counted, data.quality * done / limit)


def _impossible(ctx: Context, data: Result, limit: int, work: float) -> Iterator[Result]:
    """Counts like `good`, but reports impossible work for its last step: refused, so the run
    fails there instead of answering with a NaN or negative time."""
    for done in range(1, limit + 1):
        ctx.tick(work if done == limit else 1)
        yield Result(done, data.quality * done / limit)


@interruptible("catalogue-ticks-nan", inputs=["data"], profile=COUNTING, registry=BROKEN)
def ticks_nan(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    yield from _impossible(ctx, data, limit, math.nan)


@interruptible("catalogue-ticks-negative", inputs=["data"], profile=COUNTING, registry=BROKEN)
def ticks_negative(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    yield from _impossible(ctx, data, limit, -1.0)


@interruptible("catalogue-ticks-inf", inputs=["data"], profile=COUNTING, registry=BROKEN)
def ticks_inf(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    yield from _impossible(ctx, data, limit, math.inf)


class Halving:
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance(args=(float(rng.random()),))

    def score(self, instance: Instance, value: Any) -> float:
        return float(value[1])


HALVING = tabulate(lambda t: np.minimum(t, 20) / 20, [0, 10, 20, 30], kind="contract")


@contract("catalogue-halve", inputs=[], profile=HALVING, registry=GOOD)
def halve(ctx: Context, x: float) -> Result:
    """Half of `x`, with a quality that grows with the work it can afford (at most 20)."""
    work = min(ctx.allocation, 20)
    ctx.tick(work)
    return Result((x / 2, work / 20), work / 20)


@contract("catalogue-greedy", inputs=[], profile=HALVING, registry=BROKEN)
def greedy(ctx: Context, x: float) -> Result:
    """Like `halve`, but always does its 20 ticks of work, whatever it was given."""
    ctx.tick(20)
    work = min(ctx.allocation, 20)
    return Result((x / 2, work / 20), work / 20)


@interruptible("catalogue-numpy", inputs=["data"], profile=COUNTING, registry=GOOD)
def numpy_counts(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`, its answers numpy scalars (which need not pickle to the same bytes
    after a process round trip: the value is compared by its own equality)."""
    for done in range(1, limit + 1):
        ctx.tick()
        yield Result(np.int64(done), data.quality * done / limit)


@contract("catalogue-halve-or-none", inputs=[], profile=HALVING, registry=GOOD)
def halve_or_none(ctx: Context, x: float) -> Result | None:
    """Like `halve`, but with less than 10 ticks it says it has no result (None)."""
    if ctx.allocation < 10:
        return None
    return halve.function(ctx, x)  # type: ignore[no-any-return]


for _module in [*GOOD, *BROKEN]:
    register_problems(
        _module,
        Halving() if _module.kind == "contract" else Counting(),
        time=[0, 10, 20, 30] if _module.kind == "contract" else TIME,
        input_grids=[] if _module.kind == "contract" else [QUALITIES],
    )

GOOD_CASES = catalogue_cases(AnytimeLibrary([RegistrySource(GOOD)]))


def problems_of(module: AnytimeModule) -> Any:
    return Halving() if module.kind == "contract" else Counting()


# --- the API -----------------------------------------------------------------------------------


@pytest.mark.parametrize("case", GOOD_CASES, ids=[case.id for case in GOOD_CASES])
def test_well_behaved_modules_pass_every_check(case: Any) -> None:
    report = assert_module_passes(case.module, case.problems, trials=10)
    assert [check.name for check in report.checks] == list(CHECKS)
    assert all(c.passed and not c.skipped for c in report.checks), report.format()


@pytest.mark.parametrize(
    ("module", "check", "message"),
    [
        (
            overrun,
            "deadline",
            "used 1001 ticks, 1001 past the allocation; its largest step before the deadline"
            " was 1 (allocation 0, trial 0 at input qualities [0.5]); 70 of 100 runs missed the"
            " deadline",
        ),
        (
            greedy,
            "deadline",
            "overran its contract: used 20 ticks (allocation 0, trial 0); 20 of 40 runs missed"
            " the deadline",
        ),
        (
            bare,
            "quality",
            "yielded tuple (116, 0.5), not a Result (allocation 150, trial 0 at input qualities"
            " [0.5]); 38 of 120 runs broke the Result protocol",
        ),
        (
            overjoyed,
            "quality",
            "tried to build a Result of quality outside [0, 1]: ValueError: a Result's quality"
            " must be in [0, 1], got 1.01 (allocation 150, trial 0 at input qualities [1.0]);"
            " 22 of 120 runs broke the Result protocol",
        ),
        (
            crashing,
            "errors",
            "RuntimeError: counted past the end (allocation 150, trial 0 at input qualities"
            " [0.5]); 37 of 120 runs raised",
        ),
    ],
    ids=["overrun", "contract-overrun", "not-a-result", "quality-above-1", "raises"],
)
def test_a_broken_module_fails_exactly_its_check(
    module: AnytimeModule, check: str, message: str
) -> None:
    report = check_module(module, problems_of(module), trials=10)
    assert [c.name for c in report.failed] == [check], report.format()
    assert report[check].message == message


@pytest.mark.parametrize(
    ("module", "work"), [(ticks_nan, "nan"), (ticks_negative, "-1.0"), (ticks_inf, "inf")]
)
def test_a_module_that_reports_impossible_work_fails_the_errors_check(
    module: AnytimeModule, work: str
) -> None:
    report = check_module(module, Counting(), trials=10)
    assert [c.name for c in report.failed] == ["errors"], report.format()
    assert report["errors"].message == (
        f"ValueError: ctx.tick({work}): work must be a finite number of units, 0 or more"
        " (allocation 150, trial 0 at input qualities [0.5]); 38 of 120 runs raised"
    )


def test_a_declared_profile_that_disagrees_with_the_behaviour() -> None:
    report = check_module(boastful, Counting(), trials=10)
    assert [c.name for c in report.failed] == ["profile"], report.format()
    assert report["profile"].message == (
        "the measured profile disagrees with the declared one at 4 of 10 cells; worst at input"
        " qualities [1.0], time 50: measured 0.540 (n=10, se 0.021), declared 0.955, allowed"
        " 0.121"
    )


@pytest.mark.parametrize(
    "mode", [Isolated(), Isolated(limits=Limits(cpu=60)), SOFT], ids=["isolated", "limits", "soft"]
)
def test_numpy_scalar_values_and_contracts_without_a_result_pass(mode: RunMode) -> None:
    # With limits, every run has a process of its own.
    for module in (numpy_counts, halve_or_none):
        problems = Counting() if module.kind == "interruptible" else Halving()
        report = check_module(module, problems, trials=5, mode=mode)
        assert report.passed, report.format()


@pytest.mark.parametrize(
    ("mode", "message"),
    [
        (
            Hard(),
            "mode: Hard() is not for the catalogue: a hard run answers at its deadline whatever"
            " the module does, which would hide what the deadline and interruption checks test;"
            " give Soft() or Isolated()",
        ),
        ("process", "mode: expected Soft() or Isolated(), got 'process'"),
    ],
)
def test_the_catalogue_refuses_a_mode_it_cannot_check_in(mode: Any, message: str) -> None:
    with pytest.raises(CatalogueError) as error:
        check_module(numpy_counts, Counting(), trials=1, mode=mode)
    assert str(error.value) == message


def test_a_module_that_changes_a_registered_value() -> None:
    # The profile builder scores a run's answers after the run, so it sees the changed values
    # too: the measured profile is wrong as well.
    report = check_module(rewriter, Counting(), trials=10)
    assert [c.name for c in report.failed] == ["interruption", "profile"], report.format()
    assert report["interruption"].message == (
        "changed the value of a result after registering it (stopped at tick 102.096, trial 0"
        " at input qualities [0.5]); 13 of 20 runs did not answer with their best registered"
        " result"
    )


def test_a_module_defined_in_a_function_does_not_pickle() -> None:
    @interruptible("catalogue-local", inputs=["data"], profile=COUNTING, registry=Registry())
    def local(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
        for done in range(1, limit + 1):
            ctx.tick()
            yield Result(done, data.quality * done / limit)

    report = check_module(local, Counting(), trials=5)
    assert [c.name for c in report.failed] == ["pickle"], report.format()
    where = "test_a_module_defined_in_a_function_does_not_pickle.<locals>.local"
    assert report["pickle"].message == (
        f"does not pickle: test_catalogue.{where} cannot be imported by a worker process, nor"
        f" its function pickled by value (AttributeError: Can't pickle local object '{where}');"
        " define the module at the top level of a Python module"
    )


def test_a_problem_set_that_does_not_pickle() -> None:
    problems = Counting()
    problems.unpicklable = lambda: None  # type: ignore[attr-defined]
    report = check_module(good, problems, trials=5)
    assert [c.name for c in report.failed] == ["pickle"]
    assert report["pickle"].message.startswith(
        "the module pickles, but its problem set (Counting) does not: "
    )


def test_assert_module_passes_raises_with_the_report() -> None:
    with pytest.raises(AssertionError) as raised:
        assert_module_passes(overrun, Counting(), trials=5)
    text = str(raised.value)
    assert text.startswith("module 'catalogue-overrun' (interruptible): 1 of 6 checks failed")
    assert "\n  FAIL  deadline      used 1001 ticks" in text
    assert "\n  pass  profile       the measured profile agrees" in text


def test_the_profile_check_reads_a_profile_file_and_skips_without_one(tmp_path: Path) -> None:
    path = tmp_path / "counting.yaml"
    save_profile(attrs.evolve(COUNTING, module="catalogue-good"), path)
    from_file = attrs.evolve(good, profile_source=path)
    assert check_module(from_file, Counting(), trials=5)["profile"].passed
    wrong = tmp_path / "wrong.yaml"
    save_profile(attrs.evolve(COUNTING, module="something-else"), wrong)
    report = check_module(attrs.evolve(good, profile_source=wrong), Counting(), trials=2)
    assert report["profile"].message == (
        f"the declared profile cannot be used: {wrong}: module: expected 'catalogue-good' (the"
        " module it is the profile of), got 'something-else'"
    )
    unprofiled = check_module(attrs.evolve(good, profile_source=None), Counting(), trials=2)
    assert unprofiled["profile"].skipped and unprofiled["profile"].passed
    assert unprofiled["profile"].message == "no declared profile to compare with"


def test_explicit_grids_and_a_module_with_no_grid() -> None:
    report = check_module(good, Counting(), trials=2, time=[0, 40], input_grids=[[1.0]])
    assert report.runs == 2 * 2 + 2  # every instance at every allocation, then interrupted once
    bare_module = attrs.evolve(good, name="catalogue-nowhere", profile_source=None)
    with pytest.raises(CatalogueError) as raised:
        check_module(bare_module, Counting())
    assert str(raised.value) == (
        "module 'catalogue-nowhere': no grid to run it on (no declared profile in ticks, no"
        " registered problem set): give time= and input_grids="
    )


def test_catalogue_cases_are_the_modules_with_registered_problem_sets() -> None:
    registry = Registry()
    for module in (good, halve, greedy):
        registry.add(module)
    registry.add(attrs.evolve(good, name="catalogue-unmeasured"))
    cases = catalogue_cases(AnytimeLibrary([RegistrySource(registry)]))
    assert [case.id for case in cases] == ["catalogue-good", "catalogue-greedy", "catalogue-halve"]
    assert isinstance(cases[0].problems, Counting)
    assert cases[0].grid.time.tolist() == TIME


# --- `anytime check MODULE` ----------------------------------------------------------------------


@pytest.fixture(autouse=True)
def only_these_modules(monkeypatch: pytest.MonkeyPatch) -> None:
    everything = Registry()
    for module in [*GOOD, *BROKEN]:
        everything.add(module)
    monkeypatch.setattr(anytime.library, "REGISTRY", everything)


def test_check_a_passing_module(cli: Cli) -> None:
    code, out, err = cli("check", "Catalogue-Good", "--trials", "5", "--no-plugins")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0] == (
        "module 'catalogue-good' (interruptible): all 6 checks passed (60 runs, 5 trials per"
        " cell, seed 0)"
    )
    assert [line.split()[:2] for line in lines[1:]] == [["pass", name] for name in CHECKS]


def test_check_a_failing_module(cli: Cli) -> None:
    code, out, err = cli("check", "catalogue-greedy", "--trials", "4", "--no-plugins")
    assert code == 1
    assert err == "anytime: error: module 'catalogue-greedy' fails 1 of 6 checks: deadline\n"
    assert "\n  FAIL  deadline      overran its contract: used 20 ticks (allocation 0" in out


def test_check_json(cli: Cli) -> None:
    code, out, _ = cli("check", "catalogue-bare", "--trials", "3", "--json", "--no-plugins")
    assert code == 1
    report = json.loads(out)
    assert report["module"] == "catalogue-bare" and report["passed"] is False
    statuses = {"quality": "fail", "profile": "skip"}  # 3 trials cannot judge a profile
    assert {c["check"]: c["status"] for c in report["checks"]} == {
        name: statuses.get(name, "pass") for name in CHECKS
    }
    (profile,) = [c for c in report["checks"] if c["check"] == "profile"]
    assert profile["message"] == (
        "skipped: judging a profile needs at least 5 trials per cell, got 3 (one shows no"
        " spread, and with two any gap is within the bound)"
    )


def test_check_a_module_without_a_problem_set(cli: Cli, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("anytime.problems._MEASUREMENTS", {})
    code, out, err = cli("check", "catalogue-good", "--no-plugins")
    assert (code, out) == (1, "")
    assert err == (
        "anytime: error: no problem set is registered for module 'catalogue-good'"
        " (registered: none)\n"
    )


class Drawn(Counting):
    """Counting problems that remember every instance's random draw (within one process: an
    isolated trial's draw stays in its child process)."""

    def __init__(self) -> None:
        self.draws: list[int] = []

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        draw = int(rng.integers(1 << 62))
        self.draws.append(draw)
        limit = int(LIMITS[draw % len(LIMITS)])
        return Instance(args=(None, limit), reference=(limit, input_qualities[0]))


def test_the_catalogue_checks_on_instances_the_profile_never_saw() -> None:
    """With the same seed as the profile builder it re-measured the very instances the
    profile came from, so "measured agrees with declared" could not fail (difference 0.0)."""
    profiled, checked = Drawn(), Drawn()  # in this process: they record their draws
    build_profile(good, profiled, time=TIME, input_grids=[QUALITIES], trials=10, seed=0, mode=SOFT)
    check_module(good, checked, trials=10, seed=0, mode=SOFT)
    assert profiled.draws and checked.draws
    assert not set(profiled.draws) & set(checked.draws)


def test_the_catalogue_gives_the_same_report_on_two_workers() -> None:
    one = check_module(good, Counting(), trials=6, seed=3)
    two = check_module(good, Counting(), trials=6, seed=3, workers=2)
    assert one.format() == two.format() and one.passed


@interruptible(
    "catalogue-modest", inputs=["data"], profile=COUNTING, registry=GOOD, reports="estimate"
)
def modest(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts as `good` does, but its self-estimate falls as it goes (it is not its quality)."""
    for done in range(1, limit + 1):
        ctx.tick()
        yield Result(done, 1.0 / done)


def test_a_module_whose_quality_is_an_estimate_answers_with_its_latest_result() -> None:
    """The executor keeps its latest result, not the one it rates highest, and the catalogue
    checks exactly that."""
    report = check_module(modest, Counting(), trials=5)
    assert report.passed, report.format()
    assert report["interruption"].message.endswith(
        "all answered with the latest result registered before"
    )


# --- a declared step -----------------------------------------------------------------------------

STEPPED = Registry()


def _by_fives(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts five a time, in one tick of 5, registering after each: its step is 5 ticks."""
    for done in range(5, limit + 5, 5):
        ctx.tick(5)
        yield Result(min(done, limit), data.quality * min(done, limit) / limit)


@interruptible("catalogue-fives", inputs=["data"], profile=COUNTING, registry=STEPPED, step=2)
def fives(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts five a time; declares a step of 2."""
    yield from _by_fives(ctx, data, limit)


@interruptible("catalogue-fives-5", inputs=["data"], profile=COUNTING, registry=STEPPED, step=5)
def fives_honest(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts five a time; declares its step, 5."""
    yield from _by_fives(ctx, data, limit)


@interruptible("catalogue-ones", inputs=["data"], profile=COUNTING, registry=STEPPED, step=1)
def ones(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`, registering every tick; declares its step, 1."""
    yield from good.function(ctx, data, limit)


@interruptible("catalogue-halves", inputs=["data"], profile=COUNTING, registry=STEPPED, step=0.5)
def halves(ctx: Context, data: Result, limit: int) -> Iterator[Result]:
    """Counts like `good`, registering every tick; declares a step of 0.5."""
    yield from good.function(ctx, data, limit)


def test_a_declared_step_smaller_than_the_module_s_fails_the_deadline_check() -> None:
    # Given 0 ticks it registers its first result at 5 (the other allocations are multiples of
    # 5, where it stops on time, or more than it needs).
    report = check_module(fives, Counting(), trials=10)
    assert [c.name for c in report.failed] == ["deadline"], report.format()
    assert report["deadline"].message == (
        "used 5 ticks, 5 past the allocation, more than its declared step (2 ticks) (allocation"
        " 0, trial 0 at input qualities [0.5]); 20 of 100 runs missed the deadline"
    )
    # The profile check measured the step too, and warns.
    assert report["profile"].message.endswith(
        "; warning: a run went 5 ticks without a result, more than its declared step (2 ticks):"
        " right only if it stops on ctx.expired in between"
    )
    honest = check_module(fives_honest, Counting(), trials=10)
    assert honest.passed, honest.format()
    assert "warning" not in honest["profile"].message


def test_a_declared_step_below_the_module_s_ticks_fails_the_deadline_check() -> None:
    assert check_module(ones, Counting(), trials=5).passed
    report = check_module(halves, Counting(), trials=5)
    assert [c.name for c in report.failed] == ["deadline"], report.format()
    assert report["deadline"].message.startswith(
        "used 1 tick, 1 past the allocation, more than its declared step (0.5 ticks)"
    )
    assert report["profile"].message.endswith(
        "; warning: a run went 1 tick without a result, more than its declared step (0.5"
        " ticks): right only if it stops on ctx.expired in between"
    )
