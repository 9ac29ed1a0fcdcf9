"""A compiled program keeps its contract on the work clock when a module overshoots: a module
may pass its allocation by its last step, and the calls after it then get that much less (the
calls after it ran on their full shares, and the program overran)."""

from __future__ import annotations

from collections.abc import Iterator

import attrs
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.clocks import WorkClock
from anytime.compiler import compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, interruptible
from anytime.profiles import tabulate
from anytime.runtime import Budget, Status, run_program

MODULES = Registry()
TIME = np.arange(0.0, 61.0, 10.0)


def _rising(t: object) -> object:
    return np.minimum(1.0, np.asarray(t, dtype=np.float64) / 30)


@interruptible("coarse-steps", inputs=[], profile=tabulate(_rising, TIME), registry=MODULES)
def coarse_steps(ctx: Context, x: object) -> Iterator[Result]:
    """Works in steps of 7 ticks, so it passes its allocation by up to 6."""
    done = 0
    while not ctx.expired:
        ctx.tick(7)
        done += 7
        yield Result(x, float(_rising(done)))


@interruptible(
    "fine-steps",
    inputs=["m"],
    profile=tabulate(lambda t, q: np.asarray(q) * _rising(t), TIME, input_grids=[[0.0, 1.0]]),
    registry=MODULES,
)
def fine_steps(ctx: Context, m: Result) -> Iterator[Result]:
    """Works one tick at a time: it never passes its allocation."""
    done = 0
    while True:
        yield Result(m.value, m.quality * float(_rising(done)))
        if ctx.remaining <= 0:
            return
        ctx.tick(1)
        done += 1


@pytest.fixture(scope="module")
def program() -> object:
    schema = parse_schemas("(defschema p (x) (fine-steps (coarse-steps x)))", "p.any")["p"]
    return compile_program(schema, AnytimeLibrary.default(registry=MODULES, plugins=False), TIME)


@pytest.mark.parametrize("total", [10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
def test_an_overshoot_is_taken_from_the_calls_after_it(program: object, total: float) -> None:
    """What the first module uses past its share comes off the second's, so the program keeps
    its total whenever the second's share can absorb it; what no later call can absorb (the
    last module's own overshoot) is still a contract-expired run, which reserving each
    module's measured step will remove."""
    planned = program.allocation_at([], total)
    record = run_program(program, {"x": "data"}, total)
    first, second = record.records
    overshoot = first.time_used - first.allocation
    assert 0 <= overshoot <= 6
    assert second.allocation == min(planned[1], max(0.0, total - first.time_used))
    if planned[1] >= overshoot:
        assert record.time_used <= total
        assert record.status == Status.COMPLETED
        clock = WorkClock()
        run_program(program, {"x": "data"}, Budget(total, clock=clock))
        assert clock.now() <= total


@pytest.fixture(scope="module")
def declared() -> object:
    """The same program, with the coarse module's step (7 ticks) declared."""
    registry = Registry()
    for module in MODULES:
        registry.add(attrs.evolve(module, step=7.0) if module.name == "coarse-steps" else module)
    schema = parse_schemas("(defschema p (x) (fine-steps (coarse-steps x)))", "p.any")["p"]
    library = AnytimeLibrary.default(registry=registry, plugins=False)
    return compile_program(schema, library, np.arange(0.0, 61.0, 1.0))


def test_with_its_step_kept_back_no_run_ends_over_its_total(declared: object) -> None:
    """Every total from 0 to 60 ticks: the coarse module runs with its share less 7, so it
    answers within its share, and the program within its total."""
    for total in np.arange(0.0, 61.0, 1.0):
        share = declared.allocation_at([], total)[0]
        record = run_program(declared, {"x": "data"}, total)
        first = record.records[0]
        assert record.time_used <= total, (total, record)
        assert first.time_used <= share + 1e-9
        if share < 7:  # it is not started: it could not be sure to answer within its share
            assert (first.status, first.time_used) == (Status.NO_RESULT, 0.0)
            assert first.error == (
                f"not run: its share ({share:g}) is less than its step (7): it could not be"
                " sure to answer within it"
            )
        else:
            assert first.allocation == share - 7


@settings(max_examples=200, deadline=None)
@given(share=st.floats(0, 1e6), step=st.floats(0, 1e6))
def test_a_module_runs_with_its_share_less_its_step(share: float, step: float) -> None:
    node = attrs.evolve(_node(), step=step)
    run = float(node.run_time(share))
    assert 0.0 <= run <= share
    assert bool(node.starts(share)) == (share >= step - 1e-9 * max(1.0, step))
    if node.starts(share):
        assert run + step <= share * (1 + 1e-12) + 1e-9


def _node() -> object:
    schema = parse_schemas("(defschema p (x) (coarse-steps x))", "p.any")["p"]
    compiled = compile_program(
        schema, AnytimeLibrary.default(registry=MODULES, plugins=False), TIME
    )
    return compiled.model.anytime_nodes[0]
