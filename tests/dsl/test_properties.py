"""Property-based tests of the DSL front end (hypothesis).

* printing a well-formed `Program` and parsing it back gives the same program;
* the dataflow graph ignores step-variable names, the order of independent steps, and whether
  the schema is written straight-line or as one nested expression;
* whatever bytes or text come in, the front end raises nothing but `SchemaError`;
* very deep nesting is refused with a precise error, very long chains are fine;
* every graph's topological order and shape agree with its edges.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Iterable, Sequence
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import anytime.dsl
from anytime.dsl import (
    MAX_NESTING,
    Call,
    DataflowGraph,
    Literal,
    NodeRef,
    Program,
    SchemaCall,
    SchemaFile,
    Step,
    Var,
    format_program,
    parse_schemas,
)
from anytime.dsl.normalize import SPECIAL_FORMS
from anytime.dsl.parser import decode_source
from anytime.dsl.program import variables
from anytime.errors import SchemaError, SchemaSyntaxError

# --- names and literals --------------------------------------------------------------------

_GRAMMAR = (Path(anytime.dsl.__file__).parent / "grammar.lark").read_text(encoding="utf-8")
_SYMBOL_MATCH = re.search(r"^SYMBOL:\s*/(.*)/\s*$", _GRAMMAR, re.MULTILINE)
assert _SYMBOL_MATCH is not None, "grammar.lark no longer defines SYMBOL as a regex"
SYMBOL = re.compile(_SYMBOL_MATCH.group(1))
RESERVED = frozenset({"defschema", "setf", *SPECIAL_FORMS})  # words a name cannot be

_FIRST = "abcdefghijklmnopqrstuvwxyz_*"
_REST = _FIRST + "0123456789+!?<>=/-"
# Names that look like other things or are close to the reserved words.
_TRICKY_NAMES = [
    "x",
    "y",
    "a",
    "f",
    "g",
    "t1",
    "t2",
    "*",
    "_",
    "e",
    "e5",
    "inf",
    "nan",
    "setf-x",
    "setfx",
    "defschemas",
    "a->b",
    "x/y",
    "-",
]


def _is_name(text: str) -> bool:
    return SYMBOL.fullmatch(text) is not None and text == text.lower() and text not in RESERVED


names = st.one_of(
    st.sampled_from(_TRICKY_NAMES),
    st.builds(
        str.__add__,
        st.text(alphabet=_FIRST, min_size=1, max_size=1),
        st.text(alphabet=_REST, max_size=7),
    ),
).filter(_is_name)

_tricky_text = st.text(alphabet='"\\\n\r\t ;()#:abc\u00e9\u4e2d', max_size=12)
strings = st.one_of(st.text(max_size=16), _tricky_text)
literals = st.one_of(
    st.integers(),
    st.integers(min_value=-(10**40), max_value=10**40),
    st.floats(allow_nan=False, allow_infinity=False),
    strings,
).map(Literal)


# --- random well-formed programs -----------------------------------------------------------


def prune(steps: Sequence[Step], output: str) -> tuple[Step, ...]:
    """Only the steps whose result reaches the output."""
    needed = {output}
    kept = []
    for step in reversed(steps):
        if step.target in needed:
            kept.append(step)
            needed.update(variables(step))
    return tuple(reversed(kept))


@st.composite
def programs(
    draw: st.DrawFn,
    *,
    name: str | None = None,
    tree: bool = False,
    forbidden_functions: frozenset[str] = frozenset(),
    callees: Sequence[Program] = (),
    max_steps: int = 8,
) -> Program:
    """A well-formed program: every step a call, every step used.

    With `tree`, every step's result is read exactly once (inputs may be read any number of
    times). `callees` are earlier schemas of the same file that steps may call.
    """
    n_inputs = draw(st.integers(0, 4))
    n_steps = draw(st.integers(0, max_steps))
    if n_steps == 0:
        n_inputs = max(n_inputs, 1)
    variables = draw(
        st.lists(names, min_size=n_inputs + n_steps, max_size=n_inputs + n_steps, unique=True)
    )
    inputs = tuple(variables[:n_inputs])
    targets = variables[n_inputs:]
    program_name = name if name is not None else draw(names)
    functions = names.filter(
        lambda f: f != program_name and f not in forbidden_functions and f not in SPECIAL_FORMS
    )

    available: list[str] = []  # targets that later steps may read
    unused: list[str] = []  # targets not read yet

    def pick(pool: Sequence[str]) -> str:
        return pool[draw(st.integers(0, len(pool) - 1))]

    def arg() -> Literal | Var:
        # 0: a constant, 1: an input, 2-3: an earlier step (read more often than constants).
        choice = draw(st.integers(0, 3))
        if choice >= 2 and available:
            chosen = pick(available)
            if chosen in unused:
                unused.remove(chosen)
            if tree:
                available.remove(chosen)
            return Var(chosen)
        if choice >= 1 and inputs:
            return Var(pick(inputs))
        return draw(literals)

    steps: list[Step] = []
    for position, target in enumerate(targets):
        last = position == len(targets) - 1
        if callees and draw(st.booleans()):
            callee = draw(st.sampled_from(list(callees)))
            args = tuple(arg() for _ in callee.inputs)
            steps.append(SchemaCall(target, callee.name, args))
        else:
            function = draw(functions)
            args = tuple(arg() for _ in range(draw(st.integers(0, 4))))
            if last and draw(st.integers(0, 7)) > 0:
                # Mostly, the last step reads every result not read yet: nothing gets pruned.
                args += tuple(Var(t) for t in unused)
                unused.clear()
                if tree:
                    available.clear()  # in a tree, `available` is exactly `unused`
            keyword_names = draw(
                st.lists(names | st.sampled_from(sorted(RESERVED)), unique=True, max_size=3)
            )
            keywords = tuple((k, arg()) for k in keyword_names)
            steps.append(Call(target, function, args, keywords))
        available.append(target)
        unused.append(target)

    if steps:
        output = steps[-1].target
    else:
        output = draw(st.sampled_from(inputs))
    doc = draw(st.none() | strings)
    return Program(program_name, inputs, prune(steps, output), output, doc)


@st.composite
def program_files(draw: st.DrawFn) -> list[Program]:
    """Several programs with distinct names; later ones may call earlier ones."""
    schema_names = draw(st.lists(names, min_size=1, max_size=4, unique=True))
    result: list[Program] = []
    for schema_name in schema_names:
        result.append(
            draw(
                programs(
                    name=schema_name,
                    forbidden_functions=frozenset(schema_names),
                    callees=tuple(result),
                    max_steps=5,
                )
            )
        )
    return result


def roundtrip(program: Program) -> Program:
    parsed = parse_schemas(format_program(program))
    assert len(parsed) == 1
    return parsed.programs[0]


# --- 1. round trip -------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(programs())
def test_format_then_parse_gives_back_the_program(program: Program) -> None:
    text = format_program(program)
    parsed = parse_schemas(text)
    assert isinstance(parsed, SchemaFile)
    assert parsed.programs == (program,)
    assert parsed[program.name] == program
    # Printing is a fixed point.
    assert format_program(parsed.programs[0]) == text


@settings(max_examples=75, deadline=None)
@given(program_files())
def test_a_file_of_several_programs_round_trips(schemas: list[Program]) -> None:
    text = "\n\n".join(format_program(p) for p in schemas)
    parsed = parse_schemas(text, filename="many.any")
    assert parsed.programs == tuple(schemas)
    assert parsed.filename == "many.any"
    assert parsed.names == tuple(p.name for p in schemas)
    # Every callee comes before its callers, both as written and in dependency order.
    order = [p.name for p in parsed.dependency_order()]
    for program in parsed:
        for callee in program.callees():
            assert order.index(callee) < order.index(program.name)


# --- 2. graph invariance -------------------------------------------------------------------


def rename(program: Program, mapping: dict[str, str]) -> Program:
    """The program with step targets renamed consistently."""

    def arg(a: Literal | Var) -> Literal | Var:
        return Var(mapping.get(a.name, a.name)) if isinstance(a, Var) else a

    def renamed(s: Step) -> Step:
        args = tuple(arg(a) for a in s.args)
        if isinstance(s, SchemaCall):
            return SchemaCall(mapping[s.target], s.schema, args)
        assert isinstance(s, Call)
        keywords = tuple((k, arg(v)) for k, v in s.keywords)
        return Call(mapping[s.target], s.function, args, keywords)

    steps = tuple(renamed(s) for s in program.steps)
    return Program(
        program.name,
        program.inputs,
        steps,
        mapping.get(program.output, program.output),
        program.doc,
    )


def topological_reorder(data: st.DataObject, steps: Sequence[Step]) -> tuple[Step, ...]:
    """Another valid order of the steps: each one after the steps it reads."""
    targets = {s.target for s in steps}
    remaining = list(steps)
    placed: set[str] = set()
    order: list[Step] = []
    while remaining:
        ready = [s for s in remaining if all(v in placed or v not in targets for v in variables(s))]
        step = data.draw(st.sampled_from(ready))
        remaining.remove(step)
        placed.add(step.target)
        order.append(step)
    return tuple(order)


def format_literal(value: int | float | str) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(value)


def nested_expression(program: Program) -> str:
    """A tree-shaped program (every step result read once) as one nested s-expression."""
    producer = {s.target: s for s in program.steps}
    reads = Counter(v for s in program.steps for v in variables(s) if v in producer)
    assert all(count == 1 for count in reads.values()), "not a tree"

    def expr(a: Literal | Var) -> str:
        if isinstance(a, Literal):
            return format_literal(a.value)
        step = producer.get(a.name)
        if step is None:
            return a.name
        assert isinstance(step, Call | SchemaCall)
        name = step.function if isinstance(step, Call) else step.schema
        parts = [name, *(expr(x) for x in step.args)]
        if isinstance(step, Call):
            parts += [f":{k} {expr(v)}" for k, v in step.keywords]
        return "(" + " ".join(parts) + ")"

    return expr(Var(program.output))


@settings(max_examples=120, deadline=None)
@given(programs(), st.data())
def test_graph_ignores_step_variable_names(program: Program, data: st.DataObject) -> None:
    n = len(program.steps)
    new_names = data.draw(
        st.lists(names, min_size=n, max_size=n, unique=True).filter(
            lambda ns: not set(ns) & set(program.inputs)
        ),
        label="new names",
    )
    renamed = rename(program, dict(zip((s.target for s in program.steps), new_names, strict=True)))
    assert renamed.graph == program.graph
    assert [node.variable for node in renamed.graph.nodes] == [
        new_names[[s.target for s in program.steps].index(node.variable)]
        for node in program.graph.nodes
    ]
    # The renamed program is still well-formed and parses to the same graph.
    assert roundtrip(renamed) == renamed
    assert roundtrip(renamed).graph == program.graph


@settings(max_examples=120, deadline=None)
@given(programs(), st.data())
def test_graph_ignores_the_order_of_independent_steps(
    program: Program, data: st.DataObject
) -> None:
    steps = topological_reorder(data, program.steps)
    reordered = Program(program.name, program.inputs, steps, program.output, program.doc)
    assert reordered.graph == program.graph
    assert roundtrip(reordered) == reordered
    assert roundtrip(reordered).graph == program.graph


@settings(max_examples=150, deadline=None)
@given(programs(tree=True))
def test_nested_and_straight_line_forms_give_equal_graphs(program: Program) -> None:
    graph = program.graph
    assert graph.shape in ("chain", "tree")
    doc = "" if program.doc is None else " " + format_literal(program.doc)
    text = (
        f"(defschema {program.name} ({' '.join(program.inputs)}){doc}\n"
        f"  {nested_expression(program)})"
    )
    parsed = parse_schemas(text).programs[0]
    assert parsed.graph == graph
    assert parsed.graph.shape == graph.shape
    assert len(parsed.steps) == len(program.steps)
    assert parsed.doc == program.doc
    assert parsed.inputs == program.inputs


def test_nested_helper_on_the_shipped_navigation_schema(navigation_any: Path) -> None:
    schemas = parse_schemas(navigation_any.read_text(encoding="utf-8"))
    program = schemas["navigate"]
    assert nested_expression(program) == "(find-path start goal (get-domain-description sensor))"
    assert program.graph == schemas["navigate-nested"].graph


# --- 3. robustness -------------------------------------------------------------------------


def parse_or_schema_error(text: str) -> SchemaFile | None:
    """Parse; a `SchemaError` is fine, any other exception fails the test."""
    try:
        return parse_schemas(text, filename="fuzz.any")
    except SchemaError as error:
        assert error.diagnostics
        assert error.line >= 1 and error.column >= 1
        assert error.message
        str(error)  # formatting the diagnostics must not fail either
        return None


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_random_bytes_raise_only_schema_errors(data: bytes) -> None:
    try:
        text = decode_source(data, "fuzz.any")
    except SchemaError as error:
        assert isinstance(error, SchemaSyntaxError)
        return
    parse_or_schema_error(text)


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=200))
def test_random_text_raises_only_schema_errors(text: str) -> None:
    parse_or_schema_error(text)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=60))
def test_random_bytes_after_a_valid_prefix_raise_only_schema_errors(tail: bytes) -> None:
    data = b"(defschema f (x) (setf a (g x)) " + tail
    try:
        text = decode_source(data, "fuzz.any")
    except SchemaError as error:
        assert isinstance(error, SchemaSyntaxError)
        return
    parse_or_schema_error(text)


TOKENS = [
    "(",
    ")",
    "defschema",
    "setf",
    "DefSchema",
    "SETF",
    "x",
    "f",
    "g",
    "1",
    "-2.5",
    "1e999",
    '"s"',
    '"unterminated',
    ":k",
    ";comment\n",
    "\n",
    "[",
    "#",
    "12abc",
    "+",
    ".",
    "\\",
    '"a\\"b"',
    # Larger pieces, to reach the grammar and the normaliser more often.
    "(defschema f (x)",
    "(defschema g ()",
    "(setf a",
    "(g x)",
    "(f x)",
    "x)",
    "a)",
    ":level 2",
]


@settings(max_examples=400, deadline=None)
@given(st.lists(st.sampled_from(TOKENS), max_size=30))
def test_token_soups_raise_only_schema_errors(tokens: list[str]) -> None:
    parse_or_schema_error(" ".join(tokens))


# Characters that str.splitlines() treats as line breaks although they are not '\n'.
_LINE_BREAKS_BUT_NOT_NEWLINE = "\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
_BAD_LINES = [
    "  (setf zzz-unused (g zzz-undefined))",  # two errors of the normaliser
    "  (setf zzz-dup (g :k 1 :k 2))",  # an error of the syntax-tree builder
]


@settings(max_examples=100, deadline=None)
@given(
    st.text(alphabet="ab \t" + _LINE_BREAKS_BUT_NOT_NEWLINE, max_size=6),
    st.booleans(),
    st.sampled_from(_BAD_LINES),
)
@example(noise="\x0c", in_comment=True, bad=_BAD_LINES[0])
def test_diagnostics_quote_the_line_they_point_at(noise: str, in_comment: bool, bad: str) -> None:
    """Line numbers count '\n' only, so the quoted source line must be split the same way,
    even after a comment or a string holding a character that str.splitlines() breaks at."""
    noisy = f"  (setf a (g x)) ; {noise}" if in_comment else f'  (setf a (g x "{noise}"))'
    text = "\n".join(["(defschema f (x)", noisy, "  (setf b (g a))", bad, "  b)"])
    with pytest.raises(SchemaError) as caught:
        parse_schemas(text)
    text_lines = text.split("\n")
    for diagnostic in caught.value.diagnostics:
        assert 1 <= diagnostic.line <= len(text_lines)
        line = text_lines[diagnostic.line - 1]
        assert line == bad
        assert diagnostic.source_line.rstrip("\r") == line.rstrip("\r")
        assert 1 <= diagnostic.column <= len(line) + 1


# --- 4. deep nesting and long programs -----------------------------------------------------


def first_too_deep(text: str) -> int:
    """Offset of the first '(' beyond MAX_NESTING levels (the text has no strings/comments)."""
    depth = 0
    for offset, char in enumerate(text):
        if char == "(":
            depth += 1
            if depth > MAX_NESTING:
                return offset
        elif char == ")":
            depth -= 1
    raise AssertionError("not too deep")


def test_very_deep_nesting_is_refused_where_it_gets_too_deep() -> None:
    text = "(defschema f (x) " + "(g " * 10_000 + "x" + ")" * 10_001
    with pytest.raises(SchemaSyntaxError) as caught:
        parse_schemas(text)
    error = caught.value
    assert error.message == f"nested too deeply: more than {MAX_NESTING} levels of parentheses"
    assert error.line == 1
    offset = first_too_deep(text)
    assert error.column == offset + 1
    assert text[offset] == "("
    assert len(error.diagnostics) == 1


def test_nesting_just_at_the_limit_is_accepted() -> None:
    depth = MAX_NESTING - 1  # the defschema form itself is one level
    text = "(defschema f (x) " + "(g " * depth + "x" + ")" * (depth + 1)
    program = parse_schemas(text)["f"]
    assert len(program.steps) == depth
    assert program.graph.shape == "chain"


@pytest.mark.parametrize(
    "text",
    [
        "(" * 10_000,
        ")" * 10_000,
        "(defschema f (x) " + "(" * 10_000,
        "(defschema f (x) x)" + ")" * 10_000,
        "(" * 10_000 + ")" * 10_000,
    ],
    ids=["open", "close", "open-in-body", "close-after", "balanced"],
)
def test_many_parentheses_give_a_syntax_error_not_a_recursion_error(text: str) -> None:
    with pytest.raises(SchemaSyntaxError) as caught:
        parse_schemas(text)
    assert caught.value.line == 1


def test_a_long_chain_of_setf_steps_parses() -> None:
    n = 3_000
    lines = ["(defschema long (x)", "  (setf v1 (g x))"]
    lines += [f"  (setf v{i} (g v{i - 1}))" for i in range(2, n + 1)]
    lines.append(f"  v{n})")
    text = "\n".join(lines)
    program = parse_schemas(text)["long"]
    assert len(program.steps) == n
    graph = program.graph
    assert len(graph.nodes) == n
    assert graph.shape == "chain"
    assert graph.topological_order() == tuple(range(n))
    assert graph.output == NodeRef(n - 1)
    assert format_program(program) == text


# --- 5. graph invariants -------------------------------------------------------------------


def node_reads(graph: DataflowGraph) -> list[set[int]]:
    return [
        {source.index for _, source in node.sources() if isinstance(source, NodeRef)}
        for node in graph.nodes
    ]


def node_uses(graph: DataflowGraph) -> Counter[int]:
    """How many argument slots read each node's result."""
    return Counter(
        source.index
        for node in graph.nodes
        for _, source in node.sources()
        if isinstance(source, NodeRef)
    )


