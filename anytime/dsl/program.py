"""The straight-line normal form of a schema: a `Program` of steps `(setf u (f v1 ... vn))`.

Zilberstein & Russell compile straight-line programs, "a sequence of expressions of the form
(setf u (f v1 ... vn)) where u is a new variable and v1 ... vn are program arguments or existing
variables"; nested calls map one-to-one onto such code. Every schema is normalised into this form
(see `normalize`), so the compiler and the runtime see one shape only.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from attrs import Factory, field, frozen

from anytime.dsl.nodes import Span
from anytime.dsl.source import Source

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

#: The precondition of a best-of alternative written without `when`: always applicable.
ALWAYS = Literal(1)

#: What a step does: a library call, a call to another schema, a choice among alternatives
#: (`(best-of (when PRE EXPR) ...)`), or a conditional (`(if COND THEN ELSE :p P)`).
STEP_KINDS = ("call", "schema", "best-of", "if")

#: Which choice a step belongs to: (the choice step's target, the alternative's index). For
#: `best-of`, the precondition and the steps of alternative i carry index i; for `if`, the
#: steps of the then branch carry 0 and those of the else branch 1.
Branch = tuple[str, int]


@frozen
class Step:
    """`(setf target (function args... :keyword value...))`.

    `kind` is "call" for a function of the anytime library and "schema" for a call to another
    schema of the same file (hierarchical composition: that schema is compiled first).

    A `best-of` step has function "best-of", the n preconditions' results then the n
    alternatives' values as arguments; an `if` step has function "if", arguments (condition,
    then, else) and possibly the keyword `p`. `branch` says which alternative or branch of
    which choice a step is inside (None: it always runs).
    """

    target: str
    function: str
    args: tuple[Arg, ...]
    keywords: tuple[tuple[str, Arg], ...] = ()
    kind: str = "call"
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)
    branch: Branch | None = None

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

    def inside(self, step: Step, branch: Branch) -> bool:
        """Whether `step` is inside `branch`, directly or through nested choices."""
        tag = step.branch
        while tag is not None:
            if tag == branch:
                return True
            tag = self.step(tag[0]).branch
        return False

    def callees(self) -> tuple[str, ...]:
        """Names of the schemas this program calls, in order of first call."""
        return tuple(dict.fromkeys(s.function for s in self.steps if s.kind == "schema"))


@frozen
class SchemaFile:
    """All the programs of one schema file, in the order they are written."""

    filename: str
    programs: tuple[Program, ...]
    #: The file's name and text, for diagnostics about it (`normalize` sets it; without it,
    #: diagnostics name the file but show no source line).
    source: Source = field(
        default=Factory(lambda self: Source(self.filename, ""), takes_self=True),
        eq=False,
        repr=False,
        kw_only=True,
    )

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
