"""Fast loading: the C loader gives the pure loader's data and messages, tables are read in a
few vectorised passes, and large tables travel in a validated binary companion (`NAME.npz`)."""

from __future__ import annotations

import hashlib
import io
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from toy_modules import toy_registry

from anytime.compiler import compile_file, load_compiled, save_compiled
from anytime.dsl import parse_schemas
from anytime.errors import ProfileError
from anytime.library import AnytimeLibrary, RegistrySource
from anytime.profiles import ConditionalPerformanceProfile, Exponential, tabulate
from anytime.profiles import io as profile_io
from anytime.profiles.io import (
    COMPANION_THRESHOLD,
    load_profile,
    read_profile_file,
    save_profile,
)
from anytime.profiles.io import companion as companion_module
from anytime.profiles.io import document as document_module
from anytime.profiles.io.reader import Reader, plain_table


def _stochastic(n_times: int = 6, seed: int = 3) -> ConditionalPerformanceProfile:
    rng = np.random.default_rng(seed)
    probability = rng.dirichlet(np.ones(4), size=(2, n_times))
    return ConditionalPerformanceProfile(
        input_grids=[[0.5, 1.0]],
        inputs=["map"],
        time=np.arange(n_times, dtype=np.float64),
        bins=[0, 0.25, 0.5, 0.75, 1],
        probability=probability,
        mean=probability @ np.array([0.2, 0.4, 0.6, 0.8]),
        samples=rng.integers(1, 9, size=(2, n_times)),
        module="plan",
    )


def _header(path: Path) -> dict[str, object]:
    data = yaml.safe_load(path.read_text())
    assert isinstance(data, dict)
    return data


# --- the companion -------------------------------------------------------------------------


def test_a_companion_round_trips_and_replaces_the_tables_in_the_text(tmp_path: Path) -> None:
    profile = _stochastic()
    path = tmp_path / "plan.yaml"
    save_profile(profile, path, companion=True)
    header = _header(path)
    tables = header["tables"]
    assert isinstance(tables, dict)
    assert tables["file"] == "plan.npz"
    assert tables["shapes"] == {"probability": [2, 6, 4], "mean": [2, 6], "samples": [2, 6]}
    assert tables["sha256"] == hashlib.sha256((tmp_path / "plan.npz").read_bytes()).hexdigest()
    assert not {"probability", "mean", "samples"} & set(header)
    assert load_profile(path) == profile
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.npz", "plan.yaml"]  # no partials


def test_a_deterministic_profile_keeps_its_expected_form_in_the_companion(tmp_path: Path) -> None:
    profile = tabulate(Exponential(0.1), np.arange(50.0), module="e")
    path = tmp_path / "e.yaml"
    save_profile(profile, path, companion=True)
    assert _header(path)["tables"] == {
        "file": "e.npz",
        "sha256": hashlib.sha256((tmp_path / "e.npz").read_bytes()).hexdigest(),
        "shapes": {"expected": [50]},
    }
    assert load_profile(path) == profile


def test_writers_add_the_companion_only_above_the_threshold(tmp_path: Path) -> None:
    small = tabulate(Exponential(0.1), np.arange(100.0), module="small")
    large = tabulate(Exponential(0.1), np.arange(COMPANION_THRESHOLD + 1.0), module="large")
    save_profile(small, tmp_path / "small.yaml")
    save_profile(large, tmp_path / "large.yaml")
    assert "expected" in _header(tmp_path / "small.yaml")
    assert not (tmp_path / "small.npz").exists()
    header = _header(tmp_path / "large.yaml")
    assert "time" not in header  # a grid this long goes with the tables it indexes
    assert header["tables"]["shapes"] == {  # type: ignore[index]
        "time": [COMPANION_THRESHOLD + 1],
        "expected": [COMPANION_THRESHOLD + 1],
    }
    assert load_profile(tmp_path / "large.yaml") == large


def test_a_compiled_program_with_a_companion_loads_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(companion_module, "COMPANION_THRESHOLD", 0)
    schemas = parse_schemas("(defschema chain (x) (refine (sense x)))", "chain.any")
    library = AnytimeLibrary([RegistrySource(toy_registry())])
    (original,) = compile_file(schemas, library, [0, 10, 20, 40])
    save_compiled(original, tmp_path / "chain.yaml")
    assert "tables" in _header(tmp_path / "chain.yaml")
    loaded = load_compiled(tmp_path / "chain.yaml", library)
    assert loaded.profile == original.profile
    np.testing.assert_array_equal(loaded.allocation, original.allocation)


