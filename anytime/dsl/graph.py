"""The dataflow graph of a program: nodes are calls, edges carry variables.

Nodes are numbered canonically, in the order a left-to-right evaluation of the output
expression first needs them. So the graph does not depend on how the schema was written: the
nested `(f (g x))` and the straight-line `(setf a (g x)) (setf b (f a)) b` give equal graphs,
whatever the variables are called and in whichever order independent steps were listed.
The numbering is also a topological order.

The shape tells the compiler which allocators are exact: in a *chain* every call feeds the next;
in a *tree* every result is used exactly once; in a general *DAG* some result is shared, so the
qualities flowing into a later call are correlated. Program inputs do not count: the compiler
conditions on their qualities.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from typing import Literal as Choice
from typing import Protocol

import attrs
from attrs import field, frozen

from anytime.dsl.steps import (
    Arg,
    BestOf,
    Call,
    If,
    Literal,
    Map,
    Repeat,
    SchemaCall,
    Step,
    Var,
    variables,
)


class StraightLine(Protocol):
    """What a graph is made from: a program (`anytime.dsl.program.Program`, which imports this
    module for its `graph`)."""

    @property
    def name(self) -> str: ...

    @property
    def inputs(self) -> tuple[str, ...]: ...

    @property
    def output(self) -> str: ...

    def walk(self) -> Iterator[Step]: ...


@frozen
class InputRef:
    """A program input."""

    name: str


@frozen
class NodeRef:
    """The result of the node with this index."""

    index: int


Source = InputRef | NodeRef | Literal

Shape = Choice["chain", "tree", "dag"]


@frozen
class Node:
    """One step, as dataflow: what it is (`function`: the function or schema called, or
    "best-of" or "if"), where its arguments come from, and the typed `step` it stands for.

    A call's sources are its positional `args` and its `keywords`; a choice's are labelled
    keywords: a best-of's ("when 1", ...) for its preconditions' results and ("alternative 1",
    ...) for its alternatives' values, an if's "condition", "then" and "else". A loop's
    (`function` "map F" or "repeat F") are its calls' arguments, a map's collection first, and
    the literal keyword "max" (a map's largest compiled count) or "count" (a repeat's). `variable`
    names the result in the program; neither it nor `step` takes part in equality.
    """

    function: str
    args: tuple[Source, ...]
    keywords: tuple[tuple[str, Source], ...] = ()
    variable: str = field(default="", eq=False)
    step: Step | None = field(default=None, eq=False, repr=False)

    def sources(self) -> Iterator[tuple[int | str, Source]]:
        """(slot, source) for every argument: slots are positions, then keyword names."""
        yield from enumerate(self.args)
        yield from self.keywords


@frozen
class Edge:
    """A variable flowing from an input or a node into one argument slot of a node."""

    source: InputRef | NodeRef
    target: int
    slot: int | str
    variable: str = field(eq=False)


@frozen
class DataflowGraph:
    """Calls and the variables between them; `output` is the node (or input) the program returns."""

    inputs: tuple[str, ...]
    nodes: tuple[Node, ...]
    output: InputRef | NodeRef
    name: str = field(default="", eq=False)

    @classmethod
    def from_program(cls, program: StraightLine) -> DataflowGraph:
        producer = {step.target: step for step in program.walk()}
        index: dict[str, int] = {}
        # Iterative post-order depth-first search: a long chain must not hit the recursion limit.
        stack = [(program.output, False)]
        while stack:
            variable, expanded = stack.pop()
            if variable in index or variable not in producer:
                continue
            if expanded:
                index[variable] = len(index)
                continue
            stack.append((variable, True))
            needs = [v for v in variables(producer[variable]) if v not in index]
            stack.extend((v, False) for v in reversed(needs))

        def source(arg: Arg) -> Source:
            if isinstance(arg, Literal):
                return arg
            if arg.name in index:
                return NodeRef(index[arg.name])
            return InputRef(arg.name)

        nodes = []
        for variable in sorted(index, key=index.__getitem__):
            step = producer[variable]
            match step:
                case Call(function=function, args=args, keywords=keywords):
                    node = Node(
                        function,
                        tuple(source(a) for a in args),
                        tuple((k, source(v)) for k, v in keywords),
                    )
                case SchemaCall(schema=schema, args=args):
                    node = Node(schema, tuple(source(a) for a in args))
                case BestOf(alternatives=alternatives):
                    labelled = [
                        (f"when {i}", source(Var(a.precondition.target)))
                        for i, a in enumerate(alternatives, 1)
                        if a.precondition is not None
                    ]
                    labelled += [
                        (f"alternative {i}", source(a.value)) for i, a in enumerate(alternatives, 1)
                    ]
                    node = Node("best-of", (), tuple(labelled))
                case If(condition=condition, then=then, else_=other):
                    parts = zip(
                        ("condition", "then", "else"),
                        (condition, then.value, other.value),
                        strict=True,
                    )
                    node = Node("if", (), tuple((k, source(v)) for k, v in parts))
                case Map(function=function, items=items, args=args, max_items=most):
                    sources = tuple(source(a) for a in (items, *args))
                    node = Node(f"map {function}", sources, (("max", Literal(most)),))
                case Repeat(function=function, count=n, args=args):
                    sources = tuple(source(a) for a in args)
                    node = Node(f"repeat {function}", sources, (("count", Literal(n)),))
            nodes.append(attrs.evolve(node, variable=variable, step=step))
        output = source(Var(program.output))
        assert not isinstance(output, Literal)
        return cls(inputs=program.inputs, nodes=tuple(nodes), output=output, name=program.name)

    def source(self, arg: Arg) -> Source:
        """Where an argument's value comes from: a literal, a program input or a node."""
        if isinstance(arg, Literal):
            return arg
        for i, node in enumerate(self.nodes):
            if node.variable == arg.name:
                return NodeRef(i)
        return InputRef(arg.name)

    def index_of(self, variable: str) -> int:
        """The index of the node whose result is `variable`."""
        return next(i for i, node in enumerate(self.nodes) if node.variable == variable)

    def variable(self, ref: InputRef | NodeRef) -> str:
        return ref.name if isinstance(ref, InputRef) else self.nodes[ref.index].variable

    @property
    def edges(self) -> tuple[Edge, ...]:
        return tuple(
            Edge(source, target, slot, self.variable(source))
            for target, node in enumerate(self.nodes)
            for slot, source in node.sources()
            if not isinstance(source, Literal)
        )

    def producers(self, index: int) -> tuple[int, ...]:
        """The nodes whose results node `index` reads (each once, in argument order)."""
        refs = (s.index for _, s in self.nodes[index].sources() if isinstance(s, NodeRef))
        return tuple(dict.fromkeys(refs))

    def consumers(self, index: int) -> tuple[int, ...]:
        """The nodes that read the result of node `index`."""
        return tuple(j for j in range(len(self.nodes)) if index in self.producers(j))

    def topological_order(self) -> tuple[int, ...]:
        """Node indices, every producer before its consumers (the canonical numbering is one)."""
        return tuple(range(len(self.nodes)))

    @property
    def shape(self) -> Shape:
        uses = Counter(
            source.index
            for node in self.nodes
            for _, source in node.sources()
            if isinstance(source, NodeRef)
        )
        if any(count > 1 for count in uses.values()):
            return "dag"
        if all(len(self.producers(i)) <= 1 for i in range(len(self.nodes))):
            return "chain"
        return "tree"