def check_graph_invariants(graph: DataflowGraph, steps: Iterable[Step]) -> None:
    steps = list(steps)
    n = len(graph.nodes)
    assert n == len(steps)  # every step is used, so every step is a node
    order = graph.topological_order()
    assert sorted(order) == list(range(n))
    position = {node: i for i, node in enumerate(order)}
    reads = node_reads(graph)
    for consumer, producers in enumerate(reads):
        assert set(graph.producers(consumer)) == producers
        for producer in producers:
            assert position[producer] < position[consumer]
            assert consumer in graph.consumers(producer)
    uses = node_uses(graph)
    # Every node but the output feeds some other node.
    for index in range(n):
        if graph.output != NodeRef(index):
            assert uses[index] >= 1
    is_chain = all(len(r) <= 1 for r in reads) and all(c <= 1 for c in uses.values())
    assert (graph.shape == "chain") == is_chain
    if not is_chain:
        assert graph.shape == ("tree" if all(c <= 1 for c in uses.values()) else "dag")


@settings(max_examples=150, deadline=None)
@given(programs())
def test_parsed_graphs_are_topologically_ordered_and_shaped_by_their_edges(
    program: Program,
) -> None:
    parsed = roundtrip(program)
    check_graph_invariants(parsed.graph, parsed.steps)


@settings(max_examples=50, deadline=None)
@given(programs(tree=True))
def test_nested_programs_have_consistent_graphs(program: Program) -> None:
    text = f"(defschema {program.name} ({' '.join(program.inputs)}) {nested_expression(program)})"
    parsed = parse_schemas(text).programs[0]
    check_graph_invariants(parsed.graph, parsed.steps)
