"""Every static error names its file, line and column, in plain words."""

from pathlib import Path

import pytest

from anytime.dsl import MAX_NESTING, load_schemas, parse_schemas
from anytime.errors import SchemaError, SchemaSyntaxError

# (source, line, column, message); every source is in file "e.any".
SYNTAX_ERRORS = {
    "unclosed-paren": (
        "(defschema p (x) (setf a (f x) a)\n",
        1,
        1,
        "unbalanced parentheses: this '(' is never closed",
    ),
    "unclosed-paren-found-by-indentation": (
        "(defschema p (x)\n  (setf a (f x)\n  a)\n(defschema q (y) y)\n",
        2,
        3,
        "unbalanced parentheses: ')' missing for this '(' (a later line is outdented)",
    ),
    "extra-close-paren": (
        "(defschema p (x)\n  (f x)))\n",
        2,
        9,
        "unmatched ')': no '(' is open here",
    ),
    "unterminated-string": (
        '(defschema p (x)\n  "doc\n  x)\n',
        2,
        3,
        "unterminated string: no closing '\"'",
    ),
    "missing-schema-name": (
        "(defschema (x)\n  x)\n",
        1,
        12,
        "missing schema name after 'defschema'",
    ),
    "missing-parameter-list": (
        "(defschema p x\n  x)\n",
        1,
        14,
        "missing parameter list: expected '(' and the parameter names after the schema name",
    ),
    "parameter-not-a-name": (
        "(defschema p (x 2)\n  x)\n",
        1,
        17,
        "a parameter must be a name",
    ),
    "stray-token-at-top-level": (
        "(defschema p (x) x)\nplan\n",
        2,
        1,
        "a file holds only (defschema NAME (PARAMS...) BODY...) forms",
    ),
    "top-level-call": (
        "(find-path start goal)\n",
        1,
        2,
        "a file holds only (defschema NAME (PARAMS...) BODY...) forms",
    ),
    "setf-without-variable": (
        "(defschema p (x)\n  (setf (f x) x)\n  x)\n",
        2,
        9,
        "setf needs a variable name: (setf VAR EXPR)",
    ),
    "setf-without-expression": (
        "(defschema p (x)\n  (setf a)\n  a)\n",
        2,
        10,
        "setf needs an expression after the variable name: (setf VAR EXPR)",
    ),
    "setf-with-two-expressions": (
        "(defschema p (x)\n  (setf a (f x) x)\n  a)\n",
        2,
        17,
        "setf takes one variable and one expression: (setf VAR EXPR)",
    ),
    "call-without-function-name": (
        "(defschema p (x)\n  ((f x) x))\n",
        2,
        4,
        "a call must start with a function name",
    ),
    "empty-call": (
        "(defschema p (x)\n  (f ()))\n",
        2,
        7,
        "a call must start with a function name",
    ),
    "keyword-without-value": (
        "(defschema p (x)\n  (f x :level))\n",
        2,
        14,
        "a keyword argument needs a value after it",
    ),
    "keyword-outside-call": (
        "(defschema p (x)\n  :level)\n",
        2,
        3,
        "keywords are only allowed as arguments in a call, before their value",
    ),
    "nested-defschema": (
        "(defschema p (x)\n  (defschema q (y) y))\n",
        2,
        4,
        "'defschema' can only appear at the top level of a file",
    ),
    "setf-inside-expression": (
        "(defschema p (x)\n  (f (setf a x)))\n",
        2,
        7,
        "'setf' can only appear directly in a schema body, not inside an expression",
    ),
    "unexpected-character": (
        "(defschema p (x)\n  (f [x]))\n",
        2,
        6,
        "unexpected character '['",
    ),
    "invalid-number": (
        "(defschema p (x)\n  (f 12abc))\n",
        2,
        6,
        "invalid number '12abc'",
    ),
    "number-too-large": (
        "(defschema p (x)\n  (f 1e999))\n",
        2,
        6,
        "number '1e999' is too large",
    ),
    "huge-integer": (
        "(defschema p (x)\n  (f " + "7" * 5000 + "))\n",
        2,
        6,
        "integer of 5,000 digits is too large (at most 1,000)",
    ),
    "positional-after-keyword": (
        "(defschema p (x)\n  (f :level 2 x))\n",
        2,
        15,
        "a positional argument cannot follow keyword arguments",
    ),
    "keyword-twice": (
        "(defschema p (x)\n  (f x :level 2 :level 3))\n",
        2,
        17,
        "keyword :level is given twice",
    ),
    "empty-file": (
        "; nothing here\n",
        1,
        1,
        "the file holds no schema: expected (defschema NAME (PARAMS...) BODY...)",
    ),
}

