"""Contract -> interruptible: the schedules' acceleration ratios against the published formulas,
the analytic profile of the constructed algorithm, and real runs of the constructed module (on
the work clock, through a compiled program, and on two worker processes)."""

from __future__ import annotations

import math
import multiprocessing
import pickle
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.clocks import WallClock, WorkClock
from anytime.compiler import CompiledProgram, compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary, RegistrySource
from anytime.measure.builder import Measurement, ProfileRequest, profile_module
from anytime.modules import (
    AnytimeModule,
    Context,
    ModuleError,
    Registry,
    Result,
    contract,
    interruptible,
)
from anytime.problems import Instance
from anytime.profiles import (
    ConditionalPerformanceProfile,
    Exponential,
    PerformanceProfile,
    tabulate,
)
from anytime.runtime import Budget
from anytime.runtime.conversion import (
    ConversionError,
    interruptible_profile,
    make_interruptible,
)
from anytime.runtime.executor import run
from anytime.runtime.schedules import (
    Schedule,
    ScheduleError,
    geometric,
    optimal_ratio,
    randomised,
    round_robin,
    worst_ratio,
)

#: The contract of the profile tests: q(t) = 1 - exp(-t / 500), on a grid of one tick up to N.
N = 1024
CURVE = Exponential(rate=0.002)
CONTRACT_PROFILE = tabulate(CURVE, np.arange(N + 1.0), kind="contract", module="toy")

#: Modules the tests run; at the top level, so that worker processes can import them.
TOYS = Registry()


@contract("toy", profile=CONTRACT_PROFILE, registry=TOYS)
def toy(ctx: Context, problem: Any) -> Result:
    """Spends its whole allocation and answers with its profile's quality; the value is the
    allocation it was given. It reports the work in one tick (many small ones would drift in
    floating point); on the wall clock ticks move nothing, so it busy-waits the time out."""
    ctx.tick(ctx.allocation)
    if ctx.clock.unit == "seconds":
        while not ctx.expired:
            pass
    return Result(ctx.allocation, float(CURVE(ctx.allocation)))


@contract("hangs", profile=CONTRACT_PROFILE, registry=TOYS)
def hangs(ctx: Context, problem: Any) -> Result:
    """A contract that never ends and never looks at its context."""
    time.sleep(3600)
    raise AssertionError("unreachable")


@contract("interrupted-at-8", registry=TOYS)
def interrupted_at_8(ctx: Context, problem: Any) -> Result:
    """Ticks its allocation; halfway through the contract of length 8 the outside world
    interrupts the run (sets the shared stop), and the contract still returns something."""
    if ctx.allocation >= 8:
        ctx.tick(ctx.allocation / 2)
        ctx.stop.set()
        return Result("cut short", 1.0)
    ctx.tick(ctx.allocation)
    return Result(ctx.allocation, 0.5)


@contract("not-a-result", registry=TOYS)
def not_a_result(ctx: Context, problem: Any) -> Result:
    return 42  # type: ignore[return-value]


def drive(module: AnytimeModule, ctx: Context, *args: Any) -> list[tuple[float, Result]]:
    """Run an interruptible module to its end: (clock time, result) at every yield."""
    return [(ctx.clock.now(), result) for result in module(ctx, *args)]


def quality_at(trace: list[tuple[float, Result]], times: np.ndarray) -> np.ndarray:
    """The quality of the last result yielded at or before each time (0 before any)."""
    at = np.array([t for t, _ in trace])
    q = np.array([0.0] + [r.quality for _, r in trace])
    return q[np.searchsorted(at, times, side="right")]


# --- schedules and their acceleration ratios ----------------------------------------------------


