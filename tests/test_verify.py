"""`anytime.verify`: the compiled promise against runs on fresh problems (tests/verify_modules.py
has the modules: a promise that holds, one whose downstream module's profile was measured on
inputs unlike what its upstream module makes, and a module that overruns its budget)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import verify_modules as lab

from anytime import (
    CompiledProgram,
    ConditionalPerformanceProfile,
    compile_file,
    parse_schemas,
    verify,
)
from anytime.library import AnytimeLibrary, LibraryError, Plugin, PluginSource
from anytime.plugin import Instance, ProgramProblems
from anytime.verification import (
    BudgetCheck,
    Verification,
    VerifyError,
    format_verification,
    verification_to_dict,
)

RUNS = 200


@pytest.fixture(scope="module")
def programs() -> dict[str, CompiledProgram]:
    compiled = compile_file(lab.schemas(), lab.library(), lab.TOTALS, resolution=lab.RESOLUTION)
    return {program.name: program for program in compiled}


@pytest.fixture(scope="module")
def fair(programs: dict[str, CompiledProgram]) -> Verification:
    return verify(programs["fair"], lab.HiddenNumbers(), runs=RUNS)


def test_a_promise_that_holds_passes_at_every_budget_the_smallest_included(
    programs: dict[str, CompiledProgram], fair: Verification
) -> None:
    assert fair.passed and fair.failed == ()
    assert [c.total for c in fair.budgets] == [float(t) for t in lab.TOTALS]
    assert fair.budgets[0].promised == fair.budgets[0].realised == 0.0  # nothing runs at T = 0
    for check, expected in zip(fair.budgets, programs["fair"].expected, strict=True):
        assert check.promised == pytest.approx(float(expected))  # no program input quality
        assert abs(check.realised - check.promised) <= max(0.01, 3 * check.se)
        assert check.runs == RUNS and check.over_budget == check.failed == 0
        assert check.no_result == (RUNS if check.total == 0 else 0)  # polish gets no time at 0
        assert check.se == check.se_runs > 0 or check.total == 0
        assert check.se_promise == 0.0  # an exact table
        assert check.qualities.shape == check.time_used.shape == (RUNS,)
        assert check.time_used.max() <= check.total
    assert (fair.schema, fair.problems, fair.scored, fair.seed) == (
        "fair",
        "HiddenNumbers",
        True,
        0,
    )


def test_a_promise_made_on_inputs_unlike_the_programs_fails(
    programs: dict[str, CompiledProgram],
) -> None:
    """`polish` was measured on estimates that err above or below the truth alike; `guess-low`
    errs below only, which its quality does not say: wherever `polish` runs, the program
    delivers about (1 - q) / 2 less than it is promised, far outside the tolerance."""
    low = verify(programs["low"], lab.HiddenNumbers(), runs=RUNS)
    assert not low.passed
    assert [c.total for c in low.failed] == [float(t) for t in lab.TOTALS[1:]]
    for check in low.failed:
        assert check.realised < check.promised - 0.04
        assert check.z < -10 and check.over_budget == 0
    assert low.budgets[0].passed


def test_a_run_over_its_budget_fails_its_budget(programs: dict[str, CompiledProgram]) -> None:
    over = verify(programs["over"], lab.HiddenNumbers(), runs=5, budgets=[0, 4])
    assert [(c.total, c.realised, c.over_budget, c.passed) for c in over.budgets] == [
        (0.0, 1.0, 5, False),
        (4.0, 1.0, 5, False),
    ]
    assert over.budgets[1].time_used.tolist() == [5.0] * 5
    assert "T = 4: 5 of 5 runs over budget" in format_verification(over)


def test_workers_give_the_same_runs(
    programs: dict[str, CompiledProgram], fair: Verification
) -> None:
    spread = verify(programs["fair"], lab.HiddenNumbers(), runs=RUNS, workers=2, chunk_size=7)
    assert spread == fair
    assert [c.qualities.tolist() for c in spread.budgets] == [
        c.qualities.tolist() for c in fair.budgets
    ]


def test_a_budget_checked_alone_meets_the_same_problems(
    programs: dict[str, CompiledProgram], fair: Verification
) -> None:
    alone = verify(programs["fair"], lab.HiddenNumbers(), runs=RUNS, budgets=[8.0, 2])
    assert [c.total for c in alone.budgets] == [2.0, 8.0]
    assert alone.budgets == (fair.budgets[1], fair.budgets[4])


def test_another_seed_other_problems(programs: dict[str, CompiledProgram]) -> None:
    one = verify(programs["fair"], lab.HiddenNumbers(), runs=20, budgets=[4], seed=1)
    two = verify(programs["fair"], lab.HiddenNumbers(), runs=20, budgets=[4], seed=2)
    assert one.budgets[0].qualities.tolist() != two.budgets[0].qualities.tolist()


def test_without_a_score_a_run_counts_the_quality_its_result_reports(
    programs: dict[str, CompiledProgram], fair: Verification
) -> None:
    """The modules report their true quality, so the realised means are the scored ones."""
    reported = verify(programs["fair"], ProgramProblems.of(lab.Unscored()), runs=RUNS)
    assert reported.scored is False and reported.problems == "Unscored"
    assert [c.realised for c in reported.budgets] == pytest.approx(
        [c.realised for c in fair.budgets]
    )


class _WithStandardError:
    """A compiled program whose table is estimated by sampling, with this standard error."""

    def __init__(self, compiled: CompiledProgram, error: float) -> None:
        self._compiled = compiled
        self.standard_error = np.full(compiled.expected.shape, error)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._compiled, name)


def test_the_tables_own_standard_error_widens_the_tolerance(
    programs: dict[str, CompiledProgram],
) -> None:
    sampled: Any = _WithStandardError(programs["low"], 0.05)
    low = verify(sampled, lab.HiddenNumbers(), runs=RUNS, budgets=[10, 12])
    for check in low.budgets:
        assert check.se_promise == pytest.approx(0.05)
        assert check.se == pytest.approx(np.hypot(check.se_runs, 0.05))
        assert check.tolerance == pytest.approx(3 * check.se) and check.passed


def test_the_result_as_data(fair: Verification) -> None:
    data = verification_to_dict(fair)
    assert list(data) == [
        "schema", "time_unit", "problem_set", "scored", "runs_per_budget", "seed", "passed",
        "min_tolerance", "sigmas", "budgets", "dependence_fit", "seconds",
    ]  # fmt: skip
    assert list(data["budgets"][1]) == [
        "budget", "expected_quality", "realised_quality", "se", "realised_quality_se",
        "expected_quality_se", "z", "tolerance", "runs", "overruns", "no_result", "failures",
        "passed", "expected_quality_if_dependent",
    ]  # fmt: skip
    assert data["passed"] is True and len(data["budgets"]) == len(lab.TOTALS)
    assert isinstance(fair.budgets[0], BudgetCheck)


def test_the_table(fair: Verification) -> None:
    text = format_verification(fair)
    lines = text.splitlines()
    assert lines[0] == (
        "schema fair: 200 runs per budget on HiddenNumbers problems, seed 0, scored by"
        " HiddenNumbers.score"
    )
    assert lines[1] == "  T (ticks)  promised  realised ± se      z  over budget   ok"
    assert lines[2].split() == ["0", "0.000", "0.000", "±", "0.000", "+0.00", "0/200", "yes"]
    assert lines[-1] == (
        "  passed at all 7 budgets (|realised - promised| <= max(0.01, 3 se), no run over its"
        " budget)"
    )


# --- errors ---------------------------------------------------------------------------------


class Failing:
    def __init__(self, how: str) -> None:
        self.how = how

    def instance(self, rng: np.random.Generator) -> Any:
        if self.how == "raises":
            raise RuntimeError("no more numbers\nsorry")
        if self.how == "not an instance":
            return (lab.hidden(rng),)
        if self.how == "two inputs":
            return Instance((lab.hidden(rng), 2))
        return Instance((lab.hidden(rng),))

    def score(self, instance: Instance, value: Any) -> float:
        if self.how == "score raises":
            raise ZeroDivisionError("division by zero")
        return 1.5


@pytest.mark.parametrize(
    ("how", "message"),
    [
        ("raises", "Failing.instance failed (run 0 at T = 4): RuntimeError: no more numbers"),
        ("not an instance", "Failing.instance: expected an Instance, got tuple (run 0 at T = 4)"),
        (
            "two inputs",
            "Failing.instance: its problem does not fit the program (run 0 at T = 4): schema"
            " 'fair' takes 1 input (x), got 2",
        ),
        (
            "score raises",
            "Failing.score failed (run 0 at T = 4): ZeroDivisionError: division by zero",
        ),
        ("score", "Failing.score: expected a quality in [0, 1], got 1.5 (run 0 at T = 4)"),
    ],
)
def test_a_problem_set_that_breaks_its_contract_is_named(
    programs: dict[str, CompiledProgram], how: str, message: str
) -> None:
    with pytest.raises(VerifyError) as error:
        verify(programs["fair"], Failing(how), runs=3, budgets=[4])
    assert str(error.value) == message


@pytest.mark.parametrize("workers", [1, 2])
def test_a_problem_sets_error_reaches_the_caller_from_a_worker(
    programs: dict[str, CompiledProgram], workers: int
) -> None:
    with pytest.raises(VerifyError, match=r"^Failing.instance failed \(run 0 at T = 4\)"):
        verify(programs["fair"], Failing("raises"), runs=3, budgets=[4], workers=workers)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (
            {"budgets": [5]},
            "budget 5 is not a total of the compiled table of schema 'fair' (0, 2, ..., 12)",
        ),
        ({"budgets": []}, "budgets: expected at least one total of the compiled table"),
        ({"runs": 0}, "runs: expected an integer >= 1, got 0"),
        ({"workers": 0}, "workers: expected an integer >= 1, got 0"),
        ({"seed": -1}, "seed: expected an integer >= 0, got -1"),
        ({"chunk_size": 0}, "chunk_size: expected an integer >= 1, got 0"),
        ({"mode": "process"}, "mode: expected Soft(), Hard() or Isolated(), got 'process'"),
    ],
)
def test_bad_arguments(
    programs: dict[str, CompiledProgram], options: dict[str, Any], message: str
) -> None:
    with pytest.raises(VerifyError) as error:
        verify(programs["fair"], lab.HiddenNumbers(), **options)
    assert str(error.value) == message


def test_a_problem_set_needs_an_instance_method(programs: dict[str, CompiledProgram]) -> None:
    with pytest.raises(VerifyError) as error:
        verify(programs["fair"], object(), runs=1)  # type: ignore[arg-type]
    assert str(error.value) == (
        "problems: expected ProgramProblems or a problem set with an instance(rng) method, got"
        " object"
    )


# --- the program problem sets of plugins ----------------------------------------------------


def test_program_problems_declares_a_compilation() -> None:
    declared = ProgramProblems.of(lab.HiddenNumbers(), time_grid=range(0, 9, 4), resolution=2)
    assert (declared.time_grid, declared.resolution) == ((0.0, 4.0, 8.0), 2.0)
    assert declared.scored and not ProgramProblems.of(lab.Unscored()).scored
    for bad, message in [
        ({"time_grid": []}, "time_grid: expected finite totals >= 0, got []"),
        ({"time_grid": [0, 4, 4]}, "time_grid: expected increasing totals, got [0, 4, 4]"),
        ({"resolution": 0}, "resolution: expected a finite number > 0, got 0"),
    ]:
        with pytest.raises(ValueError) as error:
            ProgramProblems.of(lab.HiddenNumbers(), **bad)
        assert str(error.value) == message
    with pytest.raises(TypeError, match=r"^ProgramProblems.problems: expected a problem set"):
        ProgramProblems.of(object())  # type: ignore[arg-type]


def test_a_plugin_declares_program_problems_by_schema_name() -> None:
    with pytest.raises(TypeError) as error:
        Plugin("bad", program_problems={"fair": lab.HiddenNumbers()})  # type: ignore[dict-item]
    assert str(error.value) == (
        "Plugin.program_problems['fair']: expected ProgramProblems (ProgramProblems.of(problems)),"
        " got HiddenNumbers"
    )
    plugin = lab.plugin()
    assert sorted(plugin.program_problems) == ["fair", "low", "over"]


class _EntryPoint:
    def __init__(self, name: str, loaded: Any) -> None:
        self.name, self.value, self._loaded = name, f"{name}:PLUGIN", loaded

    def load(self) -> Any:
        return self._loaded


@pytest.fixture
def plugged() -> Iterator[AnytimeLibrary]:
    shadow = ProgramProblems.of(lab.Unscored())
    second = Plugin("second", program_problems={"FAIR": shadow, "solo": shadow})
    yield AnytimeLibrary(
        [PluginSource([_EntryPoint("lab", lab.plugin()), _EntryPoint("second", second)])]  # type: ignore[list-item]
    )


def test_the_library_finds_a_schemas_problems_first_plugin_first(
    plugged: AnytimeLibrary,
) -> None:
    assert plugged.program_problems("Fair").problems.__class__ is lab.HiddenNumbers
    assert plugged.program_problems("solo").problems.__class__ is lab.Unscored
    with pytest.raises(LibraryError) as error:
        plugged.program_problems("fiar")
    assert str(error.value) == (
        "no program problem set is declared for schema 'fiar'; did you mean 'fair'?"
    )
    with pytest.raises(LibraryError) as error:
        plugged.program_problems("side-length")
    assert str(error.value) == (
        "no program problem set is declared for schema 'side-length' (declared for: fair, low,"
        " over, solo); a plugin declares them in Plugin.program_problems"
    )


# --- the shipped plugins' program problem sets ----------------------------------------------


def test_every_shipped_schema_has_program_problems() -> None:
    from anytime_navigation.resources import load_schema_file as navigation_schemas
    from anytime_routing.resources import load_schema_file as routing_schemas

    library = AnytimeLibrary.default()
    names = [
        *navigation_schemas("navigation.any").names,
        *navigation_schemas("obstacles.any").names,
        *routing_schemas().names,
    ]
    assert len(names) == 8
    for name in names:
        declared = library.program_problems(name)
        assert declared.scored and declared.time_grid is not None


@pytest.mark.parametrize(
    ("schema", "budgets"), [("navigate", [0, 250, 1000]), ("deliver", [0, 40])]
)
def test_a_shipped_schema_on_a_few_of_its_problems(schema: str, budgets: list[float]) -> None:
    """A smoke test (`anytime verify` on every budget with 100 runs is the real check: the
    tables are in the docs); the navigation planner's first search compiles it (numba)."""
    from anytime_navigation.resources import load_schema_file as navigation_schemas
    from anytime_routing.resources import load_schema_file as routing_schemas

    library = AnytimeLibrary.default()
    declared = library.program_problems(schema)
    schemas = navigation_schemas("navigation.any") if schema == "navigate" else routing_schemas()
    assert declared.time_grid is not None
    (compiled,) = compile_file(
        schemas, library, declared.time_grid, schema=schema, resolution=declared.resolution
    )
    checked = verify(compiled, declared, runs=4, budgets=budgets)
    assert [c.total for c in checked.budgets] == budgets
    assert all(c.over_budget == 0 for c in checked.budgets)
    assert checked.budgets[0].realised == 0.0 and checked.budgets[-1].realised > 0.5


