"""Adaptive re-allocation by value of information (`Execution.adapt`, the compiler's
`Replanner`).

A call whose outcome the plan already knew (a quality its profile predicts, its whole share
used) is not news: adaptive runs do not re-plan after it, and are the fixed runs exactly. A call
that is news is re-planned after, and the plan is remembered: the runs of one program search
once per distinct outcome. A new split is kept only where the compiler expects it to beat the
split planned (a property over random observations and kept splits). A search is made only
where its expected gain beats what its time on the run's clock is worth.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_program import (
    ADAPTIVE,
    ADAPTIVE_TEXT,
    LEVELS,
    RATE,
    SEEDS,
    TIME,
    compiled,
    conditional,
    draw_level,
    rising,
)

from anytime.clocks import WorkClock
from anytime.compiler import CompiledProgram
from anytime.compiler.allocators.reallocate import (
    CACHE_SIZE,
    QUANTUM,
    Replanner,
    reallocate,
    replanner,
)
from anytime.compiler.evaluate import Evaluator
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.profiles import tabulate
from anytime.runtime import Budget, run_program
from anytime.runtime.execution import Execution
from anytime.runtime.modes import SOFT

ESTIMATES = Registry()


@contract(
    "gauge",
    inputs=[],
    profile=tabulate(rising(RATE), TIME, kind="contract"),
    reports="estimate",
    registry=ESTIMATES,
)
def gauge(ctx: Context, seed: int) -> Result:
    """Uses all it is given and says only an estimate of its quality."""
    ctx.tick(ctx.allocation)
    return Result(seed, draw_level(seed))


@interruptible(
    "shape", inputs=["m"], profile=conditional(RATE), reports="estimate", registry=ESTIMATES
)
def shape(ctx: Context, m: Result) -> Iterator[Result]:
    while True:
        yield Result(m.value, m.quality * float(rising(RATE)(ctx.elapsed)))
        ctx.tick(1)


@pytest.fixture(scope="module")
def adaptive_program() -> CompiledProgram:
    return compiled(ADAPTIVE_TEXT, ADAPTIVE, allocator="exhaustive")


@pytest.mark.parametrize("total", [15.0, 30.0, 40.0])
def test_a_call_whose_outcome_the_plan_knew_is_not_re_planned_after(total: float) -> None:
    """A chain of modules reporting estimates, each using its whole share: nothing a run
    shows is news, so adaptive runs never ask for a re-plan and are the fixed runs."""
    program = compiled("(defschema p (seed) (shape (gauge seed)))", ESTIMATES)
    planner = replanner(program.model, program.resolution)
    asked = planner.asked
    for seed in range(20):
        fixed = run_program(program, {"seed": seed}, total)
        adaptive = run_program(program, {"seed": seed}, total, adaptive=True)
        assert adaptive == fixed
    assert planner.asked == asked


@pytest.mark.parametrize("total", [20.0, 40.0])
def test_the_runs_of_a_program_search_once_per_outcome(
    adaptive_program: CompiledProgram, total: float
) -> None:
    """roll's true quality is one of three levels: its 200 runs ask for a re-plan each, and
    search at most once per level (the rest are remembered); the answers are the same as
    searching afresh."""
    planner = replanner(adaptive_program.model, adaptive_program.resolution)
    asked, searched = planner.asked, planner.searches
    records = [run_program(adaptive_program, {"seed": s}, total, adaptive=True) for s in SEEDS]
    assert planner.asked - asked == len(SEEDS)
    assert planner.searches - searched <= len(LEVELS)
    fresh = Replanner(adaptive_program.model, adaptive_program.resolution)
    for seed, record in zip(SEEDS, records, strict=True):
        kept = adaptive_program.allocation_at([], total)
        level = draw_level(seed)
        new = fresh.plan([], kept, [1, 2], total, {0: level})
        assert new is not None
        assert record.allocations == tuple(new)


def test_a_search_costlier_than_its_share_of_the_time_left_is_not_run(
    adaptive_program: CompiledProgram,
) -> None:
    """With the searches measured to cost more than the time left on the work clock, a run
    whose re-plan is not remembered keeps its compiled split."""
    total = 35.0  # a total no other test re-plans at
    planner = replanner(adaptive_program.model, adaptive_program.resolution)
    saved = dict(planner.costs)
    planner.costs["WorkClock"] = (1e9, 1.0, 1)
    try:
        searched = planner.searches
        fixed = run_program(adaptive_program, {"seed": 3}, total)
        adaptive = run_program(adaptive_program, {"seed": 3}, total, adaptive=True)
        assert planner.searches == searched
        assert adaptive.allocations == fixed.allocations
    finally:
        planner.costs.clear()
        planner.costs.update(saved)


@settings(max_examples=40, deadline=None)
@given(
    level=st.sampled_from([*LEVELS, 0.3, 0.77, -1.0]),
    total=st.sampled_from([10.0, 20.0, 25.0, 40.0]),
    share=st.floats(0.0, 1.0),
)
def test_a_new_split_is_kept_only_where_it_is_expected_to_beat_the_planned_one(
    adaptive_program: CompiledProgram, level: float, total: float, share: float
) -> None:
    """For any observed quality of roll (-1: no result) and any planned split of the time
    between refine2 and polish, the allocation `plan` answers spends exactly that time
    (where it re-splits) and is expected to do at least as well as the planned one, at the
    observed quality rounded to `QUANTUM`."""
    planner = Replanner(adaptive_program.model, adaptive_program.resolution)
    kept = np.array([0.0, share * total, (1 - share) * total])
    new = planner.plan([], kept, [1, 2], total, {0: level})
    assert new is not None
    seen = level if level < 0 else round(level / QUANTUM) * QUANTUM
    evaluator = Evaluator(adaptive_program.model)
    value = evaluator.expected([], np.vstack([new, kept]), {0: seen})
    assert value[0] >= value[1] - 1e-12
    if not np.array_equal(new, kept):
        assert new[1:].sum() == pytest.approx(total, abs=1e-9)
        assert value[0] > value[1]
    assert planner.plan([], kept, [1, 2], total, {0: level}, search=False) is not None


def test_a_planner_remembers_at_most_its_cache_size(adaptive_program: CompiledProgram) -> None:
    planner = Replanner(adaptive_program.model, adaptive_program.resolution)
    for k in range(CACHE_SIZE + 5):
        planner.plans[k] = None
    planner.plan([], np.array([0.0, 5.0, 5.0]), [1, 2], 10.0, {0: 0.5})
    assert len(planner.plans) == CACHE_SIZE
    assert 0 not in planner.plans


def test_a_search_is_worth_making_where_its_gain_beats_what_its_time_is_worth(
    adaptive_program: CompiledProgram,
) -> None:
    """`worth`: free on the work clock; never when it would take all the time left; else
    where its expected gain is more than the compiled profile's gain over its last `cost` of
    the time left."""
    execution = Execution(adaptive_program, {"seed": 0}, Budget(40.0, WorkClock()), True, SOFT, {})
    expected = adaptive_program.profile.expected(np.zeros((2, 0)), np.array([30.0, 25.0]))
    lost = float(expected[0] - expected[1])
    assert lost > 0
    assert execution.worth(0.0, 0.0, 30.0)
    assert not execution.worth(30.0, 1.0, 30.0)
    assert execution.worth(5.0, lost + 1e-6, 30.0)
    assert not execution.worth(5.0, lost, 30.0)


@pytest.mark.parametrize("one_call", [True, False])
@pytest.mark.parametrize("total", [20.0, 40.0])
@pytest.mark.parametrize("level", LEVELS)
def test_a_re_plan_is_the_compilers_search(
    adaptive_program: CompiledProgram,
    monkeypatch: pytest.MonkeyPatch,
    one_call: bool,
    total: float,
    level: float,
) -> None:
    """Where it re-splits, a re-plan is what `reallocate` (the compiler's search on the
    lattice) answers, whether every split is evaluated in one call or the search runs."""
    if not one_call:
        # The package's name `reallocate` is the function: the module is looked up.
        module = importlib.import_module("anytime.compiler.allocators.reallocate")
        monkeypatch.setattr(module, "ONE_CALL_ROWS", 0)
    model, resolution = adaptive_program.model, adaptive_program.resolution
    kept = adaptive_program.allocation_at([], total)
    new = Replanner(model, resolution).plan([], kept, [1, 2], total, {0: level})
    searched = reallocate(model, resolution, [], kept, [1, 2], total, {0: level})
    assert new is not None
    if not np.array_equal(new, kept):
        np.testing.assert_allclose(new, searched)
