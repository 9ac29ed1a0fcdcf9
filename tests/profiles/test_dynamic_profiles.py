"""Dynamic profiles from recorded traces: the builder records the traces (the same for any
workers), `from_traces` counts transitions right, and both file formats round-trip exactly and
refuse bad files with their reason."""

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from anytime.errors import ProfileError
from anytime.library import AnytimeLibrary, LibraryEntry, ProfileDirectory
from anytime.measure.builder import (
    Instance,
    Measurement,
    ProfileRequest,
    build_profile,
    profile_module,
)
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.profiles.dynamic import OBSERVED, DynamicProfile, QualityTraces, entry_edges
from anytime.profiles.dynamic_io import (
    dynamic_profile_path,
    load_dynamic_profile,
    load_traces,
    save_dynamic_profile,
    save_traces,
)
from anytime.profiles.io import save_profile

# Toy modules live at the top level of this file: worker processes import them by reference.
TOYS = Registry()


@interruptible("climb", inputs=["x"], reports="estimate", registry=TOYS)
def climb(ctx: Context, x: Result, rng: np.random.Generator) -> Iterator[Result]:
    """Climbs by random steps to its input's quality; reports 1.2 times its quality."""
    q = 0.0
    while not ctx.expired:
        ctx.tick(5)
        q = min(x.quality, q + float(rng.uniform(0, 0.2)))
        yield Result(q, min(1.0, 1.2 * q))


@contract("guess", inputs=[], reports="estimate", registry=TOYS)
def guess(ctx: Context, rng: np.random.Generator) -> Result:
    ctx.tick(ctx.allocation)
    q = min(1.0, ctx.allocation / 100)
    return Result(q, 1.0 - q)  # a report that has it backwards


@interruptible("honest", inputs=[], registry=TOYS)
def honest(ctx: Context, rng: np.random.Generator) -> Iterator[Result]:
    q = 0.0
    while not ctx.expired:
        ctx.tick(10)
        q = min(1.0, q + 0.25)
        yield Result(q, q)


class ValueIsQuality:
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance((*input_qualities, rng))

    def score(self, instance: Instance, value: Any) -> float:
        return float(value)


TIME = [0, 10, 20, 40]


def traces_of(module: Any, **kwargs: Any) -> QualityTraces:
    options: dict[str, Any] = dict(time=TIME, trials=12, seed=3, traces=True) | kwargs
    build = build_profile(module, ValueIsQuality(), **options)
    assert build.traces is not None
    return build.traces


# --- the builder's traces --------------------------------------------------------------------


def test_the_traces_are_what_the_profile_is_tabulated_from() -> None:
    build = build_profile(
        climb, ValueIsQuality(), time=TIME, input_grids=[[0.5, 1.0]], trials=12, traces=True
    )
    traces = build.traces
    assert traces is not None and traces.quality.shape == (2, 12, 4)
    assert (traces.module, traces.reports, traces.inputs, traces.time_unit) == (
        "climb",
        "estimate",
        ("x",),
        "ticks",
    )
    assert build.profile.mean is not None
    np.testing.assert_array_equal(traces.quality.mean(axis=-2), build.profile.mean)
    assert not traces.scored[..., 0].any() and traces.scored[..., 1:].all()  # first yield at 5
    assert traces.estimate is not None
    np.testing.assert_array_equal(traces.estimate, np.minimum(1.0, 1.2 * traces.quality))


def test_without_traces_none_are_kept() -> None:
    build = build_profile(honest, ValueIsQuality(), time=TIME, trials=2)
    assert build.traces is None


def test_a_contract_module_reports_per_allocation_and_a_true_one_keeps_no_estimate() -> None:
    traces = traces_of(guess)
    assert traces.estimate is not None
    np.testing.assert_array_equal(traces.quality[0], [0, 0.1, 0.2, 0.4])
    np.testing.assert_array_equal(traces.estimate[0], [1, 0.9, 0.8, 0.6])
    honest_traces = traces_of(honest)
    assert honest_traces.estimate is None and honest_traces.reports == "true"


