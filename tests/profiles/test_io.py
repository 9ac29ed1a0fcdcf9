"""The `anytime-profile/1` file format: what loads, what round-trips, and every refusal."""

from collections.abc import Callable
from pathlib import Path

import attrs
import numpy as np
import pytest
import yaml

from anytime.errors import ProfileError
from anytime.profiles import (
    ConditionalPerformanceProfile,
    Exponential,
    PerformanceProfile,
    VisionHyperbola,
    default_bins,
    point_mass,
    tabulate,
)
from anytime.profiles.io import (
    MAX_CELLS,
    load_profile,
    profile_from_dict,
    profile_to_dict,
    save_profile,
)

DATA = Path(__file__).parent / "data"

# --- an example of the format (docs/profiles.md) ---------------------------------------------


def test_design_example_loads() -> None:
    profile = load_profile(DATA / "find-path.yaml")
    assert profile.module == "find-path"
    assert profile.kind == "interruptible"
    assert profile.time_unit == "ticks"
    assert profile.inputs == ("domain",)
    assert np.array_equal(profile.input_grids[0], [0.8, 0.9, 1.0])
    assert np.array_equal(profile.time, [0, 100, 200, 400])
    assert np.array_equal(profile.bins, [0, 0.25, 0.5, 0.75, 1])
    assert profile.probability.shape == (3, 4, 4)
    assert np.array_equal(profile.probability[0, 1], [0.5, 0.5, 0, 0])
    assert np.array_equal(profile.probability[2, 3], [0, 0, 0, 1])
    assert profile.samples is not None and profile.samples.shape == (3, 4)
    assert profile.mean is None and profile.std is None
    # Bin midpoints are 0.125, 0.375, 0.625, 0.875: at domain 1.0 and t=400 all mass is in the top.
    assert profile.expected([1.0], 400) == 0.875
    assert profile.expected([0.8], 100) == 0.25


def test_expected_form_is_a_point_mass_that_keeps_the_exact_quality(tmp_path: Path) -> None:
    path = tmp_path / "vision.yaml"
    path.write_text(
        "format: anytime-profile/1\n"
        "kind: contract\n"
        "time_unit: seconds\n"
        "time: [0, 0.5, 1.5]\n"
        "quality_bins: [0, 0.25, 0.5, 0.75, 1]\n"
        "expected: [0, 0.3, 1]\n"
    )
    profile = load_profile(path)
    assert profile.module == "vision"  # the file's stem
    assert (profile.kind, profile.time_unit, profile.inputs) == ("contract", "seconds", ())
    assert np.array_equal(profile.probability, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]])
    assert profile.mean is not None and np.array_equal(profile.mean, [0, 0.3, 1])
    assert profile.expected(np.zeros((3, 0)), [0.5, 1.0, 1.5]).tolist() == [0.3, 0.65, 1.0]


