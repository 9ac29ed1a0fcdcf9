"""`best-of` and `if`: their straight-line form, JSON, round trip, and their errors."""

from __future__ import annotations

import pytest

from anytime.dsl import format_program, parse_schemas, program_to_json
from anytime.dsl.program import Alternative, BestOf, Branch, Call, If, Var
from anytime.errors import SchemaError, SchemaSyntaxError

CHOOSE = """(defschema choose (w)
  (setf plan (best-of (when (left-clear? w) (detour-left (sense w)))
                      (when (right-clear? w) (detour-right w))))
  (setf out (if (lucky? plan) (refine plan) (refine2 (refine plan)) :p 0.7))
  out)
"""


def test_choices_hold_their_alternatives_and_branches() -> None:
    program = parse_schemas(CHOOSE)["choose"]
    plan, condition, out = program.steps  # the steps of a choice are nested inside it
    assert isinstance(plan, BestOf) and isinstance(condition, Call) and isinstance(out, If)
    first, second = plan.alternatives
    assert first == Alternative(
        Call("t1", "left-clear?", (Var("w"),)),
        (Call("t3", "sense", (Var("w"),)), Call("t4", "detour-left", (Var("t3"),))),
        Var("t4"),
    )
    assert second == Alternative(
        Call("t2", "right-clear?", (Var("w"),)),
        (Call("t5", "detour-right", (Var("w"),)),),
        Var("t5"),
    )
    assert condition == Call("t6", "lucky?", (Var("plan"),))  # the condition always runs
    assert out == If(
        "out",
        Var("t6"),
        Branch((Call("t7", "refine", (Var("plan"),)),), Var("t7")),
        Branch(
            (Call("t8", "refine", (Var("plan"),)), Call("t9", "refine2", (Var("t8"),))),
            Var("t9"),
        ),
        0.7,
    )
    assert [s.target for s in program.walk()] == [
        *("t1", "t2", "t3", "t4", "t5", "plan"),
        *("t6", "t7", "t8", "t9", "out"),
    ]


def test_print_parses_back_to_the_same_program() -> None:
    program = parse_schemas(CHOOSE)["choose"]
    assert parse_schemas(format_program(program))["choose"] == program


def test_json_names_the_parts_of_each_choice() -> None:
    steps = program_to_json(parse_schemas(CHOOSE)["choose"])["steps"]
    best_of = next(s for s in steps if s["kind"] == "best-of")
    assert [(a["when"]["function"], a["value"]) for a in best_of["alternatives"]] == [
        ("left-clear?", "t4"),
        ("right-clear?", "t5"),
    ]
    assert [s["function"] for s in best_of["alternatives"][0]["steps"]] == ["sense", "detour-left"]
    conditional = next(s for s in steps if s["kind"] == "if")
    assert (conditional["condition"], conditional["then"]["value"]) == ("t6", "t7")
    assert [s["target"] for s in conditional["else"]["steps"]] == ["t8", "t9"]
    assert conditional["p"] == 0.7


ERRORS = {
    "when-outside-best-of": (
        "(defschema p (x) (f (when (ok x) x)))",
        1,
        22,
        "'when' is allowed only as an alternative of best-of: "
        "(best-of (when PRECONDITION EXPR) ...)",
    ),
    "best-of-without-alternatives": (
        "(defschema p (x) (best-of))",
        1,
        18,
        "best-of needs at least one alternative: (best-of (when PRECONDITION EXPR) ...)",
    ),
    "when-arity": (
        "(defschema p (x) (best-of (when (ok x))))",
        1,
        27,
        "when takes a precondition and an expression: (when PRECONDITION EXPR), got 1 argument",
    ),
    "precondition-variable": (
        "(defschema p (x) (best-of (when x (f x))))",
        1,
        33,
        "the precondition of 'when' must be a call of an elementary function, not a variable",
    ),
    "precondition-nested-call": (
        "(defschema p (x) (best-of (when (ok (g x)) (f x))))",
        1,
        37,
        "the arguments of a precondition must be variables or constants "
        "(a precondition is one cheap, elementary test)",
    ),
    "if-arity": (
        "(defschema p (x) (if (ok x) (f x)))",
        1,
        18,
        "if takes a condition, a then expression and an else expression: "
        "(if CONDITION THEN ELSE [:p P]), got 2 arguments",
    ),
    "p-out-of-range": (
        "(defschema p (x) (if (ok x) (f x) (g x) :p 1.5))",
        1,
        44,
        "the :p of if must be a number in [0, 1] (the probability that the condition holds), "
        "got 1.5",
    ),
    "p-not-a-number": (
        '(defschema p (x) (if (ok x) (f x) (g x) :p "high"))',
        1,
        44,
        "the :p of if must be a number in [0, 1] (the probability that the condition holds), "
        "got a string",
    ),
    "if-other-keyword": (
        "(defschema p (x) (if (ok x) (f x) (g x) :q 0.5))",
        1,
        41,
        "if takes only the keyword :p, the probability of the condition (got :q)",
    ),
    "dependence-out-of-range": (
        "(defschema p (x) (best-of (f x) (g x) :dependence 1.5))",
        1,
        51,
        "the :dependence of best-of must be a number in [0, 1] (the probability that one "
        "draw decides all its alternatives), got 1.5",
    ),
    "dependence-not-a-number": (
        "(defschema p (x) (best-of (f x) (g x) :dependence high))",
        1,
        51,
        "the :dependence of best-of must be a number in [0, 1] (the probability that one "
        "draw decides all its alternatives), got a symbol",
    ),
    "best-of-other-keyword": (
        "(defschema p (x) (best-of (f x) (g x) :p 0.5))",
        1,
        39,
        "best-of takes only the keyword :dependence, the probability that one draw decide"
        "s all its alternatives (got :p)",
    ),
}


