"""What the compiler needs of a program: its calls, their profiles, and where qualities flow.

A `CompileModel` resolves every node of a program's dataflow graph against the anytime library:
an *anytime* node (interruptible, contract, or a compiled schema) gets a share of the time and
is described by its conditional performance profile; an *elementary* node takes no time and
combines its inputs' qualities (min by default). For each quality-carrying input of a node, a
`Slot` says where its quality comes from: another node, a quality-carrying program input, or a
constant (a literal argument has quality 1).
"""

from __future__ import annotations

import builtins
import inspect
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal

import attrs
import numpy as np
from attrs import frozen

from anytime.dsl.graph import DataflowGraph, InputRef, NodeRef, Source
from anytime.dsl.normalize import count, suggest
from anytime.dsl.program import Literal as LiteralArg
from anytime.dsl.program import Program, Step, Var
from anytime.errors import AnytimeError, Diagnostic, SchemaError
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.profiles.profile import (
    ConditionalPerformanceProfile,
    default_bins,
    new_profile,
    point_mass,
)


class CompileError(AnytimeError, ValueError):
    """A program cannot be compiled as asked (grids, units); the message says what to change."""


@frozen
class Slot:
    """Where one quality-carrying input of a node gets its quality."""

    kind: Literal["node", "input", "constant"]
    index: int = 0  # node index, or index among the program's quality-carrying inputs
    value: float = 1.0  # for a constant


Role = Literal["module", "precondition", "best-of", "if"]


@frozen(eq=False)
class BranchPlan:
    """One branch of an `if`, compiled as a program of its own.

    Attributes:
        probability: the probability that this branch runs.
        compiled: the branch compiled on the time lattice (a `CompiledProgram`).
        axes: for each quality-carrying input of the branch, its position in the if node's slots.
    """

    probability: float
    compiled: Any
    axes: tuple[int, ...]

    @property
    def deterministic(self) -> bool:
        return is_deterministic(self.compiled.profile)


@frozen(eq=False)
class CompileNode:
    """One call of the program as the compiler sees it.

    Attributes:
        index: the node's index in the dataflow graph (topological).
        name: the function called.
        kind: "anytime" (gets time) or "elementary" (takes none).
        slots: the sources of its quality-carrying inputs, in profile-axis order.
        profile: the conditional performance profile (anytime nodes).
        deterministic: every cell of the profile is a point mass at its mean quality.
        combine: how an elementary node combines input qualities, on arrays along axis 0.
        monotone_combine: the combination is known to be non-decreasing in every input.
        time_index: the node's position in an allocation vector (anytime nodes).
        entry: the library entry (None for elementary functions unknown to the library).
        role: "module" for an ordinary call; "precondition" for the test of a best-of
            alternative (elementary, its quality flows nowhere); "best-of" for the choice
            (elementary: its slots are the alternatives, its quality their maximum); "if" for a
            conditional (anytime: its time goes to the branch that runs).
        branch: (choice node index, alternative) for a call inside a best-of alternative.
        preconditions: for a best-of, the node index of each alternative's precondition (None
            for an alternative that is always applicable).
        branches: for an if, the then and else branches.
        condition: for an if, where the condition's value comes from.
    """

    index: int
    name: str
    kind: Literal["anytime", "elementary"]
    slots: tuple[Slot, ...]
    profile: ConditionalPerformanceProfile | None = None
    deterministic: bool = False
    combine: Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]] | None = None
    monotone_combine: bool = True
    time_index: int | None = None
    entry: LibraryEntry | None = None
    role: Role = "module"
    branch: tuple[int, int] | None = None
    preconditions: tuple[int | None, ...] = ()
    branches: tuple[BranchPlan, ...] = ()
    condition: Source | None = None


