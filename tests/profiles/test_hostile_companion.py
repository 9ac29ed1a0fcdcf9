"""A hostile binary companion (`NAME.npz`) is refused before it is decompressed: declared shapes
are bounded by `MAX_CELLS`, each member's `.npy` header is read alone and compared with the
declared shape, and the member's uncompressed size in the zip directory must be the one its
header implies. What is decompressed is counted (never timed): a bomb costs a header."""

from __future__ import annotations

import hashlib
import io
import struct
import zipfile
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.errors import ProfileError
from anytime.profiles import ConditionalPerformanceProfile
from anytime.profiles.io import MAX_CELLS, load_profile, read_profile_file, save_profile
from anytime.profiles.io.companion import MAX_MEMBERS

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

#: The header numpy writes for a float64 table of shape (2, 6, 4): 128 bytes, then 48 numbers.
HEADER = {"descr": "<f8", "fortran_order": False, "shape": (2, 6, 4)}
SIZE = 128 + 48 * 8


def _profile() -> ConditionalPerformanceProfile:
    rng = np.random.default_rng(3)
    probability = rng.dirichlet(np.ones(4), size=(2, 6))
    return ConditionalPerformanceProfile(
        input_grids=[[0.5, 1.0]],
        inputs=["map"],
        time=np.arange(6, dtype=np.float64),
        bins=[0, 0.25, 0.5, 0.75, 1],
        probability=probability,
        module="plan",
    )


@pytest.fixture
def pair(tmp_path: Path) -> Path:
    """A profile whose one table, probability of shape [2, 6, 4], is in its companion."""
    path = tmp_path / "plan.yaml"
    save_profile(_profile(), path, companion=True)
    return path


@pytest.fixture
def decompressed(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """The bytes every zip member's deflate stream has produced, counted as they come."""
    counted = [0]
    real = zlib.decompressobj

    class Counting:
        def __init__(self, *args: Any) -> None:
            self.inner = real(*args)

        def decompress(self, data: bytes, max_length: int = 0) -> bytes:
            out = self.inner.decompress(data, max_length)
            counted[0] += len(out)
            return out

        def __getattr__(self, name: str) -> Any:
            return getattr(self.inner, name)

    monkeypatch.setattr(zipfile.zlib, "decompressobj", Counting)  # type: ignore[attr-defined]
    yield counted


def _header_bytes(header: dict[str, Any] = HEADER) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, header)
    return buffer.getvalue()