def test_doubling_reaches_at_4t_the_contract_quality_at_t() -> None:
    """The analytic profile with r = 2: at 4t the interruptible algorithm is at least as good as
    the contract at t, for every t on the grid; and the worst case over the grid is 4 to within
    the grid (exactly what the grid allows, computed below)."""
    horizon = np.arange(4 * N + 1.0)  # every 4t on the grid, so nothing is interpolated
    profile = interruptible_profile(CONTRACT_PROFILE, geometric(1.0, 2.0), horizon)
    assert isinstance(profile, PerformanceProfile) and profile.kind == "interruptible"
    assert isinstance(CONTRACT_PROFILE, PerformanceProfile)
    t = CONTRACT_PROFILE.time
    contract_q = CONTRACT_PROFILE.expected_at(t)
    interruptible_q = profile.expected_at(horizon)
    assert np.all(interruptible_q[4 * t.astype(int)] >= contract_q - 1e-15)

    # The time the interruptible algorithm needs to reach the contract's quality at t (the
    # curve is strictly increasing, so qualities identify lengths), over t in [t0, N].
    reach = np.searchsorted(interruptible_q, contract_q[1:] - 1e-15) / t[1:]
    # Contracts 1, 2, 4, ... finish at 1, 3, 7, ..., 2^(k+1) - 1. The ratio jumps just above
    # each length L = 2^(k-1) to (2^(k+1) - 1) / L = 4 - 2 / L: the last L below N is 512, and
    # the first grid point above it is 513. So the grid's worst case is 2047 / 513.
    assert reach.max() == pytest.approx(2047 / 513, rel=1e-12)
    assert 4 - 2 / 512 - 4 / 513 <= reach.max() <= 4  # 4, less the horizon's and grid's shares


@settings(max_examples=40, deadline=None)
@given(r=st.floats(1.05, 6.0), t0=st.floats(0.01, 100.0), n=st.integers(2, 40))
def test_the_exact_worst_case_of_a_geometric_schedule(r: float, t0: float, n: int) -> None:
    """On lengths t0 r^k the sup of needed(t)/t over [t0, t0 r^(n-1)] is F_{n-1} / L_{n-2}
    = r^2/(r - 1) - 1/((r - 1) r^(n-2)): it grows to the formula without reaching it."""
    contracts = geometric(t0, r).contracts(t0 * r ** (n - 1) * (1 - 1e-9))
    up_to = t0 * r ** (n - 1)
    expected = r**2 / (r - 1) - 1 / ((r - 1) * r ** (n - 2))
    assert contracts.worst_ratio(up_to) == pytest.approx(expected, rel=1e-9)
    assert contracts.worst_ratio(up_to) <= geometric(t0, r).worst_case_ratio * (1 + 1e-12)


@pytest.mark.parametrize(
    ("m", "published"), [(1, 4.0), (2, 2.598), (3, 2.117), (4, 1.869)], ids=lambda x: str(x)
)
def test_round_robin_matches_the_optimal_ratio_on_m_workers(m: int, published: float) -> None:
    """Measured on a grid of times with ratio 1 + eps between neighbours, from t0 to H.

    The sup lies just above a length L_{k-1}, where contract k is needed; the first grid point
    above L_{k-1} is at most (1 + eps) L_{k-1}, so the grid misses the sup by a factor of at
    most 1 + eps. Contract k, the (j+1)-th on its worker (j = k div m), finishes at
    b^k (1 - b^(-m(j+1))) / (1 - b^(-m)), so the sup over (L_{k-1}, L_k] is the formula times
    1 - b^(-m(j+1)) > 1 - b^(-k): the horizon costs at most b^(-k) for the last L_{k-1} < H.
    And it never exceeds the formula. So: formula (1 - b^-k) / (1 + eps) <= measured <= formula.
    """
    schedule = round_robin(m, t0=1.0)
    theory = (m + 1) ** ((m + 1) / m) / m
    assert schedule.worst_case_ratio == pytest.approx(theory, rel=1e-12)
    assert optimal_ratio(m) == pytest.approx(theory, rel=1e-12)
    assert theory == pytest.approx(published, abs=5e-4)

    horizon, eps = 1e4, 1e-4
    grid = np.exp(np.arange(0.0, math.log(horizon), math.log1p(eps)))
    measured = float(schedule.contracts(horizon).ratio(grid).max())
    b = schedule.base
    k = math.floor(math.log(horizon, b)) + 1  # the last k with L_{k-1} = b^(k-1) below H
    assert theory * (1 - b**-k) / (1 + eps) <= measured <= theory
    assert measured == pytest.approx(theory, rel=2e-4)
    # And exactly, with no grid, far out: the formula to within b^-k.
    assert float(schedule.contracts(1e9).worst_ratio(1e9)) == pytest.approx(theory, rel=1e-8)


