"""Programs out: straight-line DSL text (which parses back to the same program), JSON, DOT."""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

from anytime.dsl.graph import DataflowGraph, InputRef, Node, NodeRef, Source
from anytime.dsl.program import (
    DEFAULT_MAX_ITEMS,
    Arg,
    BestOf,
    Call,
    If,
    Literal,
    Map,
    Program,
    Repeat,
    SchemaCall,
    Step,
    Var,
)

INDENT = "  "


def format_literal(value: int | float | str) -> str:
    if isinstance(value, str):
        return '"' + re.sub(r'(["\\])', r"\\\1", value) + '"'
    return repr(value)


def format_arg(arg: Arg) -> str:
    return arg.name if isinstance(arg, Var) else format_literal(arg.value)


def format_step(step: Step) -> str:
    """A step's right-hand side as an expression; the steps nested in a choice's alternatives
    or branches written back inside it."""
    match step:
        case Call(function=function, args=args, keywords=keywords):
            parts = [function, *(format_arg(a) for a in args)]
            parts += [f":{name} {format_arg(value)}" for name, value in keywords]
        case SchemaCall(schema=schema, args=args):
            parts = [schema, *(format_arg(a) for a in args)]
        case BestOf(alternatives=alternatives, dependence=dependence):
            parts = ["best-of"]
            for alternative in alternatives:
                value = _nested(alternative.steps, alternative.value)
                test = alternative.precondition
                parts.append(value if test is None else f"(when {format_step(test)} {value})")
            if dependence:
                parts.append(f":dependence {format_literal(dependence)}")
        case If(condition=condition, then=then, else_=other, p=p):
            parts = ["if", format_arg(condition)]
            parts += [_nested(then.steps, then.value), _nested(other.steps, other.value)]
            if p is not None:
                parts.append(f":p {format_literal(p)}")
        case Map(function=function, items=items, args=args, max_items=most):
            parts = ["map", function, *(format_arg(a) for a in (items, *args))]
            if most != DEFAULT_MAX_ITEMS:
                parts.append(f":max {most}")
        case Repeat(function=function, count=n, args=args):
            parts = ["repeat", str(n), "(" + " ".join([function, *map(format_arg, args)]) + ")"]
    return "(" + " ".join(parts) + ")"


def _nested(steps: tuple[Step, ...], value: Arg) -> str:
    """The expression that computes `value` from nested steps (each used once, in place)."""
    by_target = {s.target: s for s in steps}

    def expression(arg: Arg) -> str:
        if not (isinstance(arg, Var) and arg.name in by_target):
            return format_arg(arg)
        step = by_target[arg.name]
        match step:
            case Call(function=function, args=args, keywords=keywords):
                parts = [function, *(expression(a) for a in args)]
                parts += [f":{name} {expression(v)}" for name, v in keywords]
                return "(" + " ".join(parts) + ")"
            case SchemaCall(schema=schema, args=args):
                return "(" + " ".join([schema, *(expression(a) for a in args)]) + ")"
            case _:
                return format_step(step)

    return expression(value)


def format_program(program: Program) -> str:
    """The program as a straight-line `defschema`; parsing it gives back an equal program.
    Steps inside a choice's alternatives or branches are written nested in the choice."""
    lines = [f"(defschema {program.name} ({' '.join(program.inputs)})"]
    if program.doc is not None:
        lines.append(INDENT + format_literal(program.doc))
    lines += [f"{INDENT}(setf {s.target} {format_step(s)})" for s in program.steps]
    lines.append(f"{INDENT}{program.output})")
    return "\n".join(lines)


def format_programs(programs: Iterable[Program]) -> str:
    """Several programs, each preceded by a comment giving its shape."""
    blocks = []
    for program in programs:
        graph = program.graph
        steps = sum(1 for _ in program.walk())
        comment = f"; {program.name}: {graph.shape}, {steps} step{'s' * (steps != 1)}"
        blocks.append(comment + "\n" + format_program(program))
    return "\n\n".join(blocks) + "\n"


# --- JSON ----------------------------------------------------------------------------------


def arg_to_json(arg: Arg) -> Any:
    """A variable is its name; a literal is {"literal": value}, so the two never look alike."""
    return arg.name if isinstance(arg, Var) else {"literal": arg.value}


def step_to_json(step: Step) -> dict[str, Any]:
    """A step by its kind: a call's `function`, `args` and `keywords`; a schema call's
    `schema` and `args`; a best-of's `alternatives` [{"when", "steps", "value"}]; an if's
    `condition`, `then` and `else` ({"steps", "value"}) and `p`; a map's `function`, `items`,
    `args` and `max`; a repeat's `count`, `function` and `args`."""
    out: dict[str, Any] = {"target": step.target}
    match step:
        case Call(function=function, args=args, keywords=keywords):
            out |= {
                "kind": "call",
                "function": function,
                "args": [arg_to_json(a) for a in args],
                "keywords": {name: arg_to_json(value) for name, value in keywords},
            }
        case SchemaCall(schema=schema, args=args):
            out |= {"kind": "schema", "schema": schema, "args": [arg_to_json(a) for a in args]}
        case BestOf(alternatives=alternatives, dependence=dependence):
            out["kind"] = "best-of"
            out["dependence"] = dependence
            out["alternatives"] = [
                {
                    "when": None if a.precondition is None else step_to_json(a.precondition),
                    "steps": [step_to_json(s) for s in a.steps],
                    "value": arg_to_json(a.value),
                }
                for a in alternatives
            ]
        case If(condition=condition, then=then, else_=other, p=p):
            out |= {
                "kind": "if",
                "condition": arg_to_json(condition),
                "then": _branch_to_json(then.steps, then.value),
                "else": _branch_to_json(other.steps, other.value),
                "p": p,
            }
        case Map(function=function, items=items, args=args, max_items=most):
            out |= {
                "kind": "map",
                "function": function,
                "items": arg_to_json(items),
                "args": [arg_to_json(a) for a in args],
                "max": most,
            }
        case Repeat(function=function, count=n, args=args):
            out |= {
                "kind": "repeat",
                "count": n,
                "function": function,
                "args": [arg_to_json(a) for a in args],
            }
    return out


def _branch_to_json(steps: tuple[Step, ...], value: Arg) -> dict[str, Any]:
    return {"steps": [step_to_json(s) for s in steps], "value": arg_to_json(value)}


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
    loops (`map`, `repeat`) as stacked boxes (a map's collection edge says `items`), other
    edges labelled with the variable they carry."""
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
            border = ", peripheries=2" if isinstance(node.step, SchemaCall) else ""
            shape = (
                "diamond"
                if isinstance(node.step, BestOf | If)
                else "box3d"
                if isinstance(node.step, Map | Repeat)
                else "box"
            )
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
    """What an argument of a choice is: its label ("when 1", "alternative 1"; "condition",
    "then", "else"), and a map's collection "items"; a call's arguments are labelled by the
    variable alone."""
    if isinstance(target.step, BestOf | If) and isinstance(slot, str):
        return slot
    if isinstance(target.step, Map) and slot == 0:
        return "items"
    return None


def _literals(
    sources: Iterable[tuple[int | str, Source]],
) -> Iterable[tuple[int | str, Literal]]:
    return ((slot, s) for slot, s in sources if isinstance(s, Literal))


def _source_text(source: Literal) -> str:
    return format_literal(source.value).replace("\\", "\\\\").replace('"', '\\"')
