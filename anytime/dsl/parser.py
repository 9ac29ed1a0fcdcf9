"""Schema text -> syntax tree (`SourceFile`), with every syntax error pointing at its place.

Parsing runs in two passes. A linear scan checks that parentheses balance and do not nest too
deeply: it gives a precise "never closed" position that an LALR parser reaching the end of the
file cannot, and it keeps the recursive tree transformation far from Python's recursion limit.
Then the LALR parser built from `grammar.lark` reads the forms; its errors are translated into
plain words with `match_examples`.
"""

from __future__ import annotations

import math
import re
from functools import cache
from typing import Any, TypeVar

from lark import Lark, Token, Transformer, v_args
from lark.exceptions import (
    UnexpectedCharacters,
    UnexpectedEOF,
    UnexpectedInput,
    UnexpectedToken,
    VisitError,
)
from lark.tree import Meta

from anytime.dsl.nodes import (
    BestOfForm,
    Call,
    Expr,
    FormBase,
    IfForm,
    KeywordArg,
    MapForm,
    Number,
    RepeatForm,
    SchemaDef,
    Setf,
    SourceFile,
    String,
    Symbol,
    WhenForm,
    expr_span,
)
from anytime.dsl.source import Source, Span
from anytime.errors import Diagnostic, SchemaSyntaxError

FormT = TypeVar("FormT", bound=FormBase)  # the special forms' base class

#: Deeper nesting than this is refused with a clear error (real schemas nest a few levels).
MAX_NESTING = 100

# Each message is matched against the parser state at the error by lark's `match_examples`.
SYNTAX_EXAMPLES: dict[str, list[str]] = {
    "missing schema name after 'defschema'": [
        "(defschema (x) x)",
        "(defschema)",
        "(defschema 1 (x) x)",
        '(defschema "f" (x) x)',
        "(defschema :f (x) x)",
    ],
    "missing parameter list: expected '(' and the parameter names after the schema name": [
        "(defschema f x)",
        "(defschema f)",
        "(defschema f 1 x)",
        '(defschema f "doc" (x) x)',
        "(defschema f :k)",
    ],
    "a parameter must be a name": [
        "(defschema f (1) x)",
        '(defschema f ("a") x)',
        "(defschema f ((x)) x)",
        "(defschema f (:k) x)",
        "(defschema f (x 2) x)",
    ],
    "a file holds only (defschema NAME (PARAMS...) BODY...) forms": [
        "x",
        "1",
        '"s"',
        ":k",
        "(f x)",
        "(setf a b)",
        "()",
        "(defschema f (x) x) y",
        "(defschema f (x) x) (g)",
        "(defschema f (x) x) 2",
    ],
    "setf needs a variable name: (setf VAR EXPR)": [
        "(defschema f (x) (setf))",
        "(defschema f (x) (setf 1 x))",
        "(defschema f (x) (setf (g) x))",
        '(defschema f (x) (setf "a" x))',
        "(defschema f (x) (setf :k x))",
    ],
    "setf needs an expression after the variable name: (setf VAR EXPR)": [
        "(defschema f (x) (setf a))",
        "(defschema f (x) (setf a :k 1))",
    ],
    "setf takes one variable and one expression: (setf VAR EXPR)": [
        "(defschema f (x) (setf a b c))",
        "(defschema f (x) (setf a b (c)))",
        "(defschema f (x) (setf a b :k))",
    ],
    "a call must start with a function name": [
        "(defschema f (x) ((g x)))",
        "(defschema f (x) (1 x))",
        "(defschema f (x) ())",
        '(defschema f (x) ("g" x))',
        "(defschema f (x) (:k x))",
        "(defschema f (x) (g (1)))",
        "(defschema f (x) (g ()))",
        "(defschema f (x) (g ((h))))",
        "(defschema f (x) (setf a ()))",
        "(defschema f (x) (setf a (1)))",
    ],
    "a keyword argument needs a value after it": [
        "(defschema f (x) (g :k))",
        "(defschema f (x) (g :k :j 1))",
        "(defschema f (x) (g x :k))",
    ],
    "keywords are only allowed as arguments in a call, before their value": [
        "(defschema f (x) :k)",
        "(defschema f (x) (setf a b) :k)",
    ],
    "'defschema' can only appear at the top level of a file": [
        "(defschema f (x) (defschema g (y) y))",
        "(defschema f (x) (g (defschema)))",
        "(defschema f (x) (setf a (defschema)))",
        "(defschema f (defschema) x)",
    ],
    "'setf' can only appear directly in a schema body, not inside an expression": [
        "(defschema f (x) (g (setf a x)))",
        "(defschema f (x) (setf a (setf b x)))",
        "(defschema f (setf) x)",
    ],
}