# --- a companion that is not the header's is refused ----------------------------------------


@pytest.fixture
def pair(tmp_path: Path) -> Path:
    path = tmp_path / "plan.yaml"
    save_profile(_stochastic(), path, companion=True)
    return path


def _refused(path: Path) -> str:
    with pytest.raises(ProfileError) as caught:
        load_profile(path)
    return str(caught.value).removeprefix(f"{path}: ")


def _edit_header(path: Path, **tables: object) -> None:
    header = _header(path)
    assert isinstance(header["tables"], dict)
    header["tables"].update(tables)
    path.write_text(yaml.safe_dump(header, sort_keys=False))


def _write_npz(path: Path, **arrays: np.ndarray) -> str:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    path.write_bytes(buffer.getvalue())
    return hashlib.sha256(buffer.getvalue()).hexdigest()


def test_a_stale_companion_is_refused_by_its_digest(pair: Path) -> None:
    old = _header(pair)["tables"]
    assert isinstance(old, dict)
    save_profile(_stochastic(seed=4), pair.with_name("other.yaml"), companion=True)
    pair.with_name("other.npz").replace(pair.with_name("plan.npz"))  # another profile's tables
    new = hashlib.sha256(pair.with_name("plan.npz").read_bytes()).hexdigest()
    assert _refused(pair) == (
        "tables.sha256: the companion 'plan.npz' is not the one this file was written with"
        f" (expected sha256 {old['sha256']}, got {new}): write the profile again"
    )


def test_a_missing_companion_is_refused(pair: Path) -> None:
    pair.with_name("plan.npz").unlink()
    assert _refused(pair) == (
        "tables.file: cannot read the companion 'plan.npz': No such file or directory"
    )


def test_a_companion_outside_the_files_directory_is_refused(pair: Path) -> None:
    _edit_header(pair, file="../plan.npz")
    assert _refused(pair) == (
        "tables.file: expected the name of a .npz file beside this one, got '../plan.npz'"
    )


FIVE_TIMES = {"probability": [2, 5, 4], "mean": [2, 5], "samples": [2, 5]}


@pytest.mark.parametrize(
    ("mean_times", "shapes", "message"),
    [
        (  # the header says 6 times, the companion holds 5
            6,
            None,
            "tables.shapes.probability: expected numbers of shape [2, 6, 4] (the header's),"
            " got float64 of shape [2, 5, 4] in the companion 'plan.npz'",
        ),
        (  # the header agrees with the companion, but the time grid has 6 times
            5,
            FIVE_TIMES,
            "probability: expected shape [2, 6, 4] (one per map quality, one per time, one per"
            " quality bin), got [2, 5, 4] in the companion",
        ),
    ],
)
def test_a_companion_of_other_shapes_is_refused(
    pair: Path, mean_times: int, shapes: dict[str, list[int]] | None, message: str
) -> None:
    rng = np.random.default_rng(0)
    digest = _write_npz(
        pair.with_name("plan.npz"),
        probability=rng.dirichlet(np.ones(4), size=(2, 5)),
        mean=np.zeros((2, mean_times)),
        samples=np.ones((2, mean_times)),
    )
    _edit_header(pair, sha256=digest, **({"shapes": shapes} if shapes else {}))
    assert _refused(pair) == message


def test_a_companion_missing_a_table_the_header_names_is_refused(pair: Path) -> None:
    rng = np.random.default_rng(0)
    digest = _write_npz(
        pair.with_name("plan.npz"), probability=rng.dirichlet(np.ones(4), size=(2, 6))
    )
    _edit_header(pair, sha256=digest)
    assert _refused(pair) == (
        "tables.shapes: expected the companion 'plan.npz' to hold mean, probability, samples,"
        " got probability"
    )


def test_a_companion_with_pickled_objects_is_refused_unread(pair: Path) -> None:
    buffer = io.BytesIO()
    np.savez(buffer, probability=np.array([{"a": 1}], dtype=object), allow_pickle=True)
    pair.with_name("plan.npz").write_bytes(buffer.getvalue())
    _edit_header(pair, sha256=hashlib.sha256(buffer.getvalue()).hexdigest())
    assert _refused(pair) == (
        "tables.file: the companion 'plan.npz' is not an archive of arrays: Object arrays"
        " cannot be loaded when allow_pickle=False"
    )


