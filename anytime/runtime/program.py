"""Running a compiled program through the executor, with a fixed or an adaptive allocation.

The calls run in topological order on one clock, each through `run` (so each answers with a run
record and never loses its best result), with its share of the total from the compiled
allocation table. In **adaptive** mode, each time a module finishes the time that is left is
re-allocated among the modules still to run, given the quality its result was *observed* to
have: the compiled profiles are conditional, so the best split of the rest depends on it
(Zilberstein & Russell). The re-allocation searches the lattice of the compiled resolution,
exhaustively when that is small, else by hill-climbing.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.clocks import Clock, WorkClock
from anytime.compiler.allocators import Exhaustive, HillClimbing
from anytime.compiler.compile import CompiledProgram
from anytime.compiler.evaluate import Evaluator
from anytime.compiler.execute import (
    Choices,
    NoApplicableAlternative,
    bind_inputs,
    call_arguments,
    judge,
    not_run,
)
from anytime.compiler.model import CompileNode
from anytime.dsl.graph import NodeRef
from anytime.modules import Result
from anytime.profiles.profile import Array
from anytime.runtime.executor import RunRecord, Status, run


@frozen
class ProgramRecord:
    """What a program run gives back.

    Attributes:
        result: the output's best result (None when the output module registered none).
        status: "failed" if any call failed, "no-result" without an output result,
            "contract-expired" if the run used more than its total, else "completed".
        records: one run record per call, in execution order.
        allocations: the time each anytime module was given, in allocation-vector order.
        time_used: time on the run's clock from start to the answer.
    """

    result: Result | None
    status: Status
    records: tuple[RunRecord, ...]
    allocations: tuple[float, ...]
    time_used: float

    @property
    def quality(self) -> float:
        return self.result.quality if self.result is not None else 0.0


class _Conditioned:
    """The program's evaluator with some results observed, over the modules still to run."""

    def __init__(
        self, evaluator: Evaluator, observed: Mapping[int, float], free: Sequence[int]
    ) -> None:
        self.evaluator = evaluator
        self.observed = dict(observed)
        self.free = list(free)

    @property
    def n_modules(self) -> int:
        return len(self.free)

    def expected(self, quality: ArrayLike, allocation: ArrayLike) -> Array:
        part = np.atleast_2d(np.asarray(allocation, dtype=np.float64))
        full = np.zeros((len(part), self.evaluator.n_modules))
        full[:, self.free] = part
        return self.evaluator.expected(quality, full, self.observed)