def test_one_and_two_workers_and_any_chunk_size_give_the_same_traces() -> None:
    kwargs: dict[str, Any] = dict(input_grids=[[0.5, 1.0]], trials=20)
    one = traces_of(climb, workers=1, **kwargs)
    two = traces_of(climb, workers=2, chunk_size=7, **kwargs)
    tiny = traces_of(climb, workers=1, chunk_size=1, **kwargs)
    assert one == two == tiny
    assert traces_of(climb, seed=4, **kwargs) != one


@interruptible("settle", inputs=["x"], registry=TOYS)
def settle(ctx: Context, x: Result, rng: np.random.Generator) -> Iterator[Result]:
    """Rises by 0.25 every 10 ticks and returns once it has reached its input's quality."""
    q = 0.0
    while not ctx.expired and q < x.quality:
        ctx.tick(10)
        q = min(x.quality, q + 0.25)
        yield Result(q, q)


def test_the_traces_say_when_each_run_ended() -> None:
    """A run that returns by itself ends its trace there; one still going at the last grid
    time (input 1.0 takes 40 ticks, its allocation) ends there."""
    traces = traces_of(settle, input_grids=[[0.5, 1.0]], trials=2)
    assert traces.finished is not None
    np.testing.assert_array_equal(traces.finished, [[20, 20], [40, 40]])
    np.testing.assert_array_equal(traces.end_index(), [[2, 2], [3, 3]])
    unknown = attrs.evolve(traces, finished=None)
    np.testing.assert_array_equal(unknown.end_index(), [[3, 3], [3, 3]])
    honest_traces = traces_of(honest, trials=2)  # never returns before its time is up
    assert honest_traces.finished is not None and np.all(honest_traces.finished == 40)


def test_a_finish_after_the_last_grid_time_is_refused() -> None:
    with pytest.raises(ProfileError) as raised:
        attrs.evolve(hand_made(), finished=[1.0, 2.5])
    assert str(raised.value) == (
        "hand: finished[1]: expected a time from 0 to the last grid time 2, got 2.5"
    )


def test_a_request_for_traces_gets_them() -> None:
    plan = Measurement.of(ValueIsQuality(), time=TIME)
    build = profile_module(honest, ProfileRequest(trials=3, traces=True), measurement=plan)
    assert build.traces is not None and build.traces.trials == 3


# --- from_traces on a hand-made case ---------------------------------------------------------


def hand_made(estimate: Any = None) -> QualityTraces:
    return QualityTraces(
        module="hand",
        time=[0, 1, 2],
        quality=[[0.0, 0.6, 0.8], [0.0, 0.2, 0.7]],
        scored=[[False, True, True], [False, True, True]],
        estimate=estimate,
        reports="true" if estimate is None else "estimate",
    )


def test_from_traces_counts_the_transitions() -> None:
    p = DynamicProfile.from_traces(hand_made(), bins=[0, 0.5, 1])
    np.testing.assert_array_equal(p.occupancy, [[1, 0], [0.5, 0.5], [0, 1]])
    # From time 0 both runs are in the low state: one stays, one rises. No run is high then,
    # so that row is the identity. From time 1 the low run rises and the high one stays.
    np.testing.assert_array_equal(p.transition, [[[0.5, 0.5], [0, 1]], [[0, 1], [0, 1]]])
    np.testing.assert_allclose(p.quality_mean, [[0, 0.75], [0.2, 0.6], [0.25, 0.75]])
    assert p.observation is None and p.samples == 2 and p.observed == "true"
    np.testing.assert_array_equal(p.transition_over(0, 2), [[0, 1], [0, 1]])
    # The unseen high state at time 0 stays high: its gain is from its midpoint to the mean.
    gain = [[0.4 - 0, 0.6 - 0.75], [0.75 - 0.2, 0.75 - 0.6]]
    np.testing.assert_allclose(p.expected_gain(), gain)


