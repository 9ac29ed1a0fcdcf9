"""Running a compiled program: the one executor, with a fixed or an adaptive allocation.

The calls run in topological order on one clock, each through `run` (so each answers with a run
record and never loses its best result), with its share of the total from the compiled
allocation table (`CompiledProgram.allocation_at`). A call to another schema runs that schema's
compiled program the same way with the call's share; a best-of evaluates its preconditions,
re-splits its alternatives' time among the applicable ones and answers with the best of their
results; an if runs the compiled branch its condition selects with the if's time; a loop (map,
repeat) splits its time among its calls by the rule it was compiled with
(`anytime.compiler.loops`), each call's curve at its own item's quality, and answers with the
list of their results, its quality their mean. When a map's collection is not of the size the
table was planned for, the time left is re-split among the calls still to run with that count's
profile of the loop (as in adaptive mode).

In **adaptive** mode, the time that is left is re-allocated among the modules still to run
given the qualities *observed* so far: the compiled profiles are conditional, so the best split
of the rest depends on them (Zilberstein & Russell). It re-plans by value of information: only
after a call that showed the plan something new (time it left unused, a quality drawn from a
stochastic profile and reported true, no result; not a quality its profile predicts), keeping
the new split only where the compiler expects it to beat the planned one, and remembering the
re-plans of a program across its runs (the compiler's `Replanner`; `Execution.adapt`). The
best-of's and the loop's re-splits are the compiler's `reallocate`.

No placeholders: a call one of whose inputs has no result (its producer registered none) is not
made, and has no result either (its record says why), unless its module declares
`accepts_missing` (it then gets `MISSING` for that input); a best-of's precondition without a
value makes its alternative inapplicable, and an alternative without a result is not a
candidate.

The qualities decisions go by (keeping a best-of's winner, re-allocating) are each result's own
where its module reports its true quality, else what the module's profile predicts for the time
it used (`decision_quality`): a self-estimate is not what the compiler measured.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from attrs import frozen

from anytime.clocks import Clock, WorkClock
from anytime.compiler.compile import CompiledProgram
from anytime.compiler.model import (
    ModuleNode,
)
from anytime.modules import AnytimeModule, Context, Result
from anytime.runtime.execution import Execution, ProgramRecord
from anytime.runtime.modes import SOFT, Budget, RunMode, budget_of
from anytime.runtime.observe import Observer
from anytime.runtime.values import ExecutionError, bind_inputs, decision_quality, resplit

__all__ = [
    "Call",
    "ExecutionError",
    "ProgramRecord",
    "bind_inputs",
    "decision_quality",
    "program_module",
    "resplit",
    "run_program",
    "run_until",
]


def run_program(
    compiled: CompiledProgram,
    inputs: Sequence[Any] | Mapping[str, Any],
    budget: Budget | float,
    *,
    adaptive: bool = False,
    mode: RunMode = SOFT,
    observers: Mapping[str, Observer] | None = None,
) -> ProgramRecord:
    """Run `compiled` within `budget` (its total time on its clock, a fresh work clock by
    default; its stop event, when set, interrupts every module), inputs positional or by name
    (`Result`s carry their quality, plain values have quality 1).

    `mode` is how each anytime module's call is run (see `anytime.runtime.run`): under
    `Isolated()` a module that crashes or hangs loses its own result only (status `crashed` or
    `failed` in its record), and the program goes on without it, as it does after any failed
    call. `observers` watch the runs of the modules they are named by (see
    `anytime.runtime.observe`), in every call of the module, in called schemas too.

    Raises:
        ExecutionError: the inputs do not match the program's, or a module has no code.
    """
    given = budget_of(budget)
    execution = Execution(compiled, inputs, given, adaptive, mode, observers or {})
    return execution.run()


@frozen
class Call:
    """What one call of a program is given in a run: its arguments, as the runtime passes
    them (`Result`s where they carry quality), and its share of the time."""

    args: tuple[Any, ...]
    kwargs: Mapping[str, Any]
    share: float


def run_until(
    compiled: CompiledProgram,
    inputs: Sequence[Any] | Mapping[str, Any],
    total: float,
    node: int,
    *,
    clock: Clock | None = None,
) -> Call | None:
    """Run `compiled` with `total` time as `run_program` does, up to the call of graph node
    `node` (a module's call, not made), and return what that call is given; None when it would
    not be made (an input without a result, an alternative found inapplicable). This is how a
    module is measured on the inputs its program feeds it (`anytime profile --upstream`)."""
    execution = Execution(compiled, inputs, Budget(total, clock or WorkClock()), False, SOFT, {})
    target = compiled.model.node(node)
    if not isinstance(target, ModuleNode) or target.callee is not None:
        raise ExecutionError(f"node {node} of schema '{compiled.name}' is not a module's call")
    execution.run(until=node)
    if not execution.active(target) or execution.not_run(target) is not None:
        return None
    _, args, kwargs = execution.arguments(target)
    return Call(tuple(args), kwargs, execution.budget(target))


def program_module(compiled: CompiledProgram, origin: str | None = None) -> AnytimeModule:
    """A compiled program as a contract module with its compiled profile: it runs the program
    with its allocation, on its context's clock."""
    program = compiled.model.program
    return AnytimeModule(
        name=program.name,
        kind="contract",
        function=_CompiledContract(compiled),
        parameters=program.inputs,
        inputs=compiled.model.quality_inputs,
        profile_source=compiled.profile,
        origin=origin or f"compiled schema '{program.name}'",
    )


class _CompiledContract:
    """The function of `program_module` (a class, so that it pickles with its program)."""

    def __init__(self, compiled: CompiledProgram) -> None:
        self.compiled = compiled
        self.__name__ = self.__qualname__ = compiled.name.replace("-", "_")

    def __call__(self, ctx: Context, *args: Any) -> Result | None:
        record = run_program(self.compiled, args, Budget(ctx.allocation, ctx.clock, ctx.stop))
        return record.result