def test_a_module_known_by_its_profile_alone_cannot_run() -> None:
    from pathlib import Path

    from anytime.library import LibraryEntry

    guess, _, polish, _ = lab.modules()
    library = AnytimeLibrary()
    assert isinstance(guess.profile_source, ConditionalPerformanceProfile)
    library.add(LibraryEntry.of_profile(guess.profile_source, Path("guess.yaml")))
    library.add(LibraryEntry.of_module(polish))
    (fair, *_) = compile_file(
        parse_schemas(lab.SCHEMAS.splitlines()[1], "lab.any", library.known_functions()),
        library,
        lab.TOTALS,
    )
    with pytest.raises(VerifyError) as error:
        verify(fair, lab.HiddenNumbers(), runs=2, budgets=[4])
    assert str(error.value) == (
        "schema 'fair' cannot run (run 0 at T = 4): schema 'fair': 'guess' is known only by its"
        " profile (no code to run)"
    )


class Roughs:
    """Problems for `refine`: an estimate of a random quality from 0.3 to 1, above or below
    the hidden number alike, as `polish` was measured on."""

    def instance(self, rng: np.random.Generator) -> Instance:
        q = float(rng.uniform(0.3, 1.0))
        rough, problem = lab.Roughs().instance(rng, (q,)).args
        return Instance((rough, problem), problem.x)

    def score(self, instance: Instance, value: Any) -> float:
        return lab.quality(value, instance.reference)


