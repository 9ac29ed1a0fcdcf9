"""Running a compiled program as a contract algorithm: a simple sequential executor.

`execute` runs the calls in topological order, each with its share of the total time from the
compiled allocation table (interpolated at the actual input qualities and total), on one shared
clock (a `WorkClock` unless given). An interruptible module runs until its allocation is spent
and answers with the last `Result` it yielded; a contract module gets its allocation up front;
an elementary function's output quality combines its inputs' qualities. A best-of evaluates
its preconditions, re-splits its alternatives' time among the applicable ones (`resplit`), runs
those and answers with the result of highest quality (none applicable: `NoApplicableAlternative`);
an if runs the compiled branch its condition selects with the if's time. Failure handling,
hard interruption and adaptive re-allocation belong to the runtime; this executor lets a
module's exception propagate.

No placeholders: a call one of whose inputs has no result (its producer registered none) is not
made, and has no result either, unless its module declares `accepts_missing` (it then gets
`MISSING` for that input); a best-of's precondition without a value makes its alternative
inapplicable, and an alternative without a result is not a candidate.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from anytime.clocks import Clock, WorkClock
from anytime.compiler.evaluate import Evaluator
from anytime.dsl.graph import InputRef, NodeRef, Source
from anytime.dsl.program import Literal
from anytime.errors import AnytimeError
from anytime.modules import MISSING, AnytimeModule, Context, Result
from anytime.profiles.profile import Array

if TYPE_CHECKING:
    from anytime.compiler.compile import CompiledProgram
    from anytime.compiler.model import CompileNode


class ExecutionError(AnytimeError, RuntimeError):
    """A compiled program cannot run: missing inputs, or a module known only by its profile."""


class NoApplicableAlternative(ExecutionError):
    """Every precondition of a best-of was false: there is no alternative to run."""


def execute(
    compiled: CompiledProgram,
    inputs: Sequence[Any] | Mapping[str, Any],
    total: float,
    clock: Clock | None = None,
    stop: threading.Event | None = None,
) -> Result | None:
    """Run `compiled` with `total` time; inputs are positional or by name (`Result`s carry
    their quality, plain values have quality 1). Setting `stop` interrupts every module. The
    answer is the output's result, or None when it has none."""
    model = compiled.model
    program = model.program
    values = bind_inputs(program.name, program.inputs, inputs)
    qualities = [_quality(values[name]) for name in model.quality_inputs]
    clock = clock if clock is not None else WorkClock()
    start = clock.now()
    results: dict[int, Result] = {}
    judged: dict[int, float] = {}  # the qualities decisions go by (see `decision_quality`)
    choices = Choices(compiled, qualities, compiled.allocation_at(qualities, total))

    for node in model.nodes:
        if not choices.active(node, results):
            continue
        answer: Result | None
        used = 0.0
        if node.role == "best-of":
            answer = choices.best(node, values, results, judged)
        elif node.role == "if":
            if choices.undecidable(node, results):
                continue
            plan, branch_inputs, given = choices.branch(node, values, results)
            answer = execute(plan.compiled, branch_inputs, given, clock, stop)
        elif not_run(compiled, node, values, results):
            continue
        else:
            module, args, kwargs = call_arguments(compiled, node, values, results)
            if node.kind == "elementary":
                carrying = {module.parameters.index(name) for name in module.inputs}
                answer = _elementary(module, args, kwargs, carrying)
            else:
                assert node.time_index is not None
                given = choices.budget(node, clock.now() - start, total)
                ctx = Context(allocation=given, clock=clock, stop=stop)
                answer = _anytime(module, ctx, args, kwargs)
                used = ctx.elapsed
        if answer is not None:
            results[node.index] = answer
            judged[node.index] = judge(node, answer, used, judged, results, qualities)
    output = model.graph.output
    if isinstance(output, NodeRef):
        return results.get(output.index)
    value = values[output.name]
    return value if isinstance(value, Result) else Result(value, 1.0)