@frozen(eq=False)
class CompileModel:
    """A program resolved against a library, ready for evaluating allocations."""

    program: Program
    graph: DataflowGraph
    nodes: tuple[CompileNode, ...]
    quality_inputs: tuple[str, ...]  # program inputs whose quality conditions the output
    output: Slot
    time_unit: str

    @property
    def anytime_nodes(self) -> tuple[CompileNode, ...]:
        """The nodes that get time, in allocation-vector order."""
        return tuple(n for n in self.nodes if n.kind == "anytime")

    @property
    def module_names(self) -> tuple[str, ...]:
        return tuple(n.name for n in self.anytime_nodes)

    def node(self, index: int) -> CompileNode:
        """The node with this graph index."""
        return next(n for n in self.nodes if n.index == index)

    def alternative_modules(self, choice: int, alternative: int) -> tuple[int, ...]:
        """The allocation-vector positions of the anytime modules inside one alternative of a
        best-of (through nested choices too)."""
        return tuple(
            n.time_index
            for n in self.anytime_nodes
            if n.time_index is not None and self.inside(n, (choice, alternative))
        )

    def inside(self, node: CompileNode, branch: tuple[int, int]) -> bool:
        tag = node.branch
        while tag is not None:
            if tag == branch:
                return True
            tag = self.node(tag[0]).branch
        return False


def is_deterministic(profile: ConditionalPerformanceProfile) -> bool:
    """True when each cell is a point mass at the cell's mean (a tabulated quality curve)."""
    return profile.mean is not None and bool(
        np.array_equal(profile.probability, point_mass(profile.mean, profile.bins))
    )


_COMBINATIONS: dict[Callable[..., Any], Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]]] = {
    builtins.min: lambda q: np.min(q, axis=0),
    builtins.max: lambda q: np.max(q, axis=0),
}


