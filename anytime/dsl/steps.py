"""The steps of a straight-line program, one class per kind, and how a pass walks them.

A step is one of six kinds, matched structurally (`match step:`) by every pass: a `Call` of a
function of the anytime library, a `SchemaCall` of another schema of the file, a `BestOf`
choice among alternatives, an `If`, and the loops `Map` (a module applied to each item of a
collection known at run time) and `Repeat` (a call made a fixed number of times). The steps of
an alternative or a branch are nested inside it, so which choice a step belongs to is where it
is, never a tag to decode. A program (`anytime.dsl.program`) and its dataflow graph
(`anytime.dsl.graph`) are both made of them.
"""

from __future__ import annotations

from collections.abc import Iterator

from attrs import field, frozen

from anytime.dsl.source import Span


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
    """`(best-of ALTERNATIVE... [:dependence D])`: every precondition first, then every
    applicable alternative, sharing the time; the answer is the best of their results.
    `dependence` is the probability that one draw decides every alternative's quality
    (comonotone), where otherwise they are independent given their inputs: what the compiler
    takes them as (0, the default, is independent)."""

    target: str
    alternatives: tuple[Alternative, ...]
    span: Span | None = field(default=None, eq=False, repr=False)
    function_span: Span | None = field(default=None, eq=False, repr=False)
    dependence: float = 0.0


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