def test_entry_classes_split_a_bin_by_when_each_run_entered_it() -> None:
    """Two runs in the high bin at time 2: one since time 1, one since time 2. With a class per
    entry time the state tells them apart, and says which true qualities each holds."""
    p = DynamicProfile.from_traces(hand_made(), bins=[0, 0.5, 1], entered=[0, 1, 2, 3])
    assert p.classes == 3 and p.n_states == 6 and p.entered is not None
    # States: (low, entered 0..2), (high, entered 0..2). At time 2 run 1 is (high, 1), run 2
    # (high, 2); at time 1 run 1 is (high, 1), run 2 (low, 0).
    np.testing.assert_array_equal(p.occupancy[2], [0, 0, 0, 0, 0.5, 0.5])
    np.testing.assert_array_equal(p.occupancy[1], [0.5, 0, 0, 0, 0.5, 0])
    np.testing.assert_array_equal(p.transition[1][0], [0, 0, 0, 0, 0, 1])  # (low, 0) -> (high, 2)
    np.testing.assert_array_equal(p.transition[1][4], [0, 0, 0, 0, 1, 0])  # (high, 1) stays
    assert p.observation is not None and p.observation.shape == (3, 6, 2)
    np.testing.assert_array_equal(p.observation[2][4:], [[0, 1], [0, 1]])
    # Each state's own mean quality in its bin: 0.8 for the run there since 1, 0.7 since 2.
    np.testing.assert_allclose(p.quality_mean[2][4:, 1], [0.8, 0.7])
    assert [p.entry_class(j) for j in range(3)] == [0, 1, 2]
    np.testing.assert_array_equal(entry_edges(32, 8), [0, 1, 2, 3, 4, 7, 12, 20, 32])


def test_runs_that_ended_are_in_ended_states_of_their_own() -> None:
    """The first run returns at time 1 (its answer 0.6 from then on), the second runs to the
    end: from time 1 the first is in the ended state of the high bin, absorbing."""
    traces = attrs.evolve(hand_made(), finished=[1.0, 2.0])
    p = DynamicProfile.from_traces(traces, bins=[0, 0.5, 1], ends=True)
    assert p.ends and p.n_states == 4 and p.running_states == 2
    np.testing.assert_array_equal(p.state_bin, [0, 1, 0, 1])
    np.testing.assert_array_equal(p.occupancy, [[1, 0, 0, 0], [0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5]])
    np.testing.assert_array_equal(p.transition[0][0], [0.5, 0, 0, 0.5])  # half end, high
    np.testing.assert_array_equal(p.transition[1][3], [0, 0, 0, 1])  # ended stays ended
    np.testing.assert_array_equal(p.transition[1][0], [0, 1, 0, 0])  # the other rises
    with pytest.raises(ProfileError) as error:
        DynamicProfile.from_traces(hand_made(), ends=True)
    assert str(error.value) == ("hand: ends needs traces that say when each run ended (finished)")


def test_an_estimate_gets_an_observation_table() -> None:
    # The first run's estimate is low at time 1 though its true quality is high.
    p = DynamicProfile.from_traces(
        hand_made(estimate=[[0.0, 0.3, 0.9], [0.0, 0.1, 0.4]]), bins=[0, 0.5, 1]
    )
    assert p.observed == "estimate" and p.observation is not None
    np.testing.assert_array_equal(p.occupancy[1], [1, 0])  # both estimates are low
    np.testing.assert_array_equal(p.observation[1], [[0.5, 0.5], [0.5, 0.5]])  # unseen: marginal
    np.testing.assert_array_equal(p.observation[2], [[0, 1], [0, 1]])  # the low one is wrong


def test_a_measured_estimate_module_has_an_observation_table_per_cell() -> None:
    p = DynamicProfile.from_traces(traces_of(climb, input_grids=[[0.5, 1.0]]), states=5)
    assert p.observation is not None and p.observation.shape == (2, 4, p.n_states, p.n_states)
    np.testing.assert_allclose(p.observation.sum(axis=-1), 1.0)


# --- file formats: round trips ---------------------------------------------------------------


@st.composite
def random_traces(draw: st.DrawFn) -> QualityTraces:
    n_inputs = draw(st.integers(0, 1))
    grids = [[0.5, 1.0][: draw(st.integers(1, 2))] for _ in range(n_inputs)]
    trials, m = draw(st.integers(1, 4)), draw(st.integers(1, 4))
    shape = (*(len(g) for g in grids), trials, m)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    rounded = draw(st.booleans())  # equal qualities: quantile bins must not split them
    quality = rng.random(shape)
    if rounded:
        quality = np.round(quality, 1)
    reports = draw(st.sampled_from(OBSERVED))
    time = np.cumsum(rng.integers(1, 5, m)) - 1.0
    finished = rng.uniform(0, time[-1], shape[:-1]) if draw(st.booleans()) else None
    return QualityTraces(
        module="random",
        time=time,
        quality=quality,
        finished=finished,
        scored=rng.random(shape) < 0.8,
        estimate=rng.random(shape) if reports == "estimate" else None,
        reports=reports,
        input_grids=grids,
        inputs=["x"] * n_inputs,
        time_unit=draw(st.sampled_from(["ticks", "seconds"])),
    )


