"""Which quality drives decisions is declared: a module says whether its `Result.quality` is its
true quality (the default), an estimate or nothing; where it is not the true one, the runtime
keeps the module's latest result and judges it by its profile's prediction, as the compiler
does, not by what the module says of itself."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from anytime.clocks import WorkClock
from anytime.compiler import compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, ModuleError, Registry, Result, interruptible
from anytime.profiles import tabulate
from anytime.runtime import Budget, run, run_program

TIME = np.arange(0.0, 41.0, 10.0)


def _modest(t: Any) -> Any:
    return np.minimum(0.3, np.asarray(t, dtype=np.float64) / 40)


def _better(t: Any) -> Any:
    return np.minimum(0.6, np.asarray(t, dtype=np.float64) / 20)


def boaster(reports: str, registry: Registry) -> Any:
    """Improves with time (its profile, what it was measured to reach: at most 0.3), and says
    of itself 0.9 at first, less later."""

    @interruptible("boaster", inputs=[], profile=tabulate(_modest, TIME), registry=registry,
                   reports=reports)  # fmt: skip
    def body(ctx: Context, x: Any) -> Iterator[Result]:
        for step in range(100):
            yield Result(("boaster", step), max(0.0, 0.9 - 0.1 * step))
            ctx.tick(5)

    return body


def honest(registry: Registry) -> Any:
    @interruptible("honest", inputs=[], profile=tabulate(_better, TIME), registry=registry)
    def body(ctx: Context, x: Any) -> Iterator[Result]:
        for step in range(1, 100):
            ctx.tick(5)
            yield Result(("honest", step), float(_better(5 * step)))

    return body


@pytest.mark.parametrize(("reports", "kept"), [("true", 0), ("estimate", 4), ("none", 4)])
def test_an_interruptible_that_does_not_report_its_true_quality_keeps_its_latest_result(
    reports: str, kept: int
) -> None:
    module = boaster(reports, Registry())
    record = run(module, ("x",), budget=20)
    assert record.result is not None and record.result.value == ("boaster", kept)


@pytest.mark.parametrize(("reports", "winner"), [("true", "boaster"), ("estimate", "honest")])
def test_a_best_of_chooses_by_the_profile_where_self_reports_are_estimates(
    reports: str, winner: str
) -> None:
    """The boaster answers at once and says 0.9 of itself; its profile says 0 for no time and
    at most 0.3 for any. The honest alternative reports its true quality."""
    registry = Registry()
    boaster(reports, registry)
    honest(registry)
    schema = parse_schemas("(defschema p (x) (best-of (boaster x) (honest x)))", "p.any")["p"]
    library = AnytimeLibrary.default(registry=registry, plugins=False)
    program = compile_program(schema, library, TIME)
    record = run_program(program, {"x": "data"}, 20)
    assert record.result is not None and record.result.value[0] == winner
    result = run_program(program, {"x": "data"}, Budget(20, clock=WorkClock())).result
    assert result is not None and result.value[0] == winner


def test_what_a_module_reports_is_checked() -> None:
    with pytest.raises(ModuleError) as raised:
        boaster("maybe", Registry())
    assert str(raised.value).endswith("reports must be one of true, estimate, none, got 'maybe'")


def test_a_best_of_of_estimated_alternatives_promises_what_the_runtime_picks() -> None:
    """Two modules that do not report their true quality: a gamble (1.0 or 0.0, even odds)
    and a sure 0.6. The runtime judges them by their profiles' means, 0.5 and 0.6, so it
    always takes the sure one and delivers 0.6; the maximum of the two, 0.8, was promised."""
    from anytime.modules import contract
    from anytime.profiles import new_profile

    time = np.arange(0.0, 11.0)
    bins = np.array([0.0, 0.001, 0.999, 1.0])
    ready = (time >= 2)[:, None]
    gamble = np.where(ready, [0.5, 0.0, 0.5], [1.0, 0.0, 0.0])
    sure = np.where(ready, [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    registry = Registry()
    for name, probability, mean in (
        ("gamble", gamble, np.where(time >= 2, 0.5, 0.0)),
        ("sure", sure, np.where(time >= 2, 0.6, 0.0)),
    ):
        profile = new_profile(
            input_grids=[], time=time, bins=bins, probability=probability, mean=mean,
            kind="contract",
        )  # fmt: skip

        def answer(ctx: Context, seed: int, name: str = name) -> Result | None:
            ctx.tick(ctx.allocation)
            if ctx.allocation < 2:
                return None
            truth = float(np.random.default_rng(seed).integers(2)) if name == "gamble" else 0.6
            return Result((name, truth), 0.9)  # what it says of itself is not its quality

        answer.__name__ = answer.__qualname__ = name
        contract(name, inputs=[], profile=profile, registry=registry, reports="estimate")(answer)
    schema = parse_schemas("(defschema p (s) (best-of (gamble s) (sure s)))", "p.any")["p"]
    program = compile_program(
        schema, AnytimeLibrary.default(registry=registry, plugins=False), time
    )
    assert program.expected[-1] == pytest.approx(0.6, abs=1e-12)
    truths = [run_program(program, [seed], 10.0).result.value for seed in range(50)]
    assert truths == [("sure", 0.6)] * 50
