"""anytime-compose: build real-time systems out of anytime algorithms.

Write a program schema in the DSL, describe its modules by conditional performance profiles,
compile it into a contract algorithm with optimal time allocation, and run it under a monitor.
"""

from anytime.dsl import (
    DataflowGraph,
    Program,
    SchemaFile,
    Step,
    format_program,
    load_schemas,
    parse_schemas,
)
from anytime.errors import (
    AnytimeError,
    Diagnostic,
    SchemaError,
    SchemaSyntaxError,
)

__version__ = "0.1.0"

__all__ = [
    "AnytimeError",
    "DataflowGraph",
    "Diagnostic",
    "Program",
    "SchemaError",
    "SchemaFile",
    "SchemaSyntaxError",
    "Step",
    "__version__",
    "format_program",
    "load_schemas",
    "parse_schemas",
]