def test_round_robin_hands_contract_k_to_worker_k_mod_m() -> None:
    contracts = round_robin(3, t0=2.0).contracts(50.0)
    b = 4 ** (1 / 3)
    np.testing.assert_allclose(contracts.length, 2.0 * b ** np.arange(len(contracts.length)))
    assert contracts.worker.tolist() == [k % 3 for k in range(len(contracts.length))]
    for w in range(3):
        start, finish = contracts.per_worker(w)
        assert start[0] == 0.0
        np.testing.assert_allclose(start[1:], finish[:-1])  # back to back
    assert (np.diff(contracts.finish) > 0).all()  # so the last completed is the longest
    assert contracts.start.max() >= 50.0  # every contract that starts before the horizon


@pytest.mark.parametrize(("b", "workers"), [(math.e, 1), (2.0, 1), (4.0, 1), (math.e, 2)], ids=str)
def test_the_randomised_schedule_averages_b_over_ln_b(b: float, workers: int) -> None:
    """For a fixed t far into the schedule, the ratio over many draws of U averages
    (b - 1)/ln b * b^m/(b^m - 1) (b / ln b on one worker) within sampling error: four standard
    errors, plus the schedule's finite start, which lowers the ratio by at most a factor
    1 - b^-k, about 1e-9 here."""
    schedule = randomised(b, t0=1.0, workers=workers)
    rng = np.random.default_rng(7)
    u = rng.random(20_000)
    ratios = schedule.contracts(1e9, u).ratio(1e9)
    se = ratios.std() / math.sqrt(len(u))
    assert abs(ratios.mean() - schedule.expected_ratio) < 4 * se + 1e-6
    assert schedule.theory_ratio == schedule.expected_ratio
    if workers == 1:
        assert schedule.expected_ratio == pytest.approx(b / math.log(b), rel=1e-12)
    # Every single draw still has the deterministic worst case.
    assert float(schedule.contracts(1e9, u[0]).worst_ratio()) <= schedule.worst_case_ratio


def test_b_over_ln_b_is_smallest_at_e() -> None:
    bases = np.linspace(1.5, 6.0, 451)
    ratios = [randomised(b).expected_ratio for b in bases]
    assert bases[int(np.argmin(ratios))] == pytest.approx(math.e, abs=0.01)
    assert randomised(math.e).expected_ratio == pytest.approx(math.e, rel=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    r=st.floats(1.1, 5.0),
    m=st.integers(1, 4),
    u=st.floats(0.0, 0.999),
    x=st.floats(0.0, 1.0),
)
def test_at_c_times_t_a_contract_of_length_t_has_completed(
    r: float, m: int, u: float, x: float
) -> None:
    """The definition of the acceleration ratio c, for any base, worker count and offset."""
    schedule = Schedule(unit=1.0, base=r, workers=m)
    c = schedule.worst_case_ratio
    contracts = schedule.contracts(1e6, u)
    first = contracts.length[0]
    t = first * (1e6 / c / first) ** x  # from the first length to the horizon / c
    assert contracts.longest_completed(c * t * (1 + 1e-12)) >= t
    assert contracts.needed(t) <= c * t * (1 + 1e-12)


def test_worst_ratio_of_measured_contracts() -> None:
    assert float(worst_ratio([1, 2, 4], [1, 3, 7])) == pytest.approx(3.5)
    with pytest.raises(ScheduleError, match="lengths must increase"):
        worst_ratio([1, 4, 2], [1, 5, 7])


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: geometric(0.0, 2.0), "t0 must be a finite number > 0, got 0.0"),
        (lambda: geometric(1.0, 1.0), r"the base \(ratio r or b\) must be > 1, got 1.0"),
        (lambda: round_robin(0), "workers must be >= 1, got 0"),
        (lambda: geometric(1.0).expected_ratio, "a geometric schedule has no random offset"),
    ],
    ids=["t0", "base", "workers", "expected"],
)
def test_schedule_errors(make: Any, message: str) -> None:
    with pytest.raises(ScheduleError, match=f"^schedule: {message}$"):
        make()


