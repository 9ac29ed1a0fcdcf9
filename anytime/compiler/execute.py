"""Running a compiled program as a contract algorithm: a simple sequential executor.

`execute` runs the calls in topological order, each with its share of the total time from the
compiled allocation table (interpolated at the actual input qualities and total), on one shared
clock (a `WorkClock` unless given). An interruptible module runs until its allocation is spent
and answers with the last `Result` it yielded; a contract module gets its allocation up front;
an elementary function's output quality combines its inputs' qualities. Failure handling,
hard interruption and adaptive re-allocation belong to the runtime; this executor lets a
module's exception propagate.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from anytime.clocks import Clock, WorkClock
from anytime.dsl.graph import InputRef, NodeRef, Source
from anytime.dsl.program import Literal
from anytime.errors import AnytimeError
from anytime.modules import AnytimeModule, Context, Result

if TYPE_CHECKING:
    from anytime.compiler.compile import CompiledProgram
    from anytime.compiler.model import CompileNode


class ExecutionError(AnytimeError, RuntimeError):
    """A compiled program cannot run: missing inputs, or a module known only by its profile."""


def execute(
    compiled: CompiledProgram,
    inputs: Sequence[Any] | Mapping[str, Any],
    total: float,
    clock: Clock | None = None,
    stop: threading.Event | None = None,
) -> Result:
    """Run `compiled` with `total` time; inputs are positional or by name (`Result`s carry
    their quality, plain values have quality 1). Setting `stop` interrupts every module."""
    model = compiled.model
    program = model.program
    values = bind_inputs(program.name, program.inputs, inputs)
    qualities = [_quality(values[name]) for name in model.quality_inputs]
    allocation = compiled.allocation_at(qualities, total)
    clock = clock if clock is not None else WorkClock()
    results: dict[int, Result] = {}
    for node in model.nodes:
        module, args, kwargs = call_arguments(compiled, node, values, results)
        if node.kind == "elementary":
            carrying = {module.parameters.index(name) for name in module.inputs}
            results[node.index] = _elementary(module, args, kwargs, carrying)
        else:
            assert node.time_index is not None
            ctx = Context(allocation=float(allocation[node.time_index]), clock=clock, stop=stop)
            results[node.index] = _anytime(module, ctx, args, kwargs)
    output = model.graph.output
    if isinstance(output, NodeRef):
        return results[output.index]
    value = values[output.name]
    return value if isinstance(value, Result) else Result(value, 1.0)


def call_arguments(
    compiled: CompiledProgram,
    node: CompileNode,
    values: Mapping[str, Any],
    results: Mapping[int, Result],
) -> tuple[AnytimeModule, list[Any], dict[str, Any]]:
    """The module a node calls and its arguments: the results of earlier calls and the program's
    inputs, as `Result`s where the module takes quality-carrying inputs, else plain values."""
    model = compiled.model
    module = node.entry.module if node.entry is not None else None
    if module is None:
        raise ExecutionError(
            f"schema '{model.program.name}': '{node.name}' is known only by its profile "
            "(no code to run)"
        )
    carrying = {module.parameters.index(name) for name in module.inputs}

    def argument(source: Source, carries_quality: bool) -> Any:
        if isinstance(source, Literal):
            value: Any = source.value
        elif isinstance(source, InputRef):
            value = values[source.name]
        else:
            value = results[source.index]
        if carries_quality:
            return value if isinstance(value, Result) else Result(value, 1.0)
        return value.value if isinstance(value, Result) else value

    call = model.graph.nodes[node.index]
    args = [argument(source, i in carrying) for i, source in enumerate(call.args)]
    kwargs = {name: argument(source, False) for name, source in call.keywords}
    return module, args, kwargs


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


def _quality(value: Any) -> float:
    return value.quality if isinstance(value, Result) else 1.0


def _anytime(
    module: AnytimeModule, ctx: Context, args: list[Any], kwargs: dict[str, Any]
) -> Result:
    if module.kind == "contract":
        result = module(ctx, *args, **kwargs)
        if not isinstance(result, Result):
            raise ExecutionError(f"module '{module.name}' returned {result!r}, not a Result")
        return result
    best = Result(None, 0.0)  # nothing registered yet: no output
    generator = module(ctx, *args, **kwargs)
    try:
        for item in generator:
            if ctx.elapsed > ctx.allocation and ctx.remaining == 0.0:
                break  # registered after the deadline: too late to count
            if not isinstance(item, Result):
                raise ExecutionError(f"module '{module.name}' yielded {item!r}, not a Result")
            best = item
            if ctx.expired:
                break
    finally:
        generator.close()
    return best


def _elementary(
    module: AnytimeModule, args: list[Any], kwargs: dict[str, Any], carrying: set[int]
) -> Result:
    value = module(*args, **kwargs)
    if isinstance(value, Result):
        return value
    return Result(value, module.combine([args[i].quality for i in sorted(carrying)]))
