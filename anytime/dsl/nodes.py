"""The syntax tree of a schema file, with source positions.

Positions never take part in equality: two forms that differ only in layout are the same form.
These nodes are what the parser builds; `normalize` turns them into `Program`s.
New forms of the language (conditionals, choices among alternatives, loops) are new node classes
here.
"""

from __future__ import annotations

from attrs import field, frozen

from anytime.dsl.source import Source, Span


@frozen
class Symbol:
    name: str
    span: Span = field(eq=False, repr=False)


@frozen
class Number:
    value: int | float
    span: Span = field(eq=False, repr=False)


@frozen
class String:
    value: str
    span: Span = field(eq=False, repr=False)


@frozen
class KeywordArg:
    name: str
    value: Expr
    span: Span = field(eq=False, repr=False)


@frozen
class Call:
    function: str
    args: tuple[Expr, ...]
    keywords: tuple[KeywordArg, ...]
    span: Span = field(eq=False, repr=False)
    function_span: Span = field(eq=False, repr=False)


@frozen
class FormBase:
    """A special form: its arguments as a call's, its reserved word's place as `function_span`.
    Each form is a class of its own, so that passes dispatch on its type."""

    args: tuple[Expr, ...]
    keywords: tuple[KeywordArg, ...]
    span: Span = field(eq=False, repr=False)
    function_span: Span = field(eq=False, repr=False)


@frozen
class BestOfForm(FormBase):
    """`(best-of ALTERNATIVE...)`, each alternative `(when PRECONDITION EXPR)` or an EXPR."""


@frozen
class WhenForm(FormBase):
    """`(when PRECONDITION EXPR)`: an alternative of a best-of (allowed only there)."""


@frozen
class IfForm(FormBase):
    """`(if CONDITION THEN ELSE [:p P])`."""


@frozen
class MapForm(FormBase):
    """`(map FUNCTION ITEMS ARG... [:max K])`: FUNCTION applied to each item of ITEMS."""


@frozen
class RepeatForm(FormBase):
    """`(repeat N (FUNCTION ARG...))`: the call made N times."""


SpecialForm = BestOfForm | WhenForm | IfForm | MapForm | RepeatForm

#: The special forms' reserved words (each form has its own grammar rule and syntax node).
SPECIAL_FORMS = ("best-of", "if", "when", "map", "repeat")


def form_word(form: SpecialForm) -> str:
    """The reserved word a special form is written with."""
    match form:
        case BestOfForm():
            return "best-of"
        case IfForm():
            return "if"
        case WhenForm():
            return "when"
        case MapForm():
            return "map"
        case RepeatForm():
            return "repeat"


Expr = Symbol | Number | String | Call | BestOfForm | WhenForm | IfForm | MapForm | RepeatForm


@frozen
class Setf:
    target: str
    value: Expr
    span: Span = field(eq=False, repr=False)
    target_span: Span = field(eq=False, repr=False)


Form = Setf | Expr


def expr_span(expr: Form) -> Span:
    """Where a form is named in errors: a call's or a special form's function word, else the
    whole form."""
    return expr.function_span if isinstance(expr, Call | FormBase) else expr.span


@frozen
class SchemaDef:
    name: str
    params: tuple[Symbol, ...]
    doc: str | None
    body: tuple[Form, ...]
    span: Span = field(eq=False, repr=False)
    name_span: Span = field(eq=False, repr=False)


@frozen
class SourceFile:
    """A parsed file: its schemas, and the source they were parsed from."""

    schemas: tuple[SchemaDef, ...]
    source: Source = field(eq=False, repr=False)

    @property
    def filename(self) -> str:
        return self.source.filename

    @property
    def text(self) -> str:
        return self.source.text