ROUND_TRIPS = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@ROUND_TRIPS
@given(
    traces=random_traces(),
    states=st.integers(1, 6),
    companion=st.booleans(),
    entered=st.sampled_from([None, 2, 3]),
)
def test_traces_and_their_dynamic_profile_round_trip_exactly(
    tmp_path: Path, traces: QualityTraces, states: int, companion: bool, entered: int | None
) -> None:
    save_traces(traces, tmp_path / "t.traces.yaml", companion=companion)
    assert load_traces(tmp_path / "t.traces.yaml") == traces
    ends = traces.finished is not None  # ended runs in states of their own, when known
    profile = DynamicProfile.from_traces(traces, states=states, entered=entered, ends=ends)
    save_dynamic_profile(profile, tmp_path / "t.dynamic.yaml", companion=companion)
    assert load_dynamic_profile(tmp_path / "t.dynamic.yaml") == profile


@ROUND_TRIPS
@given(traces=random_traces(), states=st.integers(1, 5))
def test_from_traces_is_a_trial_by_trial_tally(traces: QualityTraces, states: int) -> None:
    p = DynamicProfile.from_traces(traces, states=states)
    k, m, n = p.n_states, len(traces.time), traces.trials
    cells = int(np.prod(p.cell_shape))
    state = np.clip(np.searchsorted(p.bins, traces.observed, side="right") - 1, 0, k - 1)
    true = np.clip(np.searchsorted(p.bins, traces.quality, side="right") - 1, 0, k - 1)
    state, true = state.reshape(cells, n, m), true.reshape(cells, n, m)
    occupancy, pairs = np.zeros((cells, m, k)), np.zeros((cells, max(m - 1, 0), k, k))
    joint = np.zeros((cells, m, k, k))
    for c in range(cells):  # the reference: one trial and time at a time
        for i in range(n):
            for j in range(m):
                occupancy[c, j, state[c, i, j]] += 1 / n
                joint[c, j, state[c, i, j], true[c, i, j]] += 1
                if j < m - 1:
                    pairs[c, j, state[c, i, j], state[c, i, j + 1]] += 1
    seen = pairs.sum(axis=-1, keepdims=True)
    transition = np.where(seen > 0, pairs / np.maximum(seen, 1), np.eye(k))
    np.testing.assert_allclose(p.occupancy.reshape(cells, m, k), occupancy, atol=1e-12)
    np.testing.assert_allclose(p.transition.reshape(transition.shape), transition, atol=1e-12)
    if p.observation is not None:
        given_state = joint.sum(axis=-1, keepdims=True)
        rows = np.broadcast_to(given_state > 0, joint.shape)
        observed = p.observation.reshape(joint.shape)
        np.testing.assert_allclose(observed[rows], (joint / np.maximum(given_state, 1))[rows])


def test_large_tables_go_to_the_companion(tmp_path: Path) -> None:
    traces = QualityTraces(
        module="big",
        time=np.arange(101.0),
        quality=np.zeros((1000, 101)),
        scored=np.ones((1000, 101), dtype=bool),
    )
    save_traces(traces, tmp_path / "big.traces.yaml")
    assert (tmp_path / "big.traces.npz").exists()
    assert "tables:" in (tmp_path / "big.traces.yaml").read_text()
    assert load_traces(tmp_path / "big.traces.yaml") == traces


def test_a_file_without_a_module_takes_its_name(tmp_path: Path) -> None:
    path = tmp_path / "walk.dynamic.yaml"
    save_dynamic_profile(DynamicProfile.from_traces(hand_made(), bins=[0, 0.5, 1]), path)
    text = path.read_text().replace("module: hand\n", "")
    path.write_text(text)
    assert load_dynamic_profile(path).module == "walk"