def test_rows_within_the_tolerance_load(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(SMALL.replace("[0.5, 0.5]", "[0.5, 0.5000009]"))
    assert load_profile(path).probability[1, 1] == 0.5000009


# --- round trips -----------------------------------------------------------------------------


def _measured() -> ConditionalPerformanceProfile:
    """A measured-looking profile: arbitrary floats, sample counts, means and deviations."""
    rng = np.random.default_rng(7)
    probability = rng.dirichlet(np.ones(5), size=(2, 3, 4))
    return ConditionalPerformanceProfile(
        input_grids=[[0.5, 1.0], [0.1, 1 / 3, 0.9]],
        inputs=["map", "sensor"],
        time=[0, 1e-7, 12.5, 1e17],
        bins=default_bins(5),
        probability=probability,
        mean=probability @ default_bins(5)[1:],
        std=rng.uniform(0, 0.3, size=(2, 3, 4)),
        samples=rng.integers(0, 50, size=(2, 3, 4)),
        module="plan",
        kind="contract",
        time_unit="seconds",
    )


ROUND_TRIPS = {
    "design-example": lambda: load_profile(DATA / "find-path.yaml"),
    "measured-two-inputs": _measured,
    "tabulated-two-inputs": lambda: tabulate(
        lambda t, q1, q2: q1 * q2 * Exponential(0.02)(t),
        [0, 10, 50, 200],
        input_grids=[[0.2, 0.7, 1.0], [0.5, 1.0]],
        inputs=["map", "goal"],
        module="plan",
    ),
    "tabulated-no-inputs": lambda: tabulate(
        VisionHyperbola(t_a=2, q_a=0.3, t_b=9), np.linspace(0, 10, 21), module="vision"
    ),
    "point-mass-with-samples-and-std": lambda: attrs.evolve(
        tabulate(Exponential(0.1), [0, 5, 10], module="e"), samples=[3, 3, 4], std=[0, 0.01, 0]
    ),
    "mean-that-is-not-the-point-mass": lambda: PerformanceProfile(
        time=[0, 1],
        bins=[0, 0.5, 1],
        probability=[[0.5, 0.5], [0, 1]],
        mean=[0.5, 0.9],
        module="m",
    ),
    "unnamed-inputs": lambda: ConditionalPerformanceProfile(
        input_grids=[[0.25, 0.75]],
        time=[3],
        bins=[0.1, 0.6, 0.9],
        probability=[[[1, 0]], [[0.1, 0.9]]],
        module="anon",
    ),
}


@pytest.mark.parametrize("make", ROUND_TRIPS.values(), ids=ROUND_TRIPS.keys())
def test_save_then_load_gives_an_equal_profile(
    tmp_path: Path, make: Callable[[], ConditionalPerformanceProfile]
) -> None:
    profile = make()
    path = tmp_path / "p.yaml"
    save_profile(profile, path)
    loaded = load_profile(path)
    assert loaded == profile
    for name in ("probability", "mean", "std", "samples"):  # bit for bit, not within a tolerance
        a, b = getattr(profile, name), getattr(loaded, name)
        assert (a is None and b is None) or a.tobytes() == b.tobytes()
    save_profile(loaded, tmp_path / "again.yaml")
    assert (tmp_path / "again.yaml").read_text() == path.read_text()


def test_a_point_mass_profile_is_written_as_expected(tmp_path: Path) -> None:
    profile = tabulate(Exponential(0.5), [0, 1, 2], bins=[0, 0.5, 1], module="e")
    save_profile(profile, tmp_path / "e.yaml")
    assert (tmp_path / "e.yaml").read_text() == (
        "format: anytime-profile/1\n"
        "module: e\n"
        "kind: interruptible\n"
        "time_unit: ticks\n"
        "inputs: []\n"
        "input_quality: []\n"
        "time: [0, 1, 2]\n"
        "quality_bins: [0, 0.5, 1]\n"
        "expected: [0, 0.3934693402873666, 0.6321205588285577]\n"
    )


def test_a_measured_profile_is_written_with_its_tables(tmp_path: Path) -> None:
    profile = ConditionalPerformanceProfile(
        input_grids=[[0.5, 1]],
        inputs=["map"],
        time=[0, 10],
        bins=[0, 0.5, 1],
        probability=[[[1, 0], [0.75, 0.25]], [[1, 0], [0.1, 0.9]]],
        mean=[[0.1, 0.3], [0.2, 0.7]],
        std=[[0, 0.125], [0, 0.25]],
        samples=[[4, 4], [4, 10]],
        module="m",
    )
    save_profile(profile, tmp_path / "m.yaml")
    assert (tmp_path / "m.yaml").read_text() == (
        "format: anytime-profile/1\n"
        "module: m\n"
        "kind: interruptible\n"
        "time_unit: ticks\n"
        "inputs: [map]\n"
        "input_quality:\n"
        "  - [0.5, 1]\n"
        "time: [0, 10]\n"
        "quality_bins: [0, 0.5, 1]\n"
        "probability:\n"
        "  - - [1, 0]\n"
        "    - [0.75, 0.25]\n"
        "  - - [1, 0]\n"
        "    - [0.1, 0.9]\n"
        "mean:\n"
        "  - [0.1, 0.3]\n"
        "  - [0.2, 0.7]\n"
        "std:\n"
        "  - [0, 0.125]\n"
        "  - [0, 0.25]\n"
        "samples:\n"
        "  - [4, 4]\n"
        "  - [4, 10]\n"
    )


def test_hand_written_expected_file_keeps_its_form(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(SMALL.replace("probability: [[1, 0], [0.5, 0.5]]", "expected: [0.25, 0.8]"))
    save_profile(load_profile(path), tmp_path / "out.yaml")
    data = yaml.safe_load((tmp_path / "out.yaml").read_text())
    assert data["expected"] == [0.25, 0.8]
    assert "probability" not in data and "mean" not in data


def test_a_performance_profile_comes_back_with_equal_fields(tmp_path: Path) -> None:
    profile = PerformanceProfile(time=[0, 1], bins=[0, 0.5, 1], probability=[[1, 0], [0, 1]])
    save_profile(profile, tmp_path / "perf.yaml")
    loaded = load_profile(tmp_path / "perf.yaml")
    assert type(loaded) is PerformanceProfile  # a file without inputs is a PerformanceProfile
    assert loaded == attrs.evolve(profile, module="perf")  # named after the file


def test_dict_form_round_trips_without_a_file() -> None:
    profile = _measured()
    data = profile_to_dict(profile)
    assert list(data) == [
        "format",
        "module",
        "kind",
        "time_unit",
        "inputs",
        "input_quality",
        "time",
        "quality_bins",
        "probability",
        "mean",
        "std",
        "samples",
    ]
    assert profile_from_dict(data, "plan.yaml") == profile


# --- malformed files: one case per problem, the whole message --------------------------------

SMALL = (
    "format: anytime-profile/1\n"
    "module: m\n"
    "time: [0, 10]\n"
    "quality_bins: [0, 0.5, 1]\n"
    "probability: [[1, 0], [0.5, 0.5]]\n"
)
WITH_INPUT = (
    "format: anytime-profile/1\n"
    "inputs: [domain]\n"
    "input_quality: [[0.5, 1]]\n"
    "time: [0, 10]\n"
    "quality_bins: [0, 0.5, 1]\n"
    "probability: [[[1, 0], [0.5, 0.5]], [[1, 0], [0, 1]]]\n"
)
KNOWN = (
    "format, module, kind, time_unit, step, inputs, input_quality, time, quality_bins, probability,"
    " expected, mean, std, samples, bin_mean, no_result, modules, allocation, compiled"
)


def _replace(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new)


def _small(old: str, new: str) -> str:
    return _replace(SMALL, old, new)


def _with_input(old: str, new: str) -> str:
    return _replace(WITH_INPUT, old, new)


# id -> (file text, the message after the file name)
MALFORMED = {
    # not YAML, or not a mapping
    "unclosed-list": (
        "format: anytime-profile/1\ntime: [0, 10\n",
        ":3:1: not YAML: while parsing a flow sequence, expected ',' or ']',"
        " but got '<stream end>'",
    ),
    "tab-indent": (
        "format: anytime-profile/1\n\ttime: [0]\n",
        ":2:1: not YAML: while scanning for the next token,"
        " found character '\\t' that cannot start any token",
    ),
    "two-documents": (
        SMALL + "---\n" + SMALL,
        ":6:1: not YAML: expected a single document in the stream, but found another document",
    ),
    "control-character": (
        "format: anytime-profile/1\nmodule: a\x07\n",
        ":2:10: not YAML: unacceptable character #x0007: special characters are not allowed",
    ),
    "top-level-list": ("- 1\n- 2\n", ": top level: expected a mapping of fields, got a list of 2"),
    "empty-file": ("", ": top level: expected a mapping of fields, got nothing (null)"),
    "local-tag": (
        _small("module: m", "module: !thing m"),
        ":2:9: module: refused YAML tag '!thing' (expected plain data: numbers, strings, lists"
        " and mappings, got a tag)",
    ),
    # the version and the field names
    "missing-format": (
        _small("format: anytime-profile/1\n", ""),
        ": format: missing field (expected 'anytime-profile/1', got nothing)",
    ),
    "unknown-version": (
        _small("anytime-profile/1", "anytime-profile/2"),
        ": format: unknown format version (expected 'anytime-profile/1', got 'anytime-profile/2')",
    ),
    "version-as-number": (
        _small("anytime-profile/1", "1"),
        ": format: unknown format version (expected 'anytime-profile/1', got 1)",
    ),
    "misspelt-field": (
        _small("probability:", "probabilty:"),
        f": probabilty: unknown field, did you mean 'probability'? (expected one of {KNOWN};"
        " got 'probabilty')",
    ),
    "unknown-field": (
        SMALL + "colour: blue\n",
        f": colour: unknown field (expected one of {KNOWN}; got 'colour')",
    ),
    "number-as-field": (
        SMALL + "1: x\n",
        f": 1: unknown field (expected one of {KNOWN}; got 1)",
    ),
    "missing-time": (
        _small("time: [0, 10]\n", ""),
        ": time: missing field (expected a list of times, got nothing)",
    ),
    "missing-bins": (
        _small("quality_bins: [0, 0.5, 1]\n", ""),
        ": quality_bins: missing field (expected a list of bin edges, got nothing)",
    ),
    "neither-probability-nor-expected": (
        _small("probability: [[1, 0], [0.5, 0.5]]\n", ""),
        ": probability: missing field (expected probability or expected, got neither)",
    ),
    "both-probability-and-expected": (
        SMALL + "expected: [0, 1]\n",
        ": probability: expected exactly one of probability and expected, got both",
    ),
    "mean-with-expected": (
        _small("probability: [[1, 0], [0.5, 0.5]]", "expected: [0, 1]\nmean: [0, 1]"),
        ": mean: not allowed next to expected, which is the mean"
        " (expected mean only with probability, got both)",
    ),
    # wrong types
    "module-not-a-string": (
        _small("module: m", "module: [m]"),
        ": module: expected a name (a non-empty string), got a list of 1",
    ),
    "module-empty": (
        _small("module: m", "module: ''"),
        ": module: expected a name (a non-empty string), got ''",
    ),
    "module-a-date": (
        _small("module: m", "module: 2024-01-01"),
        ": module: expected a name (a non-empty string), got 2024-01-01 (a date)",
    ),
    "unknown-kind": (
        SMALL + "kind: anytime\n",
        ": kind: expected 'interruptible' or 'contract', got 'anytime'",
    ),
    "unknown-time-unit": (
        SMALL + "time_unit: ms\n",
        ": time_unit: expected 'ticks' or 'seconds', got 'ms'",
    ),
    "inputs-not-a-list": (
        _with_input("inputs: [domain]", "inputs: domain"),
        ": inputs: expected a list of names, got 'domain'",
    ),
    "input-name-not-a-string": (
        _with_input("inputs: [domain]", "inputs: [1]"),
        ": inputs[0]: expected a name (a non-empty string), got 1",
    ),
    "input-named-twice": (
        _with_input("inputs: [domain]", "inputs: [domain, domain]"),
        ": inputs[1]: expected distinct names, got 'domain' twice",
    ),
    "more-inputs-than-grids": (
        _with_input("inputs: [domain]", "inputs: [domain, goal]"),
        ": inputs: expected 1 name (one per input_quality grid), got 2",
    ),
    "inputs-without-grids": (
        _small("module: m", "inputs: [domain]"),
        ": inputs: expected 0 names (one per input_quality grid), got 1",
    ),
    "input-quality-not-a-list": (
        _with_input("input_quality: [[0.5, 1]]", "input_quality: 0.5"),
        ": input_quality: expected a list of grids (one per input), got 0.5",
    ),
    "input-grid-not-a-list": (
        _with_input("input_quality: [[0.5, 1]]", "input_quality: [0.5]"),
        ": input_quality[0]: expected a list of at least 1 number, got 0.5",
    ),
    "time-not-a-list": (
        _small("time: [0, 10]", "time: 10"),
        ": time: expected a list of at least 1 number, got 10",
    ),
    "time-empty": (
        _small("time: [0, 10]", "time: []"),
        ": time: expected a list of at least 1 number, got an empty list",
    ),
    "one-bin-edge": (
        _small("quality_bins: [0, 0.5, 1]", "quality_bins: [0]"),
        ": quality_bins: expected a list of at least 2 numbers, got a list of 1",
    ),
    "time-a-word": (
        _small("time: [0, 10]", "time: [0, ten]"),
        ": time[1]: expected a number, got 'ten'",
    ),
    "time-a-yaml-1.1-string": (
        _small("time: [0, 10]", "time: [0, 1e3]"),
        ": time[1]: expected a number, got '1e3'"
        " (YAML reads it as a string: write a dot and a signed exponent, as in 1.0e+3)",
    ),
    "time-a-boolean": (
        _small("time: [0, 10]", "time: [0, true]"),
        ": time[1]: expected a number, got true",
    ),
    "time-too-large": (
        _small("time: [0, 10]", "time: [0, 1" + "0" * 400 + "]"),
        ": time[1]: expected a finite number, got 1" + "0" * 400,
    ),
    # shapes, ragged lists included
    "probability-not-a-list": (
        _small("probability: [[1, 0], [0.5, 0.5]]", "probability: 1"),
        ": probability: expected a list of 2 (one per time), got 1",
    ),
    "probability-too-few-times": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, 0]]"),
        ": probability: expected a list of 2 (one per time), got a list of 1",
    ),
    "probability-ragged": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, 0], [1]]"),
        ": probability[1]: expected a list of 2 numbers (one per quality bin), got a list of 1",
    ),
    "probability-number-for-a-row": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, 0], 1]"),
        ": probability[1]: expected a list of 2 numbers (one per quality bin), got 1",
    ),
    "probability-list-for-a-number": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, [0]], [0.5, 0.5]]"),
        ": probability[0][1]: expected a number, got a list of 1",
    ),
    "probability-missing-input-axis": (
        _with_input("[[[1, 0], [0.5, 0.5]], [[1, 0], [0, 1]]]", "[[1, 0], [0.5, 0.5]]"),
        ": probability[0][0]: expected a list of 2 numbers (one per quality bin), got 1",
    ),
    "probability-one-input-row-short": (
        _with_input("[[[1, 0], [0.5, 0.5]], [[1, 0], [0, 1]]]", "[[[1, 0], [0.5, 0.5]]]"),
        ": probability: expected a list of 2 (one per domain quality), got a list of 1",
    ),
    "expected-wrong-shape": (
        _small("probability: [[1, 0], [0.5, 0.5]]", "expected: [[0, 1]]"),
        ": expected: expected a list of 2 numbers (one per time), got a list of 1",
    ),
    "samples-wrong-shape": (
        SMALL + "samples: [[10, 10]]\n",
        ": samples: expected a list of 2 numbers (one per time), got a list of 1",
    ),
    "std-a-matrix": (
        SMALL + "std: [[0, 0], [0, 0]]\n",
        ": std[0]: expected a number, got a list of 2",
    ),
    "too-many-cells": (
        "format: anytime-profile/1\n"
        f"input_quality: [{', '.join(['[' + ', '.join(['0.5'] * 100) + ']'] * 3)}]\n"
        f"time: [{', '.join(str(t) for t in range(100))}]\n"
        "quality_bins: [0, 1]\n"
        "probability: []\n",
        f": probability: expected at most {MAX_CELLS} cells, got shape [100, 100, 100, 100, 1]",
    ),
    # non-increasing grids (found by the profile class, prefixed with the file)
    "time-decreasing": (
        _small("time: [0, 10]", "time: [10, 0]"),
        ": time: expected increasing values, got 10 then 0",
    ),
    "bins-repeated": (
        _small("quality_bins: [0, 0.5, 1]", "quality_bins: [0, 0.5, 0.5]"),
        ": quality_bins: expected increasing values, got 0.5 then 0.5",
    ),
    "input-grid-decreasing": (
        _with_input("input_quality: [[0.5, 1]]", "input_quality: [[1, 0.5]]"),
        ": input_quality[0]: expected increasing values, got 1 then 0.5",
    ),
    # NaN, infinity, negative numbers
    "time-nan": (
        _small("time: [0, 10]", "time: [0, .nan]"),
        ": time[1]: expected a finite number, got .nan",
    ),
    "bins-infinite": (
        _small("quality_bins: [0, 0.5, 1]", "quality_bins: [0, 0.5, .inf]"),
        ": quality_bins[2]: expected a finite number, got .inf",
    ),
    "probability-minus-infinity": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, 0], [-.inf, 0.5]]"),
        ": probability[1][0]: expected a finite number, got -.inf",
    ),
    "time-negative": (
        _small("time: [0, 10]", "time: [-1, 10]"),
        ": time[0]: expected a number >= 0, got -1",
    ),
    "probability-negative": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, 0], [1.5, -0.5]]"),
        ": probability[1][1]: expected a number >= 0, got -0.5",
    ),
    "samples-negative": (
        SMALL + "samples: [3, -2]\n",
        ": samples[1]: expected a number >= 0, got -2",
    ),
    "std-nan": (SMALL + "std: [.NaN, 0]\n", ": std[0]: expected a finite number, got .nan"),
    # rows that do not sum to 1 (within 1e-6)
    "row-short": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, 0], [0.5, 0.4]]"),
        ": probability[1]: expected a row summing to 1 (within 1e-06), got 0.9",
    ),
    "row-just-outside-the-tolerance": (
        _small("[[1, 0], [0.5, 0.5]]", "[[1, 0], [0.5, 0.5000011]]"),
        ": probability[1]: expected a row summing to 1 (within 1e-06), got 1.0000011",
    ),
    "row-with-inputs": (
        _with_input("[[1, 0], [0, 1]]]", "[[1, 0], [0, 2]]]"),
        ": probability[1][1]: expected a row summing to 1 (within 1e-06), got 2",
    ),
    # qualities outside [0, 1]
    "bin-edge-above-one": (
        _small("quality_bins: [0, 0.5, 1]", "quality_bins: [0, 0.5, 1.5]"),
        ": quality_bins[2]: expected a quality in [0, 1], got 1.5",
    ),
    "input-quality-above-one": (
        _with_input("input_quality: [[0.5, 1]]", "input_quality: [[0.5, 1.25]]"),
        ": input_quality[0][1]: expected a quality in [0, 1], got 1.25",
    ),
    "expected-above-one": (
        _small("probability: [[1, 0], [0.5, 0.5]]", "expected: [0.5, 1.01]"),
        ": expected[1]: expected a quality in [0, 1], got 1.01",
    ),
    "expected-negative": (
        _small("probability: [[1, 0], [0.5, 0.5]]", "expected: [-0.5, 1]"),
        ": expected[0]: expected a number >= 0, got -0.5",
    ),
    "expected-below-the-bins": (
        _small("quality_bins: [0, 0.5, 1]\nprobability: [[1, 0], [0.5, 0.5]]", "")
        + "quality_bins: [0.5, 0.75, 1]\nexpected: [0.2, 1]\n",
        ": expected[0]: expected a quality within the bins [0.5, 1], got 0.2",
    ),
    "mean-above-one": (
        SMALL + "mean: [0.5, 2]\n",
        ": mean[1]: expected a quality in [0, 1], got 2",
    ),
}


