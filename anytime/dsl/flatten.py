"""One schema's body flattened into straight-line steps, in evaluation order (arguments left to
right, innermost first), each call's result in a fresh temporary; `(setf a b)` and `(setf n 4)`
only give a name to a value, so later uses see `b` or `4` directly. The errors of the body's
forms are reported, with their places, to the file's checker (`anytime.dsl.normalize`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Collection, Iterable, Mapping
from typing import Protocol

from anytime.dsl.nodes import (
    BestOfForm,
    Call,
    Expr,
    IfForm,
    MapForm,
    Number,
    RepeatForm,
    SchemaDef,
    Setf,
    SpecialForm,
    String,
    Symbol,
    WhenForm,
    expr_span,
    form_word,
)
from anytime.dsl.program import Program
from anytime.dsl.source import Span
from anytime.dsl.steps import (
    DEFAULT_MAX_ITEMS,
    Alternative,
    Arg,
    BestOf,
    Branch,
    If,
    Literal,
    Map,
    Repeat,
    SchemaCall,
    Step,
    Var,
    variables,
    walk,
)
from anytime.dsl.steps import Call as CallStep


class Reporter(Protocol):
    """Where a builder reports errors: the checker of the whole file."""

    def error(self, span: Span | None, message: str) -> None: ...

    def suggest(self, name: str, *known: Collection[str]) -> str: ...


class ProgramBuilder:
    """Flattens one schema's body into steps; reports errors through the checker."""

    def __init__(self, checker: Reporter, schema: SchemaDef, schema_arity: Mapping[str, int]):
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
        return Var(name) if isinstance(form.value, Call | SpecialForm) else value

    def expression(self, expr: Expr, name: str | None) -> Arg:
        """Flatten `expr`; a call's result goes to `name` or, when None, to a fresh temporary."""
        if isinstance(expr, Number | String):
            return Literal(expr.value)
        if isinstance(expr, Symbol):
            return self.lookup(expr)
        match expr:
            case BestOfForm():
                return self.best_of(expr, name)
            case IfForm():
                return self.conditional(expr, name)
            case MapForm():
                return self.mapping(expr, name)
            case RepeatForm():
                return self.repeat(expr, name)
            case WhenForm():
                self.checker.error(
                    expr.function_span,
                    "'when' is allowed only as an alternative of best-of: "
                    "(best-of (when PRECONDITION EXPR) ...)",
                )
                self.quiet_dead_code = True  # the uses inside it are not read
                for arg in (*expr.args, *(k.value for k in expr.keywords)):
                    self.expression(arg, None)
                return Var(name if name is not None else self.fresh())
        return self.call(expr, name)

    def call(self, call: Call, name: str | None) -> Var:
        args = tuple(self.expression(arg, None) for arg in call.args)
        target = name if name is not None else self.fresh()
        step: Step
        if call.function in self.schemas:
            for keyword in call.keywords:
                self.expression(keyword.value, None)
                self.checker.error(
                    call.function_span,
                    f"schema '{call.function}' takes no keyword arguments (got :{keyword.name})",
                )
            step = SchemaCall(target, call.function, args, call.span, call.function_span)
        else:
            keywords = tuple((k.name, self.expression(k.value, None)) for k in call.keywords)
            step = CallStep(target, call.function, args, keywords, call.span, call.function_span)
        self.steps.append(step)
        return Var(target)

    def nested(self, flatten: Callable[[], Arg]) -> tuple[tuple[Step, ...], Arg]:
        """Flatten an alternative's or a branch's expression into steps of its own."""
        outer, self.steps = self.steps, []
        try:
            value = flatten()
            return tuple(self.steps), value
        finally:
            self.steps = outer

    def best_of(self, call: BestOfForm, name: str | None) -> Var:
        """`(best-of (when PRE EXPR) ... EXPR [:dependence D])`: an alternative written without
        `when` is always applicable."""
        error = self.checker.error
        target = name if name is not None else self.fresh()
        dependence = 0.0
        for keyword in call.keywords:
            if keyword.name != "dependence":
                error(
                    keyword.span,
                    "best-of takes only the keyword :dependence, the probability that one draw"
                    f" decides all its alternatives (got :{keyword.name})",
                )
            elif not isinstance(keyword.value, Number) or not 0 <= keyword.value.value <= 1:
                error(
                    keyword.value.span,
                    "the :dependence of best-of must be a number in [0, 1] (the probability"
                    f" that one draw decides all its alternatives), got {written(keyword.value)}",
                )
            else:
                dependence = float(keyword.value.value)
        if not call.args:
            error(
                call.span,
                "best-of needs at least one alternative: (best-of (when PRECONDITION EXPR) ...)",
            )
        forms: list[tuple[Expr | None, Expr]] = []
        for form in call.args:
            if not isinstance(form, WhenForm):
                forms.append((None, form))  # unconditional
            elif len(form.args) != 2 or form.keywords:
                got = len(form.args) + len(form.keywords)
                error(
                    form.span,
                    "when takes a precondition and an expression: (when PRECONDITION EXPR), "
                    f"got {count(got)}",
                )
                self.quiet_dead_code = True  # the uses inside it are not read
            else:
                forms.append((form.args[0], form.args[1]))
        preconditions = [None if pre is None else self.precondition(pre) for pre, _ in forms]
        alternatives = []
        for test, (_, expr) in zip(preconditions, forms, strict=True):
            steps, value = self.nested(functools.partial(self.expression, expr, None))
            alternatives.append(Alternative(test, steps, value))
        self.steps.append(
            BestOf(target, tuple(alternatives), call.span, call.function_span, dependence)
        )
        return Var(target)

    def precondition(self, expr: Expr) -> CallStep | None:
        """A precondition is one call of an elementary function of variables and constants
        (whether the function is elementary is checked against the library by the compiler)."""
        error = self.checker.error
        if isinstance(expr, SpecialForm) or (
            isinstance(expr, Call) and expr.function in self.schemas
        ):
            name = form_word(expr) if isinstance(expr, SpecialForm) else expr.function
            error(
                expr.function_span,
                "the precondition of 'when' must be a call of an elementary function, "
                f"not of '{name}'",
            )
            self.quiet_dead_code = True
            self.nested(lambda: self.expression(expr, None))
            return None
        if not isinstance(expr, Call):
            what = "a variable" if isinstance(expr, Symbol) else "a constant"
            error(
                expr.span,
                f"the precondition of 'when' must be a call of an elementary function, not {what}",
            )
            self.expression(expr, None)
            return None
        for arg in expr.args:
            if isinstance(arg, Call | SpecialForm):
                error(
                    arg.span,
                    "the arguments of a precondition must be variables or constants "
                    "(a precondition is one cheap, elementary test)",
                )
        steps, value = self.nested(lambda: self.call(expr, None))
        assert isinstance(value, Var)
        *outside, test = steps  # nested calls (already reported) run before the test
        self.steps.extend(outside)
        assert isinstance(test, CallStep)
        return test

    def conditional(self, call: IfForm, name: str | None) -> Var:
        """`(if CONDITION THEN ELSE [:p P])`: the condition always runs; each branch's steps
        are nested in it."""
        error = self.checker.error
        target = name if name is not None else self.fresh()
        p: float | None = None
        for keyword in call.keywords:
            if keyword.name != "p":
                error(
                    keyword.span,
                    f"if takes only the keyword :p, the probability of the condition "
                    f"(got :{keyword.name})",
                )
            elif not isinstance(keyword.value, Number) or not 0 <= keyword.value.value <= 1:
                error(
                    keyword.value.span,
                    f"the :p of if must be a number in [0, 1] (the probability that the "
                    f"condition holds), got {written(keyword.value)}",
                )
            else:
                p = float(keyword.value.value)
        if len(call.args) != 3:
            return self.malformed(
                call.span,
                "if takes a condition, a then expression and an else expression: "
                f"(if CONDITION THEN ELSE [:p P]), got {count(len(call.args))}",
                call.args,
                target,
            )
        condition = self.expression(call.args[0], None)
        then = Branch(*self.nested(lambda: self.expression(call.args[1], None)))
        other = Branch(*self.nested(lambda: self.expression(call.args[2], None)))
        self.steps.append(If(target, condition, then, other, p, call.span, call.function_span))
        return Var(target)

    def mapping(self, form: MapForm, name: str | None) -> Var:
        """`(map FUNCTION ITEMS ARG... [:max K])`: FUNCTION is named, not evaluated; ITEMS and
        the other arguments are computed before the loop."""
        error = self.checker.error
        target = name if name is not None else self.fresh()
        most = DEFAULT_MAX_ITEMS
        for keyword in form.keywords:
            if keyword.name != "max":
                error(
                    keyword.span,
                    "map takes only the keyword :max, the most items its profile is compiled "
                    f"for (got :{keyword.name})",
                )
            elif whole(keyword.value) is None:
                error(
                    expr_span(keyword.value),
                    "the :max of map must be a whole number >= 1 (the most items its profile "
                    f"is compiled for), got {describe(keyword.value)}",
                )
            else:
                most = whole(keyword.value) or most
        if len(form.args) < 2:
            return self.malformed(
                form.span,
                "map takes a function and a collection: (map FUNCTION ITEMS ARG... "
                f"[:max K]), got {count(len(form.args))}",
                form.args[1:],
                target,
            )
        function = form.args[0]
        if not isinstance(function, Symbol):
            return self.malformed(
                expr_span(function),
                f"the function of 'map' must be the name of a module, not {describe(function)}",
                form.args[1:],
                target,
            )
        if function.name in self.schemas:
            error(
                function.span,
                f"map applies a module of the library, not the schema '{function.name}'",
            )
        items, *args = (self.expression(arg, None) for arg in form.args[1:])
        if isinstance(items, Literal):
            error(
                expr_span(form.args[1]),
                "the collection of 'map' must be a variable or a call, not a constant",
            )
        self.steps.append(
            Map(target, function.name, items, tuple(args), most, form.span, function.span)
        )
        return Var(target)

    def repeat(self, form: RepeatForm, name: str | None) -> Var:
        """`(repeat N (FUNCTION ARG...))`: N a whole number written in the schema; the call's
        arguments are computed before the loop."""
        error = self.checker.error
        target = name if name is not None else self.fresh()
        for keyword in form.keywords:
            error(keyword.span, f"repeat takes no keyword arguments (got :{keyword.name})")
        if len(form.args) != 2:
            return self.malformed(
                form.span,
                "repeat takes a count and a call: (repeat N (FUNCTION ARG...)), "
                f"got {count(len(form.args))}",
                form.args,
                target,
            )
        number, body = form.args
        n = whole(number)
        if n is None:
            hint = " (for a count known only at run time, map over a collection)"
            error(
                expr_span(number),
                f"the count of 'repeat' must be a whole number >= 1, got {describe(number)}"
                + (hint if isinstance(number, Symbol | Call) else ""),
            )
        if not isinstance(body, Call) or body.function in self.schemas or body.keywords:
            if not isinstance(body, Call):
                what = describe(body)
                message = f"the body of 'repeat' must be one call of a module, not {what}"
            elif body.keywords:
                message = (
                    "the call inside 'repeat' takes no keyword arguments "
                    f"(got :{body.keywords[0].name})"
                )
            else:
                message = f"repeat calls a module of the library, not the schema '{body.function}'"
            return self.malformed(expr_span(body), message, (body,), target)
        args = tuple(self.expression(arg, None) for arg in body.args)
        self.steps.append(
            Repeat(target, n or 1, body.function, args, form.span, body.function_span)
        )
        return Var(target)

    def malformed(self, span: Span, message: str, inside: Iterable[Expr], target: str) -> Var:
        """Report a malformed form; what it holds is flattened only to report the errors in
        it (its uses are not read, so no dead-code errors follow)."""
        self.checker.error(span, message)
        self.quiet_dead_code = True

        def flatten() -> Arg:
            for expr in inside:
                self.expression(expr, None)
            return Literal(0)

        self.nested(flatten)
        return Var(target)

    def lookup(self, symbol: Symbol) -> Arg:
        if symbol.name in self.values:
            return self.values[symbol.name]
        hint = self.checker.suggest(symbol.name, self.values.keys())
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
        steps = list(walk(tuple(self.steps)))
        needed = {output}
        for step in reversed(steps):
            if step.target in needed:
                needed.update(variables(step))
        for step in steps:
            if step.target not in needed and step.target in self.assigned_at:
                self.checker.error(
                    self.assigned_at[step.target],
                    f"variable '{step.target}' is assigned but never used",
                )


def whole(expr: Expr) -> int | None:
    """The value of a whole-number literal >= 1, else None."""
    if isinstance(expr, Number) and isinstance(expr.value, int) and expr.value >= 1:
        return expr.value
    return None


def describe(expr: Expr) -> str:
    """How an error names what was written: a number as written, else its kind."""
    match expr:
        case Number(value=value):
            return format(value)
        case Symbol(name=name):
            return f"the variable '{name}'"
        case String():
            return "a string"
        case Call():
            return "a call"
    return f"a {form_word(expr)} form"


def written(value: Expr) -> str:
    """How an error names a keyword's value: a number as written, else its kind."""
    if isinstance(value, Number):
        return format(value.value)
    return "a " + type(value).__name__.lower()


def count(n: int) -> str:
    """The phrase for n arguments: 1 argument, 2 arguments."""
    return f"{n} argument" if n == 1 else f"{n} arguments"