def _bomb(zeros: int, header: dict[str, Any] = HEADER) -> bytes:
    """A deflated archive whose member `probability.npy` is `header` then `zeros` zero bytes."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open("probability.npy", "w", force_zip64=True) as member:
            member.write(_header_bytes(header))
            chunk = bytes(1 << 20)
            for _ in range(zeros >> 20):
                member.write(chunk)
    return buffer.getvalue()


def _install(pair: Path, raw: bytes, **shapes: list[int]) -> None:
    """Put `raw` as the companion of `pair`, its digest (and `shapes`) in the header."""
    pair.with_name("plan.npz").write_bytes(raw)
    data = yaml.safe_load(pair.read_text())
    data["tables"]["sha256"] = hashlib.sha256(raw).hexdigest()
    data["tables"]["shapes"].update(shapes)
    pair.write_text(yaml.safe_dump(data, sort_keys=False))


def _refused(path: Path) -> str:
    with pytest.raises(ProfileError) as caught:
        load_profile(path)
    return str(caught.value)


def test_the_header_bytes_are_numpys(tmp_path: Path) -> None:
    buffer = io.BytesIO()
    np.save(buffer, np.zeros((2, 6, 4)))
    assert buffer.getvalue()[:128] == _header_bytes()
    assert len(buffer.getvalue()) == SIZE


def test_a_declared_shape_over_the_cell_limit_is_refused_unread(pair: Path) -> None:
    pair.with_name("plan.npz").unlink()  # nothing is opened: the header alone is refused
    data = yaml.safe_load(pair.read_text())
    data["tables"]["shapes"]["probability"] = [100_000, 100_000, 4]
    pair.write_text(yaml.safe_dump(data, sort_keys=False))
    assert MAX_CELLS == 10_000_000
    assert _refused(pair) == (
        f"{pair}: tables.shapes.probability: expected at most 10000000 cells, got shape"
        " [100000, 100000, 4] (40,000,000,000 cells)"
    )


def test_a_zip_bomb_is_refused_after_its_header(pair: Path, decompressed: list[int]) -> None:
    """64 MB of zeros behind a header of 48 numbers: the directory says 64 MB, the header 512
    bytes; nothing past the header is decompressed."""
    raw = _bomb(64 << 20)
    assert len(raw) < 200_000
    _install(pair, raw)
    assert _refused(pair) == (
        f"{pair}: tables.file: the companion 'plan.npz' is damaged or forged: its member"
        " 'probability.npy' holds 67,108,992 bytes, where its header (float64 of shape"
        " [2, 6, 4]) says 512"
    )
    assert decompressed[0] <= 64 << 10  # the header and zlib's first output block, at most


def _patch_sizes(raw: bytes, size: int) -> bytes:
    """`raw` with its one member's uncompressed size, in the local header and the central
    directory, set to `size` (what a forger writes to pass the size check)."""
    data = bytearray(raw)
    local = data.index(b"PK\x03\x04")
    central = data.index(b"PK\x01\x02")
    struct.pack_into("<I", data, local + 22, size)
    struct.pack_into("<I", data, central + 24, size)
    return bytes(data)


def test_a_zip_directory_that_lies_is_refused_reading_no_more_than_it_says(
    pair: Path, decompressed: list[int]
) -> None:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("probability.npy", _header_bytes() + bytes(16 << 20))
    _install(pair, _patch_sizes(buffer.getvalue(), SIZE))
    assert _refused(pair) == (
        f"{pair}: tables.file: the companion 'plan.npz' is not an archive of arrays:"
        " Bad CRC-32 for file 'probability.npy'"
    )
    assert decompressed[0] <= 2 * (64 << 10)  # its header, then the 512 bytes it says


def test_a_header_of_another_shape_is_refused_before_its_data(
    pair: Path, decompressed: list[int]
) -> None:
    raw = _bomb(4 << 20, {**HEADER, "shape": (1 << 40,)})
    _install(pair, raw)
    assert _refused(pair) == (
        f"{pair}: tables.shapes.probability: expected numbers of shape [2, 6, 4] (the"
        " header's), got float64 of shape [1099511627776] in the companion 'plan.npz'"
    )
    assert decompressed[0] <= 64 << 10


def test_numbers_wider_than_eight_bytes_are_refused_before_their_data(
    pair: Path, decompressed: list[int]
) -> None:
    """A float128 table would cost twice what `MAX_CELLS` cells of float64 cost."""
    _install(pair, _bomb(1 << 20, {**HEADER, "descr": "<f16"}))
    assert _refused(pair) == (
        f"{pair}: tables.shapes.probability: expected numbers of shape [2, 6, 4] (the"
        " header's), got float128 of shape [2, 6, 4] in the companion 'plan.npz'"
    )
    assert decompressed[0] <= 64 << 10


def test_a_member_that_is_not_a_npy_stream_is_refused(pair: Path) -> None:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("probability.npy", b"not an array" * 10)
    _install(pair, buffer.getvalue())
    assert _refused(pair) == (
        f"{pair}: tables.file: the companion 'plan.npz' is not an archive of arrays:"
        " the magic string is not correct; expected b'\\x93NUMPY', got b'not an'"
    )


def test_a_member_given_twice_is_refused(pair: Path) -> None:
    array = io.BytesIO()
    np.save(array, np.full((2, 6, 4), 0.25))
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive, pytest.warns(UserWarning, match="Duplicate"):
        archive.writestr("probability.npy", array.getvalue())
        archive.writestr("probability.npy", array.getvalue())
    _install(pair, buffer.getvalue())
    assert _refused(pair) == (
        f"{pair}: tables.file: the companion 'plan.npz' is not an archive of arrays:"
        " it holds 'probability.npy' twice"
    )


def test_a_directory_of_many_members_is_refused_before_it_is_listed(
    pair: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for i in range(100):
            archive.writestr(f"t{i}.npy", b"")
    _install(pair, buffer.getvalue())

    def unlisted(*args: object) -> None:
        raise AssertionError("the directory was listed")

    monkeypatch.setattr(zipfile, "ZipFile", unlisted)
    assert MAX_MEMBERS == 64
    assert _refused(pair) == (
        f"{pair}: tables.file: the companion 'plan.npz' is not an archive of arrays:"
        " its directory lists 100 members (at most 64)"
    )


def test_an_honest_compressed_companion_still_loads(pair: Path) -> None:
    """A deflated archive (np.savez_compressed) of the right shapes reads as the plain one."""
    profile = _profile()
    buffer = io.BytesIO()
    np.savez_compressed(buffer, probability=np.asfortranarray(profile.probability))
    _install(pair, buffer.getvalue())
    assert load_profile(pair) == profile


def test_every_reader_of_profiles_goes_through_the_check(pair: Path) -> None:
    _install(pair, _bomb(1 << 20))
    with pytest.raises(ProfileError, match="damaged or forged"):
        read_profile_file(pair)


def test_plot_of_a_bomb_is_one_line_and_exit_1(pair: Path, cli: Cli) -> None:
    _install(pair, _bomb(64 << 20))
    code, out, err = cli("plot", str(pair), "-o", str(pair.with_name("plot.png")))
    assert (code, out, err) == (
        1,
        "",
        f"anytime: error: {pair}: tables.file: the companion 'plan.npz' is damaged or"
        " forged: its member 'probability.npy' holds 67,108,992 bytes, where its header"
        " (float64 of shape [2, 6, 4]) says 512\n",
    )
    assert not pair.with_name("plot.png").exists()


@pytest.mark.slow
def test_the_issues_bomb_of_two_to_the_31_zeros(pair: Path, decompressed: list[int]) -> None:
    """The case of issue 37: a 2 MB companion whose member holds 2**31 zeros."""
    raw = _bomb(1 << 31)
    assert len(raw) < 3 << 20
    _install(pair, raw)
    assert _refused(pair).endswith(
        f"holds {128 + (1 << 31):,} bytes, where its header (float64 of shape [2, 6, 4]) says 512"
    )
    assert decompressed[0] <= 64 << 10


@pytest.fixture(scope="module")
def honest(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, bytes, bytes]:
    """A pair on disk, with its companion stored (np.savez) and deflated (savez_compressed)."""
    path = tmp_path_factory.mktemp("fuzz") / "plan.yaml"
    save_profile(_profile(), path, companion=True)
    deflated = io.BytesIO()
    np.savez_compressed(deflated, probability=_profile().probability)
    return path, path.with_name("plan.npz").read_bytes(), deflated.getvalue()


@settings(max_examples=100, deadline=None)
@given(
    deflate=st.booleans(),
    flips=st.lists(
        st.tuples(st.floats(min_value=0, max_value=1, exclude_max=True), st.integers(0, 255)),
        min_size=1,
        max_size=4,
    ),
)
def test_any_damaged_companion_loads_or_is_refused_naming_the_file(
    honest: tuple[Path, bytes, bytes], deflate: bool, flips: list[tuple[float, int]]
) -> None:
    """A few bytes of the archive (its directory, headers or data) changed, the digest made to
    match: the profile loads (the change was in the numbers, and they are valid) or is a
    `ProfileError` naming the file; never another exception."""
    path, stored, deflated = honest
    data = bytearray(deflated if deflate else stored)
    for place, value in flips:
        data[int(place * len(data))] = value
    _install(path, bytes(data))
    try:
        load_profile(path)
    except ProfileError as error:
        assert str(error).startswith(f"{path}: ")