class Choices:
    """Which calls of a program run, and with how much time, as its choices are decided.

    A call inside an alternative of a best-of runs only if that alternative is applicable (and
    the best-of itself runs); the first time an alternative is looked at, the preconditions
    (numbered before every alternative) decide which are, and the time the compiled allocation
    gives the alternatives is re-split among those (`resplit`). Shared by this executor and the
    runtime's `run_program`.

    Attributes:
        allocation: the time of each anytime module, updated by every re-split.
    """

    def __init__(
        self, compiled: CompiledProgram, qualities: Sequence[float], allocation: Array
    ) -> None:
        self.compiled = compiled
        self.qualities = list(qualities)
        self.allocation = allocation
        self.applicable: dict[int, list[bool]] = {}

    def active(self, node: CompileNode, results: Mapping[int, Result]) -> bool:
        """Whether `node` runs: every alternative it is inside is applicable."""
        model = self.compiled.model
        tag = node.branch
        if node.role == "precondition":
            assert tag is not None
            return self.active(model.node(tag[0]), results)
        if tag is None:
            return True
        choice = model.node(tag[0])
        if not self.active(choice, results):
            return False
        return self.decided(choice, results)[tag[1]]

    def budget(self, node: CompileNode, spent: float, total: float) -> float:
        """The time an anytime node gets: its planned share, less whatever earlier calls used
        past theirs (a module may overshoot by its last step), so that the calls still to run
        keep their planned time and the program keeps its contract."""
        assert node.time_index is not None
        later = sum(
            float(self.allocation[n.time_index])
            for n in self.compiled.model.anytime_nodes
            if n.index > node.index and n.time_index is not None and not self.ruled_out(n)
        )
        planned = float(self.allocation[node.time_index])
        left = total - spent - later
        if left >= planned - 1e-9 * max(1.0, abs(total)):  # nothing overran (up to rounding)
            return planned
        return max(0.0, left)

    def ruled_out(self, node: CompileNode) -> bool:
        """Whether `node` is known not to run: it is inside an alternative found inapplicable
        (looks only at choices already decided)."""
        tag = node.branch
        if tag is None:
            return False
        choice = self.compiled.model.node(tag[0])
        if self.ruled_out(choice):
            return True
        decided = self.applicable.get(choice.index)
        return decided is not None and not decided[tag[1]]

    def decided(self, choice: CompileNode, results: Mapping[int, Result]) -> list[bool]:
        """The applicable alternatives of a best-of (its preconditions must have run)."""
        if choice.index not in self.applicable:
            # A precondition that has no value (its input had no result) rules its out.
            found = [
                p is None or (p in results and bool(results[p].value)) for p in choice.preconditions
            ]
            self.applicable[choice.index] = found
            self.allocation = resplit(self.compiled, choice, found, self.allocation, self.qualities)
        return self.applicable[choice.index]

    def best(
        self,
        node: CompileNode,
        values: Mapping[str, Any],
        results: Mapping[int, Result],
        judged: Mapping[int, float] | None = None,
    ) -> Result:
        """A best-of's answer: its best applicable alternative's result, by the qualities
        `judged` (`decision_quality`) where given, else by the results' own.

        Raises:
            NoApplicableAlternative: every precondition was false.
        """
        applicable = self.decided(node, results)
        return _best_of(self.compiled, node, applicable, values, results, judged or {})

    def undecidable(self, node: CompileNode, results: Mapping[int, Result]) -> str | None:
        """Why an if cannot choose its branch (its condition has no value), or None."""
        condition = node.condition
        if isinstance(condition, NodeRef) and condition.index not in results:
            variable = self.compiled.model.graph.nodes[condition.index].variable
            return f"not run: its condition '{variable}' has no value"
        return None

    def branch(
        self, node: CompileNode, values: Mapping[str, Any], results: Mapping[int, Result]
    ) -> tuple[Any, dict[str, Any], float]:
        """An if's branch to run, its inputs, and the if's time: (the branch's plan, whose
        `compiled` program runs, inputs by name, time)."""
        assert node.time_index is not None and node.condition is not None
        condition = source_value(node.condition, values, results)
        plan = node.branches[0 if _truth(condition) else 1]
        index_of = {n.variable: i for i, n in enumerate(self.compiled.model.graph.nodes)}
        inputs = {
            name: values[name] if name not in index_of else results.get(index_of[name], MISSING)
            for name in plan.compiled.model.program.inputs
        }
        return plan, inputs, float(self.allocation[node.time_index])