@pytest.mark.parametrize(("text", "line", "column", "message"), ERRORS.values(), ids=ERRORS)
def test_choice_errors_point_at_the_source(text: str, line: int, column: int, message: str) -> None:
    with pytest.raises(SchemaError) as raised:
        parse_schemas(text, filename="e.any")
    first = raised.value.diagnostics[0]
    assert (first.line, first.column, first.message) == (line, column, message)


def test_a_malformed_alternative_is_the_only_error() -> None:
    """The variables used only inside it were also reported as assigned but never used."""
    text = "(defschema p (x)\n  (setf m (sense x))\n  (best-of (when (ok? m)) (f x)))"
    with pytest.raises(SchemaError) as raised:
        parse_schemas(text, filename="e.any")
    assert [(d.line, d.column, d.message) for d in raised.value.diagnostics] == [
        (
            3,
            12,
            "when takes a precondition and an expression: (when PRECONDITION EXPR), got 1 argument",
        )
    ]


UNCONDITIONAL = """(defschema p (w)
  (best-of (when (left-clear? w) (detour-left w)) (wait w)))
"""


def test_an_alternative_without_when_is_always_applicable() -> None:
    program = parse_schemas(UNCONDITIONAL)["p"]
    (best_of,) = program.steps
    assert isinstance(best_of, BestOf) and best_of.alternatives[1].precondition is None
    assert parse_schemas(format_program(program))["p"] == program
    assert "(best-of (when (left-clear? w) (detour-left w)) (wait w))" in format_program(program)
    steps = program_to_json(program)["steps"]
    assert [a["when"] for a in steps[-1]["alternatives"]] == [
        {"target": "t2", "kind": "call", "function": "left-clear?", "args": ["w"], "keywords": {}},
        None,
    ]


def test_a_declared_dependence_is_kept_printed_and_named_in_json() -> None:
    text = "(defschema p (w) (best-of (f w) (g w) :dependence 0.25))"
    program = parse_schemas(text)["p"]
    (best_of,) = program.steps
    assert isinstance(best_of, BestOf) and best_of.dependence == 0.25
    assert "(best-of (f w) (g w) :dependence 0.25)" in format_program(program)
    assert parse_schemas(format_program(program))["p"] == program
    assert program_to_json(program)["steps"][-1]["dependence"] == 0.25
    (plain,) = parse_schemas(UNCONDITIONAL)["p"].steps
    assert isinstance(plain, BestOf) and plain.dependence == 0.0  # independent by default
    assert ":dependence" not in format_program(parse_schemas(UNCONDITIONAL)["p"])


def test_known_functions_do_not_include_the_special_forms() -> None:
    text = "(defschema p (x) (best-of (when (ok x) (f x))))"
    program = parse_schemas(text, known_functions={"ok": 1, "f": 1})["p"]
    assert isinstance(program.steps[-1], BestOf)


def test_dot_draws_choices_as_diamonds_with_labelled_arguments() -> None:
    from anytime.dsl import graph_to_dot

    text = (
        "(defschema c (w) (best-of (when (l? w) (left w)) (when (r? w) (right w))))\n"
        "(defschema d (w) (if (sunny? w) (left w) (right w) :p 0.7))"
    )
    dot = graph_to_dot(program.graph for program in parse_schemas(text).programs)
    lines = [line.strip() for line in dot.splitlines()]
    assert 's0_n4 [shape=diamond, label="best-of"];' in lines
    assert [line for line in lines if "-> s0_n4" in line] == [
        's0_n0 -> s0_n4 [label="when 1: t2"];',
        's0_n1 -> s0_n4 [label="when 2: t3"];',
        's0_n2 -> s0_n4 [label="alternative 1: t4"];',
        's0_n3 -> s0_n4 [label="alternative 2: t5"];',
    ]
    assert 's1_n0 -> s1_n3 [label="condition: t2"];' in lines
    assert 's1_n1 -> s1_n3 [label="then: t3"];' in lines
    assert 's1_n2 -> s1_n3 [label="else: t4"];' in lines


ALTERNATIVES = "(when PRECONDITION EXPR) ... EXPR"


@pytest.mark.parametrize(
    ("text", "column", "word", "shape"),
    [
        ("(defschema p (when) (f when))", 15, "when", "when PRECONDITION EXPR"),
        ("(defschema p (x) (setf if (f x)) if)", 24, "if", "if CONDITION THEN ELSE [:p P]"),
        (
            "(defschema p (x) (f Best-Of))",
            21,
            "best-of",
            "best-of (when PRECONDITION EXPR) ... EXPR",
        ),
    ],
)
def test_the_special_forms_words_are_reserved(
    text: str, column: int, word: str, shape: str
) -> None:
    """Each form has a grammar rule of its own, opened by its reserved word."""
    with pytest.raises(SchemaSyntaxError) as raised:
        parse_schemas(text)
    (diagnostic,) = raised.value.diagnostics
    assert (diagnostic.line, diagnostic.column, diagnostic.message) == (
        1,
        column,
        f"'{word}' is a reserved word (best-of, if, when, map, repeat): it cannot name a "
        f"variable or a parameter, and it opens its form: ({shape})",
    )


def test_a_name_that_only_starts_with_a_reserved_word_is_a_name() -> None:
    program = parse_schemas("(defschema p (iffy best-of-3 whence) (f iffy best-of-3 whence))")["p"]
    assert program.inputs == ("iffy", "best-of-3", "whence")
