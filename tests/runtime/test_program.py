"""`run_program`: a compiled program through the executor, with a fixed or adaptive allocation.

The same answer as `CompiledProgram.run` for deterministic toy modules; one record per call with
its allocation; the program's status when a module fails (later modules still run, with the best
result it registered), registers nothing, or overruns; allocations that spend exactly the total;
hard interruption inside a program; and adaptive mode on a synthetic program whose first module's
quality is random, where re-allocating on the observed quality beats the fixed allocation.
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from toy_modules import toy_registry

from anytime.clocks import WorkClock
from anytime.compiler import CompiledProgram, compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, contract, elementary, interruptible
from anytime.profiles import ConditionalPerformanceProfile, default_bins, new_profile, tabulate
from anytime.runtime import (
    Budget,
    ExecutionError,
    Hard,
    Isolated,
    ProgramRecord,
    Status,
    run_program,
)
from anytime.vocabulary import ProfileKind as Kind

#: Totals 0..40 on a lattice of 5 ticks, and the program input-quality grid.
TIME = np.arange(0, 41, 5, dtype=np.float64)
QUALITY = [0.0, 0.5, 1.0]
LINEAR = [[0.0, 1.0]]  # an input grid on which a curve linear in q interpolates exactly


class Boom(Exception):
    pass


def rising(rate: float) -> Any:
    """t -> 1 - exp(-rate t)."""
    return lambda t: -np.expm1(-rate * np.asarray(t, dtype=np.float64))


def scaled(rate: float) -> Any:
    """(t, q) -> q (1 - exp(-rate t)): linear in q."""
    return lambda t, q: np.asarray(q) * -np.expm1(-rate * np.asarray(t, dtype=np.float64))


def conditional(
    rate: float, kind: Kind = "interruptible", input: str = "m"
) -> ConditionalPerformanceProfile:
    """q (1 - exp(-rate t)) on its one input `input`."""
    return tabulate(scaled(rate), TIME, input_grids=LINEAR, inputs=[input], kind=kind)


def library(registry: Registry) -> AnytimeLibrary:
    return AnytimeLibrary.default(registry=registry, plugins=False)


def compiled(text: str, registry: Registry, **options: Any) -> CompiledProgram:
    program = next(iter(parse_schemas(text, "p.any").programs))
    return compile_program(program, library(registry), TIME, QUALITY, **options)


# --- (a) the same answer as CompiledProgram.run -----------------------------------------------

TOY = toy_registry()  # sense, guess, both, refine (tests/toy_modules.py)


@elementary("tag", inputs=["a"], registry=TOY)
def tag(a: Result, factor: int = 1) -> Any:
    return (a.value, factor)


TOY_TEXT = "(defschema p (x) (refine (both (sense x) (guess x))))"


@pytest.fixture(scope="module")
def toy() -> CompiledProgram:
    return compiled(TOY_TEXT, TOY)


def test_a_program_answers_like_the_compiled_program(toy: CompiledProgram) -> None:
    assert toy.modules == ("sense", "guess", "refine")
    for i, q in enumerate(QUALITY):
        for j, total in enumerate(TIME):
            clock = WorkClock()
            record = run_program(toy, {"x": Result("map", q)}, Budget(total, clock=clock))
            expected = run_program(toy, {"x": Result("map", q)}, total).result
            assert record.result == expected, (q, total)
            assert record.quality == pytest.approx(toy.expected[i, j], abs=1e-12)
            assert record.status == Status.COMPLETED
            assert record.time_used == clock.now() == total
            assert run_program(toy, [Result("map", q)], total).result == expected


def test_a_program_keeps_one_record_per_call_with_its_allocation(toy: CompiledProgram) -> None:
    total = 30.0
    record = run_program(toy, {"x": Result("map", 1.0)}, total)
    allocation = toy.allocation_at([1.0], total)
    assert record.allocations == tuple(allocation)
    assert sum(record.allocations) == total
    assert [r.module for r in record.records] == ["sense", "guess", "both", "refine"]
    assert [r.status for r in record.records] == [
        Status.INTERRUPTED,
        Status.COMPLETED,
        Status.COMPLETED,
        Status.INTERRUPTED,
    ]
    sense_record, guess_record, both_record, refine_record = record.records
    assert [sense_record.allocation, guess_record.allocation, refine_record.allocation] == list(
        allocation
    )
    assert both_record.allocation == math.inf and both_record.time_used == 0
    assert [r.time_used for r in record.records] == [*allocation[:2], 0.0, allocation[2]]
    assert both_record.result == Result(
        (sense_record.result.value, "guessed"),  # type: ignore[union-attr]
        min(sense_record.quality, guess_record.quality),
    )
    assert record.result == refine_record.result
    assert refine_record.result.value == ("plan", both_record.result.value)  # type: ignore[union-attr]


def test_an_elementary_call_gets_its_keyword_arguments() -> None:
    program = compiled("(defschema kw (x) (tag (sense x) :factor 3))", TOY)
    expected = run_program(program, {"x": Result("map", 1.0)}, 20).result
    assert expected.value[1] == 3
    assert run_program(program, {"x": Result("map", 1.0)}, 20).result == expected


def test_missing_inputs_are_an_error_as_for_the_compiled_program(toy: CompiledProgram) -> None:
    with pytest.raises(ExecutionError, match=r"^schema 'p': missing inputs: x$"):
        run_program(toy, {"y": Result("map", 1.0)}, 10)


# --- (b) statuses ---------------------------------------------------------------------------

CHAIN = Registry()


@interruptible("first", inputs=["x"], profile=conditional(0.1, input="x"), registry=CHAIN)
def first(ctx: Context, x: Result) -> Iterator[Result]:
    while True:
        yield Result(("first", ctx.elapsed), float(scaled(0.1)(ctx.elapsed, x.quality)))
        ctx.tick(1)


@interruptible("middle", inputs=["m"], profile=conditional(0.1), registry=CHAIN)
def middle(ctx: Context, m: Result, k: int) -> Iterator[Result]:
    """Yields k results, then raises."""
    for i in range(k):
        ctx.tick(1)
        yield Result(("middle", i, m.value), m.quality * (i + 1) / (k + 1))
    raise Boom("middle gave up")


@interruptible("last", inputs=["m"], profile=conditional(0.1), registry=CHAIN)
def last(ctx: Context, m: Result) -> Iterator[Result]:
    while True:
        yield Result(("last", m.value), float(scaled(0.1)(ctx.elapsed, m.quality)))
        ctx.tick(1)


@interruptible("silent", inputs=["m"], profile=conditional(0.1), registry=CHAIN)
def silent(ctx: Context, m: Result) -> Iterator[Result]:
    ctx.tick(ctx.allocation)
    return
    yield


@contract("greedy", inputs=["m"], profile=conditional(0.1, "contract"), registry=CHAIN)
def greedy(ctx: Context, m: Result) -> Result:
    ctx.tick(ctx.allocation + 5)
    return Result("late", m.quality)


@pytest.mark.parametrize("k", [0, 2])
def test_a_failing_middle_module_fails_the_program_and_the_rest_still_runs(k: int) -> None:
    program = compiled("(defschema p (x k) (last (middle (first x) k)))", CHAIN)
    total = 30.0
    allocation = program.allocation_at([1.0], total)
    assert allocation[1] >= k  # the middle module reaches its k-th yield in time
    record = run_program(program, {"x": Result("map", 1.0), "k": k}, total)
    first_record, middle_record, last_record = record.records
    assert [r.status for r in record.records] == [
        Status.INTERRUPTED,
        Status.FAILED,
        Status.INTERRUPTED if k else Status.NO_RESULT,
    ]
    assert middle_record.error == f"{Boom.__module__}.Boom: middle gave up"
    assert middle_record.traceback is not None and ", in middle" in middle_record.traceback
    assert record.status == Status.FAILED
    if k:
        assert first_record.result is not None
        best = Result(
            ("middle", k - 1, first_record.result.value), first_record.quality * k / (k + 1)
        )
        assert middle_record.result == best
        assert record.result == last_record.result
        assert record.result == Result(
            ("last", best.value), float(scaled(0.1)(allocation[2], best.quality))
        )
    else:  # no placeholder: the next module is not called on "no output"
        assert middle_record.result is None
        assert (last_record.result, last_record.time_used) == (None, 0.0)
        assert last_record.error == "not run: its input from 'middle' has no result"
        assert record.result is None


@interruptible("crasher", inputs=["m"], profile=conditional(0.1), registry=CHAIN)
def crasher(ctx: Context, m: Result, k: int) -> Iterator[Result]:
    """Yields k results, then ends its process."""
    for i in range(k):
        ctx.tick(1)
        yield Result(("middle", i, m.value), m.quality * (i + 1) / (k + 1))
    os._exit(9)


def test_isolated_a_crashing_module_loses_its_own_result_only_and_the_program_goes_on() -> None:
    k = 2
    inputs = {"x": Result("map", 1.0), "k": k}
    raising = run_program(
        compiled("(defschema p (x k) (last (middle (first x) k)))", CHAIN), inputs, 30.0
    )
    program = compiled("(defschema p (x k) (last (crasher (first x) k)))", CHAIN)
    record = run_program(program, inputs, 30.0, mode=Isolated())
    assert [r.status for r in record.records] == [
        Status.INTERRUPTED, Status.CRASHED, Status.INTERRUPTED,
    ]  # fmt: skip
    crashed = record.records[1]
    assert (crashed.exit_code, crashed.error) == (
        9,
        "its process exited with code 9 before it answered",
    )
    assert record.status == Status.FAILED
    # The same answer as when the middle module raises in-process at the same point.
    assert [r.result for r in record.records] == [r.result for r in raising.records]
    assert record.result == raising.result


def test_a_program_whose_output_registers_nothing_has_no_result() -> None:
    program = compiled("(defschema p (x) (silent (first x)))", CHAIN)
    record = run_program(program, {"x": Result("map", 1.0)}, 20)
    assert (record.status, record.result, record.quality) == (Status.NO_RESULT, None, 0.0)
    assert record.records[-1].status == Status.NO_RESULT
    assert record.time_used == 20


def test_a_program_that_overruns_its_total_expires() -> None:
    program = compiled("(defschema p (x) (greedy (first x)))", CHAIN)
    record = run_program(program, {"x": Result("map", 1.0)}, 20)
    assert record.records[-1].status == Status.CONTRACT_EXPIRED
    assert record.status == Status.CONTRACT_EXPIRED
    assert record.time_used == 25
    assert record.result == Result("late", record.records[0].quality)


# --- (c) allocations spend the total --------------------------------------------------------

CONTRACTS = Registry()


def exact_contract(name: str, rate: float) -> None:
    def body(ctx: Context, m: Result) -> Result:
        ctx.tick(ctx.allocation)
        return Result((name, ctx.allocation), float(scaled(rate)(ctx.allocation, m.quality)))

    body.__name__ = body.__qualname__ = name
    contract(name, inputs=["m"], profile=conditional(rate, "contract"), registry=CONTRACTS)(body)


for _name, _rate in (("ca", 0.1), ("cb", 0.05), ("cc", 0.2)):
    exact_contract(_name, _rate)

CONTRACT_CHAIN = "(defschema p (x) (cc (cb (ca x))))"


@pytest.fixture(scope="module")
def contract_chain() -> CompiledProgram:
    return compiled(CONTRACT_CHAIN, CONTRACTS)


@settings(max_examples=60, deadline=None)
@given(total=st.floats(0, 40), q=st.floats(0, 1), adaptive=st.booleans())
def test_the_allocations_spend_exactly_the_total(
    contract_chain: CompiledProgram, total: float, q: float, adaptive: bool
) -> None:
    """Contract modules spend exactly what they are given, so the total is spent exactly, in
    fixed and in adaptive mode, on and off the compiled lattice."""
    record = run_program(contract_chain, {"x": Result("map", q)}, total, adaptive=adaptive)
    assert len(record.allocations) == 3
    assert all(a >= 0 for a in record.allocations)
    assert sum(record.allocations) == pytest.approx(total, abs=1e-9)
    assert [r.allocation for r in record.records] == list(record.allocations)
    assert record.time_used == pytest.approx(total, abs=1e-9)
    assert record.status == Status.COMPLETED


# --- (d) hard interruption inside a program --------------------------------------------------

STUCK = Registry()


@interruptible("wedge", inputs=["x"], profile=conditional(0.1, input="x"), registry=STUCK)
def wedge(ctx: Context, x: Result, release: threading.Event) -> Iterator[Result]:
    """Registers a result, works past its deadline (on the work clock the deadline has passed
    only once the module ticks past it), then is stuck until released."""
    yield Result("wedged", 0.5 * x.quality)
    ctx.tick(ctx.allocation + 1)
    release.wait(30)
    yield Result("late", x.quality)


@interruptible("after", inputs=["m"], profile=conditional(0.1), registry=STUCK)
def after(ctx: Context, m: Result) -> Iterator[Result]:
    while True:
        yield Result(("after", m.value), float(scaled(0.1)(ctx.elapsed, m.quality)))
        ctx.tick(1)


@pytest.fixture
def release() -> Iterator[threading.Event]:
    event = threading.Event()
    yield event
    event.set()


@pytest.mark.parametrize("own_stop", [False, True], ids=["no stop", "caller's stop"])
def test_a_stuck_module_cut_off_by_hard_interruption_does_not_stop_the_rest(
    release: threading.Event, own_stop: bool
) -> None:
    """The first module is cut off at its deadline; the next one still gets its time and
    registers results, also when the caller passed a `stop` event of its own (to be able to
    interrupt the program) and did not set it."""
    program = compiled("(defschema p (x release) (after (wedge x release)))", STUCK)
    stop = threading.Event() if own_stop else None
    record = run_program(
        program, {"x": Result("map", 1.0), "release": release}, Budget(20, stop=stop), mode=Hard()
    )
    wedge_record, after_record = record.records
    assert (wedge_record.status, wedge_record.result) == (
        Status.INTERRUPTED,
        Result("wedged", 0.5),
    )
    assert after_record.result is not None
    assert after_record.result.value == ("after", "wedged")
    assert record.result == after_record.result
    # The wedge overran by one tick; the next module gets one tick less, so the program keeps
    # its contract.
    assert record.status == Status.COMPLETED
    assert record.time_used == 20


# --- (e) adaptive mode ------------------------------------------------------------------------

ADAPTIVE = Registry()
#: roll's quality is one of three bin midpoints, drawn per run; its profile says so.
LEVEL_BINS = (1, 5, 9)
CHANCES = (0.4, 0.2, 0.4)


def roll_profile() -> ConditionalPerformanceProfile:
    probability = np.zeros((len(TIME), 10))
    probability[:, LEVEL_BINS] = CHANCES
    return new_profile(
        input_grids=[], time=TIME, bins=default_bins(), probability=probability, module="roll"
    )


ROLL = roll_profile()
LEVELS = tuple(float(ROLL.values[k]) for k in LEVEL_BINS)  # 0.15, 0.55, 0.95
RATE = 0.1


def draw_level(seed: int) -> float:
    return LEVELS[int(np.random.default_rng(seed).choice(len(LEVELS), p=CHANCES))]


@interruptible("roll", inputs=[], profile=ROLL, registry=ADAPTIVE)
def roll(ctx: Context, seed: int) -> Iterator[Result]:
    """A first module whose output quality varies from run to run, whatever its time."""
    level = draw_level(seed)
    while True:
        yield Result(("roll", seed), level)
        ctx.tick(1)


@interruptible("refine2", inputs=["m"], profile=conditional(RATE), registry=ADAPTIVE)
def refine2(ctx: Context, m: Result) -> Iterator[Result]:
    """Improves on its input at a rate proportional to the input's quality."""
    while True:
        yield Result(("refined", m.value), float(scaled(RATE)(ctx.elapsed, m.quality)))
        ctx.tick(1)