def missing_inputs(
    compiled: CompiledProgram,
    node: CompileNode,
    values: Mapping[str, Any],
    results: Mapping[int, Result],
) -> list[str]:
    """The call's arguments that have no result, as a message names them: "from 'f'" for a
    call of `f` that registered none, "'x'" for an input standing for one (a branch's input,
    given `MISSING`)."""
    graph = compiled.model.graph
    call = graph.nodes[node.index]
    missing = []
    for source in [*call.args, *(s for _, s in call.keywords)]:
        if isinstance(source, NodeRef) and source.index not in results:
            missing.append(f"from '{graph.nodes[source.index].function}'")
        elif isinstance(source, InputRef) and values[source.name] is MISSING:
            missing.append(f"'{source.name}'")
    return missing


def not_run(
    compiled: CompiledProgram,
    node: CompileNode,
    values: Mapping[str, Any],
    results: Mapping[int, Result],
) -> str | None:
    """Why a call is not made (an input has no result and its module does not accept that),
    or None when it runs."""
    missing = missing_inputs(compiled, node, values, results)
    module = node.entry.module if node.entry is not None else None
    if not missing or (module is not None and module.accepts_missing):
        return None
    plural = "s" if len(missing) > 1 else ""
    names = ", ".join(missing)
    return f"not run: its input{plural} {names} {'have' if plural else 'has'} no result"


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
        elif source.index not in results:
            return MISSING  # only for a module that accepts it (see `not_run`)
        else:
            value = results[source.index]
        if carries_quality:
            return value if isinstance(value, Result) else Result(value, 1.0)
        return value.value if isinstance(value, Result) else value

    call = model.graph.nodes[node.index]
    args = [argument(source, i in carrying) for i, source in enumerate(call.args)]
    kwargs = {name: argument(source, False) for name, source in call.keywords}
    return module, args, kwargs


def source_value(source: Source, values: Mapping[str, Any], results: Mapping[int, Result]) -> Any:
    """What an argument stands for: a literal's value, an input's value, or a call's Result."""
    if isinstance(source, Literal):
        return source.value
    if isinstance(source, InputRef):
        return values[source.name]
    return results[source.index]


def _truth(value: Any) -> bool:
    return bool(value.value if isinstance(value, Result) else value)


def _best_of(
    compiled: CompiledProgram,
    node: CompileNode,
    applicable: Sequence[bool],
    values: Mapping[str, Any],
    results: Mapping[int, Result],
    judged: Mapping[int, float],
) -> Result:
    """The result of highest quality among the applicable alternatives (the first on ties),
    each judged by `judged` where it has an entry (see `decision_quality`)."""
    call = compiled.model.graph.nodes[node.index]
    n = len(call.args) // 2
    chosen = [source for source, ok in zip(call.args[n:], applicable, strict=True) if ok]
    present = [s for s in chosen if not (isinstance(s, NodeRef) and s.index not in results)]
    candidates = [source_value(source, values, results) for source in present]
    if not candidates:
        why = (
            f"all {n} preconditions are false"
            if not chosen
            else "none of the applicable ones has a result"
        )
        raise NoApplicableAlternative(
            f"schema '{compiled.model.program.name}': no alternative of best-of "
            f"'{call.variable}' is applicable ({why})"
        )
    wrapped = [c if isinstance(c, Result) else Result(c, 1.0) for c in candidates]
    scores = [
        judged.get(s.index, r.quality) if isinstance(s, NodeRef) else r.quality
        for s, r in zip(present, wrapped, strict=True)
    ]
    return wrapped[max(range(len(wrapped)), key=lambda i: (scores[i], -i))]


