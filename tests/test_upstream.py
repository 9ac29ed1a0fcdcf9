"""Measuring a module where the program puts it (`measure_upstream`, `anytime profile
--upstream`): on the lab of tests/verify_modules.py, `polish` was measured on estimates that
err on either side, but the schema `low` feeds it `guess-low`'s, which err below only, where
polish cannot help: `anytime verify` fails the promise, and after `--upstream` it holds."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import verify_modules as lab

from anytime.compiler import compile_file
from anytime.library import AnytimeLibrary, LibraryError, Plugin, PluginSource
from anytime.measure.upstream import PROBES, UpstreamError, measure_upstream
from anytime.problems import ProgramProblems
from anytime.verification import verify

Cli = Callable[..., tuple[int, str, str]]

#: Every tick from 0 to 12: thirteen budgets.
TOTALS = list(range(13))


class _EntryPoint:
    def __init__(self, name: str, loaded: Any) -> None:
        self.name, self.value, self._loaded = name, f"{name}:plugin", loaded

    def load(self) -> Any:
        return self._loaded


@pytest.fixture(scope="module")
def library() -> AnytimeLibrary:
    return AnytimeLibrary([PluginSource([_EntryPoint("lab", lab.plugin())])])  # type: ignore[list-item]


def checked(library: AnytimeLibrary) -> list[bool]:
    compiled = compile_file(lab.schemas(), library, TOTALS, schema="low", resolution=1.0)[-1]
    result = verify(compiled, library.program_problems("low"), runs=150, seed=7)
    return [check.passed for check in result.budgets]


def test_verify_catches_the_wrong_promise_and_upstream_measuring_fixes_it(
    library: AnytimeLibrary,
) -> None:
    """Before: the promise fails wherever polish runs (11 of 13 budgets). Measured on
    guess-low's own estimates, the first round moves the table far and the later ones by no
    more than the measurement's noise (a cell the probes rarely reach is measured on a small
    pool of inputs, reused): the fixed point within 3 rounds, and the promise holds at 12 or
    more of the 13 budgets; the cells the program never feeds (quality 0.3) keep their profile."""
    before = checked(library)
    assert sum(before) == 2, before
    measured = measure_upstream("polish", lab.schemas(), "low", library, trials=60, rounds=3)
    assert measured.converged and len(measured.rounds) <= 3
    first, *later = measured.rounds
    assert first.change > 0.1
    assert all(r.change <= max(measured.tolerance, r.noise) for r in later)
    assert (first.reached, first.cells) == (6, 8)
    after = checked(library.with_profile("polish", measured.profile))
    assert sum(after) >= 12, after
    old = library["polish"].profile
    assert old is not None
    np.testing.assert_array_equal(measured.profile.probability[0], old.probability[0])
    assert not np.array_equal(measured.profile.probability[-2], old.probability[-2])


class Counting:
    """A program problem set that counts the problems drawn: one a program run."""

    def __init__(self, problems: Any) -> None:
        self.problems, self.drawn = problems, 0

    def instance(self, rng: np.random.Generator) -> Any:
        self.drawn += 1
        return self.problems.instance(rng)

    def __getattr__(self, name: str) -> Any:  # score, and score_step where it has one
        return getattr(self.problems, name)


def test_trials_take_their_inputs_from_the_probes_pools(library: AnytimeLibrary) -> None:
    """The probes' inputs are pooled by cell and the trials take from the pools: one round
    runs the program PROBES times, and some more for the trials of a cell whose pool is thin
    (fewer than 80 inputs) but not rare (accepted in at least 1 of FRESH_DRAWS runs): here
    one, of about 55. Each trial drew at least one program run before (PROBES + 6 x 80 at
    least). A cell's samples are the pool's effective count, fewer than its trials; an
    unreached cell keeps its profile's."""
    low = library.program_problems("low")
    counting = Counting(low.problems)
    problems = ProgramProblems.of(counting, time_grid=low.time_grid, resolution=low.resolution)
    measured = measure_upstream(
        "polish", lab.schemas(), "low", library, trials=80, rounds=1, problems=problems
    )
    (round_,) = measured.rounds
    assert round_.reached == 6
    assert PROBES < counting.drawn < PROBES + 6 * 80
    samples = measured.profile.samples
    assert samples is not None
    old = library["polish"].profile
    assert old is not None and old.samples is not None
    np.testing.assert_array_equal(samples[0], old.samples[0])  # quality 0.3: not reached
    pooled = samples[1:-1, 0]
    assert np.all((pooled > 0) & (pooled < 80)), pooled
    assert np.all(samples[1:-1] == samples[1:-1, :1])  # the same at every time


