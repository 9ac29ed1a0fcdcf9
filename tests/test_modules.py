"""The module protocol: results, contexts, and what the decorators accept and refuse."""

import math
import pickle
import threading
from collections.abc import Iterator
from pathlib import Path

import attrs
import pytest

from anytime.clocks import WallClock, WorkClock
from anytime.modules import (
    AnytimeModule,
    Context,
    ModuleError,
    RegistrationError,
    Registry,
    Result,
    contract,
    elementary,
    interruptible,
)
from anytime.profiles import Exponential, tabulate

TOYS = Registry()


@interruptible("count-up", inputs=["seed"], registry=TOYS)
def count_up(ctx: Context, seed: Result, steps: int = 3) -> Iterator[Result]:
    for i in range(1, steps + 1):
        ctx.tick(10)
        yield Result(i, seed.quality * i / steps)


def test_result_quality_must_be_in_the_unit_interval() -> None:
    assert Result("plan", 1).quality == 1.0
    for bad in (-0.1, 1.5, math.nan):
        with pytest.raises(ValueError, match=r"a Result's quality must be in \[0, 1\], got"):
            Result("plan", bad)


def test_context_counts_work_and_expires() -> None:
    ctx = Context(allocation=25)
    assert (ctx.elapsed, ctx.remaining, ctx.expired) == (0, 25, False)
    ctx.tick(10)
    ctx.tick(10)
    assert (ctx.elapsed, ctx.remaining, ctx.expired) == (20, 5, False)
    ctx.tick(5)
    assert ctx.expired and ctx.remaining == 0
    assert ctx.ticks == 25


def test_context_is_interrupted_from_outside() -> None:
    stop = threading.Event()
    ctx = Context(stop=stop)
    assert ctx.allocation == math.inf and not ctx.expired
    stop.set()
    assert ctx.expired


def test_contexts_sharing_a_work_clock_see_each_others_work() -> None:
    clock = WorkClock()
    first = Context(clock=clock)
    first.tick(7)
    second = Context(allocation=5, clock=clock)
    assert second.elapsed == 0
    first.tick(5)
    assert second.expired


def test_wall_clock_moves_without_ticks() -> None:
    ctx = Context(allocation=math.inf, clock=WallClock())
    ctx.tick(1_000_000)  # reported work does not move wall time
    assert 0 <= ctx.elapsed < 60


def test_interruptible_module_registers_with_its_declaration() -> None:
    module = TOYS.get("COUNT-UP")
    assert isinstance(module, AnytimeModule)
    assert (module.name, module.kind, module.parameters, module.inputs) == (
        "count-up",
        "interruptible",
        ("seed", "steps"),
        ("seed",),
    )
    assert module.origin == f"python module {__name__}"
    results = list(module(Context(), Result(None, 0.9)))
    assert [r.quality for r in results] == pytest.approx([0.3, 0.6, 0.9])


def test_modules_pickle_by_reference() -> None:
    assert pickle.loads(pickle.dumps(count_up)) is count_up


def test_contract_and_elementary_modules() -> None:
    registry = Registry()
    profile = tabulate(Exponential(0.1), [0, 10, 20])

    @contract("guess", profile=profile, registry=registry)
    def guess(ctx: Context, x: Result) -> Result:
        return Result(x.value, min(1.0, ctx.allocation / 100))

    @elementary(registry=registry)
    def better_plan(a: Result, b: Result) -> object:
        return a.value if a.quality >= b.quality else b.value

    assert guess.kind == "contract" and guess.profile_source is profile
    assert guess(Context(allocation=50), Result(1, 1)).quality == 0.5
    assert registry.get("better-plan") is better_plan
    assert better_plan.kind == "elementary"
    assert better_plan.inputs == ("a", "b")
    assert better_plan.combine([0.4, 0.9]) == 0.4


def test_profile_path_is_relative_to_the_defining_file() -> None:
    registry = Registry()

    @interruptible("p", profile="profiles/p.yaml", registry=registry)
    def p(ctx: Context) -> Iterator[Result]:
        yield Result(1, 1)

    assert p.profile_source == Path(__file__).parent / "profiles" / "p.yaml"


def _qualname(name: str) -> str:
    return f"{__name__}.test_declaration_errors_name_the_module.<locals>.{name}"


def test_declaration_errors_name_the_module() -> None:
    registry = Registry()

    def not_a_generator(ctx: Context) -> Result:
        return Result(1, 1)

    with pytest.raises(ModuleError) as caught:
        interruptible("a", registry=registry)(not_a_generator)  # type: ignore[arg-type]
    assert str(caught.value) == (
        f"module 'a' ({_qualname('not_a_generator')}): "
        "an interruptible module must be a generator (use yield)"
    )

    def a_generator(ctx: Context) -> Iterator[Result]:
        yield Result(1, 1)

    with pytest.raises(ModuleError) as caught:
        contract("b", registry=registry)(a_generator)  # type: ignore[arg-type]
    assert str(caught.value) == (
        f"module 'b' ({_qualname('a_generator')}): "
        "a contract module must return its Result, not yield"
    )

    def no_context(x: Result) -> Iterator[Result]:
        yield x

    with pytest.raises(ModuleError) as caught:
        interruptible("c", registry=registry)(no_context)
    assert str(caught.value) == (
        f"module 'c' ({_qualname('no_context')}): the first parameter must be the context, 'ctx'"
    )

    def planner(ctx: Context, start: Result, goal: Result, domain: Result) -> Iterator[Result]:
        yield domain

    with pytest.raises(ModuleError) as caught:
        interruptible("find-path", inputs=["domian"], registry=registry)(planner)
    assert str(caught.value) == (
        f"module 'find-path' ({_qualname('planner')}): declared input 'domian' is not a "
        "parameter of the function (parameters: start, goal, domain)"
    )
    assert len(registry) == 0


