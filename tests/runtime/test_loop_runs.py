"""Running loops: a map's calls each get the run-time split of the loop's share at its own item's
quality, the result is the list of their results with their mean quality; a repeat's calls get
equal shares; a collection of another size than planned re-plans the time left; bad
collections are clear errors; and a program with a loop plots."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import pytest
from loop_modules import loop_library

from anytime.clocks import WorkClock
from anytime.compiler import CompiledProgram, compile_file
from anytime.compiler.loops import run_time_split
from anytime.compiler.model import LoopNode
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.measure.builder import build_profile
from anytime.modules import Context, Registry, Result, interruptible
from anytime.problems import Instance
from anytime.runtime import Budget, ExecutionError, Status, run_program

LOOPS = """
(defschema tours (depots) (map tour depots))
(defschema triple (x) (repeat 3 (tour x)))
(defschema plan (sensor depots)
  (setf world (sense sensor))
  (best-of (map tour depots :max 3) world))
(defschema climbs (depots) (map climb depots :max 3))
(defschema deliver (sensor depots)
  (setf world (sense sensor))
  (map route depots world :max 3))
(defschema deliver-one (sensor depots)
  (setf world (sense sensor))
  (map route depots world :max 1))
"""


def compiled(name: str) -> CompiledProgram:
    schemas = parse_schemas(LOOPS)
    return compile_file(schemas, loop_library(), range(0, 41, 4), schema=name, resolution=1.0)[-1]


def test_a_map_runs_one_call_per_item_with_the_run_time_split() -> None:
    run = run_program(compiled("tours"), [["a", "b", Result("c", 0.5)]], 30)
    assert run.status == Status.COMPLETED
    assert [r.module for r in run.records] == ["map tour", "tour", "tour", "tour"]
    assert [r.allocation for r in run.records] == [30.0, 12.0, 12.0, 6.0]
    assert run.result is not None
    assert run.result.value == [("a", 12.0), ("b", 12.0), ("c", 6.0)]
    calls = [r.quality for r in run.records[1:]]
    assert run.quality == pytest.approx(np.mean(calls))
    assert calls[2] == pytest.approx(0.5 * -np.expm1(-0.6))


def test_the_items_quality_is_the_collections_unless_it_has_its_own() -> None:
    run = run_program(compiled("tours"), [Result(["a", Result("b", 1.0)], 0.5)], 30)
    shares = run_time_split(
        next(n for n in compiled("tours").model.nodes if isinstance(n, LoopNode)).call,
        np.array([[0.5], [1.0]]),
        30.0,
        1.0,
    )
    assert [r.allocation for r in run.records[1:]] == list(shares)
    assert shares[0] < shares[1]


def test_a_map_over_no_items_has_an_empty_result_of_quality_one() -> None:
    run = run_program(compiled("tours"), [[]], 20)
    assert run.status == Status.COMPLETED
    assert run.result == Result([], 1.0)
    assert [r.module for r in run.records] == ["map tour"]


def test_a_call_given_no_time_counts_in_the_mean() -> None:
    """Two climbs with 16 units: all to the first; the second answers at once, with nothing."""
    run = run_program(compiled("climbs"), [["a", "b"]], 16)
    assert run.result == Result([("a", 16.0), ("b", 0.0)], 0.5)
    assert [r.allocation for r in run.records] == [16.0, 16.0, 0.0]


def test_a_repeat_gives_its_calls_equal_shares() -> None:
    run = run_program(compiled("triple"), ["x"], 24)
    assert [r.allocation for r in run.records] == [24.0, 8.0, 8.0, 8.0]
    assert run.quality == pytest.approx(-np.expm1(-0.8))


def test_a_collection_of_another_size_than_planned_re_plans_the_time() -> None:
    """Planned for three items, a run over one splits the time as the table compiled for one
    item does: the loop needs less, sensing gets more."""
    deliver, one = compiled("deliver"), compiled("deliver-one")
    assert list(deliver.allocation_at([1.0], 12)) == [6.0, 6.0]
    assert list(one.allocation_at([1.0], 12)) == [7.0, 5.0]
    run = run_program(deliver, [0, ["a"]], 12)
    assert [(r.module, r.allocation) for r in run.records] == [
        ("sense", 7.0),
        ("map route", 5.0),
        ("route", 5.0),
    ]
    assert run.allocations == (7.0, 5.0)


def test_a_collection_that_is_not_a_sequence_is_an_error() -> None:
    with pytest.raises(ExecutionError) as raised:
        run_program(compiled("tours"), [42], 20)
    assert str(raised.value) == (
        "schema 'tours': the collection of map 't1' must be a sequence (a list or a tuple), got int"
    )


def test_a_program_with_a_loop_plots(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from anytime.plot import plot_compiled

    path = tmp_path / "plan.png"
    plot_compiled(compiled("plan"), path)
    assert path.stat().st_size > 0


@pytest.mark.parametrize("total", [8, 16, 40])
def test_what_runs_is_what_was_compiled_even_on_a_coarse_lattice(total: int) -> None:
    """Four items at quality 1, a lattice of 8: equal shares of the whole share, at compile
    time as at run time."""
    schemas = parse_schemas(LOOPS)
    tours = compile_file(schemas, loop_library(), range(0, 41, 8), schema="tours")[-1]
    run = run_program(tours, [["a", "b", "c", "d"]], total)
    assert [r.allocation for r in run.records[1:]] == [total / 4] * 4
    assert run.quality == pytest.approx(tours.expected[-1][total // 8])


LATE = Registry()


@interruptible("late", inputs=["depot"], registry=LATE, step=0)
def late(ctx: Context, depot: Result) -> Iterator[Result]:
    """Nothing for 10 ticks, then its input's quality; it stops when its time is up (step 0)."""
    for _ in range(10):
        if ctx.expired:
            return
        ctx.tick(1)
    yield Result(depot.value, depot.quality)


class LateProblems:
    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance((Result("x", input_qualities[0]),), input_qualities[0])

    def score(self, instance: Instance, value: Any) -> float:
        return float(instance.reference)


def test_a_call_its_profile_gives_no_result_is_not_started() -> None:
    """Two items, 12 ticks: one call gets the 10 it needs, the other what is left that could
    help it, nothing. Its profile gives it no result with that, so it is not started (as a
    module call of a program is not), and its record says why."""
    profile = build_profile(
        late, LateProblems(), time=[0, 2, 10, 12], input_grids=[[0.0, 1.0]], trials=4
    ).profile
    library = AnytimeLibrary()
    library.add(LibraryEntry.of_module(attrs.evolve(late, profile_source=profile)))
    schemas = parse_schemas("(defschema lates (depots) (map late depots :max 2))")
    lates = compile_file(schemas, library, [0, 12], schema="lates", resolution=1.0)[-1]
    run = run_program(lates, [["a", "b"]], Budget(12, clock=WorkClock()))
    ran, skipped = sorted(run.records[1:], key=lambda r: r.status == Status.NO_RESULT)
    assert (ran.result is not None, ran.allocation) == (True, 10.0)
    assert (skipped.status, skipped.time_used) == (Status.NO_RESULT, 0.0)
    assert skipped.error == "not run: with 0 of its share of 0 its profile gives it no result"
    assert (run.quality, run.time_used) == (0.5, 10.0)