def test_the_promise_is_read_at_each_problems_input_qualities() -> None:
    library = lab.library()
    schemas = parse_schemas("(defschema refine (rough x) (polish rough x))", "refine.any", None)
    (refine,) = compile_file(schemas, library, [0, 1, 2, 4], input_quality=lab.POLISH_QUALITIES)
    assert refine.model.quality_inputs == ("rough",)
    checked = verify(refine, Roughs(), runs=RUNS)
    assert checked.passed
    ones = verify(refine, ProgramProblems.of(Roughs()), runs=RUNS, budgets=[2])
    rng_qualities = []
    for i in range(RUNS):  # the problems run 2's draws: SeedSequence(0, spawn_key=(2, i))
        rng = np.random.default_rng(np.random.SeedSequence(0, spawn_key=(2, i)))
        rng_qualities.append(Roughs().instance(rng).args[0].quality)
    expected = refine.profile.interpolate(
        refine.expected, np.array(rng_qualities)[:, None], np.full(RUNS, 2.0)
    )
    assert ones.budgets[0].promised == pytest.approx(float(expected.mean()))
    assert 0.5 < ones.budgets[0].promised < float(refine.expected[-1, 2])


class _RoundedAlike(lab.HiddenNumbers):
    """Scores every result 0.7, as arithmetic on each problem's own numbers gives it: equal
    but for the last bits."""

    def score(self, instance: Any, value: Any) -> float:
        x = float(instance.reference)
        return (0.7 * x) / x


def test_scores_alike_but_for_rounding_have_no_standard_error(
    programs: dict[str, CompiledProgram],
) -> None:
    """Their standard deviation is rounding (about 1e-17): z divided by it was 1e16."""
    (check,) = verify(programs["fair"], _RoundedAlike(), runs=20, budgets=[4]).budgets
    assert np.ptp(check.qualities) > 0  # the scores do differ, in their last bits
    assert (check.se, check.se_runs) == (0.0, 0.0)
    assert check.realised == pytest.approx(0.7, abs=1e-12)
    assert check.z == pytest.approx((check.realised - check.promised) * 20)