@pytest.mark.parametrize(("text", "message"), MALFORMED.values(), ids=MALFORMED.keys())
def test_malformed_file_is_refused_with_its_file_field_and_problem(
    tmp_path: Path, text: str, message: str
) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    with pytest.raises(ProfileError) as caught:
        load_profile(path)
    assert str(caught.value) == f"{path}{message}"


def test_python_object_tag_is_refused_and_never_run(tmp_path: Path) -> None:
    canary = tmp_path / "canary"
    text = SMALL.replace(
        "module: m", f'module: !!python/object/apply:builtins.open ["{canary}", "w"]'
    )
    # The tag is live: an unsafe loader would create the canary file (checked on a copy).
    control = tmp_path / "control"
    yaml.unsafe_load(text.replace(str(canary), str(control))).get("module").close()
    assert control.exists()

    path = tmp_path / "evil.yaml"
    path.write_text(text)
    with pytest.raises(ProfileError) as caught:
        load_profile(path)
    assert str(caught.value) == (
        f"{path}:2:9: module: refused YAML tag '!!python/object/apply:builtins.open'"
        " (expected plain data: numbers, strings, lists and mappings,"
        " got a tag that would construct a Python object)"
    )
    assert not canary.exists()


def test_python_tag_deep_in_a_table_names_the_table(tmp_path: Path) -> None:
    path = tmp_path / "evil.yaml"
    path.write_text(
        SMALL.replace("[0.5, 0.5]", "[0.5, !!python/object/apply:os.getcwd []]"),
    )
    with pytest.raises(ProfileError) as caught:
        load_profile(path)
    assert str(caught.value) == (
        f"{path}:5:29: probability: refused YAML tag '!!python/object/apply:os.getcwd'"
        " (expected plain data: numbers, strings, lists and mappings,"
        " got a tag that would construct a Python object)"
    )