def run_program(
    compiled: CompiledProgram,
    inputs: Sequence[Any] | Mapping[str, Any],
    total: float,
    *,
    clock: Clock | None = None,
    adaptive: bool = False,
    hard: bool = False,
    stop: threading.Event | None = None,
) -> ProgramRecord:
    """Run `compiled` with `total` time (inputs positional or by name; `Result`s carry their
    quality, plain values have quality 1)."""
    model = compiled.model
    values = bind_inputs(model.program.name, model.program.inputs, inputs)
    qualities = [
        values[name].quality if isinstance(values[name], Result) else 1.0
        for name in model.quality_inputs
    ]
    clock = clock if clock is not None else WorkClock()
    start = clock.now()
    choices = Choices(
        compiled, qualities, np.array(compiled.allocation_at(qualities, total), dtype=np.float64)
    )
    evaluator = Evaluator(model)
    results: dict[int, Result] = {}
    records: dict[int, RunRecord] = {}
    inner: list[RunRecord] = []  # the calls of the branches that ifs ran
    observed: dict[int, float] = {}

    for node in model.nodes:
        if not choices.active(node, results):
            continue
        skipped = (
            choices.undecidable(node, results)
            if node.role == "if"
            else None
            if node.role == "best-of"
            else not_run(compiled, node, values, results)
        )
        if skipped is not None:
            record = RunRecord(
                module=node.name,
                status=Status.NO_RESULT,
                result=None,
                time_used=0.0,
                allocation=0.0,
                error=skipped,
            )
        elif node.role == "best-of":
            record = _best_of_record(choices, node, values, results, observed)
        elif node.role == "if":
            plan, branch_inputs, given = choices.branch(node, values, results)
            sub = run_program(
                plan.compiled,
                branch_inputs,
                given,
                clock=clock,
                adaptive=adaptive,
                hard=hard,
                stop=stop,
            )
            inner.extend(sub.records)
            record = RunRecord(
                module=f"if -> {plan.compiled.name}",
                status=sub.status,
                result=sub.result,
                time_used=sub.time_used,
                allocation=given,
                registered=int(sub.result is not None),
            )
        else:
            module, args, kwargs = call_arguments(compiled, node, values, results)
            if node.kind == "anytime":
                assert node.time_index is not None
                if adaptive and observed:
                    for other in model.anytime_nodes:  # alternatives that will not run
                        if other.index not in observed and choices.ruled_out(other):
                            observed[other.index] = 0.0
                    left = max(0.0, total - (clock.now() - start))
                    choices.allocation = _reallocate(
                        compiled, evaluator, qualities, observed, choices.allocation, left
                    )
                given = choices.budget(node, clock.now() - start, total)
                choices.allocation[node.time_index] = given  # what it was given, as recorded
                record = run(
                    module, args, kwargs, allocation=given, clock=clock, stop=stop, hard=hard
                )
            else:
                record = run(module, args, kwargs, clock=clock)
        records[node.index] = record
        if record.result is not None:  # no placeholder for a call that has no result
            results[node.index] = record.result
        observed[node.index] = (
            0.0
            if record.result is None
            else judge(node, record.result, record.time_used, observed, results, qualities)
        )
    allocation = choices.allocation
    output = model.graph.output
    if isinstance(output, NodeRef):
        final = records[output.index].result
    else:
        value = values[output.name]
        final = value if isinstance(value, Result) else Result(value, 1.0)
    used = clock.now() - start
    if any(r.status == Status.FAILED for r in [*records.values(), *inner]):
        status = Status.FAILED
    elif final is None:
        status = Status.NO_RESULT
    elif used > total + 1e-9:
        status = Status.CONTRACT_EXPIRED
    else:
        status = Status.COMPLETED
    return ProgramRecord(
        result=final,
        status=status,
        records=(*records.values(), *inner),
        allocations=tuple(float(a) for a in allocation),
        time_used=used,
    )


def _best_of_record(
    choices: Choices,
    node: CompileNode,
    values: Mapping[str, Any],
    results: Mapping[int, Result],
    judged: Mapping[int, float],
) -> RunRecord:
    """A best-of's answer as a run record: none applicable is a status, not an exception."""
    try:
        best = choices.best(node, values, results, judged)
    except NoApplicableAlternative as error:
        return RunRecord(
            module="best-of",
            status=Status.NO_RESULT,
            result=None,
            time_used=0.0,
            allocation=0.0,
            error=str(error),
        )
    return RunRecord(
        module="best-of",
        status=Status.COMPLETED,
        result=best,
        time_used=0.0,
        allocation=0.0,
        registered=1,
    )


def _reallocate(
    compiled: CompiledProgram,
    evaluator: Evaluator,
    qualities: Sequence[float],
    observed: Mapping[int, float],
    allocation: Array,
    left: float,
) -> Array:
    """The best split of the time `left` among the anytime modules not yet run, given the
    qualities observed so far (on the compiled lattice; whatever the lattice cannot hold goes
    to the first of them)."""
    model = compiled.model
    free = [
        n.time_index
        for n in model.anytime_nodes
        if n.index not in observed and n.time_index is not None
    ]
    if not free:
        return allocation
    dt = compiled.resolution
    units = np.array([int(np.floor(left / dt + 1e-9))])
    conditioned = _Conditioned(evaluator, observed, free)
    q = np.asarray(qualities, dtype=np.float64).reshape(1, -1)
    allocator = Exhaustive() if Exhaustive.computable(units, len(free)) else HillClimbing()
    split, _ = allocator.allocate(conditioned, q, units, dt)
    new = allocation.copy()
    new[free] = split[0] * dt
    new[free[0]] += left - units[0] * dt
    return new