def test_the_dynamic_profile_file_is_beside_the_profile() -> None:
    assert dynamic_profile_path("dir/find-path.yaml") == Path("dir/find-path.dynamic.yaml")


# --- file formats: bad files -----------------------------------------------------------------

DYNAMIC = """\
format: anytime-dynamic-profile/1
module: walk
observed: true
time: [0, 1]
quality_bins: [0, 0.5, 1]
occupancy: [[1, 0], [0.5, 0.5]]
transition: [[[0.5, 0.5], [0, 1]]]
quality_mean: [[0, 0.75], [0.2, 0.6]]
"""

TRACES = """\
format: anytime-traces/1
module: walk
trials: 2
time: [0, 1]
quality: [[0, 0.6], [0, 0.2]]
scored: [[0, 1], [0, 1]]
"""


def test_the_good_files_load(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text(DYNAMIC)
    (tmp_path / "b.yaml").write_text(TRACES)
    assert load_dynamic_profile(tmp_path / "a.yaml").n_states == 2
    assert load_traces(tmp_path / "b.yaml").trials == 2


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "anytime-dynamic-profile/1",
            "anytime-dynamic-profile/2",
            "format: unknown format version (expected 'anytime-dynamic-profile/1', got"
            " 'anytime-dynamic-profile/2')",
        ),
        (
            "observed: true",
            "observed: maybe",
            "observed: expected 'true' or 'estimate' or 'none', got 'maybe'",
        ),
        (
            "observed: true",
            "observd: true",
            "observd: unknown field, did you mean 'observed'? (expected one of format, module,"
            " observed, time_unit, samples, inputs, input_quality, time, quality_bins,"
            " ends, entered, occupancy, transition, quality_mean, observation; got 'observd')",
        ),
        (
            "occupancy: [[1, 0], [0.5, 0.5]]\n",
            "",
            "occupancy: missing field (expected a table, got nothing)",
        ),
        (
            "transition: [[[0.5, 0.5], [0, 1]]]",
            "transition: [[[0.5, 0.5], [0, 1, 0]]]",
            "transition[0][1]: expected a list of 2 numbers (one per next state), got a list of 3",
        ),
        (
            "transition: [[[0.5, 0.5], [0, 1]]]",
            "transition: [[[0.5, 0.4], [0, 1]]]",
            "transition[0][0]: expected a row summing to 1 (within 1e-06), got 0.9",
        ),
        (
            "observed: true",
            "observed: estimate",
            "observation: expected a table exactly when the state is not the true quality"
            " (observed: estimate, entered: none, ends: false), got none",
        ),
        (
            "quality_bins: [0, 0.5, 1]",
            "quality_bins: [0, 0.5, 1]\nentered: [0, 1, 3]",
            "entered: expected whole grid indices from 0 to 2, got [0, 1, 3]",
        ),
        (
            "quality_bins: [0, 0.5, 1]",
            "quality_bins: [0, 0.5, 1]\nentered: [0, 2]",
            "quality_mean[0][0]: expected a list of 2 numbers (one per true-quality bin), got 0",
        ),
        (
            "quality_mean: [[0, 0.75], [0.2, 0.6]]",
            "quality_mean: [[0, 0.75], [0.2, 1.5]]",
            "quality_mean[1][1]: expected a quality in [0, 1], got 1.5",
        ),
        ("module: walk", "module: walk\nsamples: -1", "samples: expected an integer >= 0, got -1"),
        ("module: walk", "module: walk\nends: 1", "ends: expected true or false, got 1"),
    ],
)
def test_a_bad_dynamic_profile_is_refused_with_its_reason(
    tmp_path: Path, old: str, new: str, message: str
) -> None:
    assert old in DYNAMIC
    path = tmp_path / "walk.dynamic.yaml"
    assert refused(path, DYNAMIC.replace(old, new), load_dynamic_profile) == f": {message}"


