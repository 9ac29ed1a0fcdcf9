"""The front end on well-formed input: normal form, dataflow graph, printed forms."""

from pathlib import Path

import pytest

from anytime.dsl import (
    Call,
    DataflowGraph,
    InputRef,
    Literal,
    Node,
    NodeRef,
    SchemaCall,
    Var,
    format_programs,
    graph_to_dot,
    load_schemas,
    parse_schemas,
    program_to_json,
)


def one(text: str):
    (program,) = parse_schemas(text).programs
    return program


def test_the_papers_program_in_both_forms_gives_one_graph(navigation_any: Path) -> None:
    schemas = load_schemas(navigation_any)
    straight, nested = schemas["navigate"], schemas["navigate-nested"]
    assert straight.graph == nested.graph
    assert straight.graph.nodes == (
        Node("get-domain-description", (InputRef("sensor"),)),
        Node("find-path", (InputRef("start"), InputRef("goal"), NodeRef(0))),
    )
    assert straight.graph.output == NodeRef(1)
    # The programs themselves differ only in the names of the intermediate variables.
    assert [s.function for s in straight.steps] == [s.function for s in nested.steps]
    assert nested.steps[1].args == (Var("start"), Var("goal"), Var("t1"))


def test_nesting_and_setf_give_the_same_graph() -> None:
    nested = one("(defschema p (x) (f (g x)))")
    straight = one("(defschema p (x) (setf a (g x)) (setf b (f a)) b)")
    assert nested.graph == straight.graph
    assert nested != straight
    assert nested.steps == (Call("t1", "g", (Var("x"),)), Call("t2", "f", (Var("t1"),)))
    assert nested.output == "t2"


def test_graph_does_not_depend_on_the_order_of_independent_steps() -> None:
    a = one("(defschema p (x y) (setf a (g x)) (setf b (h y)) (f a b))")
    b = one("(defschema p (x y) (setf b (h y)) (setf a (g x)) (f a b))")
    assert a != b
    assert a.graph == b.graph
    assert [n.function for n in a.graph.nodes] == ["g", "h", "f"]


def test_navigation_json_field_by_field(navigation_any: Path) -> None:
    schemas = load_schemas(navigation_any)
    assert schemas.names == (
        "navigate",
        "navigate-nested",
        "navigate-two-planners",
        "sense-plan-act",
    )
    assert program_to_json(schemas["navigate"]) == {
        "name": "navigate",
        "doc": "Sense the local map, then plan a path on it.",
        "inputs": ["start", "goal", "sensor"],
        "steps": [
            {
                "target": "domain",
                "function": "get-domain-description",
                "kind": "call",
                "args": ["sensor"],
                "keywords": {},
            },
            {
                "target": "plan",
                "function": "find-path",
                "kind": "call",
                "args": ["start", "goal", "domain"],
                "keywords": {},
            },
        ],
        "output": "plan",
        "shape": "chain",
    }
    two = program_to_json(schemas["navigate-two-planners"])
    assert two["shape"] == "dag"
    assert [s["function"] for s in two["steps"]] == [
        "get-domain-description",
        "find-path",
        "a-star",
        "better-plan",
    ]
    assert two["steps"][2]["keywords"] == {"level": {"literal": 2}}
    assert two["output"] == "t1"
    spa = program_to_json(schemas["sense-plan-act"])
    assert spa["steps"][0]["kind"] == "schema"
    assert spa["steps"][1]["args"] == ["plan", "sensor"]


def test_symbols_are_case_insensitive_strings_are_not() -> None:
    upper = one('(DEFSCHEMA Nav (Start) "Doc" (SETF Plan (Find-Path START :Mode "Fast")) PLAN)')
    lower = one('(defschema nav (start) "Doc" (setf plan (find-path start :mode "Fast")) plan)')
    assert upper == lower
    assert upper.steps[0].keywords == (("mode", Literal("Fast")),)


def test_literals_keywords_and_escapes() -> None:
    program = one(r'(defschema p (x) (f x -2 3.5 1e3 "a \"b\" \\c" :level 4 :name "n"))')
    (step,) = program.steps
    assert step.args == (
        Var("x"),
        Literal(-2),
        Literal(3.5),
        Literal(1000.0),
        Literal('a "b" \\c'),
    )
    assert step.keywords == (("level", Literal(4)), ("name", Literal("n")))
    assert program_to_json(program)["steps"][0]["args"][1:3] == [
        {"literal": -2},
        {"literal": 3.5},
    ]


def test_names_for_values_are_substituted() -> None:
    program = one("(defschema p (x) (setf level 4) (setf y x) (setf z (f y :level level)) z)")
    assert program.steps == (Call("z", "f", (Var("x"),), (("level", Literal(4)),)),)


