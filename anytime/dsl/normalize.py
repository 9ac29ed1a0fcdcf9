"""Syntax tree -> straight-line `Program`s, with the static checks of the language.

Nested calls are flattened in evaluation order (arguments left to right, innermost first) into
steps whose targets are fresh temporaries; `(setf a b)` and `(setf n 4)` only give a name to a
value, so later uses see `b` or `4` directly. Every semantic error found is collected with its
place, and all of them are raised together in one `SchemaError`.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable, Mapping

from anytime.dsl.nodes import Call, Expr, Number, SchemaDef, Setf, SourceFile, Span, String, Symbol
from anytime.dsl.program import ALWAYS, Arg, Branch, Literal, Program, SchemaFile, Step, Var
from anytime.errors import Diagnostic, SchemaError
from anytime.text import suggest as suggest  # re-exported: the compiler imports it from here

#: The special forms: choices among alternatives and conditionals, not functions.
SPECIAL_FORMS = ("best-of", "if", "when")

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


class _Checker:
    def __init__(self, source: SourceFile) -> None:
        self.source = source
        self.diagnostics: list[Diagnostic] = []

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
        programs = tuple(_ProgramBuilder(self, schema, arity).build() for schema in schemas)
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
            for step in program.steps:
                if step.kind == "schema":
                    self.check_schema_call(step, schema_arity[step.function])
                elif step.kind == "call" and known_functions is not None:
                    self.check_library_call(step, known_functions, schema_arity)

    def check_schema_call(self, step: Step, arity: int) -> None:
        if len(step.args) != arity:
            self.error(
                step.function_span,
                f"schema '{step.function}' takes {count(arity)}, got {len(step.args)}",
            )
        for name, _ in step.keywords:
            self.error(
                step.function_span,
                f"schema '{step.function}' takes no keyword arguments (got :{name})",
            )

    def check_library_call(
        self, step: Step, known: KnownFunctions, schema_arity: Mapping[str, int]
    ) -> None:
        if step.function not in known:
            hint = suggest(step.function, [*known, *schema_arity])
            self.error(step.function_span, f"unknown function '{step.function}'{hint}")
            return
        arity = known.get(step.function) if isinstance(known, Mapping) else None
        if arity is not None and len(step.args) != arity:
            self.error(
                step.function_span,
                f"function '{step.function}' takes {count(arity)}, got {len(step.args)}",
            )

    def check_recursion(self, programs: tuple[Program, ...]) -> None:
        """A schema may not call itself, directly or through other schemas."""
        by_name = {p.name: p for p in programs}
        reported: set[str] = set()
        for program in programs:
            path = self.find_cycle(program.name, by_name)
            if path is None or program.name in reported:
                continue
            reported.update(path)
            step = next(s for s in program.steps if s.kind == "schema" and s.function == path[1])
            if len(path) == 2:
                self.error(step.function_span, f"schema '{program.name}' calls itself")
            else:
                chain = " -> ".join(path)
                self.error(
                    step.function_span,
                    f"schema '{program.name}' calls itself through other schemas: {chain}",
                )

    @staticmethod
    def find_cycle(start: str, by_name: Mapping[str, Program]) -> list[str] | None:
        """The shortest call path start -> ... -> start, if there is one (breadth first)."""
        paths = [[start]]
        seen: set[str] = set()
        while paths:
            path = paths.pop(0)
            for callee in by_name[path[-1]].callees():
                if callee == start:
                    return [*path, start]
                if callee not in seen:
                    seen.add(callee)
                    paths.append([*path, callee])
        return None


class _ProgramBuilder:
    """Flattens one schema's body into steps; reports errors through the checker."""

    def __init__(self, checker: _Checker, schema: SchemaDef, schema_arity: Mapping[str, int]):
        self.checker = checker
        self.schema = schema
        self.schemas = schema_arity
        self.values: dict[str, Arg] = {}  # what each name in scope stands for
        self.assigned_at: dict[str, Span] = {}
        self.steps: list[Step] = []
        self.taken = {p.name for p in schema.params} | {
            form.target for form in schema.body if isinstance(form, Setf)
        }
        self.counter = 0
        self.branch: Branch | None = None  # the alternative or branch being flattened
        # Dead-code errors would only repeat an undefined-variable one, or follow from a
        # malformed alternative whose uses were never read.
        self.quiet_dead_code = False

    def build(self) -> Program:
        schema, error = self.schema, self.checker.error
        for param in schema.params:
            if param.name in self.values:
                error(param.span, f"parameter '{param.name}' appears twice")
            self.values[param.name] = Var(param.name)
        output: Arg = Literal(0)
        if not schema.body:
            error(schema.name_span, f"schema '{schema.name}' has an empty body")
        for index, form in enumerate(schema.body):
            last = index == len(schema.body) - 1
            if isinstance(form, Setf):
                output = self.assign(form)
            elif last:
                output = self.expression(form, name=None)
                if isinstance(output, Literal):
                    error(
                        form.span,
                        "the output of a schema must be a variable or a call, not a constant",
                    )
            else:
                error(
                    form.span,
                    "this value is never used: assign it with (setf VAR ...) or remove it",
                )
        output_name = output.name if isinstance(output, Var) else ""
        if not self.quiet_dead_code:
            self.check_all_used(output_name)
        return Program(
            name=schema.name,
            inputs=tuple(dict.fromkeys(p.name for p in schema.params)),
            steps=tuple(self.steps),
            output=output_name,
            doc=schema.doc,
            span=schema.span,
        )

    def assign(self, form: Setf) -> Arg:
        error = self.checker.error
        name = form.target
        value = self.expression(form.value, name=name)
        if any(p.name == name for p in self.schema.params):
            error(form.target_span, f"cannot assign '{name}': it is a parameter of the schema")
        elif name in self.assigned_at:
            line = self.assigned_at[name].line
            error(form.target_span, f"variable '{name}' is already assigned on line {line}")
        else:
            self.assigned_at[name] = form.target_span
            self.values[name] = value
        return Var(name) if isinstance(form.value, Call) else value

    def expression(self, expr: Expr, name: str | None) -> Arg:
        """Flatten `expr`; a call's result goes to `name` or, when None, to a fresh temporary."""
        if isinstance(expr, Number | String):
            return Literal(expr.value)
        if isinstance(expr, Symbol):
            return self.lookup(expr)
        return self.call(expr, name)

    def call(self, call: Call, name: str | None) -> Var:
        if call.function == "best-of":
            return self.best_of(call, name)
        if call.function == "if":
            return self.conditional(call, name)
        if call.function == "when":
            self.checker.error(
                call.function_span,
                "'when' is allowed only as an alternative of best-of: "
                "(best-of (when PRECONDITION EXPR) ...)",
            )
        args = tuple(self.expression(arg, None) for arg in call.args)
        keywords = tuple((k.name, self.expression(k.value, None)) for k in call.keywords)
        target = name if name is not None else self.fresh()
        kind = "schema" if call.function in self.schemas else "call"
        self.steps.append(
            Step(
                target,
                call.function,
                args,
                keywords,
                kind,
                call.span,
                call.function_span,
                self.branch,
            )
        )
        return Var(target)

    def within(self, branch: Branch, expr: Expr, flatten: Callable[[Expr], Arg]) -> Arg:
        """Flatten `expr` with its steps tagged as inside `branch`."""
        outer, self.branch = self.branch, branch
        try:
            return flatten(expr)
        finally:
            self.branch = outer

    def best_of(self, call: Call, name: str | None) -> Var:
        """`(best-of (when PRE EXPR) ... EXPR)`: every precondition first, then every
        alternative; the step's arguments are the preconditions' results (`ALWAYS` for an
        alternative written without `when`, which is always applicable), then the
        alternatives' values."""
        error = self.checker.error
        target = name if name is not None else self.fresh()
        for keyword in call.keywords:
            error(keyword.span, f"best-of takes no keyword arguments (got :{keyword.name})")
        if not call.args:
            error(
                call.span,
                "best-of needs at least one alternative: (best-of (when PRECONDITION EXPR) ...)",
            )
        forms: list[tuple[int, Expr | None, Expr]] = []
        for index, form in enumerate(call.args):
            if not (isinstance(form, Call) and form.function == "when"):
                forms.append((index, None, form))  # unconditional
            elif len(form.args) != 2 or form.keywords:
                got = len(form.args) + len(form.keywords)
                error(
                    form.span,
                    "when takes a precondition and an expression: (when PRECONDITION EXPR), "
                    f"got {count(got)}",
                )
                self.quiet_dead_code = True  # the uses inside it are not read
            else:
                forms.append((index, form.args[0], form.args[1]))
        preconditions = [
            ALWAYS if pre is None else self.within((target, i), pre, self.precondition)
            for i, pre, _ in forms
        ]
        alternatives = [
            self.within((target, i), expr, lambda e: self.expression(e, None))
            for i, _, expr in forms
        ]
        self.steps.append(
            Step(
                target,
                "best-of",
                (*preconditions, *alternatives),
                (),
                "best-of",
                call.span,
                call.function_span,
                self.branch,
            )
        )
        return Var(target)

    def precondition(self, expr: Expr) -> Arg:
        """A precondition is one call of an elementary function of variables and constants
        (whether the function is elementary is checked against the library by the compiler)."""
        error = self.checker.error
        if not isinstance(expr, Call):
            what = "a variable" if isinstance(expr, Symbol) else "a constant"
            error(
                expr.span,
                f"the precondition of 'when' must be a call of an elementary function, not {what}",
            )
            return self.expression(expr, None)
        if expr.function in SPECIAL_FORMS or expr.function in self.schemas:
            error(
                expr.function_span,
                "the precondition of 'when' must be a call of an elementary function, "
                f"not of '{expr.function}'",
            )
        for arg in expr.args:
            if isinstance(arg, Call):
                error(
                    arg.span,
                    "the arguments of a precondition must be variables or constants "
                    "(a precondition is one cheap, elementary test)",
                )
        return self.call(expr, None)

    def conditional(self, call: Call, name: str | None) -> Var:
        """`(if CONDITION THEN ELSE [:p P])`: the condition always runs; each branch's steps
        are tagged with its index (0: then, 1: else)."""
        error = self.checker.error
        target = name if name is not None else self.fresh()
        keywords: list[tuple[str, Arg]] = []
        for keyword in call.keywords:
            if keyword.name != "p":
                error(
                    keyword.span,
                    f"if takes only the keyword :p, the probability of the condition "
                    f"(got :{keyword.name})",
                )
            elif not isinstance(keyword.value, Number) or not 0 <= keyword.value.value <= 1:
                got = (
                    format(keyword.value.value)
                    if isinstance(keyword.value, Number)
                    else "a " + type(keyword.value).__name__.lower()
                )
                error(
                    keyword.value.span,
                    f"the :p of if must be a number in [0, 1] (the probability that the "
                    f"condition holds), got {got}",
                )
            else:
                keywords.append(("p", Literal(keyword.value.value)))
        if len(call.args) != 3:
            error(
                call.span,
                "if takes a condition, a then expression and an else expression: "
                f"(if CONDITION THEN ELSE [:p P]), got {count(len(call.args))}",
            )
            args: tuple[Arg, ...] = tuple(self.expression(a, None) for a in call.args)
        else:
            condition = self.expression(call.args[0], None)
            then = self.within((target, 0), call.args[1], lambda e: self.expression(e, None))
            other = self.within((target, 1), call.args[2], lambda e: self.expression(e, None))
            args = (condition, then, other)
        self.steps.append(
            Step(
                target,
                "if",
                args,
                tuple(keywords),
                "if",
                call.span,
                call.function_span,
                self.branch,
            )
        )
        return Var(target)

    def lookup(self, symbol: Symbol) -> Arg:
        if symbol.name in self.values:
            return self.values[symbol.name]
        hint = suggest(symbol.name, self.values) if self.values else ""
        if not hint.startswith(";"):
            hint = ""  # listing every variable in scope would be noise
        self.checker.error(symbol.span, f"undefined variable '{symbol.name}'{hint}")
        self.quiet_dead_code = True
        self.values[symbol.name] = Var(symbol.name)  # report each undefined name once
        return Var(symbol.name)

    def fresh(self) -> str:
        while True:
            self.counter += 1
            name = f"t{self.counter}"
            if name not in self.taken:
                self.taken.add(name)
                return name

    def check_all_used(self, output: str) -> None:
        """A step whose result never reaches the output is dead code: almost always a mistake."""
        needed = {output}
        for step in reversed(self.steps):
            if step.target in needed:
                needed.update(step.variables())
        for step in self.steps:
            if step.target not in needed and step.target in self.assigned_at:
                self.checker.error(
                    self.assigned_at[step.target],
                    f"variable '{step.target}' is assigned but never used",
                )


def _span_of(expr: Expr) -> Span:
    return expr.span


def count(n: int) -> str:
    """The phrase for n arguments: 1 argument, 2 arguments."""
    return f"{n} argument" if n == 1 else f"{n} arguments"