# --- the analytic profile ---------------------------------------------------------------------


@settings(max_examples=30, deadline=None)
@given(r=st.floats(1.2, 4.0), m=st.integers(1, 4), rate=st.floats(0.001, 0.5))
def test_the_interruptible_profile_never_beats_the_contract(r: float, m: int, rate: float) -> None:
    """By time t the longest completed contract is at most t long, so with a non-decreasing
    contract profile the interruptible algorithm is never better than the contract at t; and
    its quality never falls as time goes on."""
    grid = np.linspace(0.0, 200.0, 201)
    base = tabulate(Exponential(rate), grid, kind="contract")
    profile = interruptible_profile(base, Schedule(unit=1.0, base=r, workers=m))
    assert profile.mean is not None and base.mean is not None
    assert np.all(profile.mean <= base.expected_at(profile.time) + 1e-15)
    assert np.all(np.diff(profile.mean) >= -1e-15)
    np.testing.assert_allclose(profile.probability.sum(axis=-1), 1.0)


def test_the_profile_has_no_result_before_the_first_contract_and_keeps_input_axes() -> None:
    base = tabulate(
        lambda t, q: q * -np.expm1(-0.1 * t),
        np.arange(0.0, 41.0, 5.0),
        input_grids=[[0.0, 0.5, 1.0]],
        inputs=["x"],
        kind="contract",
        time_unit="seconds",
    )
    profile = interruptible_profile(base, geometric(10.0), base.time, module="fast")
    assert (profile.module, profile.kind, profile.time_unit) == ("fast", "interruptible", "seconds")
    assert profile.inputs == ("x",) and profile.probability.shape == base.probability.shape
    assert profile.mean is not None and base.mean is not None
    np.testing.assert_array_equal(profile.mean[:, :2], 0.0)  # nothing before t = 10
    assert (profile.probability[:, :2, 0] == 1.0).all()  # all mass on quality 0
    # Contracts of 10 and 20 finish at 10 and 30: the contract's quality at those lengths.
    np.testing.assert_allclose(profile.mean[:, 2:6], base.mean[:, [2, 2, 2, 2]])
    np.testing.assert_allclose(profile.mean[:, 6:], base.mean[:, [4, 4, 4]])


# --- the constructed module, on the work clock ------------------------------------------------


@pytest.mark.parametrize("r", [2.0, 3.0], ids=["r=2", "r=3"])
def test_the_module_yields_where_the_schedule_says_with_the_profiles_quality(r: float) -> None:
    module = make_interruptible(toy, r=r)
    assert (module.kind, module.name, module.parameters) == (
        "interruptible",
        "toy-interruptible",
        ("problem",),
    )
    clock = WorkClock()
    trace = drive(module, Context(allocation=N, clock=clock), "problem")
    contracts = geometric(1.0, r).contracts(N)  # t0 = 1: the first grid time with quality > 0
    finished = contracts.finish[contracts.finish <= N]
    assert [t for t, _ in trace] == pytest.approx(finished.tolist(), rel=1e-12)
    assert [res.value for _, res in trace] == pytest.approx(
        contracts.length[: len(finished)].tolist(), rel=1e-12
    )
    qualities = [res.quality for _, res in trace]
    assert qualities == sorted(qualities) and len(set(qualities)) == len(qualities)
    # The next contract would end past N: it was not started, so no tick was spent on it.
    assert clock.now() == pytest.approx(finished[-1], rel=1e-12)
    # Measured quality at every grid time = the analytic profile there.
    profile = module.profile_source
    assert isinstance(profile, PerformanceProfile) and profile.module == "toy-interruptible"
    grid = CONTRACT_PROFILE.time
    np.testing.assert_allclose(quality_at(trace, grid), profile.expected_at(grid), atol=1e-12)


