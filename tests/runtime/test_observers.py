"""The run hook: an observer sees each result a run keeps, looks at the times it asks for on the
run's clock (at the report of work that reaches them, whether or not the module registers
anything there), may stop the run, and sees its record; in every mode the same looks and the
same record on the work clock. `run` takes one mode value and at most six parameters."""

from __future__ import annotations

import inspect
import math
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.modules import AnytimeModule, Context, Registry, Result, contract, interruptible
from anytime.runtime import (
    Budget,
    Decision,
    Hard,
    Isolated,
    Observer,
    RunRecord,
    Soft,
    Status,
    run,
    run_program,
)

TOYS = Registry()
MODES = pytest.mark.parametrize(
    "mode", [Soft(), Hard(), Isolated(watchdog=10)], ids=["soft", "hard", "isolated"]
)


@interruptible("sparse", inputs=[], registry=TOYS)
def sparse(ctx: Context, every: int) -> Iterator[Result]:
    """One tick at a time, a result every `every` ticks (quality: the ticks so far / 100)."""
    n = 0
    while not ctx.expired:
        ctx.tick()
        n += 1
        if n % every == 0:
            yield Result(n, min(1.0, n / 100))


@contract("fixed-work", inputs=[], registry=TOYS)
def fixed_work(ctx: Context, work: int) -> Result:
    for _ in range(work):
        ctx.tick()
    return Result(work, 0.5)


class Looker(Observer):
    """Looks every `period` ticks from `first`, stops at its `stop`-th look; notes everything."""

    def __init__(self, first: float, period: float, stop: int | None = None) -> None:
        self.first, self.period, self.stop = first, period, stop
        self.calls: list[tuple[Any, ...]] = []

    def started(self, module: AnytimeModule, args: Sequence[Any], allocation: float) -> Decision:
        self.calls.append(("started", module.name, tuple(args), allocation))
        return Decision(False, look_at=self.first)

    def registered(self, elapsed: float, result: Result) -> None:
        self.calls.append(("registered", elapsed, result.value))

    def look(self, elapsed: float, best: Result | None) -> Decision:
        looks = sum(1 for c in self.calls if c[0] == "look") + 1
        self.calls.append(("look", elapsed, None if best is None else best.value))
        return Decision(looks == self.stop, look_at=elapsed + self.period)

    def ended(self, record: RunRecord) -> None:
        self.calls.append(("ended", record.status, record.time_used))


def test_looks_come_at_the_ticks_asked_for_not_only_at_results() -> None:
    looker = Looker(first=3, period=5)
    record = run(sparse, [10], budget=22, observer=looker)
    looks = [c[1:] for c in looker.calls if c[0] == "look"]
    # Nothing to look at before the first result (10): the looks due at 3 and 8 wait for it;
    # then a look at each tick asked for, between results (15) or at one (20), which it sees.
    assert looks == [(10.0, 10), (15.0, 10), (20.0, 20)]
    assert looker.calls[0] == ("started", "sparse", (10,), 22.0)
    assert [c for c in looker.calls if c[0] == "registered"] == [
        ("registered", 10.0, 10),
        ("registered", 20.0, 20),
    ]
    assert looker.calls[-1] == ("ended", Status.COMPLETED, 22.0)  # it saw expired and returned
    assert (record.looks, record.result) == (3, Result(20, 0.2))


def test_a_look_at_the_time_of_a_result_sees_that_result() -> None:
    looker = Looker(first=10, period=10)
    run(sparse, [10], budget=25, observer=looker)
    assert [c[1:] for c in looker.calls if c[0] == "look"] == [(10.0, 10), (20.0, 20)]


@MODES
def test_a_look_between_results_stops_the_run_with_its_best_result(mode: Any) -> None:
    """Its first look waits for the first result (10); stopped at its second look (tick 17),
    between results: status stopped, the answer the result of tick 10, and the same record in
    every mode on the work clock."""
    record = run(sparse, [10], budget=100, mode=mode, observer=Looker(first=7, period=7, stop=2))
    assert (record.status, record.result, record.looks) == (Status.STOPPED, Result(10, 0.1), 2)
    assert record.time_used <= 18  # the tick after the look at 17 is the module's last