def test_two_functions_under_one_name_name_both_origins() -> None:
    registry = Registry()

    @interruptible("twin", registry=registry)
    def first(ctx: Context) -> Iterator[Result]:
        yield Result(1, 1)

    def second(ctx: Context) -> Iterator[Result]:
        yield Result(2, 1)

    with pytest.raises(RegistrationError) as caught:
        interruptible("twin", registry=registry)(second)
    assert str(caught.value) == (
        f"module 'twin' is defined twice: in python module {__name__} "
        f"and in python module {__name__}"
    )
    # Registering the same function again (a reloaded module) replaces it.
    again = interruptible("twin", registry=registry)(first.function)
    assert registry.get("twin") is again


# --- a declared step ------------------------------------------------------------------------------


@interruptible("stepped", inputs=[], registry=TOYS, step=10)
def stepped(ctx: Context) -> Iterator[Result]:
    for i in range(3):
        ctx.tick(10)
        yield Result(i, i / 2)


def test_a_module_declares_its_step_or_none() -> None:
    assert stepped.step == 10.0 and isinstance(stepped.step, float)
    assert count_up.step is None

    @contract("late-by-two", registry=Registry(), step=2)
    def late(ctx: Context) -> Result:
        ctx.tick(ctx.allocation + 2)
        return Result(1, 1)

    assert (late.kind, late.step) == ("contract", 2.0)
    # It travels with the module: by reference, and in the fields a copy by value is made of.
    assert pickle.loads(pickle.dumps(stepped)) is stepped
    assert attrs.asdict(stepped, recurse=False)["step"] == 10.0


@pytest.mark.parametrize(
    ("step", "shown"),
    [
        (-1, "-1"),
        (-0.5, "-0.5"),
        (math.inf, "inf"),
        (math.nan, "nan"),
        ("5", "'5'"),
        (True, "True"),
    ],
)
def test_a_bad_step_is_refused_naming_the_module_and_the_field(step: object, shown: str) -> None:
    def g(ctx: Context) -> Iterator[Result]:
        yield Result(1, 1)

    def f(ctx: Context) -> Result:
        return Result(1, 1)

    registry = Registry()
    for declare, function in ((interruptible, g), (contract, f)):
        with pytest.raises(ModuleError) as caught:
            declare("s", registry=registry, step=step)(function)  # type: ignore[arg-type]
        assert str(caught.value) == (
            f"module 's' ({function.__module__}.{function.__qualname__}): step: expected a finite"
            " number >= 0 (the most time it uses before its next result or its return; None:"
            f" not declared), got {shown}"
        )
    assert len(registry) == 0


def test_one_decorator_family_for_users_and_plugins() -> None:
    import anytime
    import anytime.plugin
    from anytime.runtime import deadline

    for name in ("interruptible", "contract", "elementary"):
        assert getattr(anytime, name) is getattr(anytime.plugin, name) is globals()[name]
    assert anytime.plugin.critical_event is deadline.critical_event


def test_a_decorator_declares_and_registers_nowhere_unless_given_a_registry() -> None:
    from anytime import REGISTRY
    from anytime.runtime.deadline import EVENTS, CriticalEvent, critical_event

    modules, events = len(REGISTRY), len(EVENTS)

    @interruptible("declared-stepped", step=3)
    def gen(ctx: Context) -> Iterator[Result]:
        yield Result(1, 1)

    @contract("declared-late", step=0)
    def late(ctx: Context) -> Result:
        return Result(1, 1)

    @elementary("declared-pair")
    def pair(a: object, b: object) -> tuple[object, object]:
        return a, b

    @critical_event("declared-event", cost_bound=1)
    def event(ctx: Context, situation: object) -> float | None:
        return None

    assert (gen.step, late.step, pair.kind, event.cost_bound) == (3.0, 0.0, "elementary", 1.0)
    assert isinstance(event, CriticalEvent)
    assert (len(REGISTRY), len(EVENTS)) == (modules, events)
    assert "declared-stepped" not in REGISTRY and "declared-event" not in EVENTS
    with pytest.raises(ModuleError, match=r"^module 'declared-bad' .*: step: expected a finite"):
        interruptible("declared-bad", step=-3)(gen.function)
    # Given a registry, it is added there, and only there.
    mine = Registry()
    again = contract("declared-late", step=0, registry=mine)(late.function)
    assert mine.get("declared-late") is again and "declared-late" not in REGISTRY
    events_of_mine = Registry()
    found = critical_event("declared-event", cost_bound=1, registry=events_of_mine)(event.function)
    assert events_of_mine.get("declared-event") is found and "declared-event" not in EVENTS


def _first(ctx: Context) -> Result:
    return Result(1, 1.0)


def _second(ctx: Context) -> Result:
    return Result(2, 1.0)


def _race(registry: Registry) -> list[str]:
    """Two threads register `_first` and `_second` as 'raced' at once; how each ended."""
    barrier = threading.Barrier(2)
    outcomes: list[str] = []

    def register(function: object) -> None:
        barrier.wait()
        try:
            contract("raced", registry=registry)(function)
            outcomes.append("registered")
        except RegistrationError:
            outcomes.append("refused")

    threads = [threading.Thread(target=register, args=(f,)) for f in (_first, _second)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return outcomes


def test_two_threads_registering_one_name_one_wins() -> None:
    """The check for a taken name and the registration are one step: of two threads racing to
    register different functions under one name, exactly one succeeds, every time."""
    for _ in range(200):
        assert sorted(_race(Registry())) == ["refused", "registered"]
