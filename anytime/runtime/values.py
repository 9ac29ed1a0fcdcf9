"""The values a program run passes between its calls, and the qualities its decisions go by:
binding a program's inputs, wrapping and unwrapping `Result`s, and the quality a finished call
is judged by when a best-of keeps its winner or the rest of the time is re-split."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from anytime.compiler.allocators import reallocate
from anytime.compiler.allocators.reallocate import QUANTUM
from anytime.compiler.compile import CompiledProgram
from anytime.compiler.model import (
    ChoiceNode,
    CompileNode,
    IfNode,
    LoopNode,
    ModuleNode,
)
from anytime.errors import AnytimeError
from anytime.modules import MISSING, Result
from anytime.profiles.profile import Array
from anytime.runtime.executor import RunRecord, Status


class ExecutionError(AnytimeError, RuntimeError):
    """A compiled program cannot run: missing inputs, or a module known only by its profile."""


def resplit(
    compiled: CompiledProgram,
    choice: ChoiceNode,
    applicable: Sequence[bool],
    allocation: Array,
    qualities: Sequence[float],
) -> Array:
    """The time `allocation` gives a best-of's alternatives, re-split among the applicable
    ones (the compiler's `reallocate`, the others' qualities 0)."""
    model = compiled.model
    groups = [model.alternative_modules(choice.index, i) for i in range(len(choice.values))]
    everything = sorted({m for g in groups for m in g})
    free = sorted({m for g, ok in zip(groups, applicable, strict=True) if ok for m in g})
    budget = float(allocation[everything].sum())
    observed = {
        slot.index: 0.0
        for slot, ok in zip(choice.slots, applicable, strict=True)
        if not ok and slot.kind == "node"
    }
    base = np.array(allocation, dtype=np.float64)
    base[everything] = 0.0
    return reallocate(model, compiled.resolution, qualities, base, free, budget, observed)


def decision_quality(
    node: CompileNode,
    result: Result,
    used: float,
    judged: Mapping[int, float],
    qualities: Sequence[float],
) -> float:
    """The quality the runtime decides by for a call's result: the result's own where its
    module reports its true quality (`AnytimeModule.reports`); else what the module's profile
    predicts at the qualities its inputs were judged to have and the time it used (a
    self-estimate is not what the profile, and so the compiler, measured)."""
    if not isinstance(node, ModuleNode) or node.entry is None or node.entry.module is None:
        return result.quality
    if node.entry.module.reports == "true":
        return result.quality
    q = np.asarray(judged_inputs(node, judged, qualities)).reshape(1, -1)
    return float(node.profile.expected(q, np.asarray([used]))[0])


def news(
    node: CompileNode,
    record: RunRecord,
    share: float,
    resolution: float,
    judged: Mapping[int, float],
    qualities: Sequence[float],
) -> bool:
    """Whether a finished call, given `share`, tells the plan something it did not know (else
    the value of the information is 0, and re-planning could only cost): it left `resolution`
    or more of its share unused, or its outcome is a draw the plan knew only the distribution
    of -- no result from a call that ran, a true quality from a module whose profile is not
    deterministic (or is, but did not predict it), the result of a loop, an if or a called
    schema. A quality judged by a module's profile at the time it used is what the plan
    expected; a best-of's or a function's quality is that of calls already seen."""
    if not isinstance(node, ModuleNode | LoopNode | IfNode):
        return False
    if share - record.time_used >= resolution - 1e-9:
        return True
    if not isinstance(node, ModuleNode) or node.callee is not None:
        return True
    if record.result is None:
        return record.time_used > 0
    module = node.entry.module if node.entry is not None else None
    if module is None or module.reports != "true":
        return False
    if not node.deterministic:
        return True
    q = np.asarray(judged_inputs(node, judged, qualities), dtype=np.float64).reshape(1, -1)
    expected = float(node.profile.expected(q, np.asarray([record.time_used]))[0])
    return abs(record.result.quality - expected) > QUANTUM


def judged_inputs(
    node: ModuleNode, judged: Mapping[int, float], qualities: Sequence[float]
) -> list[float]:
    """The qualities a node's inputs were judged to have, in its profile's axis order (a
    missing one, for a module that accepts it, at 0)."""
    return [
        max(judged.get(slot.index, 0.0), 0.0)
        if slot.kind == "node"
        else qualities[slot.index]
        if slot.kind == "input"
        else slot.value
        for slot in node.slots
    ]


def bind_inputs(
    name: str, parameters: Sequence[str], inputs: Sequence[Any] | Mapping[str, Any]
) -> dict[str, Any]:
    """The program's inputs by name, from positional or named values."""
    if isinstance(inputs, Mapping):
        values = {str(k).lower(): v for k, v in inputs.items()}
    else:
        if len(inputs) != len(parameters):
            raise ExecutionError(
                f"schema '{name}' takes {len(parameters)} input{'s' * (len(parameters) != 1)} "
                f"({', '.join(parameters)}), got {len(inputs)}"
            )
        values = dict(zip(parameters, inputs, strict=True))
    missing = [p for p in parameters if p not in values]
    if missing:
        raise ExecutionError(f"schema '{name}': missing inputs: {', '.join(missing)}")
    return values


def no_result(name: str, why: str) -> RunRecord:
    return RunRecord(name, Status.NO_RESULT, None, 0.0, 0.0, error=why)


def quality_of(value: Any) -> float:
    return value.quality if isinstance(value, Result) else 1.0


def wrapped(value: Any) -> Result:
    return value if isinstance(value, Result) else Result(value, 1.0)


def plain(value: Any) -> Any:
    return value.value if isinstance(value, Result) else value


def is_collection(value: Any) -> bool:
    """What a map iterates over: a sequence (a list, a tuple), not a string."""
    return isinstance(value, Sequence) and not isinstance(value, str | bytes)


def passed(value: Any, carries_quality: bool) -> Any:
    """A value as a call is passed it: a `Result` where the argument carries quality, else the
    plain value (`MISSING` as it is: only for a module that accepts it, see `not_run`)."""
    if value is MISSING:
        return MISSING
    return wrapped(value) if carries_quality else plain(value)


def truth(value: Any) -> bool:
    return bool(value.value if isinstance(value, Result) else value)