def test_the_number_of_probes_is_asked(library: AnytimeLibrary) -> None:
    low = library.program_problems("low")
    counting = Counting(low.problems)
    problems = ProgramProblems.of(counting, time_grid=low.time_grid, resolution=low.resolution)
    measure_upstream(
        "polish", lab.schemas(), "low", library, trials=5, rounds=1, problems=problems, probes=200
    )
    assert 200 <= counting.drawn < PROBES
    with pytest.raises(UpstreamError) as raised:
        measure_upstream("polish", lab.schemas(), "low", library, trials=5, probes=0)
    assert str(raised.value) == "probes: expected a whole number >= 1, got 0"


def test_the_same_seed_gives_the_same_profile_on_any_workers() -> None:
    """Pools are drawn in the parent from the seed, and each trial chooses (and draws fresh
    inputs, as some do with 80 trials: see above) with its own stream: one worker and two
    measure the same profile. (The lab's
    modules as they are importable, so that they travel to the workers; their profiles are
    given to the library.)"""
    importable = (lab.guess, lab.guess_low, lab.polish)
    plugin = Plugin("lab", importable, program_problems=lab.plugin().program_problems)
    library = AnytimeLibrary([PluginSource([_EntryPoint("lab", plugin)])])  # type: ignore[list-item]
    for measured in lab.modules()[: len(importable)]:
        assert measured.profile_source is not None
        library = library.with_profile(measured.name, measured.profile_source)  # type: ignore[arg-type]
    profiles = [
        measure_upstream(
            "polish", lab.schemas(), "low", library, trials=80, rounds=2, workers=workers
        ).profile
        for workers in (1, 2)
    ]
    one, two = profiles
    for table in ("probability", "mean_table", "std", "samples", "bin_mean", "no_result_table"):
        np.testing.assert_array_equal(getattr(one, table), getattr(two, table), err_msg=table)
    assert one.step == two.step


def test_a_module_without_quality_inputs_is_measured_on_the_programs_problems(
    library: AnytimeLibrary,
) -> None:
    """`guess` takes no quality-carrying input: every call the program makes is a trial's
    input (its grid has one cell, which the program reaches); it is the program's output. (It
    failed: the distance to an empty cell was the max of nothing.)"""
    schemas = lab.parse_schemas("(defschema plain (x) (guess x))", "p.any")
    problems = ProgramProblems.of(lab.HiddenNumbers(), time_grid=TOTALS, resolution=1.0)
    measured = measure_upstream("guess", schemas, "plain", library, trials=40, problems=problems)
    assert [(r.reached, r.cells) for r in measured.rounds] == [(1, 1)] * len(measured.rounds)
    # The program feeds it what its own problem set does: the table moves by noise only.
    assert all(r.change <= r.noise for r in measured.rounds)


def test_a_module_the_schema_does_not_call_once_is_refused(library: AnytimeLibrary) -> None:
    with pytest.raises(UpstreamError) as raised:
        measure_upstream("guess", lab.schemas(), "low", library, trials=2)
    assert str(raised.value) == (
        "schema 'low' does not call module 'guess' (outside an if's branches and called"
        " schemas): measure it on its own problem set, or on a schema that calls it once"
    )