@interruptible("polish", inputs=[], profile=tabulate(rising(RATE), TIME), registry=ADAPTIVE)
def polish(ctx: Context, seed: int) -> Iterator[Result]:
    """Independent of the first module."""
    while True:
        yield Result("polished", float(rising(RATE)(ctx.elapsed)))
        ctx.tick(1)


@interruptible("early", inputs=[], profile=tabulate(rising(0.1), TIME), registry=ADAPTIVE)
def early(ctx: Context, seed: int) -> Iterator[Result]:
    """Its profile promises gains up to 40 ticks, but it is done after 3."""
    ctx.tick(3)
    yield Result(("early", seed), draw_level(seed))


def average(qualities: Sequence[float]) -> float:
    return sum(qualities) / len(qualities)


@elementary("mean2", combine=average, registry=ADAPTIVE)
def mean2(a: Result, b: Result) -> Any:
    return (a.value, b.value)


ADAPTIVE_TEXT = "(defschema p (seed) (mean2 (refine2 (roll seed)) (polish seed)))"
SEEDS = range(200)


@pytest.fixture(scope="module")
def adaptive_program() -> CompiledProgram:
    return compiled(ADAPTIVE_TEXT, ADAPTIVE, allocator="exhaustive")


def best_split(level: float, total: float) -> float:
    """The best time for refine2 on the lattice when the first module's quality is `level`."""
    t = np.arange(0, total + 1e-9, 5.0)
    value = level * rising(RATE)(t) + rising(RATE)(total - t)
    return float(t[np.argmax(value)])


