"""A module's step: the profile carries it (validated, saved, loaded) and the builder measures
it, the largest gap between an interruptible module's results (from its start, and to its end)
or the most a contract module used past its allocation, the maximum over all trials."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from toy_modules import TIME, toy_registry

from anytime.errors import ProfileError
from anytime.measure.builder import Instance, build_profile
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.profiles import tabulate
from anytime.profiles.io import load_profile, profile_from_dict, profile_to_dict, save_profile
from anytime.runtime.modes import SOFT

# Modules at the top level of this file: worker processes import them by reference.
STEPS = Registry()


@interruptible("gaps", inputs=[], registry=STEPS)
def gaps(ctx: Context, work: Sequence[float], tail: float) -> Iterator[Result]:
    """Works `work[i]` ticks before its i-th result, then `tail` ticks before it returns."""
    for n, amount in enumerate(work):
        ctx.tick(amount)
        yield Result(n, 1.0)
    ctx.tick(tail)


@contract("overshoot", inputs=[], registry=STEPS)
def overshoot(ctx: Context, extra: float, outcome: str) -> Result | None:
    """Uses its allocation plus `extra` (minus, if negative) and returns, returns None, or
    raises, as `outcome` says."""
    ctx.tick(max(0.0, ctx.allocation + extra))
    if outcome == "raise":
        raise RuntimeError("failed after its work")
    return None if outcome == "none" else Result("done", 1.0)


@interruptible("watcher", inputs=[], registry=STEPS)
def watcher(ctx: Context, first: float, chunk: float, watches: bool) -> Iterator[Result]:
    """One result after `first` ticks, then works `chunk` ticks at a time, until its time runs
    out if it `watches`, else for 100 ticks."""
    ctx.tick(first)
    yield Result("first", 0.5)
    done = 0.0
    while not ctx.expired if watches else done < 100:
        ctx.tick(chunk)
        done += chunk


class Given:
    """Hands out the given argument tuples in turn (the builder in this process makes trials
    in order, one call per run: per trial for interruptible, per trial and time for contract)."""

    def __init__(self, args: Sequence[tuple[Any, ...]]) -> None:
        self.args = list(args)
        self.made: list[tuple[Any, ...]] = []

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        made = self.args[len(self.made) % len(self.args)]
        self.made.append(made)
        return Instance(made)

    def score(self, instance: Instance, value: Any) -> float:
        return 1.0


class Drawn:
    """Random gap sequences, drawn from the trial's stream (picklable: no state)."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        work = [float(x) for x in rng.integers(0, 9, size=int(rng.integers(0, 6)))]
        return Instance((work, float(rng.integers(0, 9))))

    def score(self, instance: Instance, value: Any) -> float:
        return 1.0


def reference_step(work: Sequence[float], tail: float, allocation: float) -> float:
    """The step of one run of `gaps` as the builder defines it, computed independently: the
    gaps between the moments it gives control back, up to the first yield at or past the
    allocation (which ends the run, as `run` ends a run at a result registered at its
    allocation), else to its return. (Its stretch after its last result is one tick,
    so a return right after the tick that spent its time counts that tick: the same gap.)"""
    clock, moments = 0.0, [0.0]
    for amount in work:
        clock += amount
        moments.append(clock)
        if clock >= allocation:
            return float(max(np.diff(moments)))
    return float(max([*np.diff(moments), tail]))


runs = st.lists(
    st.tuples(
        st.lists(st.integers(0, 20).map(float), max_size=6),
        st.integers(0, 20).map(float),
    ),
    min_size=1,
    max_size=5,
)


@settings(max_examples=60, deadline=None)
@given(runs)
def test_the_step_is_the_largest_gap_when_every_run_ends_by_itself(
    trials: list[tuple[list[float], float]],
) -> None:
    longest = max(sum(work) + tail for work, tail in trials)
    problems = Given(trials)
    build = build_profile(  # in this process: the problem set records what it made
        gaps, problems, time=[0, longest + 1], trials=len(trials), progress=False, mode=SOFT
    )
    assert [made for made in problems.made] == trials
    assert build.profile.step == max(max([*work, tail]) for work, tail in trials)