def test_a_table_in_both_the_file_and_its_companion_is_refused(pair: Path) -> None:
    header = _header(pair)
    header["samples"] = [[1] * 6, [1] * 6]
    pair.write_text(yaml.safe_dump(header, sort_keys=False))
    assert _refused(pair) == (
        "samples: given both in this file and in its companion (expected one)"
    )


def test_a_bad_value_in_the_companion_is_named_by_its_cell(pair: Path) -> None:
    profile = _stochastic()
    samples = np.array(profile.samples)
    samples[1, 2] = -3
    assert profile.mean is not None
    digest = _write_npz(
        pair.with_name("plan.npz"),
        probability=profile.probability,
        mean=profile.mean,
        samples=samples,
    )
    _edit_header(pair, sha256=digest)
    assert _refused(pair) == "samples[1][2]: expected a number >= 0, got -3"


def test_a_mapping_with_a_companion_field_is_refused_outside_a_file() -> None:
    with pytest.raises(ProfileError) as caught:
        profile_io.profile_from_dict(
            {"format": "anytime-profile/1", "tables": {}, "time": [0], "quality_bins": [0, 1]},
            "p.yaml",
        )
    assert str(caught.value) == (
        "p.yaml: tables: a companion is read with its file (load_profile), not here"
    )


# --- the fast loader and the fast table reading ----------------------------------------------


def test_read_profile_file_gives_the_profile_and_the_mapping(pair: Path) -> None:
    profile, data = read_profile_file(pair)
    assert profile == _stochastic()
    assert isinstance(data["probability"], np.ndarray)  # from the companion
    assert "tables" not in data


numbers = st.one_of(
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.booleans(),
    st.text(max_size=3),
    st.none(),
)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(numbers, min_size=0, max_size=4), min_size=1, max_size=4))
def test_the_fast_loader_reads_what_the_pure_loader_reads(rows: list[list[object]]) -> None:
    text = yaml.safe_dump({"table": rows, "step": rows[0][0] if rows[0] else 1})
    assert _same(yaml.load(text, Loader=document_module.FAST_LOADER), yaml.safe_load(text))


def _same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float) and np.isnan(a):
        return bool(np.isnan(b))
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


@settings(max_examples=150, deadline=None)
@given(st.lists(st.lists(numbers, min_size=0, max_size=3), min_size=0, max_size=3))
def test_the_fast_table_path_accepts_exactly_what_the_walk_accepts(
    rows: list[list[object]],
) -> None:
    shape = (len(rows), 3)
    fast = plain_table(rows, shape)
    reader = Reader("p.yaml")
    try:
        walked = reader.table("samples", rows, shape, ["one per a", "one per b"])
    except ProfileError:
        walked = None
    if fast is not None:  # the fast path is only taken where the walk gives the same array
        np.testing.assert_array_equal(fast, np.array(rows, dtype=np.float64))
        if walked is not None:
            np.testing.assert_array_equal(fast, walked)


BROKEN = {
    "flow": "format: anytime-profile/1\ntime: [0, 1\nquality_bins: [0, 1]\n",
    "tab": "format: anytime-profile/1\n\ttime: [0]\n",
    "alias": "format: anytime-profile/1\ntime: *t\n",
    "control character": "format: anytime-profile/1\nmodule: é\x07\n",
    "python tag": "format: anytime-profile/1\ntime: !!python/object:os.system [0]\n",
}


@pytest.mark.parametrize("text", BROKEN.values(), ids=BROKEN.keys())
def test_messages_and_positions_are_the_pure_loaders(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, text: str
) -> None:
    path = tmp_path / "p.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProfileError) as fast:
        load_profile(path)
    monkeypatch.setattr(document_module, "FAST_LOADER", yaml.SafeLoader)
    with pytest.raises(ProfileError) as pure:
        load_profile(path)
    assert str(fast.value) == str(pure.value)


def test_a_profile_with_a_companion_cannot_be_named_npz(tmp_path: Path) -> None:
    with pytest.raises(OSError) as caught:
        save_profile(_stochastic(), tmp_path / "plan.npz", companion=True)
    assert str(caught.value) == (
        f"cannot write '{tmp_path / 'plan.npz'}': a profile with a companion cannot itself be"
        " named .npz"
    )
    assert list(tmp_path.iterdir()) == []


def test_the_fast_loader_is_libyamls_where_pyyaml_has_it() -> None:
    if yaml.__with_libyaml__:
        assert document_module.FAST_LOADER is yaml.CSafeLoader
    else:
        assert document_module.FAST_LOADER is yaml.SafeLoader
