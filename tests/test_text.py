"""The 'did you mean' helpers of `anytime.text`, the one module every message takes them from."""

from __future__ import annotations

import pytest

from anytime.dsl.normalize import suggest as dsl_suggest
from anytime.errors import ProfileError
from anytime.problems import BuildError, Measurement, registered_problems
from anytime.profiles.io import profile_from_dict
from anytime.text import closest, did_you_mean, suggest


def test_closest() -> None:
    assert closest("find-pth", ["find-path", "plan", "wait"]) == "find-path"
    assert closest("zzz", ["find-path", "plan"]) is None
    assert closest("x", []) is None


def test_did_you_mean() -> None:
    assert did_you_mean("halfing", ["halving", "doubling"]) == "; did you mean 'halving'?"
    assert did_you_mean("tim", ["time", "format"], separator=", ") == ", did you mean 'time'?"
    assert did_you_mean("zzz", ["halving"]) == ""


def test_suggest_names_the_closest_or_lists_the_known() -> None:
    assert suggest("m11", ["m1", "m2", "hi"]) == "; did you mean 'm1'?"
    assert suggest("zzz", ["m2", "m1", "hi", "m1"]) == " (known: hi, m1, m2)"
    many = [f"name{i:02}" for i in range(13)]
    assert suggest("q", many) == f" (known: {', '.join(many[:12])}, ...)"
    assert suggest("zzz", []) == ""


def test_the_dsl_name_is_the_same_function() -> None:
    """`anytime.dsl.normalize.suggest` stays importable (the compiler imports it from there)."""
    assert dsl_suggest is suggest


def test_the_messages_that_use_them() -> None:
    with pytest.raises(BuildError) as build:
        registered_problems("halfing", {"halving": Measurement.of([], time=[1])})
    assert str(build.value) == (
        "no problem set is registered for module 'halfing' (registered: halving); did you"
        " mean 'halving'?"
    )
    with pytest.raises(ProfileError) as profile:
        profile_from_dict({"format": "anytime-profile/1", "tim": [0, 1]}, "p.yaml")
    assert str(profile.value).startswith(
        "p.yaml: tim: unknown field, did you mean 'time'? (expected one of format, "
    )