@settings(max_examples=100, deadline=None)
@given(runs, st.integers(0, 60).map(float))
def test_the_step_follows_its_definition_at_any_longest_time(
    trials: list[tuple[list[float], float]], allocation: float
) -> None:
    build = build_profile(
        gaps, Given(trials), time=[allocation], trials=len(trials), progress=False
    )
    want = max(reference_step(work, tail, allocation) for work, tail in trials)
    assert build.profile.step == want


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(-5, 5).map(float), st.sampled_from(["result", "none", "raise"])),
        min_size=1,
        max_size=4,
    )
)
def test_a_contract_step_is_the_most_a_run_used_past_its_allocation(
    trials: list[tuple[float, str]],
) -> None:
    time = [0, 3, 10]
    build = build_profile(overshoot, Given(trials), time=time, trials=len(trials), progress=False)
    # Every run counts, whatever it answered; one that used less than it was given counts 0.
    # (An allocation of 0 and a negative extra use nothing, so nothing past it either.)
    assert build.profile.step == max(0.0, *(extra for extra, _ in trials))
    assert build.failures == len(time) * sum(outcome == "raise" for _, outcome in trials)


@pytest.mark.parametrize(
    ("first", "chunk", "watches", "step"),
    [
        # A result after 3 ticks, then ticks of 1 or 7 until its time (60) runs out: it watches
        # its time between ticks, so it would stop within one tick of any deadline after its
        # result; its step is the longer of its first gap and its longest tick.
        (3.0, 1.0, True, 3.0),
        (3.0, 7.0, True, 7.0),
        (9.0, 7.0, True, 9.0),
        # Its first result past the longest time ends the run: that gap counts.
        (80.0, 1.0, True, 80.0),
        # One that does not watch its time works 100 ticks after its result, past its
        # allocation: the whole stretch counts.
        (3.0, 1.0, False, 100.0),
        (3.0, 7.0, False, 105.0),
    ],
)
def test_a_module_that_stops_when_its_time_runs_out_counts_its_longest_tick_after_its_result(
    first: float, chunk: float, watches: bool, step: float
) -> None:
    problems = Given([(first, chunk, watches)])
    build = build_profile(watcher, problems, time=[0, 60], trials=1, progress=False)
    assert build.profile.step == step


def test_the_step_does_not_depend_on_how_trials_are_run() -> None:
    kwargs: dict[str, Any] = {"time": [0, 10, 20, 30], "trials": 40, "seed": 7, "progress": False}
    one = build_profile(gaps, Drawn(), chunk_size=1, **kwargs)
    many = build_profile(gaps, Drawn(), chunk_size=13, **kwargs)
    pooled = build_profile(gaps, Drawn(), workers=2, **kwargs)
    assert one.profile.step == many.profile.step == pooled.profile.step
    assert one.profile == many.profile == pooled.profile
    assert one.profile.step is not None and 0 < one.profile.step <= 8