def test_the_randomised_module_averages_to_its_profile() -> None:
    """One run follows one draw of U: its first contract has length b^U, and the rest follow.
    Averaged over runs, the quality at each grid time is the analytic profile's (which averages
    over U by quadrature; 4096 points make its own error negligible here) within four standard
    errors."""
    module = make_interruptible(toy, schedule="randomised", seed=3)
    schedule = randomised(math.e, t0=1.0)
    grid = np.arange(0.0, 201.0)
    runs = []
    for _ in range(300):
        trace = drive(module, Context(allocation=200.0, clock=WorkClock()), None)
        u = math.log(trace[0][1].value, math.e)
        expected = schedule.contracts(200.0, u)
        finished = expected.finish[expected.finish <= 200.0]
        assert [t for t, _ in trace] == pytest.approx(finished.tolist(), rel=1e-9)
        runs.append(quality_at(trace, grid))
    measured = np.array(runs)
    profile = interruptible_profile(CONTRACT_PROFILE, schedule, grid, offsets=4096)
    assert isinstance(profile, PerformanceProfile)
    se = measured.std(axis=0) / math.sqrt(len(runs))
    assert np.all(np.abs(measured.mean(axis=0) - profile.expected_at(grid)) <= 4 * se + 1e-3)


def test_an_outside_interruption_abandons_the_running_contract() -> None:
    module = make_interruptible(interrupted_at_8, t0=1.0)
    stop = threading.Event()
    trace = drive(module, Context(clock=WorkClock(), stop=stop), None)
    assert [res.value for _, res in trace] == [1.0, 2.0, 4.0]  # not the cut-short 8
    assert stop.is_set()


def test_converting_a_compiled_program() -> None:
    """A two-module program (a contract module feeding an interruptible one) compiled into a
    contract algorithm, then made interruptible. Its first contract is 10, the first total with
    a quality above 0 (with 5, one of the two modules gets nothing); it runs contracts of 10,
    20, 40 (done at 10, 30, 70; the next, 80, would end past the allocation) and its quality at
    every grid time is the analytic profile's."""
    compiled = tiny_program()
    module = make_interruptible(compiled)
    assert (module.name, module.parameters, module.inputs) == ("p-interruptible", ("x",), ("x",))
    profile = module.profile_source
    assert isinstance(profile, ConditionalPerformanceProfile) and profile.kind == "interruptible"
    grid = compiled.profile.time
    assert set(grid) <= set(profile.time)  # with the finish times (and the instant before) added
    for i, q in enumerate((0.0, 0.5, 1.0)):
        clock = WorkClock()
        trace = drive(module, Context(allocation=80.0, clock=clock), Result("map", q))
        assert [t for t, _ in trace] == [10.0, 30.0, 70.0]
        assert clock.now() == 70.0
        lengths = [2, 4, 8]  # indices of 10, 20, 40 on the grid
        np.testing.assert_allclose(
            [res.quality for _, res in trace], compiled.expected[i, lengths], atol=1e-12
        )
        np.testing.assert_allclose(
            quality_at(trace, grid),
            profile.expected(np.full((len(grid), 1), q), grid),
            atol=1e-12,
        )


def guess_curve(t: Any, q: Any) -> Any:
    return (0.5 + 0.5 * np.asarray(q)) * np.minimum(np.asarray(t) / 40.0, 1.0)


def refine_curve(t: Any, q: Any) -> Any:
    return np.asarray(q) * -np.expm1(-0.05 * np.asarray(t))