SEMANTIC_ERRORS = {
    "undefined-variable": (
        "(defschema navigate (start goal sensor)\n"
        "  (setf domain (get-domain-description sensor))\n"
        "  (find-path start goal domian))\n",
        3,
        25,
        "undefined variable 'domian'; did you mean 'domain'?",
    ),
    "use-before-assignment": (
        "(defschema p (x)\n  (setf a (f b))\n  (setf b (g x))\n  a)\n",
        2,
        14,
        "undefined variable 'b'",
    ),
    "assigned-twice": (
        "(defschema p (x)\n  (setf a (f x))\n  (setf a (g a))\n  a)\n",
        3,
        9,
        "variable 'a' is already assigned on line 2",
    ),
    "assigning-a-parameter": (
        "(defschema p (x)\n  (setf x (f x))\n  x)\n",
        2,
        9,
        "cannot assign 'x': it is a parameter of the schema",
    ),
    "parameter-twice": (
        "(defschema p (x y x)\n  (f x y))\n",
        1,
        19,
        "parameter 'x' appears twice",
    ),
    "empty-body": (
        "(defschema p (x))\n",
        1,
        12,
        "schema 'p' has an empty body",
    ),
    "duplicate-schema": (
        "(defschema p (x) (f x))\n\n(defschema P (y) (g y))\n",
        3,
        12,
        "schema 'p' is already defined on line 1",
    ),
    "calls-itself": (
        "(defschema p (x)\n  (f (p x)))\n",
        2,
        7,
        "schema 'p' calls itself",
    ),
    "calls-itself-through-others": (
        "(defschema p (x) (q x))\n(defschema q (y) (r y))\n(defschema r (z) (f (p z)))\n",
        1,
        19,
        "schema 'p' calls itself through other schemas: p -> q -> r -> p",
    ),
    "schema-arity": (
        "(defschema p (x)\n  (q x x))\n(defschema q (y) (f y))\n",
        2,
        4,
        "schema 'q' takes 1 argument, got 2",
    ),
    "schema-keyword": (
        "(defschema p (x)\n  (q x :level 2))\n(defschema q (y) (f y))\n",
        2,
        4,
        "schema 'q' takes no keyword arguments (got :level)",
    ),
    "value-never-used": (
        "(defschema p (x)\n  (f x)\n  (g x))\n",
        2,
        3,
        "this value is never used: assign it with (setf VAR ...) or remove it",
    ),
    "assigned-but-never-used": (
        "(defschema p (x)\n  (setf a (f x))\n  (g x))\n",
        2,
        9,
        "variable 'a' is assigned but never used",
    ),
    "constant-output": (
        "(defschema p (x)\n  42)\n",
        2,
        3,
        "the output of a schema must be a variable or a call, not a constant",
    ),
}


@pytest.mark.parametrize(
    ("source", "line", "column", "message"),
    SYNTAX_ERRORS.values(),
    ids=SYNTAX_ERRORS.keys(),
)
def test_syntax_error(source: str, line: int, column: int, message: str) -> None:
    with pytest.raises(SchemaSyntaxError) as caught:
        parse_schemas(source, "e.any")
    error = caught.value
    assert (error.filename, error.line, error.column, error.message) == (
        "e.any",
        line,
        column,
        message,
    )
    assert len(error.diagnostics) == 1


