"""Hostile and degenerate YAML: what a profile file may expand to is checked before it loads,
and duplicate keys are an error; each a one-line `ProfileError` naming FILE:LINE:COL."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.errors import ProfileError
from anytime.profiles.io import FAST_LOADER, load_profile
from anytime.profiles.yaml_limits import MAX_DEPTH, YAMLLimitError, check_document

GOOD = """\
format: anytime-profile/1
module: good
time: [0, 1]
quality_bins: [0.0, 1.0]
expected: [0.0, 1.0]
"""


def _bomb(levels: int = 9) -> str:
    """About 600 bytes standing for 9**10 values (the 'billion laughs')."""
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(levels):
        name, previous = chr(98 + i), chr(97 + i)
        lines.append(f"{name}: &{name} [" + ",".join([f"*{previous}"] * 9) + "]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            GOOD + "allocation: &x [1]\n" + _bomb(),
            "14:14: the document stands for more than 20,000,000 values"
            " (with its aliases expanded)",
        ),
        (
            "time: " + "[" * 1000 + "]" * 1000 + "\n",
            f"1:70: nested more than {MAX_DEPTH} lists and mappings deep",
        ),
        (GOOD + "time: [0, 2]\n", "6:1: duplicate key 'time' in a mapping"),
        ("meta: {a: 1, b: 2, a: 3}\n", "1:20: duplicate key 'a' in a mapping"),
        ("time: [" + "9" * 5000 + "]\n", "1:8: an integer of 5,000 digits (at most 1,000)"),
    ],
    ids=["alias-bomb", "deep", "duplicate-field", "duplicate-key", "huge-integer"],
)
def test_refused_with_the_place(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ProfileError) as raised:
        load_profile(path)
    assert str(raised.value) == f"{path}:{message}"


def test_aliases_within_the_limit_and_quoted_digits_are_fine(tmp_path: Path) -> None:
    path = tmp_path / "good.yaml"
    path.write_text(
        GOOD.replace(
            "quality_bins: [0.0, 1.0]\nexpected: [0.0, 1.0]",
            "quality_bins: &q [0.0, 1.0]\nexpected: *q",
        )
    )
    assert load_profile(path).expected_at(1.0) == 1.0
    check_document("notes: &n {a: '" + "9" * 5000 + "'}\nmore: [*n, *n]\n", FAST_LOADER)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.text(alphabet="abc", min_size=1, max_size=2), min_size=1, max_size=6))
def test_a_mapping_is_refused_exactly_when_a_key_repeats(keys: list[str]) -> None:
    text = "".join(f"{key}: {i}\n" for i, key in enumerate(keys))
    repeated = len(set(keys)) < len(keys)
    try:
        check_document(text, FAST_LOADER)
    except YAMLLimitError as error:
        assert repeated and str(error).startswith("duplicate key")
    else:
        assert not repeated
