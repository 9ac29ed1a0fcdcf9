"""The loops of the DSL, `(map F XS ARG... [:max K])` and `(repeat N (F ARG...))`: their steps,
graph nodes, printed text (which parses back), JSON and DOT, and the errors of bad loops."""

from __future__ import annotations

import pytest

from anytime.dsl import (
    InputRef,
    Literal,
    NodeRef,
    Var,
    format_program,
    graph_to_dot,
    parse_schemas,
    program_to_json,
)
from anytime.dsl.program import Call, Map, Repeat
from anytime.errors import SchemaError, SchemaSyntaxError

TOURS = """
(defschema tours (depots world)
  (setf plans (map plan-tour depots (prepare world) :max 3))
  (merge plans))
(defschema samples (x)
  (repeat 3 (sense x 2)))
"""


def test_map_and_repeat_are_steps_of_their_own() -> None:
    schemas = parse_schemas(TOURS)
    assert schemas["tours"].steps == (
        Call("t1", "prepare", (Var("world"),)),
        Map("plans", "plan-tour", Var("depots"), (Var("t1"),), 3),
        Call("t2", "merge", (Var("plans"),)),
    )
    assert schemas["samples"].steps == (Repeat("t1", 3, "sense", (Var("x"), Literal(2))),)


def test_a_map_without_max_is_compiled_for_up_to_four_items() -> None:
    (step,) = parse_schemas("(defschema f (xs) (map g xs))")["f"].steps
    assert step == Map("t1", "g", Var("xs"), (), 4)


def test_the_graph_of_a_loop_has_its_arguments_and_its_count() -> None:
    schemas = parse_schemas(TOURS)
    loop = schemas["tours"].graph.nodes[1]
    assert (loop.function, loop.args, loop.keywords) == (
        "map plan-tour",
        (InputRef("depots"), NodeRef(0)),
        (("max", Literal(3)),),
    )
    (repeat,) = schemas["samples"].graph.nodes
    assert (repeat.function, repeat.args, repeat.keywords) == (
        "repeat sense",
        (InputRef("x"), Literal(2)),
        (("count", Literal(3)),),
    )


def test_the_printed_loops_parse_back_to_the_same_programs() -> None:
    schemas = parse_schemas(TOURS)
    assert format_program(schemas["tours"]) == (
        "(defschema tours (depots world)\n"
        "  (setf t1 (prepare world))\n"
        "  (setf plans (map plan-tour depots t1 :max 3))\n"
        "  (setf t2 (merge plans))\n"
        "  t2)"
    )
    assert format_program(schemas["samples"]) == (
        "(defschema samples (x)\n  (setf t1 (repeat 3 (sense x 2)))\n  t1)"
    )
    for program in schemas:
        assert parse_schemas(format_program(program))[program.name] == program


def test_loops_in_json() -> None:
    schemas = parse_schemas(TOURS)
    assert program_to_json(schemas["tours"])["steps"][1] == {
        "target": "plans",
        "kind": "map",
        "function": "plan-tour",
        "items": "depots",
        "args": ["t1"],
        "max": 3,
    }
    assert program_to_json(schemas["samples"])["steps"] == [
        {
            "target": "t1",
            "kind": "repeat",
            "count": 3,
            "function": "sense",
            "args": ["x", {"literal": 2}],
        }
    ]


def test_loops_in_dot_are_stacked_boxes_and_a_maps_collection_is_its_items() -> None:
    dot = graph_to_dot(p.graph for p in parse_schemas(TOURS))
    assert '    s0_n1 [shape=box3d, label="map plan-tour\\nmax=3"];' in dot
    assert '    s0_in_depots -> s0_n1 [label="items: depots"];' in dot
    assert '    s0_n0 -> s0_n1 [label="t1"];' in dot
    assert '    s1_n0 [shape=box3d, label="repeat sense\\n1=2, count=3"];' in dot


def error_of(body: str) -> tuple[int, str]:
    """The column and message of the one error of a schema `(defschema f (xs x) BODY)`."""
    text = f"(defschema g (y) y)\n(defschema f (xs x) {body})"
    with pytest.raises(SchemaError) as raised:
        parse_schemas(text, "loops.any")
    (diagnostic,) = raised.value.diagnostics
    assert (diagnostic.filename, diagnostic.line) == ("loops.any", 2)
    return diagnostic.column, diagnostic.message