def tiny_program() -> CompiledProgram:
    """(refine (guess x)) on totals 0..80 by 5; both curves are linear in the input quality,
    so the modules' real qualities are their profiles' exactly."""
    registry = Registry()
    time_grid = np.arange(0.0, 81.0, 5.0)
    axes: dict[str, Any] = {"input_grids": [[0.0, 1.0]], "inputs": ["x"]}

    @contract(
        "guess",
        profile=tabulate(guess_curve, time_grid, kind="contract", **axes),
        registry=registry,
    )
    def guess(ctx: Context, x: Result) -> Result:
        ctx.tick(ctx.allocation)
        return Result("guessed", float(guess_curve(ctx.allocation, x.quality)))

    @interruptible("refine", profile=tabulate(refine_curve, time_grid, **axes), registry=registry)
    def refine(ctx: Context, x: Result) -> Iterator[Result]:
        while True:
            yield Result(("plan", x.value), float(refine_curve(ctx.elapsed, x.quality)))
            ctx.tick(1)

    library = AnytimeLibrary([RegistrySource(registry)])
    program = parse_schemas("(defschema p (x) (refine (guess x)))", "p.any")["p"]
    return compile_program(program, library, time_grid, [0.0, 0.5, 1.0])


# --- the constructed profile is the schedule's step function -----------------------------------

#: A contract profiled on a coarse grid (every 100 ticks), the common case: the schedule's
#: finish times (10, 30, 70, 150, ...) fall between its grid times.
COARSE = tabulate(CURVE, np.arange(0.0, 1001.0, 100.0), kind="contract", module="coarse")


@contract("coarse", inputs=[], profile=COARSE, registry=TOYS)
def coarse(ctx: Context, problem: Any) -> Result:
    """Its quality is its profile's (interpolated on the coarse grid), so that the tests see
    the conversion's own error, not the contract profile's."""
    ctx.tick(ctx.allocation)
    return Result(ctx.allocation, float(COARSE.expected_at(ctx.allocation)))


def test_the_made_profile_steps_exactly_where_contracts_finish() -> None:
    """Between the contract's grid times the made profile used to ramp each step (errors up to
    0.1); it now holds every finish time and the instant before it, so it is exact there and
    agrees with runs on the work clock at any time."""
    module = make_interruptible(coarse, t0=10.0, r=2.0)
    profile = module.profile_source
    assert isinstance(profile, PerformanceProfile)
    contracts = geometric(10.0, 2.0).contracts(1000.0)
    inside = contracts.finish <= 1000.0
    finish, lengths = contracts.finish[inside], contracts.length[inside]
    np.testing.assert_allclose(finish, [10, 30, 70, 150, 310, 630])
    before = profile.expected_at(np.nextafter(finish, -np.inf))
    at = profile.expected_at(finish)
    np.testing.assert_allclose(at, COARSE.expected_at(lengths), atol=1e-12)
    np.testing.assert_allclose(before[1:], at[:-1], atol=1e-12)
    assert before[0] == 0.0
    for t in (5.0, 10.0, 29.0, 30.0, 69.5, 149.0, 151.0, 629.0, 700.0, 1000.0):
        record = run(module, ("problem",), budget=t)
        assert record.quality == pytest.approx(float(profile.expected_at(t)), abs=1e-9), t


def test_a_made_module_pickles_by_value_and_profiles_on_two_workers() -> None:
    """It is not importable by any name (it is made at run time), so it pickles by value, its
    contract by reference: `anytime profile --workers 2` can measure it (a 56-line traceback
    before), and the two workers measure what one does."""
    module = make_interruptible(coarse, t0=10.0, r=2.0)
    restored = pickle.loads(pickle.dumps(module))
    assert (restored.name, restored.kind, restored.inputs) == (module.name, "interruptible", ())
    assert [r.value for r in drive_all(restored, 100.0)] == [10.0, 20.0, 40.0]
    measurement = Measurement.of(Allocations(), time=[0, 10, 30, 100, 300])
    one = profile_module(module, ProfileRequest(trials=4), measurement=measurement).profile
    two = profile_module(
        module, ProfileRequest(trials=4, workers=2), measurement=measurement
    ).profile
    assert one == two
    np.testing.assert_allclose(one.mean, module.profile_source.expected_at(one.time), atol=1e-9)