def test_a_schema_without_problems_is_refused() -> None:
    bare = AnytimeLibrary([PluginSource([_EntryPoint("lab", Plugin("lab", lab.modules()))])])  # type: ignore[list-item]
    with pytest.raises(LibraryError) as raised:
        measure_upstream("polish", lab.schemas(), "low", bare, trials=2)
    assert str(raised.value).startswith("no program problem set is declared for schema 'low'")


def test_an_inner_module_needs_its_results_scored() -> None:
    """`guess-low` is not the output of `low`: its results can only be scored by a problem set
    that scores intermediate results."""
    unscored = ProgramProblems.of(lab.HiddenNumbers(), time_grid=TOTALS, resolution=1.0)
    plugin = Plugin("lab", lab.modules(), program_problems={"twice": unscored})
    library = AnytimeLibrary([PluginSource([_EntryPoint("lab", plugin)])])  # type: ignore[list-item]
    schemas = lab.parse_schemas(
        "(defschema twice (x) (polish (polish (guess x) x) x))", "t.any", library.known_functions()
    )
    with pytest.raises(UpstreamError) as raised:
        measure_upstream("guess", schemas, "twice", library, trials=2)
    assert str(raised.value) == (
        "'guess' is not the output of schema 'twice', so its results are scored by the"
        " schema's problem set (HiddenNumbers): give it a score_step(instance, module, value)"
        " method"
    )


@pytest.fixture
def lab_any(lab_plugin: Path) -> str:
    """The lab's schema file, with the lab plugin installed (and no other)."""
    (lab_plugin / "lab.any").write_text(lab.SCHEMAS)
    return "lab.any"


def test_the_command_measures_round_by_round(cli: Cli, lab_any: str) -> None:
    code, out, err = cli(
        "profile", "polish", "--upstream", lab_any, "--schema", "low", "--trials", "30",
        "--rounds", "1", "--quiet", "-o", "polish.yaml",
    )  # fmt: skip
    assert (code, err) == (0, "")
    assert out.splitlines() == [
        "polish on schema low: 1 rounds, not converged: the last round moved the table by"
        " 0.1487, more than 0.005: give more --rounds",
        "wrote polish.yaml",
    ]
    assert Path("polish.yaml").exists()


def test_a_change_within_a_small_pools_noise_asks_for_more_probes(cli: Cli, lab_any: str) -> None:
    """Two rounds with 60 trials: the second moves the table by more than 0.005 but within
    the noise, which is the cell 0.4's, measured on a pool of 9 inputs: more trials would
    reuse them, more probes add to them."""
    code, out, err = cli(
        "profile", "polish", "--upstream", lab_any, "--schema", "low", "--trials", "60",
        "--rounds", "2", "--quiet", "-o", "polish.yaml",
    )  # fmt: skip
    assert (code, err) == (0, "")
    assert out.splitlines()[0] == (
        "polish on schema low: 2 rounds, not converged: the last round moved the table by"
        " 0.0061, more than 0.005, within the measurement's noise, most of it in a cell"
        " measured on a few inputs of the program, reused: measure with more --probes"
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--schema", "low"], "--schema NAME goes with --upstream SCHEMA_FILE"),
        (["--probes", "10"], "--probes N goes with --upstream SCHEMA_FILE"),
        (["--upstream", "lab.any", "--dynamic"], "--dynamic does not go with --upstream"),
    ],
)
def test_usage_errors(cli: Cli, lab_any: str, args: list[str], message: str) -> None:
    code, out, err = cli("profile", "polish", *args)
    assert (code, out) == (2, "")
    assert err.splitlines()[-1].endswith(f"error: {message}")


def test_a_file_of_several_schemas_needs_one_named(cli: Cli, lab_any: str) -> None:
    code, out, err = cli("profile", "polish", "--upstream", lab_any, "--quiet")
    assert (code, out) == (1, "")
    assert err == (
        "anytime: error: lab.any defines 3 schemas: say which one feeds the module with"
        " --schema NAME\n"
    )