def judge(
    node: CompileNode,
    answer: Result,
    used: float,
    judged: Mapping[int, float],
    results: Mapping[int, Result],
    qualities: Sequence[float],
) -> float:
    """The quality decisions go by for a node's answer: a best-of's is its chosen
    alternative's, a call's its `decision_quality`."""
    if node.role == "best-of":
        chosen = (judged[i] for i, r in results.items() if r is answer and i in judged)
        return next(chosen, answer.quality)
    return decision_quality(node, answer, used, judged, qualities)


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
    module = node.entry.module if node.entry is not None else None
    if module is None or module.reports == "true" or node.profile is None:
        return result.quality
    inputs = [
        judged.get(slot.index, 0.0)
        if slot.kind == "node"
        else qualities[slot.index]
        if slot.kind == "input"
        else slot.value
        for slot in node.slots
    ]
    q = np.asarray(inputs, dtype=np.float64).reshape(1, -1)
    return float(node.profile.expected(q, np.asarray([used]))[0])


class _Restricted:
    """The program's evaluator with the allocation fixed except on `free` modules, and some
    nodes' qualities fixed (the alternatives that will not run give quality 0)."""

    def __init__(
        self, evaluator: Evaluator, base: Array, free: Sequence[int], observed: dict[int, float]
    ) -> None:
        self.evaluator, self.base, self.free, self.observed = evaluator, base, list(free), observed

    @property
    def n_modules(self) -> int:
        return len(self.free)

    def expected(self, quality: ArrayLike, allocation: ArrayLike) -> Array:
        part = np.atleast_2d(np.asarray(allocation, dtype=np.float64))
        full = np.tile(self.base, (len(part), 1))
        full[:, self.free] = part
        return self.evaluator.expected(quality, full, self.observed)


def resplit(
    compiled: CompiledProgram,
    choice: CompileNode,
    applicable: Sequence[bool],
    allocation: Array,
    qualities: Sequence[float],
) -> Array:
    """Re-split the time the compiled allocation gives a best-of's alternatives among the
    applicable ones, on the fly: the same search as the compiler (exhaustive on the compiled
    lattice where affordable, else hill-climbing), maximising the program's expected quality
    with the other modules' times kept and the inapplicable alternatives at quality 0."""
    from anytime.compiler.allocators import Exhaustive, HillClimbing

    model = compiled.model
    groups = [model.alternative_modules(choice.index, i) for i in range(len(choice.slots))]
    everything = sorted({m for g in groups for m in g})
    free = sorted({m for g, ok in zip(groups, applicable, strict=True) if ok for m in g})
    new = np.array(allocation, dtype=np.float64)
    budget = float(new[everything].sum())
    new[everything] = 0.0
    if not free or budget <= 0 or all(applicable):
        return np.array(allocation, dtype=np.float64) if all(applicable) else new
    dt = compiled.resolution
    units = np.array([int(np.floor(budget / dt + 1e-9))])
    observed = {
        slot.index: 0.0
        for slot, ok in zip(choice.slots, applicable, strict=True)
        if not ok and slot.kind == "node"
    }
    restricted = _Restricted(Evaluator(model), new, free, observed)
    q = np.asarray(qualities, dtype=np.float64).reshape(1, -1)
    search = Exhaustive() if Exhaustive.computable(units, len(free)) else HillClimbing()
    split, _ = search.allocate(restricted, q, units, dt)
    new[free] = split[0] * dt
    new[free[0]] += budget - units[0] * dt
    return new


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
) -> Result | None:
    if module.kind == "contract":
        result = module(ctx, *args, **kwargs)
        if result is not None and not isinstance(result, Result):
            raise ExecutionError(f"module '{module.name}' returned {result!r}, not a Result")
        return result
    best: Result | None = None  # nothing registered yet: no output
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