@cache
def _lark() -> Lark:
    return Lark.open(
        "grammar.lark",
        rel_to=__file__,
        parser="lalr",
        lexer="basic",  # reserved words are reserved everywhere, not only where expected
        propagate_positions=True,
    )


def parse_syntax(text: str, filename: str = "<string>") -> SourceFile:
    """Parse schema source text into a syntax tree.

    Raises:
        SchemaSyntaxError: the text does not follow the grammar; the error names the place.
    """
    source = Source(filename, text)
    _check_parentheses(source)
    try:
        tree = _lark().parse(text)
    except UnexpectedInput as error:
        raise _translate(error, source) from None
    try:
        schemas: tuple[SchemaDef, ...] = _ToNodes(source).transform(tree)
    except VisitError as error:
        if isinstance(error.orig_exc, SchemaSyntaxError):
            raise error.orig_exc from None
        raise
    return SourceFile(schemas=schemas, source=source)


def decode_source(data: bytes, filename: str) -> str:
    """Decode a schema file's bytes (UTF-8, with or without a byte-order mark)."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        good = data[: error.start].decode("utf-8-sig", errors="replace")
        line = good.count("\n") + 1
        column = len(good) - (good.rfind("\n") + 1) + 1
        message = f"the file is not UTF-8 text (byte 0x{data[error.start]:02x})"
        raise SchemaSyntaxError([Diagnostic(filename, line, column, message)]) from None


# --- pass 1: parentheses -------------------------------------------------------------------

# Strings may be unterminated (the optional closing quote) and comments run to the line's end;
# the last alternative matches a line break and the indentation of the next line's first token.
_PAREN_SCAN = re.compile(r'"(?:[^"\\]|\\.)*("?)|;[^\n]*|[()]|\n[ \t]*(?=[^ \t\r\n;])', re.DOTALL)


def _check_parentheses(source: Source) -> None:
    text = source.text
    opened: list[tuple[int, int]] = []  # (offset, column) of each open '('
    line_start = 0
    suspect: int | None = None  # the first '(' that a later line is not indented inside
    for match in _PAREN_SCAN.finditer(text):
        piece = match.group()
        if piece == "(":
            opened.append((match.start(), match.start() - line_start))
            if len(opened) > MAX_NESTING:
                raise _error_at(
                    source,
                    match.start(),
                    f"nested too deeply: more than {MAX_NESTING} levels of parentheses",
                )
        elif piece == ")":
            if not opened:
                raise _error_at(source, match.start(), "unmatched ')': no '(' is open here")
            opened.pop()
        elif piece.startswith("\n"):
            line_start = match.start() + 1
            indent = match.end() - line_start
            if suspect is None:
                outdented = [offset for offset, column in opened if column >= indent]
                suspect = outdented[0] if outdented else None
        elif piece.startswith('"') and not match.group(1):
            raise _error_at(source, match.start(), "unterminated string: no closing '\"'")
    if opened and suspect is not None:
        message = "unbalanced parentheses: ')' missing for this '(' (a later line is outdented)"
        raise _error_at(source, suspect, message)
    if opened:
        # The innermost unclosed '(' is where a ')' is most likely missing.
        raise _error_at(source, opened[-1][0], "unbalanced parentheses: this '(' is never closed")


# --- pass 2: the grammar --------------------------------------------------------------------


def _translate(error: UnexpectedInput, source: Source) -> SchemaSyntaxError:
    """Turn one of lark's exceptions into the project's error, in plain words."""
    text = source.text
    if isinstance(error, UnexpectedCharacters):
        pos = error.pos_in_stream or 0
        char = text[pos] if pos < len(text) else ""
        if char.isdigit() or char in "+-.":
            token = re.match(r'[^\s();"]+', text[pos:])
            message = f"invalid number '{token.group() if token else char}'"
        else:
            message = f"unexpected character {char!r}"
        return _error_at(source, pos, message)

    if isinstance(error, UnexpectedToken) and error.token.type in _RESERVED:
        word = str(error.token).lower()
        return _error_at(
            source,
            error.token.start_pos or 0,
            f"'{word}' is a reserved word (best-of, if, when, map, repeat): it cannot name a "
            "variable or "
            "a parameter, and it opens its form: (" + _RESERVED[error.token.type] + ")",
        )
    message = error.match_examples(
        _lark().parse, SYNTAX_EXAMPLES, token_type_match_fallback=True, use_accepts=True
    ) or _generic_message(error)
    if isinstance(error, UnexpectedToken) and error.token.type != "$END":
        return _error_at(source, error.token.start_pos or 0, message)
    return _error_at(source, len(text), message)


#: The special forms' reserved words, as the grammar names them, with their shapes.
_RESERVED = {
    "BEST_OF": "best-of (when PRECONDITION EXPR) ... EXPR",
    "WHEN": "when PRECONDITION EXPR",
    "IF": "if CONDITION THEN ELSE [:p P]",
    "MAP": "map FUNCTION ITEMS ARG... [:max K]",
    "REPEAT": "repeat N (FUNCTION ARG...)",
}

_TOKEN_WORDS = {
    "LPAR": "'('",
    "RPAR": "')'",
    "SYMBOL": "a name",
    "KEYWORD": "a keyword",
    "NUMBER": "a number",
    "STRING": "a string",
    "_DEFSCHEMA": "'defschema'",
    "_SETF": "'setf'",
    "BEST_OF": "'best-of'",
    "WHEN": "'when'",
    "IF": "'if'",
    "MAP": "'map'",
    "REPEAT": "'repeat'",
    "$END": "the end of the file",
}


def _generic_message(error: UnexpectedInput) -> str:
    found = "the end of the file"
    if isinstance(error, UnexpectedToken) and error.token.type != "$END":
        found = repr(str(error.token))
    expected: set[str] = set()
    if isinstance(error, UnexpectedToken | UnexpectedEOF):
        expected = set(error.expected)
    words = sorted(_TOKEN_WORDS.get(name, name) for name in expected)
    if not words:
        return f"unexpected {found}"
    return f"unexpected {found}: expected {' or '.join(words)}"


def _error_at(source: Source, offset: int, message: str) -> SchemaSyntaxError:
    return SchemaSyntaxError([source.at_offset(offset, message)])


def _span(meta: Meta | Token) -> Span:
    return Span(meta.line or 0, meta.column or 0, meta.end_line or 0, meta.end_column or 0)


#: The longest integer literal (Python's `int` refuses more than 4,300 digits).
MAX_INTEGER_DIGITS = 1000


@v_args(meta=True)
class _ToNodes(Transformer[Token, tuple[SchemaDef, ...]]):
    """One method per grammar rule, each building the frozen node of the same name."""

    def __init__(self, source: Source) -> None:
        super().__init__()
        self._source = source

    def _fail(self, span: Span, message: str) -> SchemaSyntaxError:
        return SchemaSyntaxError([self._source.diagnostic(message, span)])

    def start(self, meta: Meta, schemas: list[SchemaDef]) -> tuple[SchemaDef, ...]:
        if not schemas:
            message = "the file holds no schema: expected (defschema NAME (PARAMS...) BODY...)"
            raise SchemaSyntaxError([self._source.diagnostic(message, line=1, column=1)])
        return tuple(schemas)

    def schema(self, meta: Meta, children: list[Any]) -> SchemaDef:
        name, params, *body = children
        doc = None
        # As in Lisp, a leading string is the docstring only when something follows it.
        if len(body) > 1 and isinstance(body[0], String):
            doc = body.pop(0).value
        return SchemaDef(
            name=name.lower(),
            params=params,
            doc=doc,
            body=tuple(body),
            span=_span(meta),
            name_span=_span(name),
        )

    def params(self, meta: Meta, names: list[Token]) -> tuple[Symbol, ...]:
        return tuple(Symbol(name.lower(), _span(name)) for name in names)

    def setf(self, meta: Meta, children: list[Any]) -> Setf:
        target, value = children
        return Setf(target.lower(), value, _span(meta), _span(target))

    def call(self, meta: Meta, children: list[Any]) -> Call:
        function, *rest = children
        args, keywords = self._arguments(rest)
        return Call(function.lower(), args, keywords, _span(meta), _span(function))

    def best_of(self, meta: Meta, children: list[Any]) -> BestOfForm:
        return self._form(BestOfForm, meta, children)

    def when(self, meta: Meta, children: list[Any]) -> WhenForm:
        return self._form(WhenForm, meta, children)

    def if_(self, meta: Meta, children: list[Any]) -> IfForm:
        return self._form(IfForm, meta, children)

    def map_(self, meta: Meta, children: list[Any]) -> MapForm:
        return self._form(MapForm, meta, children)

    def repeat(self, meta: Meta, children: list[Any]) -> RepeatForm:
        return self._form(RepeatForm, meta, children)

    def _form(self, kind: type[FormT], meta: Meta, children: list[Any]) -> FormT:
        """A special form: its reserved word, then its arguments as a call's."""
        head, *rest = children
        return kind(*self._arguments(rest), _span(meta), _span(head))

    def _arguments(self, items: list[Any]) -> tuple[tuple[Expr, ...], tuple[KeywordArg, ...]]:
        """Positional arguments, then keyword arguments, each keyword once."""
        args: list[Expr] = []
        keywords: list[KeywordArg] = []
        given: set[str] = set()
        for item in items:
            if isinstance(item, KeywordArg):
                if item.name in given:
                    raise self._fail(item.span, f"keyword :{item.name} is given twice")
                given.add(item.name)
                keywords.append(item)
            elif keywords:
                raise self._fail(
                    expr_span(item), "a positional argument cannot follow keyword arguments"
                )
            else:
                args.append(item)
        return tuple(args), tuple(keywords)

    def keyword_arg(self, meta: Meta, children: list[Any]) -> KeywordArg:
        keyword, value = children
        return KeywordArg(keyword[1:].lower(), value, _span(keyword))

    def symbol(self, meta: Meta, children: list[Token]) -> Symbol:
        return Symbol(children[0].lower(), _span(meta))

    def number(self, meta: Meta, children: list[Token]) -> Number:
        text = str(children[0])
        value: int | float
        if re.fullmatch(r"[+-]?\d+", text):
            digits = len(text.lstrip("+-"))
            if digits > MAX_INTEGER_DIGITS:
                raise self._fail(
                    _span(meta),
                    f"integer of {digits:,} digits is too large (at most {MAX_INTEGER_DIGITS:,})",
                )
            value = int(text)
        else:
            value = float(text)
            if not math.isfinite(value):
                raise self._fail(_span(meta), f"number '{text}' is too large")
        return Number(value, _span(meta))

    def string(self, meta: Meta, children: list[Token]) -> String:
        # Lisp escapes: a backslash makes the next character literal.
        return String(re.sub(r"\\(.)", r"\1", children[0][1:-1], flags=re.DOTALL), _span(meta))
