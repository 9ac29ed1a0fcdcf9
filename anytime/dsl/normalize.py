"""Syntax tree -> straight-line `Program`s, with the static checks of the language.

Each schema's body is flattened into steps by `anytime.dsl.flatten`; here are the checks of the
whole file (a schema defined twice, calls of unknown functions or with the wrong number of
arguments, recursion). Every semantic error found is collected with its place, and all of them
are raised together in one `SchemaError`.
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Collection, Iterable, Mapping, Sequence

from anytime.dsl.flatten import ProgramBuilder
from anytime.dsl.flatten import count as count  # re-exported: the compiler imports it from here
from anytime.dsl.nodes import SPECIAL_FORMS as SPECIAL_FORMS  # re-exported
from anytime.dsl.nodes import SchemaDef, SourceFile
from anytime.dsl.program import Program, SchemaFile
from anytime.dsl.source import Span
from anytime.dsl.steps import Call as CallStep
from anytime.dsl.steps import Map, Repeat, SchemaCall
from anytime.errors import Diagnostic, SchemaError
from anytime.text import suggest as suggest  # re-exported: the compiler imports it from here

#: Known functions: a name -> arity mapping (None: any number of arguments), or just names.
KnownFunctions = Mapping[str, int | None] | Collection[str]


def normalize(source: SourceFile, known_functions: KnownFunctions | None = None) -> SchemaFile:
    """Check a parsed file and return its programs in straight-line form.

    Args:
        source: the parsed file.
        known_functions: when given, a call to any other name (that is not a schema of this
            file) is an error that suggests the closest known name; with a mapping, the number
            of positional arguments is checked too.

    Raises:
        SchemaError: every static error found, in source order.
    """
    checker = _Checker(source)
    programs = checker.programs(known_functions)
    if checker.diagnostics:
        raise SchemaError(sorted(checker.diagnostics, key=lambda d: (d.line, d.column)))
    return SchemaFile(source.filename, programs, source=source.source)


#: How many errors of one file get a "did you mean" hint: each hint compares the name with
#: every known one, so a file of thousands of misspellings would take minutes to report.
MAX_HINTS = 20


class _Checker:
    def __init__(self, source: SourceFile) -> None:
        self.source = source
        self.diagnostics: list[Diagnostic] = []
        self.hints = 0

    def suggest(self, name: str, *known: Collection[str]) -> str:
        """`text.suggest`'s hint among the names of every collection of `known`, for the first
        `MAX_HINTS` errors of the file, then "" (at once: the names are not even gathered, so
        thousands of errors cost each a constant)."""
        if self.hints >= MAX_HINTS or not any(known):
            return ""
        self.hints += 1
        return suggest(name, itertools.chain(*known))

    def error(self, span: Span | None, message: str) -> None:
        self.diagnostics.append(self.source.source.diagnostic(message, span or Span(1, 1, 1, 2)))

    def programs(self, known_functions: KnownFunctions | None) -> tuple[Program, ...]:
        first_place: dict[str, Span] = {}
        schemas: list[SchemaDef] = []
        for schema in self.source.schemas:
            if schema.name in first_place:
                line = first_place[schema.name].line
                self.error(
                    schema.name_span, f"schema '{schema.name}' is already defined on line {line}"
                )
                continue
            first_place[schema.name] = schema.name_span
            schemas.append(schema)
        arity = {s.name: len(s.params) for s in schemas}
        programs = tuple(ProgramBuilder(self, schema, arity).build() for schema in schemas)
        self.check_calls(programs, arity, known_functions)
        self.check_recursion(programs)
        return programs

    def check_calls(
        self,
        programs: Iterable[Program],
        schema_arity: Mapping[str, int],
        known_functions: KnownFunctions | None,
    ) -> None:
        for program in programs:
            for step in program.walk():
                match step:
                    case SchemaCall():
                        self.check_schema_call(step, schema_arity[step.schema])
                    case CallStep() if known_functions is not None:
                        self.check_library_call(step, known_functions, schema_arity)
                    case Map() | Repeat() if known_functions is not None:
                        args = (step.items, *step.args) if isinstance(step, Map) else step.args
                        call = CallStep(
                            step.target, step.function, args, (), step.span, step.function_span
                        )
                        self.check_library_call(call, known_functions, schema_arity)

    def check_schema_call(self, step: SchemaCall, arity: int) -> None:
        if len(step.args) != arity:
            self.error(
                step.function_span,
                f"schema '{step.schema}' takes {count(arity)}, got {len(step.args)}",
            )

    def check_library_call(
        self, step: CallStep, known: KnownFunctions, schema_arity: Mapping[str, int]
    ) -> None:
        if step.function not in known:
            hint = self.suggest(step.function, known, schema_arity)
            self.error(step.function_span, f"unknown function '{step.function}'{hint}")
            return
        arity = known.get(step.function) if isinstance(known, Mapping) else None
        if arity is not None and len(step.args) != arity:
            self.error(
                step.function_span,
                f"function '{step.function}' takes {count(arity)}, got {len(step.args)}",
            )

    def check_recursion(self, programs: tuple[Program, ...]) -> None:
        """A schema may not call itself, directly or through other schemas. Only schemas on a
        cycle of the call graph (its strongly connected components, found once) are searched
        for their shortest cycle, so a long chain of calls is checked in linear time."""
        calls = {p.name: tuple(dict.fromkeys(p.callees())) for p in programs}
        component = _components(calls)
        reported: set[str] = set()
        for program in programs:
            name = program.name
            if name in reported or not _on_a_cycle(name, calls, component):
                continue
            path = self.find_cycle(name, calls, component)
            reported.update(path)
            step = next(
                s for s in program.walk() if isinstance(s, SchemaCall) and s.schema == path[1]
            )
            if len(path) == 2:
                self.error(step.function_span, f"schema '{name}' calls itself")
            else:
                chain = " -> ".join(path)
                self.error(
                    step.function_span,
                    f"schema '{name}' calls itself through other schemas: {chain}",
                )

    @staticmethod
    def find_cycle(
        start: str, calls: Mapping[str, Sequence[str]], component: Mapping[str, int]
    ) -> list[str]:
        """The shortest call path start -> ... -> start (breadth first within the strongly
        connected component of `start`, which holds every such path)."""
        mine = component[start]
        parent: dict[str, str] = {}
        queue = deque([start])
        while queue:
            here = queue.popleft()
            for callee in calls[here]:
                if callee == start:
                    path = [here]
                    while path[-1] != start:
                        path.append(parent[path[-1]])
                    return [*reversed(path), start]
                if callee not in parent and component.get(callee) == mine:
                    parent[callee] = here
                    queue.append(callee)
        raise AssertionError(f"no cycle through '{start}' in its component")  # unreachable


def _on_a_cycle(
    name: str, calls: Mapping[str, Sequence[str]], component: Mapping[str, int]
) -> bool:
    return name in calls[name] or any(component.get(c) == component[name] for c in calls[name])


def _components(calls: Mapping[str, Sequence[str]]) -> dict[str, int]:
    """Each schema's strongly connected component of the call graph (Tarjan's algorithm, with
    an explicit stack: a chain of thousands of calls must not reach Python's recursion limit)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    component: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    known = {name: [c for c in callees if c in calls] for name, callees in calls.items()}
    for root in calls:
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            callees = known[node]
            if i < len(callees):
                work.append((node, i + 1))
                callee = callees[i]
                if callee not in index:
                    work.append((callee, 0))
                elif callee in on_stack:
                    low[node] = min(low[node], index[callee])
                continue
            if low[node] == index[node]:  # the root of a component: pop it whole
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component[member] = index[node]
                    if member == node:
                        break
            if work:  # back in the caller: its low link takes the callee's
                caller = work[-1][0]
                low[caller] = min(low[caller], low[node])
    return component
