"""The straight-line normal form of a schema: a `Program` of typed steps.

Zilberstein & Russell compile straight-line programs, "a sequence of expressions of the form
(setf u (f v1 ... vn)) where u is a new variable and v1 ... vn are program arguments or existing
variables"; nested calls map one-to-one onto such code. Every schema is normalised into this form
(see `normalize`), so the compiler and the runtime see one shape only.

A step is one of six kinds, one class each (`anytime.dsl.steps`, whose names this module
re-exports): a `Call`, a `SchemaCall`, a `BestOf`, an `If`, a `Map` and a `Repeat`.
"""

from __future__ import annotations

from collections.abc import Iterator

from attrs import Factory, field, frozen

from anytime.dsl.graph import DataflowGraph
from anytime.dsl.source import Source, Span
from anytime.dsl.steps import (
    DEFAULT_MAX_ITEMS,
    Alternative,
    Arg,
    BestOf,
    Branch,
    Call,
    If,
    Literal,
    Map,
    Repeat,
    SchemaCall,
    Step,
    Var,
    inner_steps,
    reads,
    variables,
    walk,
)

#: The step names, re-exported: passes import them from here or from `anytime.dsl.steps`.
__all__ = [
    "Alternative",
    "Arg",
    "BestOf",
    "Branch",
    "Call",
    "DEFAULT_MAX_ITEMS",
    "If",
    "Literal",
    "Map",
    "Program",
    "Repeat",
    "SchemaCall",
    "SchemaFile",
    "Step",
    "Var",
    "inner_steps",
    "reads",
    "variables",
    "walk",
]


@frozen
class Program:
    """A schema in straight-line form: inputs, steps in execution order (the steps of a
    choice nested inside it), one output variable."""

    name: str
    inputs: tuple[str, ...]
    steps: tuple[Step, ...]
    output: str
    doc: str | None = None
    span: Span | None = field(default=None, eq=False, repr=False)

    @property
    def graph(self) -> DataflowGraph:
        return DataflowGraph.from_program(self)

    def walk(self) -> Iterator[Step]:
        """Every step of the program, nested ones included, in execution order."""
        return walk(self.steps)

    def step(self, target: str) -> Step:
        """The step that assigns `target` (nested or not)."""
        for step in self.walk():
            if step.target == target:
                return step
        raise KeyError(target)

    def callees(self) -> tuple[str, ...]:
        """Names of the schemas this program calls, in order of first call."""
        return tuple(dict.fromkeys(s.schema for s in self.walk() if isinstance(s, SchemaCall)))


@frozen
class SchemaFile:
    """All the programs of one schema file, in the order they are written."""

    filename: str
    programs: tuple[Program, ...]
    #: The file's name and text, for diagnostics about it (`normalize` sets it; without it,
    #: diagnostics name the file but show no source line).
    source: Source = field(
        default=Factory(lambda self: Source(self.filename, ""), takes_self=True),
        eq=False,
        repr=False,
        kw_only=True,
    )

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.programs)

    def __getitem__(self, name: str) -> Program:
        for program in self.programs:
            if program.name == name.lower():
                return program
        raise KeyError(name)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.lower() in self.names

    def __iter__(self) -> Iterator[Program]:
        return iter(self.programs)

    def __len__(self) -> int:
        return len(self.programs)

    def dependency_order(self) -> tuple[Program, ...]:
        """Programs with every callee before its callers: the order to compile them bottom-up."""
        done: dict[str, Program] = {}

        def visit(program: Program) -> None:
            if program.name in done:
                return
            for callee in program.callees():
                visit(self[callee])
            done[program.name] = program

        for program in self.programs:
            visit(program)
        return tuple(done.values())