def _vector_combine(
    combine: Callable[[Sequence[float]], float],
) -> tuple[Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]], bool]:
    """An array version of an elementary function's quality combination, and whether it is
    known to be monotone (min and max are; any other function is applied point by point)."""
    name = getattr(combine, "__name__", "")
    if combine in _COMBINATIONS:
        return _COMBINATIONS[combine], True
    if name == "_min_quality":  # the modules' default: min, with 1.0 for no inputs
        return (lambda q: np.min(q, axis=0) if len(q) else np.ones(q.shape[1:])), True

    def pointwise(q: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        flat = q.reshape(len(q), -1)
        out = np.array([combine(list(column)) for column in flat.T], dtype=np.float64)
        return out.reshape(q.shape[1:])

    return pointwise, False


def _call_mismatch(entry: LibraryEntry, n_args: int, keywords: Sequence[str]) -> str | None:
    """Why a call does not fit the module's function (its positional arity, then its keyword
    parameters, as Python would bind them), or None; a call that compiled but could not run
    failed with a TypeError at run time."""
    if entry.arity is not None and n_args != entry.arity:
        return f"function '{entry.name}' takes {count(entry.arity)}, got {n_args}"
    module = entry.module
    if module is None:
        return None
    try:
        signature = inspect.signature(module.function)
    except (TypeError, ValueError):  # a builtin or an object without a readable signature
        return None
    context = () if module.kind == "elementary" else (None,)
    try:
        signature.bind(*context, *[None] * n_args, **dict.fromkeys(keywords))
    except TypeError as error:
        return f"function '{entry.name}': {error}"
    return None


def build_model(
    program: Program,
    library: AnytimeLibrary,
    filename: str = "<schema>",
    source_lines: Sequence[str] = (),
    compile_branch: Callable[[Program], Any] | None = None,
) -> CompileModel:
    """Resolve `program` against `library`.

    A best-of becomes an elementary node taking the maximum of its alternatives' qualities
    (they run side by side, sharing the time); an if becomes one anytime node whose branches
    are compiled as programs of their own by `compile_branch` (the calls inside them are not
    nodes of this model), its profile the mixture of theirs.

    Raises:
        SchemaError: a call to an unknown function, to a module without a profile, or whose
            quality-carrying arguments cannot be told apart; each names its place.
        CompileError: profiles in different time units.
    """
    graph = program.graph
    diagnostics: list[Diagnostic] = []
    quality_inputs: dict[str, int] = {}
    nodes: list[CompileNode] = []
    spans = {step.target: step.function_span for step in program.steps}

    def complain(node_index: int, message: str) -> None:
        span = spans.get(graph.nodes[node_index].variable)
        line, column = (span.line, span.column) if span else (1, 1)
        text = source_lines[line - 1] if 0 < line <= len(source_lines) else ""
        width = span.end_column - span.column if span and span.end_line == span.line else 1
        diagnostics.append(Diagnostic(filename, line, column, message, text, width))

    def slot(source: Source) -> Slot:
        if isinstance(source, NodeRef):
            return Slot("node", source.index)
        if isinstance(source, InputRef):
            index = quality_inputs.setdefault(source.name, len(quality_inputs))
            return Slot("input", index)
        return Slot("constant", value=1.0)

    step_of = {step.target: step for step in program.steps}
    index_of = {node.variable: i for i, node in enumerate(graph.nodes)}

    def in_if(variable: str) -> bool:
        tag = step_of[variable].branch
        while tag is not None:
            if step_of[tag[0]].kind == "if":
                return True
            tag = step_of[tag[0]].branch
        return False

    def role_and_branch(variable: str) -> tuple[Role, tuple[int, int] | None]:
        tag = step_of[variable].branch
        if tag is None:
            return "module", None
        choice = step_of[tag[0]]
        n = len(choice.args) // 2
        is_test = choice.kind == "best-of" and Var(variable) in choice.args[:n]
        role: Role = "precondition" if is_test else "module"
        return role, (index_of[tag[0]], tag[1])

    time_index = 0
    for index, node in enumerate(graph.nodes):
        if in_if(node.variable):
            continue
        if node.kind == "best-of":
            n = len(node.args) // 2
            pre = tuple(s.index if isinstance(s, NodeRef) else None for s in node.args[:n])
            _, branch = role_and_branch(node.variable)
            nodes.append(
                CompileNode(
                    index,
                    "best-of",
                    "elementary",
                    tuple(slot(s) for s in node.args[n:]),
                    None,
                    True,
                    _COMBINATIONS[builtins.max],
                    True,
                    role="best-of",
                    branch=branch,
                    preconditions=pre,
                )
            )
            continue
        if node.kind == "if":
            built = _if_node(program, graph, step_of[node.variable], index, library, compile_branch)
            if isinstance(built, str):
                complain(index, built)
                continue
            plans, names = built
            _, branch = role_and_branch(node.variable)
            reads: list[Source] = [
                InputRef(v) if v not in index_of else NodeRef(index_of[v]) for v in names
            ]
            mixture = _mixture(plans, names, f"{program.name}/{node.variable}")
            nodes.append(
                CompileNode(
                    index,
                    "if",
                    "anytime",
                    tuple(slot(s) for s in reads),
                    mixture,
                    False,
                    time_index=time_index,
                    role="if",
                    branch=branch,
                    branches=plans,
                    condition=node.args[0],
                )
            )
            time_index += 1
            continue
        role, branch = role_and_branch(node.variable)
        entry = library.get(node.function)
        if entry is None:
            hint = suggest(node.function, library.names())
            complain(index, f"unknown function '{node.function}'{hint}")
            continue
        mismatch = _call_mismatch(entry, len(node.args), [name for name, _ in node.keywords])
        if mismatch is not None:
            complain(index, mismatch)
            continue
        sources = _quality_sources(node.args, entry, node_variables(graph, node.args))
        if isinstance(sources, str):
            complain(index, sources)
            continue
        slots = tuple(slot(s) for s in sources)
        if role == "precondition" and entry.kind != "elementary":
            complain(
                index,
                f"the precondition '{entry.name}' must be an elementary function (it takes no "
                f"time), but it is {'an' if entry.kind == 'interruptible' else 'a'} "
                f"{entry.kind} module",
            )
            continue
        if entry.kind == "elementary":
            assert entry.module is not None
            combine, monotone = _vector_combine(entry.module.combine)
            nodes.append(
                CompileNode(
                    index,
                    entry.name,
                    "elementary",
                    slots,
                    None,
                    True,
                    combine,
                    monotone,
                    entry=entry,
                    role=role,
                    branch=branch,
                )
            )
            continue
        try:
            profile = entry.profile
        except AnytimeError as error:
            complain(index, f"the profile of '{entry.name}' cannot be read: {error}")
            continue
        if profile is None:
            complain(
                index,
                f"module '{entry.name}' has no performance profile ({entry.origin}): "
                "the compiler cannot allocate time to it",
            )
            continue
        nodes.append(
            CompileNode(
                index,
                entry.name,
                "anytime",
                slots,
                profile,
                is_deterministic(profile),
                time_index=time_index,
                entry=entry,
                branch=branch,
            )
        )
        time_index += 1
    if diagnostics:
        raise SchemaError(diagnostics)
    units = {n.profile.time_unit for n in nodes if n.profile is not None}
    if len(units) > 1:
        detail = ", ".join(
            f"{n.name}: {n.profile.time_unit}" for n in nodes if n.profile is not None
        )
        raise CompileError(
            f"{filename}: schema '{program.name}': its modules' profiles are in different time "
            f"units ({detail}); measure them with one clock"
        )
    # Program inputs only count when some quality slot reads them (or when one is the output);
    # number them in the program's input order.
    if isinstance(graph.output, InputRef):
        quality_inputs.setdefault(graph.output.name, len(quality_inputs))
    order = [name for name in program.inputs if name in quality_inputs]
    renumber = {quality_inputs[name]: i for i, name in enumerate(order)}
    nodes = [_renumbered(n, renumber) for n in nodes]
    if isinstance(graph.output, InputRef):
        output = Slot("input", order.index(graph.output.name))
    else:
        output = Slot("node", graph.output.index)
    return CompileModel(
        program=program,
        graph=graph,
        nodes=tuple(nodes),
        quality_inputs=tuple(order),
        output=output,
        time_unit=units.pop() if units else "ticks",
    )


def node_variables(graph: DataflowGraph, args: Sequence[Source]) -> list[str | None]:
    """The variable name each argument was written as (None for literals)."""
    return [None if isinstance(a, LiteralArg) else graph.variable(a) for a in args]


def _quality_sources(
    args: Sequence[Source], entry: LibraryEntry, variables: Sequence[str | None]
) -> list[Source] | str:
    """The arguments that carry the quality of each of the entry's inputs, in its axis order
    (or a message saying why they cannot be told)."""
    if entry.parameters:
        positions = [entry.parameters.index(name) for name in entry.inputs]
        if any(p >= len(args) for p in positions):
            return (
                f"'{entry.name}' takes its quality-carrying inputs ({', '.join(entry.inputs)}) "
                f"at positions the call does not reach (it passes {len(args)} arguments)"
            )
        return [args[p] for p in positions]
    # Known by its profile alone: match input names to argument names, else the arguments
    # computed by other calls, in order.
    if all(name in variables for name in entry.inputs):
        return [args[variables.index(name)] for name in entry.inputs]
    computed: list[Source] = [a for a in args if isinstance(a, NodeRef)]
    if len(computed) == len(entry.inputs):
        return computed
    return (
        f"cannot tell which arguments of '{entry.name}' carry the quality of its inputs "
        f"({', '.join(entry.inputs)}): it is known only by its profile; name the arguments "
        "like its inputs"
    )


def _renumbered(node: CompileNode, renumber: Mapping[int, int]) -> CompileNode:
    slots = tuple(Slot("input", renumber[s.index]) if s.kind == "input" else s for s in node.slots)
    return attrs.evolve(node, slots=slots)


def branch_program(program: Program, choice: Step, branch: int) -> Program | str:
    """One branch of an `if` as a program of its own: its inputs are the variables it reads
    from outside (program inputs or earlier results), in order of first use."""
    tag = (choice.target, branch)
    steps = [
        attrs.evolve(s, branch=None) if s.branch == tag else s
        for s in program.steps
        if program.inside(s, tag)
    ]
    output = choice.args[1 + branch]
    word = ("then", "else")[branch]
    if not isinstance(output, Var):
        return f"the {word} branch of 'if' is a constant: give a variable or a call"
    produced = {s.target for s in steps}
    reads = [v for s in steps for v in s.variables() if v not in produced]
    if output.name not in produced:
        reads.append(output.name)
    return Program(
        name=f"{program.name}/{choice.target}/{word}",
        inputs=tuple(dict.fromkeys(reads)),
        steps=tuple(steps),
        output=output.name,
    )


def _if_node(
    program: Program,
    graph: DataflowGraph,
    step: Step,
    index: int,
    library: AnytimeLibrary,
    compile_branch: Callable[[Program], Any] | None,
) -> tuple[tuple[BranchPlan, ...], list[str]] | str:
    """The branches of an if, compiled, and the names of the quality inputs they read."""
    keywords = dict(step.keywords)
    p: float | None = None
    if "p" in keywords and isinstance(keywords["p"], LiteralArg):
        p = float(keywords["p"].value)
    else:
        condition = graph.nodes[index].args[0]
        function = graph.nodes[condition.index].function if isinstance(condition, NodeRef) else None
        entry = library.get(function) if function is not None else None
        declared = getattr(entry.module, "probability", None) if entry and entry.module else None
        if declared is None:
            what = f"'{function}' declares" if function else "the condition is not a call and"
            return (
                f"the probability of the condition of 'if' is unknown: {what} no probability; "
                "give it as (if CONDITION THEN ELSE :p P)"
            )
        p = float(declared)
    if compile_branch is None:
        return "an 'if' can only be compiled by compile_program"
    compiled = []
    for branch in (0, 1):
        sub = branch_program(program, step, branch)
        if isinstance(sub, str):
            return sub
        compiled.append(compile_branch(sub))
    names = list(dict.fromkeys(n for c in compiled for n in c.model.quality_inputs))
    plans = tuple(
        BranchPlan(
            prob,
            c,
            tuple(names.index(n) for n in c.model.quality_inputs),
        )
        for prob, c in zip((p, 1.0 - p), compiled, strict=True)
    )
    return plans, names


def _mixture(
    plans: Sequence[BranchPlan], names: Sequence[str], module: str
) -> ConditionalPerformanceProfile:
    """The if's profile: the branches' compiled profiles mixed with their probabilities, on the
    union of their input axes (a branch that does not read an input is constant along it)."""
    profiles = [plan.compiled.profile for plan in plans]
    grids = [np.asarray(g) for p in profiles for g in p.input_grids]
    q_grid = grids[0] if grids else np.zeros(0)
    time = profiles[0].time
    bins = profiles[0].bins
    same = all(np.array_equal(p.bins, bins) for p in profiles)
    if not same:
        bins = default_bins()
    m = len(names)
    shape = (len(q_grid),) * m + (len(time),)
    mean = np.zeros(shape)
    probability = np.zeros(shape + (len(bins) - 1,))
    for plan, profile in zip(plans, profiles, strict=True):
        order = np.argsort(plan.axes)
        expand = [a for a in range(m) if a not in plan.axes]
        cells = profile.mean if profile.mean is not None else profile.probability @ profile.values
        cells = np.moveaxis(cells, list(range(len(order))), list(np.argsort(order)))
        probs = profile.probability
        if not same:  # each old bin's mass to the new bin holding its midpoint
            k = np.clip(np.searchsorted(bins, profile.values, side="right") - 1, 0, len(bins) - 2)
            probs = np.einsum("...k,kj->...j", probs, np.eye(len(bins) - 1)[k])
        probs = np.moveaxis(probs, list(range(len(order))), list(np.argsort(order)))
        mean = mean + plan.probability * np.expand_dims(cells, tuple(expand))
        probability = probability + plan.probability * np.expand_dims(probs, tuple(expand))
    return new_profile(
        input_grids=[q_grid] * m,
        time=time,
        bins=bins,
        probability=probability,
        mean=np.clip(mean, 0.0, 1.0),
        inputs=names,
        module=module,
        kind="contract",
        time_unit=profiles[0].time_unit,
    )