def refused(path: Path, text: str, load: Callable[[Path], object]) -> str:
    """The message of loading `text` from `path`, without the file's name."""
    path.write_text(text)
    with pytest.raises(ProfileError) as error:
        load(path)
    return str(error.value).removeprefix(str(path))


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("trials: 2", "trials: 0", "trials: expected an integer >= 1, got 0"),
        (
            "trials: 2",
            "trials: 3",
            "quality: expected a list of 3 (one per trial), got a list of 2",
        ),
        (
            "scored: [[0, 1], [0, 1]]",
            "scored: [[0, 1], [0, 0.5]]",
            "scored[1][1]: expected 0 or 1 (a result or none), got 0.5",
        ),
        (
            "module: walk",
            "module: walk\nreports: estimate",
            "estimate: expected a table of estimates exactly when the module reports an"
            " estimate (reports: estimate), got none",
        ),
        (
            "time: [0, 1]",
            "time: [0, 1",
            "not YAML: while parsing a flow sequence, expected ',' or ']', but got ':'",
        ),
    ],
)
def test_bad_traces_are_refused_with_their_reason(
    tmp_path: Path, old: str, new: str, message: str
) -> None:
    assert old in TRACES
    where = ":5:8" if message.startswith("not YAML") else ""  # a YAML error's line and column
    path = tmp_path / "walk.traces.yaml"
    assert refused(path, TRACES.replace(old, new), load_traces) == f"{where}: {message}"


def test_a_companion_that_is_not_the_files_own_is_refused(tmp_path: Path) -> None:
    traces = hand_made()
    save_traces(traces, tmp_path / "a.traces.yaml", companion=True)
    save_traces(traces.select([1, 0]), tmp_path / "b.traces.yaml", companion=True)
    (tmp_path / "b.traces.npz").replace(tmp_path / "a.traces.npz")
    with pytest.raises(ProfileError, match=r"tables.sha256: the companion 'a.traces.npz' is not"):
        load_traces(tmp_path / "a.traces.yaml")


# --- where a module's dynamic profile lives --------------------------------------------------


def measured(tmp_path: Path, name: str = "climb") -> Path:
    build = build_profile(
        climb, ValueIsQuality(), time=TIME, input_grids=[[1.0]], trials=6, traces=True
    )
    assert build.traces is not None
    save_profile(build.profile, tmp_path / f"{name}.yaml")
    dynamic = DynamicProfile.from_traces(build.traces, states=3)
    save_dynamic_profile(dynamic, tmp_path / f"{name}.dynamic.yaml")
    save_traces(build.traces, tmp_path / f"{name}.traces.yaml")
    return tmp_path / f"{name}.yaml"


def test_a_profile_directory_finds_the_dynamic_profile_beside_a_profile(tmp_path: Path) -> None:
    measured(tmp_path)
    library = AnytimeLibrary([ProfileDirectory(tmp_path)])
    assert library.names() == ("climb",)  # neither climb.dynamic nor climb.traces
    dynamic = library["climb"].dynamic_profile
    assert dynamic == load_dynamic_profile(tmp_path / "climb.dynamic.yaml")
    assert library["climb"].dynamic_profile is dynamic  # read once


def test_a_module_whose_profile_has_none_beside_it_has_no_dynamic_profile(
    tmp_path: Path,
) -> None:
    path = measured(tmp_path)
    (tmp_path / "climb.dynamic.yaml").unlink()
    assert LibraryEntry.of_module(attrs.evolve(climb, profile_source=path)).dynamic_profile is None
    assert LibraryEntry.of_module(honest).dynamic_profile is None  # no profile file


def test_a_plugins_module_looks_beside_its_packaged_profile() -> None:
    entry = AnytimeLibrary.default()["find-path"]
    assert entry.profile_file is not None and entry.profile_file.name == "find-path.yaml"
    dynamic = entry.dynamic_profile  # the plugin ships find-path.dynamic.yaml beside it
    assert dynamic is not None and dynamic.module == "find-path"


def test_another_modules_dynamic_profile_is_refused(tmp_path: Path) -> None:
    measured(tmp_path)
    (tmp_path / "climb.dynamic.yaml").replace(tmp_path / "other.dynamic.yaml")
    (tmp_path / "climb.yaml").replace(tmp_path / "other.yaml")
    entry = LibraryEntry.of_module(
        attrs.evolve(climb, name="other", profile_source=tmp_path / "other.yaml")
    )
    with pytest.raises(ProfileError) as error:
        _ = entry.dynamic_profile
    assert str(error.value) == (
        f"{tmp_path / 'other.dynamic.yaml'}: module: expected 'other' (the module it is the"
        " dynamic profile of), got 'climb'"
    )