class Plain:
    """An instance with a quality-carrying input of the asked quality."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance(("x",))

    def score(self, instance: Instance, value: Any) -> float:
        return 1.0


def test_the_toy_modules_measured_steps() -> None:
    toys = toy_registry()
    steps = {}
    for name in ("sense", "guess", "refine"):
        module = toys.get(name)
        assert module is not None
        build = build_profile(
            module, Plain(), time=TIME, input_grids=[[0.0, 1.0]], trials=2, progress=False
        )
        steps[name] = build.profile.step
    # sense and refine yield at once, then every tick; guess uses exactly its allocation.
    assert steps == {"sense": 1.0, "guess": 0.0, "refine": 1.0}


def test_the_approach_toy_of_the_builder_tests_has_its_yield_interval_as_step() -> None:
    from test_builder import STEP, TIME, NoisyProblems, approach

    build = build_profile(
        approach, NoisyProblems(), time=TIME, input_grids=[[0.5, 1.0]], trials=3, progress=False
    )
    assert build.profile.step == STEP


# --- the profile's field ----------------------------------------------------------------------

PROFILE = tabulate(lambda t: np.minimum(t / 10, 1.0), time=[0, 5, 10], module="m")


def test_a_profile_has_no_step_unless_given() -> None:
    assert PROFILE.step is None
    stepped = attrs.evolve(PROFILE, step=3)
    assert stepped.step == 3.0 and isinstance(stepped.step, float)
    assert attrs.evolve(PROFILE, step=np.int64(2)).step == 2.0
    assert stepped != PROFILE and stepped == attrs.evolve(PROFILE, step=3.0)


@pytest.mark.parametrize(
    ("step", "shown"),
    [(-1, "-1"), (math.inf, "inf"), (math.nan, "nan"), ("3", "'3'"), (True, "True"), ([1], "[1]")],
)
def test_a_bad_step_is_refused_naming_the_field(step: Any, shown: str) -> None:
    with pytest.raises(ProfileError) as caught:
        attrs.evolve(PROFILE, step=step)
    assert str(caught.value) == (
        f"m: step: expected a finite number >= 0 (or None: unknown), got {shown}"
    )


# --- the file format ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("step", "text"),
    [
        (0.0, "0"),
        (3.0, "3"),
        (0.1 + 0.2, "0.30000000000000004"),
        (1e-12, "1.0e-12"),  # as YAML 1.1 reads it back: a dot and a signed exponent
        (2.0**60, "1.152921504606847e+18"),
    ],
)
def test_the_step_round_trips_through_the_file(tmp_path: Path, step: float, text: str) -> None:
    profile = attrs.evolve(PROFILE, step=step)
    path = tmp_path / "m.yaml"
    save_profile(profile, path)
    back = load_profile(path)
    assert back == profile and back.step == step
    assert path.read_text().splitlines()[:5] == [
        "format: anytime-profile/1",
        "module: m",
        "kind: interruptible",
        "time_unit: ticks",
        f"step: {text}",
    ]
    assert profile_from_dict(profile_to_dict(profile), "m.yaml") == profile


def test_a_file_without_a_step_has_none_and_is_written_without_one(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    save_profile(PROFILE, path)
    assert "step" not in path.read_text()
    assert load_profile(path).step is None
    shipped = Path(__file__).parent / "data" / "find-path.yaml"
    assert "step" not in shipped.read_text() and load_profile(shipped).step is None


def test_a_measured_profile_saves_its_step(tmp_path: Path) -> None:
    build = build_profile(gaps, Given([([2.0, 5.0], 1.0)]), time=[0, 10], trials=1, progress=False)
    path = tmp_path / "gaps.yaml"
    save_profile(build.profile, path)
    assert "step: 5\n" in path.read_text()
    assert load_profile(path).step == 5.0


FILE = (
    "format: anytime-profile/1\n"
    "module: m\n"
    "time: [0, 10]\n"
    "quality_bins: [0, 0.5, 1]\n"
    "step: {step}\n"
    "probability: [[1, 0], [0.5, 0.5]]\n"
)
EXPECTED = "expected a finite number >= 0 (the module's step, in time_unit), got"


@pytest.mark.parametrize(
    ("value", "column", "got"),
    [
        ("-1", 7, "-1"),
        ("-0.5", 7, "-0.5"),
        (".inf", 7, ".inf"),
        (".nan", 7, ".nan"),
        ("null", 7, "nothing (null)"),
        ("'3'", 7, "'3'"),
        ("true", 7, "true"),
        ("[1, 2]", 7, "a list of 2"),
        ("  {a: 1}", 9, "a mapping"),
        (
            "1e3",
            7,
            "'1e3' (YAML reads it as a string: write a dot and a signed exponent, as in 1.0e+3)",
        ),
    ],
)
def test_a_bad_step_in_a_file_names_the_file_line_and_column(
    tmp_path: Path, value: str, column: int, got: str
) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(FILE.format(step=value))
    with pytest.raises(ProfileError) as caught:
        load_profile(path)
    assert str(caught.value) == f"{path}:5:{column}: step: {EXPECTED} {got}"


def test_a_bad_step_in_a_mapping_names_the_file_alone() -> None:
    data = {"format": "anytime-profile/1", "time": [0], "quality_bins": [0, 1], "step": -2}
    data["probability"] = [[1]]
    with pytest.raises(ProfileError) as caught:
        profile_from_dict(data, "given.yaml")
    assert str(caught.value) == f"given.yaml: step: {EXPECTED} -2"


def test_a_misspelt_step_is_an_unknown_field_with_a_hint(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(FILE.format(step="1").replace("step:", "stpe:"))
    with pytest.raises(ProfileError, match=r"stpe: unknown field, did you mean 'step'\?"):
        load_profile(path)