def test_an_observer_that_fails_at_a_look_fails_the_run_and_keeps_the_best_result() -> None:
    class Broken(Observer):
        label = "my observer"

        def started(self, module: AnytimeModule, args: Sequence[Any], allocation: float) -> Any:
            return Decision(False, look_at=12)

        def look(self, elapsed: float, best: Result | None) -> Any:
            raise ValueError("no idea")

    record = run(sparse, [5], budget=100, observer=Broken())
    assert (record.status, record.error) == (Status.FAILED, "my observer: ValueError: no idea")
    assert record.result == Result(10, 0.1)


def test_an_observer_that_answers_garbage_fails_the_run() -> None:
    class Garbage(Observer):
        def registered(self, elapsed: float, result: Result) -> Any:
            return "stop"

    record = run(sparse, [5], budget=100, observer=Garbage())
    assert (record.status, record.error) == (
        Status.FAILED,
        "observer: anytime.runtime.observe.PolicyError: observer answered with str 'stop', not"
        " a Decision",
    )


def test_an_observer_sees_a_contract_and_its_end() -> None:
    looker = Looker(first=math.inf, period=1)
    record = run(fixed_work, [7], budget=10, observer=looker)
    assert looker.calls == [
        ("started", "fixed-work", (7,), 10.0),
        ("registered", 7.0, 7),
        ("ended", Status.COMPLETED, 7.0),
    ]
    assert record.result == Result(7, 0.5)


def test_run_programs_observers_watch_the_named_modules() -> None:
    from anytime import AnytimeLibrary, RegistrySource, compile_file, parse_schemas
    from anytime.profiles import tabulate

    profile = tabulate(lambda t: np.minimum(t, 100) / 100, [0, 50, 100], module="sparse")
    registry = Registry()
    interruptible("sparse", inputs=[], profile=profile, registry=registry)(sparse.function)
    library = AnytimeLibrary([RegistrySource(registry)])
    schemas = parse_schemas("(defschema p (n) (sparse n))")
    [compiled] = compile_file(schemas, library, [0, 50, 100])
    looker = Looker(first=25, period=25)
    record = run_program(compiled, [10], 100, observers={"sparse": looker})
    assert record.result == Result(100, 1.0)
    # Not at 100: a look where the run ends anyway could not change its answer.
    assert [c[1] for c in looker.calls if c[0] == "look"] == [25.0, 50.0, 75.0]


@settings(max_examples=30, deadline=None)
@given(
    st.integers(1, 12),
    st.integers(0, 30),
    st.integers(1, 9),
    st.integers(1, 6),
    st.integers(5, 60),
)
def test_soft_and_hard_runs_make_the_same_looks(
    every: int, first: int, period: int, stop: int, allocation: int
) -> None:
    """On the work clock a run's looks and record do not depend on the mode."""
    outcomes = []
    for mode in (Soft(), Hard()):
        looker = Looker(first=first, period=period, stop=stop)
        record = run(sparse, [every], budget=allocation, mode=mode, observer=looker)
        outcomes.append((looker.calls, record.status, record.result, record.time_used))
    assert outcomes[0] == outcomes[1]


def test_run_takes_a_mode_and_at_most_six_parameters() -> None:
    parameters = inspect.signature(run).parameters
    assert len(parameters) <= 6
    assert {"budget", "mode", "observer"} <= set(parameters)
    with pytest.raises(TypeError, match=r"run: mode: expected Soft\(\), Hard\(\) or Isolated"):
        run(sparse, [5], budget=Budget(10), mode="hard")  # type: ignore[arg-type]


@interruptible("pressed", inputs=[], registry=TOYS)
def pressed(ctx: Context) -> Iterator[Result]:
    ctx.tick()
    yield Result("draft", 0.4)
    raise KeyboardInterrupt


def test_an_interrupted_run_crosses_a_process_boundary_with_its_record() -> None:
    """The builder's isolated trials send what their run raised to the caller: an interrupt
    arrives as itself, with its record."""
    import pickle

    from anytime.runtime import RunInterrupted

    with pytest.raises(RunInterrupted) as raised:
        run(pressed, budget=10)
    again = pickle.loads(pickle.dumps(raised.value))
    assert isinstance(again, RunInterrupted) and again.record == raised.value.record
    assert (again.record.status, again.record.result) == (Status.INTERRUPTED, Result("draft", 0.4))