class Allocations:
    """Problems for `coarse` made interruptible: its quality is its profile's, exactly."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        return Instance(("problem",), None)

    def score(self, instance: Instance, value: Any) -> float:
        return float(COARSE.expected_at(value))


def drive_all(module: AnytimeModule, allocation: float) -> list[Result]:
    return list(module(Context(allocation=allocation), "problem"))


# --- on worker processes ----------------------------------------------------------------------


def test_two_worker_processes_run_the_round_robin_schedule() -> None:
    """Lengths 20 ms * sqrt(3)^k: worker 0 runs 20, 60, 180 ms (done at 20, 80, 260 ms),
    worker 1 runs 35 and 104 ms (done at 35, 139 ms; its next, 312 ms, would end too late).
    Process start-up and a busy machine delay the completions, so the test asks only for
    results from the schedule's contracts, longer each time, all within the allocation."""
    module = make_interruptible(toy, t0=0.02, workers=2, schedule="round-robin")
    clock = WallClock()
    start = time.perf_counter()
    trace = drive(module, Context(allocation=0.4, clock=clock), "problem")
    assert time.perf_counter() - start < 2.0
    lengths = [res.value for _, res in trace]
    assert lengths and lengths == sorted(lengths)
    planned = round_robin(2, t0=0.02).contracts(0.4).length
    assert all(np.isclose(planned, length, rtol=1e-12).any() for length in lengths)
    assert all(t <= 0.4 for t, _ in trace)


def test_a_hanging_contract_on_workers_leaves_no_process_behind() -> None:
    """The run answers at its deadline and its worker processes are stopped (they kept the
    interpreter waiting at exit for as long as the contract hung)."""
    module = make_interruptible(hangs, t0=0.02, workers=2)
    before = set(multiprocessing.active_children())
    record = run(module, ("problem",), budget=Budget(0.3, clock=WallClock()))
    assert record.result is None
    deadline = time.monotonic() + 10.0  # processes take a moment to be reaped, not a timing test
    while set(multiprocessing.active_children()) - before and time.monotonic() < deadline:
        time.sleep(0.05)
    assert set(multiprocessing.active_children()) - before == set()


def test_several_workers_need_the_wall_clock() -> None:
    module = make_interruptible(toy, t0=0.02, workers=2)
    with pytest.raises(ConversionError) as raised:
        drive(module, Context(allocation=1.0, clock=WorkClock()), None)
    assert str(raised.value) == (
        "module 'toy' on 2 workers runs its contracts in other processes, whose work ticks a "
        "WorkClock cannot see: give it a context with a WallClock"
    )


# --- errors -----------------------------------------------------------------------------------


def _yields(ctx: Context) -> Iterator[Result]:
    yield Result(None, 0.0)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: make_interruptible(interruptible("gen", registry=Registry())(_yields)),
            "module 'gen' is interruptible, not a contract module: only a contract algorithm "
            "needs converting",
        ),
        (
            lambda: make_interruptible(not_a_result),
            "module 'not-a-result' has no profile to choose the first allocation from: give t0",
        ),
        (
            lambda: make_interruptible(toy, schedule="doubling"),  # type: ignore[arg-type]
            "module 'toy': unknown schedule 'doubling' (expected one of geometric, "
            "round-robin, randomised)",
        ),
        (
            lambda: make_interruptible(toy, schedule=geometric(1.0), r=3.0),
            "module 'toy': a Schedule fixes t0, r and workers; give either it or them",
        ),
        (
            lambda: make_interruptible(toy, workers=0),
            "module 'toy': workers must be an integer >= 1, got 0",
        ),
    ],
    ids=["interruptible", "no-t0", "schedule", "schedule-and-r", "workers"],
)
def test_conversion_errors(call: Any, message: str) -> None:
    with pytest.raises(ConversionError) as raised:
        call()
    assert str(raised.value) == message


def test_a_contract_that_returns_no_result_is_named() -> None:
    module = make_interruptible(not_a_result, t0=1.0)
    with pytest.raises(
        ModuleError, match=r"^contract module 'not-a-result' returned 42, not a Result$"
    ):
        drive(module, Context(allocation=10.0), None)