def test_unreadable_files(tmp_path: Path) -> None:
    missing = tmp_path / "missing.yaml"
    with pytest.raises(ProfileError) as caught:
        load_profile(missing)
    assert str(caught.value) == f"{missing}: cannot read the file: No such file or directory"

    with pytest.raises(ProfileError) as caught:
        load_profile(tmp_path)
    assert str(caught.value) == f"{tmp_path}: cannot read the file: Is a directory"

    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"format: \xff\n")
    with pytest.raises(ProfileError) as caught:
        load_profile(binary)
    assert str(caught.value) == (
        f"{binary}: cannot read the file: expected UTF-8 text, got byte 0xff at offset 8"
    )


def test_profile_from_dict_names_the_file_it_is_given() -> None:
    with pytest.raises(ProfileError) as caught:
        profile_from_dict({"format": "anytime-profile/1", "time": [0]}, "lib/plan.yaml")
    assert str(caught.value) == (
        "lib/plan.yaml: quality_bins: missing field (expected a list of bin edges, got nothing)"
    )
    data = {"format": "anytime-profile/1", "time": [0], "quality_bins": [0, 1], "expected": [1]}
    profile = profile_from_dict(data, "lib/plan.yaml")
    assert profile.module == "plan"
    assert np.array_equal(profile.probability, point_mass([1.0], [0, 1]))