@pytest.mark.parametrize(
    ("source", "line", "column", "message"),
    SEMANTIC_ERRORS.values(),
    ids=SEMANTIC_ERRORS.keys(),
)
def test_semantic_error(source: str, line: int, column: int, message: str) -> None:
    with pytest.raises(SchemaError) as caught:
        parse_schemas(source, "e.any")
    error = caught.value
    assert not isinstance(error, SchemaSyntaxError)
    assert [(d.line, d.column, d.message) for d in error.diagnostics] == [(line, column, message)]


def test_message_format_with_source_line_and_caret() -> None:
    source = SEMANTIC_ERRORS["undefined-variable"][0]
    with pytest.raises(SchemaError) as caught:
        parse_schemas(source, "schemas/navigation.any")
    assert str(caught.value) == (
        "schemas/navigation.any:3:25: error: undefined variable 'domian'; "
        "did you mean 'domain'?\n"
        "    (find-path start goal domian))\n"
        "                          ^~~~~~"
    )


def test_syntax_error_is_a_python_syntax_error_too() -> None:
    with pytest.raises(SyntaxError) as caught:
        parse_schemas("(defschema (x) x)", "e.any")
    assert (caught.value.filename, caught.value.lineno, caught.value.offset) == ("e.any", 1, 12)


def test_every_semantic_error_is_reported_in_source_order() -> None:
    source = (
        "(defschema p (x)\n"
        "  (setf a (f y))\n"  # undefined y
        "  (setf a (g x))\n"  # a twice
        "  (q a))\n"  # q: wrong arity
        "(defschema q (u v) (h u v))\n"
    )
    with pytest.raises(SchemaError) as caught:
        parse_schemas(source, "e.any")
    assert [(d.line, d.column, d.message) for d in caught.value.diagnostics] == [
        (2, 14, "undefined variable 'y'"),
        (3, 9, "variable 'a' is already assigned on line 2"),
        (4, 4, "schema 'q' takes 2 arguments, got 1"),
    ]


def test_unknown_function_suggests_the_closest_known_name() -> None:
    source = "(defschema navigate (start goal sensor)\n  (find-pth start goal (sense sensor)))\n"
    known = {"find-path": 3, "sense": 1, "execute-plan": 3}
    with pytest.raises(SchemaError) as caught:
        parse_schemas(source, "e.any", known_functions=known)
    assert [(d.line, d.column, d.message) for d in caught.value.diagnostics] == [
        (2, 4, "unknown function 'find-pth'; did you mean 'find-path'?"),
    ]


def test_unknown_function_without_a_close_name_lists_the_known_ones() -> None:
    with pytest.raises(SchemaError) as caught:
        parse_schemas("(defschema p (x) (zzz x))", "e.any", known_functions=["sense", "plan"])
    assert caught.value.message == "unknown function 'zzz' (known: p, plan, sense)"


def test_library_arity_mismatch() -> None:
    with pytest.raises(SchemaError) as caught:
        parse_schemas("(defschema p (x)\n  (sense x x))", "e.any", known_functions={"sense": 1})
    assert (caught.value.line, caught.value.column, caught.value.message) == (
        2,
        4,
        "function 'sense' takes 1 argument, got 2",
    )


def test_nested_too_deeply() -> None:
    source = "(defschema p (x) " + "(f " * 10_000 + "x" + ")" * 10_001
    with pytest.raises(SchemaSyntaxError) as caught:
        parse_schemas(source, "e.any")
    # The first '(' beyond the limit: the defschema's own is level 1.
    column = len("(defschema p (x) ") + 3 * (MAX_NESTING - 1) + 1
    assert (caught.value.line, caught.value.column, caught.value.message) == (
        1,
        column,
        f"nested too deeply: more than {MAX_NESTING} levels of parentheses",
    )


def test_a_file_that_is_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "bad.any"
    path.write_bytes(b"(defschema p (x)\n  (f \xff))\n")
    with pytest.raises(SchemaSyntaxError) as caught:
        load_schemas(path)
    assert (caught.value.filename, caught.value.line, caught.value.column) == (str(path), 2, 6)
    assert caught.value.message == "the file is not UTF-8 text (byte 0xff)"
