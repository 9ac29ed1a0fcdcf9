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
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal

import numpy as np
from attrs import frozen

from anytime.dsl.graph import DataflowGraph, InputRef, NodeRef, Source
from anytime.dsl.normalize import suggest
from anytime.dsl.program import Literal as LiteralArg
from anytime.dsl.program import Program
from anytime.errors import AnytimeError, Diagnostic, SchemaError
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.profiles.profile import ConditionalPerformanceProfile, point_mass


class CompileError(AnytimeError, ValueError):
    """A program cannot be compiled as asked (grids, units); the message says what to change."""


@frozen
class Slot:
    """Where one quality-carrying input of a node gets its quality."""

    kind: Literal["node", "input", "constant"]
    index: int = 0  # node index, or index among the program's quality-carrying inputs
    value: float = 1.0  # for a constant


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


def build_model(
    program: Program,
    library: AnytimeLibrary,
    filename: str = "<schema>",
    source_lines: Sequence[str] = (),
) -> CompileModel:
    """Resolve `program` against `library`.

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

    time_index = 0
    for index, node in enumerate(graph.nodes):
        entry = library.get(node.function)
        if entry is None:
            hint = suggest(node.function, library.names())
            complain(index, f"unknown function '{node.function}'{hint}")
            continue
        sources = _quality_sources(node.args, entry, node_variables(graph, node.args))
        if isinstance(sources, str):
            complain(index, sources)
            continue
        slots = tuple(slot(s) for s in sources)
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
    return CompileNode(
        node.index,
        node.name,
        node.kind,
        slots,
        node.profile,
        node.deterministic,
        node.combine,
        node.monotone_combine,
        node.time_index,
        node.entry,
    )