@pytest.mark.parametrize("total", [20.0, 40.0])
def test_adaptive_mode_never_does_worse_than_the_fixed_allocation(
    adaptive_program: CompiledProgram, total: float
) -> None:
    """Over 200 seeded runs the first module's quality is 0.15, 0.55 or 0.95. The fixed
    allocation is the best in expectation; adaptive mode re-splits the rest between refine2
    (whose gains scale with that quality) and polish once it has seen it. Paired per seed it is
    never worse, so neither is its mean; and it is better by a margin, so the test has teeth."""
    assert adaptive_program.modules == ("roll", "refine2", "polish")
    j = int(np.flatnonzero(TIME == total)[0])
    fixed_split = adaptive_program.allocation[j]
    assert fixed_split[0] == 0  # roll's time buys nothing
    fixed, adaptive = [], []
    for seed in SEEDS:
        level = draw_level(seed)
        plain = run_program(adaptive_program, {"seed": seed}, total)
        smart = run_program(adaptive_program, {"seed": seed}, total, adaptive=True)
        for record in (plain, smart):
            assert record.status == Status.COMPLETED
            assert record.records[0].quality == level
            assert sum(record.allocations) == pytest.approx(total, abs=1e-9)
            assert record.time_used == total
        assert plain.allocations == tuple(fixed_split)
        assert smart.allocations[1] == best_split(level, total)
        assert smart.quality >= plain.quality - 1e-9, seed
        fixed.append(plain.quality)
        adaptive.append(smart.quality)
    fixed_mean, adaptive_mean = float(np.mean(fixed)), float(np.mean(adaptive))
    gain = np.asarray(adaptive) - np.asarray(fixed)
    assert adaptive_mean >= fixed_mean - 1e-9
    assert gain.mean() > 0.003
    # The fixed allocation gets what the compiled profile expects, within sampling error.
    se = float(np.std(fixed, ddof=1)) / math.sqrt(len(fixed))
    assert abs(fixed_mean - adaptive_program.expected[j]) < 4 * se


def test_adaptive_mode_gives_the_rest_the_time_a_module_left_unused() -> None:
    program = compiled(
        "(defschema p (seed) (mean2 (refine2 (early seed)) (polish seed)))", ADAPTIVE
    )
    total = 40.0
    plain = run_program(program, {"seed": 1}, total)
    assert plain.allocations[0] > 3  # its profile earns it time it will not use
    smart = run_program(program, {"seed": 1}, total, adaptive=True)
    early_record, refine_record, polish_record, _ = smart.records
    assert (early_record.status, early_record.time_used) == (Status.COMPLETED, 3.0)
    assert refine_record.allocation + polish_record.allocation == total - 3
    assert smart.time_used == total
    assert plain.time_used == total - plain.allocations[0] + 3
    assert smart.quality >= plain.quality


def test_a_program_run_on_the_work_clock_is_deterministic(toy: CompiledProgram) -> None:
    record = run_program(toy, {"x": Result("map", 0.5)}, 10, adaptive=True)
    assert isinstance(record, ProgramRecord)
    assert record == run_program(toy, {"x": Result("map", 0.5)}, 10, adaptive=True)