def test_a_final_setf_is_the_output_and_an_input_can_be_the_output() -> None:
    assert one("(defschema p (x) (setf y (f x)))").output == "y"
    identity = one("(defschema p (x) x)")
    assert identity.steps == ()
    assert identity.graph.output == InputRef("x")
    assert identity.graph.shape == "chain"


def test_docstring_only_when_something_follows() -> None:
    assert one('(defschema p (x) "doc" x)').doc == "doc"
    assert one("(defschema p (x) x)").doc is None


def test_comments_crlf_and_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "p.any"
    path.write_bytes(b"\xef\xbb\xbf; comment\r\n(defschema p (x) ; why\r\n  (f x)) ; done\r\n")
    (program,) = load_schemas(path).programs
    assert program.steps == (Call("t1", "f", (Var("x"),)),)


@pytest.mark.parametrize(
    ("body", "shape"),
    [
        ("(f x)", "chain"),
        ("(h (g (f x)))", "chain"),
        ("(h (f x) (g x))", "tree"),  # an input shared by two calls is not a shared result
        ("(h (f x) (g (k y)))", "tree"),
        ("(setf a (f x)) (h a a)", "dag"),
        ("(setf a (f x)) (setf b (g a)) (h a b)", "dag"),
    ],
    ids=["one-call", "chain", "tree-shared-input", "tree", "dag-same-consumer", "dag-diamond"],
)
def test_shape(body: str, shape: str) -> None:
    assert one(f"(defschema p (x y) {body})").graph.shape == shape


def test_topological_order_producers_and_consumers() -> None:
    graph = one("(defschema p (x) (setf a (f x)) (setf b (g a)) (setf c (k a)) (h b c))").graph
    assert [n.function for n in graph.nodes] == ["f", "g", "k", "h"]
    assert graph.topological_order() == (0, 1, 2, 3)
    assert graph.producers(3) == (1, 2)
    assert graph.consumers(0) == (1, 2)
    assert [(e.source, e.target, e.slot, e.variable) for e in graph.edges] == [
        (InputRef("x"), 0, 0, "x"),
        (NodeRef(0), 1, 0, "a"),
        (NodeRef(0), 2, 0, "a"),
        (NodeRef(1), 3, 0, "b"),
        (NodeRef(2), 3, 1, "c"),
    ]


def test_schema_calls_and_bottom_up_order() -> None:
    schemas = parse_schemas(
        "(defschema top (x) (mid (low x)))\n(defschema mid (y) (f y))\n(defschema low (z) (g z))\n"
    )
    top = schemas["top"]
    assert top.steps == (
        SchemaCall("t1", "low", (Var("x"),)),
        SchemaCall("t2", "mid", (Var("t1"),)),
    )
    assert top.callees() == ("low", "mid")
    assert [p.name for p in schemas.dependency_order()] == ["low", "mid", "top"]


def test_a_long_straight_line_program_needs_no_recursion() -> None:
    steps = " ".join(f"(setf v{i + 1} (f v{i}))" for i in range(2000))
    graph = one(f"(defschema p (v0) {steps} v2000)").graph
    assert len(graph.nodes) == 2000
    assert graph.shape == "chain"


def test_known_functions_with_arity() -> None:
    text = "(defschema p (x) (f x x))"
    assert parse_schemas(text, known_functions={"f": 2}).names == ("p",)
    assert parse_schemas(text, known_functions={"f": None}).names == ("p",)
    assert parse_schemas(text, known_functions=["f"]).names == ("p",)


def test_printed_form_parses_back(navigation_any: Path) -> None:
    schemas = load_schemas(navigation_any)
    again = parse_schemas(format_programs(schemas), str(navigation_any))
    assert again == schemas


def test_dot_output(navigation_any: Path) -> None:
    dot = graph_to_dot([load_schemas(navigation_any)["navigate-two-planners"].graph])
    assert dot.startswith("digraph schemas {\n")
    assert 'label="navigate-two-planners (dag)";' in dot
    assert 's0_n2 [shape=box, label="a-star\\nlevel=2"];' in dot
    assert 's0_n0 -> s0_n1 [label="domain"];' in dot
    assert 's0_n0 -> s0_n2 [label="domain"];' in dot
    assert "s0_n3 -> s0_output;" in dot
    assert dot.count("{") == dot.count("}")


def test_graph_from_program_is_the_graph_property(navigation_any: Path) -> None:
    program = load_schemas(navigation_any)["navigate"]
    assert DataflowGraph.from_program(program) == program.graph
    assert program.graph.name == "navigate"