@pytest.mark.parametrize(
    ("body", "column", "message"),
    [
        (
            "(map tour)",
            21,
            "map takes a function and a collection: (map FUNCTION ITEMS ARG... [:max K]), "
            "got 1 argument",
        ),
        ("(map (h x) xs)", 27, "the function of 'map' must be the name of a module, not a call"),
        ("(map 3 xs)", 26, "the function of 'map' must be the name of a module, not 3"),
        ("(map g xs)", 26, "map applies a module of the library, not the schema 'g'"),
        (
            "(map tour 3)",
            31,
            "the collection of 'map' must be a variable or a call, not a constant",
        ),
        (
            "(map tour xs :max 0)",
            39,
            "the :max of map must be a whole number >= 1 (the most items its profile is "
            "compiled for), got 0",
        ),
        (
            "(map tour xs :max 2.5)",
            39,
            "the :max of map must be a whole number >= 1 (the most items its profile is "
            "compiled for), got 2.5",
        ),
        (
            "(map tour xs :each 2)",
            34,
            "map takes only the keyword :max, the most items its profile is compiled for "
            "(got :each)",
        ),
        (
            "(repeat 3)",
            21,
            "repeat takes a count and a call: (repeat N (FUNCTION ARG...)), got 1 argument",
        ),
        (
            "(repeat x (tour x))",
            29,
            "the count of 'repeat' must be a whole number >= 1, got the variable 'x' (for a "
            "count known only at run time, map over a collection)",
        ),
        ("(repeat 2.5 (tour x))", 29, "the count of 'repeat' must be a whole number >= 1, got 2.5"),
        ("(repeat 0 (tour x))", 29, "the count of 'repeat' must be a whole number >= 1, got 0"),
        (
            "(repeat 3 x)",
            31,
            "the body of 'repeat' must be one call of a module, not the variable 'x'",
        ),
        ("(repeat 3 (g x))", 32, "repeat calls a module of the library, not the schema 'g'"),
        (
            "(repeat 3 (tour x :fast 1))",
            32,
            "the call inside 'repeat' takes no keyword arguments (got :fast)",
        ),
        ("(repeat 3 (tour x) :k 1)", 40, "repeat takes no keyword arguments (got :k)"),
    ],
)
def test_bad_loops_are_errors_at_their_place(body: str, column: int, message: str) -> None:
    assert error_of(body) == (column, message)


def test_a_loops_error_names_the_file_line_and_column() -> None:
    with pytest.raises(SchemaError) as raised:
        parse_schemas("(defschema f (x)\n  (repeat n (tour x)))", "loops.any")
    assert str(raised.value).splitlines()[0] == (
        "loops.any:2:11: error: the count of 'repeat' must be a whole number >= 1, got the "
        "variable 'n' (for a count known only at run time, map over a collection)"
    )


def test_a_loops_function_is_checked_against_the_library() -> None:
    with pytest.raises(SchemaError) as raised:
        parse_schemas("(defschema f (xs) (map tuor xs))", "f.any", {"tour": 1})
    assert raised.value.diagnostics[0].message == "unknown function 'tuor'; did you mean 'tour'?"
    with pytest.raises(SchemaError) as raised:
        parse_schemas("(defschema f (xs w) (map tour xs w))", "f.any", {"tour": 1})
    assert raised.value.diagnostics[0].message == "function 'tour' takes 1 argument, got 2"


@pytest.mark.parametrize("word", ["map", "repeat"])
def test_map_and_repeat_are_reserved_words(word: str) -> None:
    with pytest.raises(SchemaSyntaxError) as raised:
        parse_schemas(f"(defschema f ({word}) x)")
    assert raised.value.diagnostics[0].message.startswith(
        f"'{word}' is a reserved word (best-of, if, when, map, repeat): it cannot name a "
        "variable or a parameter, and it opens its form: "
    )


def test_a_name_that_only_starts_with_map_or_repeat_is_a_name() -> None:
    program = parse_schemas("(defschema p (mapping repeated) (f mapping repeated))")["p"]
    assert program.inputs == ("mapping", "repeated")
