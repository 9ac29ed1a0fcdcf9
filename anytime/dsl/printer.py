"""Programs out: straight-line DSL text (which parses back to the same program), JSON, DOT."""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

from anytime.dsl.graph import DataflowGraph, InputRef, NodeRef, Source
from anytime.dsl.program import Arg, Literal, Program, Step, Var

INDENT = "  "


def format_literal(value: int | float | str) -> str:
    if isinstance(value, str):
        return '"' + re.sub(r'(["\\])', r"\\\1", value) + '"'
    return repr(value)


def format_arg(arg: Arg) -> str:
    return arg.name if isinstance(arg, Var) else format_literal(arg.value)


def format_call(step: Step) -> str:
    parts = [step.function, *(format_arg(a) for a in step.args)]
    parts += [f":{name} {format_arg(value)}" for name, value in step.keywords]
    return "(" + " ".join(parts) + ")"


def format_program(program: Program) -> str:
    """The program as a straight-line `defschema`; parsing it gives back an equal program."""
    lines = [f"(defschema {program.name} ({' '.join(program.inputs)})"]
    if program.doc is not None:
        lines.append(INDENT + format_literal(program.doc))
    lines += [f"{INDENT}(setf {s.target} {format_call(s)})" for s in program.steps]
    lines.append(f"{INDENT}{program.output})")
    return "\n".join(lines)


def format_programs(programs: Iterable[Program]) -> str:
    """Several programs, each preceded by a comment giving its shape."""
    blocks = []
    for program in programs:
        graph = program.graph
        steps = len(program.steps)
        comment = f"; {program.name}: {graph.shape}, {steps} step{'s' * (steps != 1)}"
        blocks.append(comment + "\n" + format_program(program))
    return "\n\n".join(blocks) + "\n"


# --- JSON ----------------------------------------------------------------------------------


def arg_to_json(arg: Arg) -> Any:
    """A variable is its name; a literal is {"literal": value}, so the two never look alike."""
    return arg.name if isinstance(arg, Var) else {"literal": arg.value}


def program_to_json(program: Program) -> dict[str, Any]:
    graph = program.graph
    return {
        "name": program.name,
        "doc": program.doc,
        "inputs": list(program.inputs),
        "steps": [
            {
                "target": step.target,
                "function": step.function,
                "kind": step.kind,
                "args": [arg_to_json(a) for a in step.args],
                "keywords": {name: arg_to_json(value) for name, value in step.keywords},
            }
            for step in program.steps
        ],
        "output": program.output,
        "shape": graph.shape,
    }


# --- Graphviz DOT --------------------------------------------------------------------------


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def graph_to_dot(graphs: Iterable[DataflowGraph]) -> str:
    """One digraph with a cluster per program: inputs as ellipses, calls as boxes
    (schema calls with a double border), edges labelled with the variable they carry."""
    out = ["digraph schemas {", "  rankdir=LR;", '  node [fontname="Helvetica"];']
    for number, graph in enumerate(graphs):
        prefix = f"s{number}_"

        def ident(ref: InputRef | NodeRef, prefix: str = prefix) -> str:
            return prefix + (f"in_{ref.name}" if isinstance(ref, InputRef) else f"n{ref.index}")

        out.append(f"  subgraph cluster_{number} {{")
        out.append(f"    label={_quote(f'{graph.name} ({graph.shape})')};")
        for name in graph.inputs:
            out.append(f"    {ident(InputRef(name))} [shape=ellipse, label={_quote(name)}];")
        for index, node in enumerate(graph.nodes):
            constants = [f"{slot}={_source_text(s)}" for slot, s in _literals(node.sources())]
            label = node.function + ("\\n" + ", ".join(constants) if constants else "")
            border = ", peripheries=2" if node.kind == "schema" else ""
            out.append(f'    {ident(NodeRef(index))} [shape=box{border}, label="{label}"];')
        for edge in graph.edges:
            out.append(
                f"    {ident(edge.source)} -> {ident(NodeRef(edge.target))}"
                f" [label={_quote(edge.variable)}];"
            )
        out.append(f'    {prefix}output [shape=doublecircle, label="out"];')
        out.append(f"    {ident(graph.output)} -> {prefix}output;")
        out.append("  }")
    out.append("}")
    return "\n".join(out) + "\n"


def _literals(
    sources: Iterable[tuple[int | str, Source]],
) -> Iterable[tuple[int | str, Literal]]:
    return ((slot, s) for slot, s in sources if isinstance(s, Literal))


def _source_text(source: Literal) -> str:
    return format_literal(source.value).replace("\\", "\\\\").replace('"', '\\"')
