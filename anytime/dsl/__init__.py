"""The program-schema language: grammar, parser, straight-line normal form, dataflow graph."""

from __future__ import annotations

import os

from anytime.dsl.graph import DataflowGraph, Edge, InputRef, Node, NodeRef
from anytime.dsl.normalize import KnownFunctions, normalize
from anytime.dsl.parser import MAX_NESTING, decode_source, parse_syntax
from anytime.dsl.printer import format_program, format_programs, graph_to_dot, program_to_json
from anytime.dsl.program import (
    Alternative,
    BestOf,
    Branch,
    Call,
    If,
    Literal,
    Program,
    SchemaCall,
    SchemaFile,
    Step,
    Var,
)
from anytime.files import MAX_SCHEMA_BYTES, read_input

__all__ = [
    "MAX_NESTING",
    "Alternative",
    "BestOf",
    "Branch",
    "Call",
    "If",
    "SchemaCall",
    "DataflowGraph",
    "Edge",
    "InputRef",
    "KnownFunctions",
    "Literal",
    "Node",
    "NodeRef",
    "Program",
    "SchemaFile",
    "Step",
    "Var",
    "format_program",
    "format_programs",
    "graph_to_dot",
    "load_schemas",
    "parse_schemas",
    "program_to_json",
]


def parse_schemas(
    text: str, filename: str = "<string>", known_functions: KnownFunctions | None = None
) -> SchemaFile:
    """Parse and check schema source text.

    Raises:
        SchemaSyntaxError: the text does not follow the grammar.
        SchemaError: the schemas are well-formed but wrong (undefined variable, recursion...).
    """
    return normalize(parse_syntax(text, filename), known_functions)


def load_schemas(
    path: str | os.PathLike[str], known_functions: KnownFunctions | None = None
) -> SchemaFile:
    """Read, parse and check a schema file; errors name the file as it was given.

    Raises:
        InputFileError: the file is not a regular file, or is larger than `MAX_SCHEMA_BYTES`
            (it is not read).
        OSError: the file cannot be read.
        SchemaError: as `parse_schemas`, or the file is not UTF-8 text.
    """
    filename = os.fspath(path)
    text = decode_source(read_input(path, limit=MAX_SCHEMA_BYTES, kind="schema files"), filename)
    return parse_schemas(text, filename, known_functions)
