"""The straight-line normal form of a schema: a `Program` of typed steps.

Zilberstein & Russell compile straight-line programs, "a sequence of expressions of the form
(setf u (f v1 ... vn)) where u is a new variable and v1 ... vn are program arguments or existing
variables"; nested calls map one-to-one onto such code. Every schema is normalised into this form
(see `normalize`), so the compiler and the runtime see one shape only.

A step is one of six kinds, one class each, matched structurally (`match step:`) by every pass:
a `Call` of a function of the anytime library, a `SchemaCall` of another schema of the file, a
`BestOf` choice among alternatives, an `If`, and the loops `Map` (a module applied to each item
of a collection known at run time) and `Repeat` (a call made a fixed number of times). The steps
of an alternative or a branch are nested inside it, so which choice a step belongs to is where
it is, never a tag to decode.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from attrs import Factory, field, frozen

from anytime.dsl.source import Source, Span

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


@frozen
class Call:
    """`(setf target (function args... :keyword value...))`: a call of a library function."""

    target: str
    function: str
    args: tuple[Arg, ...]
    keywords: tuple[tuple[str, Arg], ...] = ()
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)


@frozen
class SchemaCall:
    """`(setf target (schema args...))`: a call of another schema of the same file
    (hierarchical composition: that schema is compiled first)."""

    target: str
    schema: str
    args: tuple[Arg, ...]
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)


@frozen
class Alternative:
    """One alternative of a best-of: `(when PRECONDITION EXPR)`, or `EXPR` alone, which is
    always applicable (precondition None). Its steps compute `value`."""

    precondition: Call | None
    steps: tuple[Step, ...]
    value: Arg


@frozen
class BestOf:
    """`(best-of ALTERNATIVE...)`: every precondition first, then every applicable
    alternative, sharing the time; the answer is the best of their results."""

    target: str
    alternatives: tuple[Alternative, ...]
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)


@frozen
class Branch:
    """The then or else part of an if: the steps that compute `value`."""

    steps: tuple[Step, ...]
    value: Arg


@frozen
class If:
    """`(if CONDITION THEN ELSE [:p P])`: the condition is computed outside (it always runs);
    `p` is the probability that it holds, when written."""

    target: str
    condition: Arg
    then: Branch
    else_: Branch
    p: float | None = None
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)


#: The largest count a map's table is compiled for when its form gives no `:max`.
DEFAULT_MAX_ITEMS = 4


@frozen
class Map:
    """`(map FUNCTION ITEMS ARG... [:max K])`: `(FUNCTION item ARG...)` for each item of the
    collection ITEMS, whose size is known only at run time; the loop's profile is compiled for
    0 to `max_items` items. The result is the list of the calls' results."""

    target: str
    function: str
    items: Arg
    args: tuple[Arg, ...] = ()
    max_items: int = DEFAULT_MAX_ITEMS
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)


@frozen
class Repeat:
    """`(repeat N (FUNCTION ARG...))`: the call made `count` times (a count fixed in the
    schema, as Nakamura et al.'s `for`). The result is the list of the calls' results."""

    target: str
    count: int
    function: str
    args: tuple[Arg, ...] = ()
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)


Loop = Map | Repeat
Step = Call | SchemaCall | BestOf | If | Map | Repeat


def reads(step: Step) -> tuple[Arg, ...]:
    """What a step itself reads, in evaluation order: a call's arguments (positional, then
    keyword values); a best-of's preconditions' results, then its alternatives' values; an
    if's condition, then and else values; a map's collection, then the other arguments of its
    calls; a repeat's arguments of its call."""
    match step:
        case Call(args=args, keywords=keywords):
            return (*args, *(value for _, value in keywords))
        case SchemaCall(args=args):
            return args
        case BestOf(alternatives=alternatives):
            tests = [Var(a.precondition.target) for a in alternatives if a.precondition]
            return (*tests, *(a.value for a in alternatives))
        case If(condition=condition, then=then, else_=other):
            return (condition, then.value, other.value)
        case Map(items=items, args=args):
            return (items, *args)
        case Repeat(args=args):
            return args


def variables(step: Step) -> Iterator[str]:
    """Names of the variables a step reads, in order."""
    for arg in reads(step):
        if isinstance(arg, Var):
            yield arg.name


def inner_steps(step: Step) -> Iterator[Step]:
    """The steps nested directly inside a choice, in execution order: a best-of's
    preconditions, then each alternative's steps; an if's then steps, then its else steps."""
    match step:
        case BestOf(alternatives=alternatives):
            yield from (a.precondition for a in alternatives if a.precondition is not None)
            for alternative in alternatives:
                yield from alternative.steps
        case If(then=then, else_=other):
            yield from then.steps
            yield from other.steps
        case _:
            return


def walk(steps: tuple[Step, ...]) -> Iterator[Step]:
    """Every step, nested ones before the choice that holds them: execution order."""
    for step in steps:
        for inner in inner_steps(step):
            yield from walk((inner,))
        yield step


@frozen
class Program:
    """A schema in straight-line form: inputs, steps in execution order (the steps of a
    choice nested inside it), one output variable."""

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

    def walk(self) -> Iterator[Step]:
        """Every step of the program, nested ones included, in execution order."""
        return walk(self.steps)

    def step(self, target: str) -> Step:
        """The step that assigns `target` (nested or not)."""
        for step in self.walk():
            if step.target == target:
                return step
        raise KeyError(target)

    def callees(self) -> tuple[str, ...]:
        """Names of the schemas this program calls, in order of first call."""
        return tuple(dict.fromkeys(s.schema for s in self.walk() if isinstance(s, SchemaCall)))


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
