"""The straight-line normal form of a schema: a `Program` of steps `(setf u (f v1 ... vn))`.

Zilberstein & Russell compile straight-line programs, "a sequence of expressions of the form
(setf u (f v1 ... vn)) where u is a new variable and v1 ... vn are program arguments or existing
variables"; nested calls map one-to-one onto such code. Every schema is normalised into this form
(see `normalize`), so the compiler and the runtime see one shape only.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from attrs import field, frozen

from anytime.dsl.nodes import Span

if TYPE_CHECKING:
    from anytime.dsl.graph import DataflowGraph


@frozen
class Var:
    """A reference to a program input or to the target of an earlier step."""

    name: str


@frozen
class Literal:
    """A constant argument: a number or a string."""

    value: int | float | str


Arg = Var | Literal

#: What a step does; the language grows new kinds (conditionals, choices) beside these two.
STEP_KINDS = ("call", "schema")


@frozen
class Step:
    """`(setf target (function args... :keyword value...))`.

    `kind` is "call" for a function of the anytime library and "schema" for a call to another
    schema of the same file (hierarchical composition: that schema is compiled first).
    """

    target: str
    function: str
    args: tuple[Arg, ...]
    keywords: tuple[tuple[str, Arg], ...] = ()
    kind: str = "call"
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)

    def inputs(self) -> Iterator[Arg]:
        """Every argument, positional first, then keyword values."""
        yield from self.args
        for _, value in self.keywords:
            yield value

    def variables(self) -> Iterator[str]:
        """Names of the variables this step reads, in argument order."""
        for arg in self.inputs():
            if isinstance(arg, Var):
                yield arg.name


@frozen
class Program:
    """A schema in straight-line form: inputs, steps in execution order, one output variable."""

    name: str
    inputs: tuple[str, ...]
    steps: tuple[Step, ...]
    output: str
    doc: str | None = None
    span: Span | None = field(default=None, eq=False, repr=False)

    @property
    def graph(self) -> DataflowGraph:
        from anytime.dsl.graph import DataflowGraph

        return DataflowGraph.from_program(self)

    def step(self, target: str) -> Step:
        """The step that assigns `target`."""
        for step in self.steps:
            if step.target == target:
                return step
        raise KeyError(target)

    def callees(self) -> tuple[str, ...]:
        """Names of the schemas this program calls, in order of first call."""
        return tuple(dict.fromkeys(s.function for s in self.steps if s.kind == "schema"))


@frozen
class SchemaFile:
    """All the programs of one schema file, in the order they are written."""

    filename: str
    programs: tuple[Program, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.programs)

    def __getitem__(self, name: str) -> Program:
        for program in self.programs:
            if program.name == name.lower():
                return program
        raise KeyError(name)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.lower() in self.names

    def __iter__(self) -> Iterator[Program]:
        return iter(self.programs)

    def __len__(self) -> int:
        return len(self.programs)

    def dependency_order(self) -> tuple[Program, ...]:
        """Programs with every callee before its callers: the order to compile them bottom-up."""
        done: dict[str, Program] = {}

        def visit(program: Program) -> None:
            if program.name in done:
                return
            for callee in program.callees():
                visit(self[callee])
            done[program.name] = program

        for program in self.programs:
            visit(program)
        return tuple(done.values())
