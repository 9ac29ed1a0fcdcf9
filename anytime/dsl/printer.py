"""Programs out: straight-line DSL text (which parses back to the same program), JSON, DOT."""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any

from anytime.dsl.graph import DataflowGraph, InputRef, Node, NodeRef, Source
from anytime.dsl.program import ALWAYS, Arg, Literal, Program, Step, Var

INDENT = "  "


def format_literal(value: int | float | str) -> str:
    if isinstance(value, str):
        return '"' + re.sub(r'(["\\])', r"\\\1", value) + '"'
    return repr(value)


def format_arg(arg: Arg) -> str:
    return arg.name if isinstance(arg, Var) else format_literal(arg.value)


def format_call(step: Step, inline: Mapping[str, Step] | None = None) -> str:
    """A step as a call; a `best-of` or `if` step with its alternatives or branches written
    back as nested expressions (the steps in `inline`, those inside choices)."""
    inline = inline or {}

    def arg(a: Arg) -> str:
        if isinstance(a, Var) and a.name in inline:
            return format_call(inline[a.name], inline)
        return format_arg(a)

    if step.kind == "best-of":
        n = len(step.args) // 2
        whens = [
            arg(e) if p == ALWAYS else f"(when {arg(p)} {arg(e)})"
            for p, e in zip(step.args[:n], step.args[n:], strict=True)
        ]
        return "(" + " ".join(["best-of", *whens]) + ")"
    parts = [step.function, *(arg(a) for a in step.args)]
    parts += [f":{name} {arg(value)}" for name, value in step.keywords]
    return "(" + " ".join(parts) + ")"


def format_program(program: Program) -> str:
    """The program as a straight-line `defschema`; parsing it gives back an equal program.
    Steps inside a choice's alternatives or branches are written nested in the choice."""
    inline = {s.target: s for s in program.steps if s.branch is not None}
    lines = [f"(defschema {program.name} ({' '.join(program.inputs)})"]
    if program.doc is not None:
        lines.append(INDENT + format_literal(program.doc))
    lines += [
        f"{INDENT}(setf {s.target} {format_call(s, inline)})"
        for s in program.steps
        if s.branch is None
    ]
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


def step_to_json(step: Step) -> dict[str, Any]:
    """A step; a step inside a choice adds `branch`, and the choices name their parts:
    best-of `alternatives` [{"when", "value"}], if `condition`, `then`, `else`, `p`."""
    out: dict[str, Any] = {
        "target": step.target,
        "function": step.function,
        "kind": step.kind,
        "args": [arg_to_json(a) for a in step.args],
        "keywords": {name: arg_to_json(value) for name, value in step.keywords},
    }
    if step.kind == "best-of":
        n = len(step.args) // 2
        out["alternatives"] = [
            {"when": None if p == ALWAYS else arg_to_json(p), "value": arg_to_json(e)}
            for p, e in zip(step.args[:n], step.args[n:], strict=True)
        ]
    elif step.kind == "if" and len(step.args) == 3:
        p = dict(step.keywords).get("p")
        out["condition"], out["then"], out["else"] = (arg_to_json(a) for a in step.args)
        out["p"] = p.value if isinstance(p, Literal) else None
    if step.branch is not None:
        out["branch"] = {"choice": step.branch[0], "alternative": step.branch[1]}
    return out


def program_to_json(program: Program) -> dict[str, Any]:
    graph = program.graph
    return {
        "name": program.name,
        "doc": program.doc,
        "inputs": list(program.inputs),
        "steps": [step_to_json(step) for step in program.steps],
        "output": program.output,
        "shape": graph.shape,
    }


# --- Graphviz DOT --------------------------------------------------------------------------


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def graph_to_dot(graphs: Iterable[DataflowGraph]) -> str:
    """One digraph with a cluster per program: inputs as ellipses, calls as boxes
    (schema calls with a double border), choices (`best-of`, `if`) as diamonds whose incoming
    edges say what they carry (`when 1`, `alternative 1`, ...; `condition`, `then`, `else`),
    other edges labelled with the variable they carry."""
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
            constants = [
                f"{slot}={_source_text(s)}"
                for slot, s in _literals(node.sources())
                if not (node.kind == "best-of" and s == ALWAYS)  # an unconditional alternative
            ]
            label = node.function + ("\\n" + ", ".join(constants) if constants else "")
            border = ", peripheries=2" if node.kind == "schema" else ""
            shape = "diamond" if node.kind in ("best-of", "if") else "box"
            out.append(f'    {ident(NodeRef(index))} [shape={shape}{border}, label="{label}"];')
        for edge in graph.edges:
            role = _edge_role(graph.nodes[edge.target], edge.slot)
            text = edge.variable if role is None else f"{role}: {edge.variable}"
            out.append(
                f"    {ident(edge.source)} -> {ident(NodeRef(edge.target))} [label={_quote(text)}];"
            )
        out.append(f'    {prefix}output [shape=doublecircle, label="out"];')
        out.append(f"    {ident(graph.output)} -> {prefix}output;")
        out.append("  }")
    out.append("}")
    return "\n".join(out) + "\n"


def _edge_role(target: Node, slot: int | str) -> str | None:
    """What an argument of a choice is: a best-of's preconditions come first, then its
    alternatives (as many); an if's are its condition, then and else."""
    if not isinstance(slot, int):
        return None
    if target.kind == "best-of":
        n = len(target.args) // 2
        return f"when {slot + 1}" if slot < n else f"alternative {slot - n + 1}"
    if target.kind == "if":
        return ("condition", "then", "else")[slot] if slot < 3 else None
    return None


def _literals(
    sources: Iterable[tuple[int | str, Source]],
) -> Iterable[tuple[int | str, Literal]]:
    return ((slot, s) for slot, s in sources if isinstance(s, Literal))


def _source_text(source: Literal) -> str:
    return format_literal(source.value).replace("\\", "\\\\").replace('"', '\\"')
