"""`run(..., policy=...)`: a stopping policy watching an interruptible module, soft and hard.

The policy is consulted before the run and at the first result at or after each time it asks to
look; it stops the run at its word or at its stop time (status `stopped`), never after the
allocation; its decisions go to the event log; a module that cannot be watched is refused.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stopping_models import Linear, traces

from anytime import AnytimeLibrary, RegistrySource, compile_file, parse_schemas
from anytime.modules import Context, Registry, Result, contract, interruptible
from anytime.profiles import Exponential, tabulate
from anytime.profiles.dynamic import DynamicProfile, QualityTraces
from anytime.runtime import (
    ConformalStopping,
    Decision,
    EventLog,
    FixedStopping,
    Hard,
    HistoryStopping,
    MyopicStopping,
    OptimalStopping,
    PolicyError,
    ProjectedStopping,
    Soft,
    Status,
    Stopping,
    Utility,
    replay,
    run,
)
from anytime.runtime.conversion import make_interruptible

TOYS = Registry()


@interruptible("climb", inputs=[], registry=TOYS)
def climb(ctx: Context, rate: float, every: float = 1.0) -> Iterator[Result]:
    """1 - exp(-rate t), one result every `every` ticks, forever."""
    k = 0
    while True:
        ctx.tick(every)
        k += 1
        yield Result(k, 1 - math.exp(-rate * k * every))


@interruptible("guess", inputs=[], registry=TOYS, reports="estimate")
def guess(ctx: Context) -> Iterator[Result]:
    while True:
        ctx.tick()
        yield Result(None, 0.5)


@interruptible("short", inputs=[], registry=TOYS)
def short(ctx: Context) -> Iterator[Result]:
    for k in range(3):
        ctx.tick()
        yield Result(k, (k + 1) / 4)


@contract("solve", inputs=[], registry=TOYS,
          profile=tabulate(Exponential(0.2), range(0, 41, 2), kind="contract"))  # fmt: skip
def solve(ctx: Context) -> Result:
    ctx.tick(ctx.allocation)
    return Result("solved", float(Exponential(0.2)(ctx.allocation)))


class Script:
    """A policy that says what it is told, in order, and keeps what it was shown."""

    name = "script"
    observed = None

    def __init__(self, *decisions: Decision) -> None:
        self.decisions = list(decisions)
        self.shown: list[tuple[float, float | None]] = []

    def start(self, allocation: float) -> Decision:
        return self.decisions.pop(0)

    def observe(self, time: float, quality: float | None) -> Decision:
        self.shown.append((time, quality))
        return self.decisions.pop(0)


def later(look_at: float, stop_at: float = math.inf) -> Decision:
    return Decision.later(look_at, stop_at, "told to")


def climb_profile() -> DynamicProfile:
    """The dynamic profile of `climb` over rates drawn from [0.1, 1.5], on ticks 0..10."""
    time = np.arange(11.0)
    rate = np.random.default_rng(0).uniform(0.1, 1.5, (300, 1))
    quality = np.where(time > 0, 1 - np.exp(-rate * time), 0.0)
    traces = QualityTraces(
        module="climb", time=time, quality=quality, scored=time > 0 + quality * 0
    )
    return DynamicProfile.from_traces(traces, states=6)


HARD = pytest.mark.parametrize("hard", [False, True], ids=["soft", "hard"])


@HARD
def test_the_policy_is_consulted_at_its_looks_and_stops_the_run(hard: bool) -> None:
    policy = Script(later(2.5), later(4), Decision.now("enough"))
    log = EventLog()
    record = run(
        climb, [0.5], budget=10, mode=Hard() if hard else Soft(), observer=Stopping(policy, log)
    )
    assert (record.status, record.time_used, record.looks) == (Status.STOPPED, 4.0, 2)
    assert record.result == Result(4, 1 - math.exp(-2.0))
    assert [t for t, _ in policy.shown] == [3.0, 4.0]  # the first results at or after 2.5 and 4
    assert [(e.time, e.kind, e.data["decision"], e.data["look_at"]) for e in log] == [
        (0.0, "stopping", "continue", 2.5),
        (3.0, "stopping", "continue", 4.0),
        (4.0, "stopping", "stop", None),
    ]
    assert log[2].as_dict() == {
        "time": 4.0,
        "kind": "stopping",
        "policy": "script",
        "quality": 1 - math.exp(-2.0),
        "decision": "stop",
        "look_at": None,
        "stop_at": None,
        "reason": "enough",
    }


@HARD
def test_the_run_stops_at_the_policys_stop_time_without_looking(hard: bool) -> None:
    record = run(
        climb,
        [0.5],
        budget=10,
        mode=Hard() if hard else Soft(),
        observer=Stopping(Script(later(math.inf, 6))),
    )
    assert (record.status, record.time_used, record.looks) == (Status.STOPPED, 6.0, 0)
    assert record.result is not None and record.result.value == 6


@HARD
def test_a_result_after_the_stop_time_does_not_count(hard: bool) -> None:
    record = run(
        climb,
        [0.5, 4.0],
        budget=20,
        mode=Hard() if hard else Soft(),
        observer=Stopping(Script(later(math.inf, 6))),
    )
    assert (record.status, record.result) == (Status.STOPPED, Result(1, 1 - math.exp(-2.0)))


@HARD
def test_the_allocation_still_ends_a_run_the_policy_lets_go_on(hard: bool) -> None:
    policy = Script(later(0), *[later(t + 1) for t in range(1, 20)])
    record = run(climb, [0.5], budget=5, mode=Hard() if hard else Soft(), observer=Stopping(policy))
    # Looks at 1, 2, 3 and 4: the one due at 5 is at the deadline, where it could not change
    # the answer, and is not taken.
    assert (record.status, record.time_used, record.looks) == (Status.INTERRUPTED, 5.0, 4)


def test_a_module_that_finishes_first_completes() -> None:
    record = run(short, [], budget=10, observer=Stopping(Script(later(0), later(5))))
    assert (record.status, record.looks, record.quality) == (Status.COMPLETED, 1, 0.75)


def test_a_policy_that_stops_before_the_start_runs_nothing() -> None:
    log = EventLog()
    record = run(climb, [0.5], budget=10, observer=Stopping(Script(Decision.now("no time")), log))
    assert (record.status, record.result, record.time_used, record.looks) == (
        Status.STOPPED,
        None,
        0.0,
        0,
    )
    assert [e.data["reason"] for e in log] == ["no time"]


def test_a_policy_that_fails_fails_the_run_with_its_message() -> None:
    class Broken(Script):
        def observe(self, time: float, quality: float | None) -> Decision:
            raise ValueError("no idea")

    record = run(climb, [0.5], budget=10, observer=Stopping(Broken(later(0))))
    assert (record.status, record.error) == (Status.FAILED, "stopping policy: ValueError: no idea")
    assert record.result == Result(1, 1 - math.exp(-0.5))
    wrong = run(climb, [0.5], budget=10, observer=Stopping(Script(later(0), "stop")))  # type: ignore[arg-type]
    assert (wrong.status, wrong.error) == (
        Status.FAILED,
        "stopping policy: anytime.runtime.observe.PolicyError: policy 'script' answered with"
        " str 'stop', not a Decision",
    )


@HARD
def test_the_optimal_policy_runs_a_module_and_logs_why(hard: bool) -> None:
    model = Linear(10, 0.4)
    policy = OptimalStopping(climb_profile(), model, model)
    log = EventLog()
    record = run(
        climb, [0.8], budget=10, mode=Hard() if hard else Soft(), observer=Stopping(policy, log)
    )
    assert record.status == Status.STOPPED
    assert record.looks == len(log) - 1 and record.time_used <= 10
    assert {e.data["policy"] for e in log} == {"optimal"}
    assert log[-1].data["decision"] == "stop"


def test_a_module_sees_the_policys_stop_time_as_its_allocation() -> None:
    """A contract made interruptible starts no contract that cannot end by the stop time: it
    ends by itself (completed) instead of running one whose result would not count."""
    anytime_solve = make_interruptible(solve)  # contracts of 2, 4, 8, ...: results at 2, 6, 14
    record = run(anytime_solve, [], budget=40, observer=Stopping(Script(later(math.inf, 20))))
    assert (record.status, record.time_used, record.allocation) == (Status.COMPLETED, 14.0, 40)
    assert record.quality == pytest.approx(float(Exponential(0.2)(8)))


@given(st.floats(0, 12), st.floats(0.05, 2), st.floats(0, 3), st.booleans())
@settings(max_examples=40, deadline=None)
def test_a_policy_run_never_passes_its_allocation(
    allocation: float, rate: float, cost: float, fixed: bool
) -> None:
    model = Linear(10, cost)
    kind = FixedStopping if fixed else OptimalStopping
    record = run(
        climb, [rate], budget=allocation, observer=Stopping(kind(climb_profile(), model, model))
    )
    assert record.time_used <= allocation + 1  # within its step, as any run
    assert record.status in (Status.STOPPED, Status.INTERRUPTED, Status.NO_RESULT)


# --- what cannot be watched --------------------------------------------------------------------


def test_a_policy_needs_an_interruptible_module() -> None:
    with pytest.raises(PolicyError) as error:
        run(solve, [], budget=10, observer=Stopping(Script(later(0))))
    assert str(error.value) == (
        "run: a stopping policy needs an interruptible module; 'solve' is a contract module"
        " (make_interruptible turns a contract into one)"
    )


def test_a_policy_must_read_what_the_module_reports() -> None:
    model = Linear(1, 0)
    with pytest.raises(PolicyError) as error:
        run(guess, [], budget=10, observer=Stopping(OptimalStopping(climb_profile(), model, model)))
    assert str(error.value) == (
        "run: policy 'optimal' reads the true quality, but module 'guess' reports an estimate"
        " of the quality"
    )


@interruptible("noisy", inputs=[], registry=TOYS, reports="estimate")
def noisy(ctx: Context, level: float) -> Iterator[Result]:
    """Reports an estimate of its quality every 10 ticks."""
    for k in range(1, 100):
        ctx.tick(10)
        yield Result(k, min(1.0, level * k))


@HARD
def test_a_module_that_reports_an_estimate_is_watched_through_the_observation_model(
    hard: bool,
) -> None:
    profile = DynamicProfile.from_traces(traces(3, 5, 40, "estimate"), states=3)
    model = Linear(10, 0.05)
    policy = OptimalStopping(profile, model, model)
    log = EventLog()
    record = run(
        noisy, [0.2], budget=40, mode=Hard() if hard else Soft(), observer=Stopping(policy, log)
    )
    assert record.status in (Status.STOPPED, Status.INTERRUPTED)
    assert record.looks == len(log) - 1 >= 1
    assert [e.data["quality"] for e in log[1:]] == [0.2 * (k + 1) for k in range(record.looks)]


@interruptible("grind", inputs=[], registry=TOYS)
def grind(ctx: Context) -> Iterator[Result]:
    """Yields once, then works for 50 ticks without yielding (nor looking at its context)."""
    ctx.tick()
    yield Result("first", 0.3)
    for _ in range(50):
        time.sleep(0.002)
        ctx.tick()
    yield Result("late", 0.9)


def test_hard_interruption_cuts_a_stuck_module_at_the_policys_stop_time() -> None:
    record = run(grind, [], budget=100, mode=Hard(), observer=Stopping(Script(later(math.inf, 5))))
    assert (record.status, record.result, record.allocation) == (
        Status.STOPPED,
        Result("first", 0.3),
        100,
    )
    assert record.time_used < 51


def test_the_log_of_an_unbounded_run_is_plain_json() -> None:
    log = EventLog()
    run(climb, [0.5], observer=Stopping(Script(later(3), Decision.now("done")), log))
    assert EventLog.from_jsonl(log.to_jsonl()) == log
    assert [(e.data["look_at"], e.data["stop_at"]) for e in log] == [(3.0, None), (None, None)]


def test_a_compiled_program_made_interruptible_runs_under_a_policy() -> None:
    (program,) = compile_file(
        parse_schemas("(defschema once () (solve))"),
        AnytimeLibrary([RegistrySource(TOYS)]),
        time_grid=range(0, 41, 2),
    )
    anytime_program = make_interruptible(program)
    record = run(
        anytime_program, [], budget=40, observer=Stopping(Script(later(5), Decision.now("ok")))
    )
    assert (record.status, record.looks) == (Status.STOPPED, 1)
    assert record.result is not None and record.result.value == "solved"


@interruptible("playback", inputs=[], registry=TOYS)
def playback(ctx: Context, qualities: list[float]) -> Iterator[Result]:
    """A recorded trace played back: its quality at ticks 10, 20, ..."""
    for k, q in enumerate(qualities[1:], 1):
        ctx.tick(10)
        yield Result(k, q)


@given(st.integers(0, 10**6), st.floats(0, 2), st.sampled_from([0.0, 2.0]), st.floats(10, 45))
@settings(max_examples=40, deadline=None)
def test_replay_stops_a_trace_where_a_run_of_it_stops(
    seed: int, rate: float, cost: float, allocation: float
) -> None:
    """The answer a run under a policy keeps is the one `replay` stops the trace at."""
    recorded = traces(seed, 5, 30)
    profile = DynamicProfile.from_traces(recorded, states=3)
    model = Linear(10, rate / 10)
    trace = [float(q) for q in traces(seed + 1, 5, 1).quality[0]]
    for policy in (
        OptimalStopping(profile, model, model, monitoring_cost=cost),
        FixedStopping(profile, model, model),
        MyopicStopping(profile, model, model, monitoring_cost=cost),
        ProjectedStopping(profile, model, model),
        HistoryStopping(recorded, Utility(model, model), monitoring_cost=cost, neighbours=5),
    ):
        offline = replay(policy, profile.time, trace, allocation, scored=[0, 1, 1, 1, 1])
        record = run(playback, [trace], budget=allocation, observer=Stopping(policy))
        kept = 0 if record.result is None else record.result.value  # the grid index of its answer
        assert (kept, record.looks) == (offline.stop_index, offline.looks), policy.name


@interruptible("stall", inputs=[], registry=TOYS)
def stall(ctx: Context, qualities: list[float]) -> Iterator[Result]:
    """A recorded trace played back by a module that registers only when it improves (a search
    that stalls): ten ticks of work a step, no result while the quality stays where it was."""
    best = -1.0
    for k, q in enumerate(qualities[1:], 1):
        for _ in range(10):
            if ctx.expired:  # a module that watches its time
                return
            ctx.tick(1)
        if q > best:
            best = q
            yield Result(k, q)


@given(st.integers(0, 10**6), st.floats(0, 2), st.sampled_from([0.0, 2.0]), st.floats(10, 95))
@settings(max_examples=40, deadline=None)
def test_a_run_that_stalls_stops_where_replay_stops_its_trace(
    seed: int, rate: float, cost: float, allocation: float
) -> None:
    """Looks come on the policy's schedule, not at registrations: a module that improves
    rarely is looked at when the policy asks, and a run keeps the answer `replay` stops its
    trace at, after the same looks (neither takes a look where the run ends anyway)."""
    recorded = traces(seed, 10, 30)
    profile = DynamicProfile.from_traces(recorded, states=3)
    model = Linear(10, rate / 10)
    trace = [float(q) for q in np.floor(traces(seed + 1, 10, 1).quality[0] * 4) / 4]  # plateaus
    scored = [False] + [True] * (len(trace) - 1)  # its first result comes at its first step
    makers = {
        "optimal": lambda: OptimalStopping(profile, model, model, monitoring_cost=cost),
        "myopic": lambda: MyopicStopping(profile, model, model, monitoring_cost=cost),
        "projected": lambda: ProjectedStopping(profile, model, model),
        "history": lambda: HistoryStopping(
            recorded, Utility(model, model), monitoring_cost=cost, neighbours=5
        ),
        "conformal": lambda: ConformalStopping(recorded, 0.05, 0.2, min_traces=5),
    }
    for name, make in makers.items():  # a policy afresh for each run
        offline = replay(make(), profile.time, trace, allocation, scored=scored)
        record = run(stall, [trace], budget=allocation, observer=Stopping(make()))
        kept = 0 if record.result is None else record.result.value
        assert (trace[kept], record.looks) == (trace[offline.stop_index], offline.looks), name
