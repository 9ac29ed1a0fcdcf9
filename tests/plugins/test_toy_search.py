"""The toy plugin's stalling module (tests/plugins/toy_plugin/toy_anytime_plugin/search.py): a
random-restart local search that registers a result only when it improves, often at first and
rarely after about 40 ticks; the stopping benchmark's fourth module."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime import Context, run
from anytime.measure.builder import build_profile

TOY_PLUGIN = Path(__file__).resolve().parent / "toy_plugin"


@pytest.fixture(scope="module")
def search() -> Iterator[ModuleType]:
    sys.path.insert(0, str(TOY_PLUGIN))
    try:
        from toy_anytime_plugin import search

        yield search
    finally:
        sys.path.remove(str(TOY_PLUGIN))


@settings(max_examples=30, deadline=None)
@given(landscape=st.integers(0, 2**32 - 1), seed=st.integers(0, 2**32 - 1))
def test_it_registers_only_improvements_each_its_true_quality(
    search: ModuleType, landscape: int, seed: int
) -> None:
    problems = search.Landscapes()
    land = search.Landscape(landscape)
    assert land.values.min() == 0.0 and land.values.max() == 1.0
    instance = search.Instance(args=(land, seed), reference=land)
    ctx = Context(120.0)
    qualities = []
    for result in search.toy_search(ctx, land, seed):
        assert result.quality == problems.score(instance, result.value)
        qualities.append(result.quality)
        if ctx.expired:
            break
    assert all(np.diff(qualities) > 0)  # a result only when it improves


def test_a_run_under_a_budget_answers_with_its_best(search: ModuleType) -> None:
    land = search.Landscape(7)
    record = run(search.toy_search, (land, 3), budget=60)
    assert record.time_used <= 60
    ctx = Context(60.0)
    best = None
    for result in search.toy_search(ctx, land, 3):
        best = result
        if ctx.expired:
            break
    assert best is not None and record.result is not None
    assert record.result.value == best.value


def test_it_stalls_improving_often_at_first_and_rarely_after_40_ticks(search: ModuleType) -> None:
    (module,) = search.PLUGIN.modules
    problems = search.PLUGIN.problem_sets["toy-search"].problems
    build = build_profile(
        module, problems, time=search.TIMES, trials=300, seed=5, progress=False, traces=True
    )
    assert build.traces is not None
    quality = build.traces.quality.reshape(-1, len(search.TIMES))
    improved = np.diff(quality, axis=1) > 0  # per step of 2 ticks
    early, late = improved[:, :10].mean(), improved[:, 20:].mean()  # ticks 0-20, 40-100
    assert early > 0.4 and late < 0.1  # measured: 0.55 and 0.074
