"""`anytime compile` checks every call against the module it calls: the number of positional
arguments and the keywords, with the file, line and column (a wrong call compiled and then
failed at run time with a TypeError)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from anytime.compiler import compile_program
from anytime.dsl import parse_schemas
from anytime.errors import SchemaError
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, interruptible
from anytime.profiles import tabulate
from anytime.runtime import run_program

MODULES = Registry()
PROFILE = tabulate(
    lambda t, q: np.asarray(q) * np.minimum(1.0, np.asarray(t) / 10),
    [0, 10],
    input_grids=[[0.0, 1.0]],
    inputs=["x"],
)


@interruptible("plan", inputs=["x"], profile=PROFILE, registry=MODULES)
def plan(ctx: Context, x: Result, goal: object, levels: int = 2) -> Iterator[Result]:
    yield Result((x.value, goal, levels), x.quality)


def compile_text(text: str) -> object:
    schemas = parse_schemas(text, "calls.any")
    library = AnytimeLibrary.default(registry=MODULES, plugins=False)
    return compile_program(schemas["p"], library, [0, 10], source=schemas.source)


@pytest.mark.parametrize(
    ("call", "message", "column"),
    [
        ("(plan x)", "function 'plan': missing a required argument: 'goal'", 21),
        ("(plan x g 3 4)", "function 'plan': too many positional arguments", 21),
        ("(plan x g :level 3)", "function 'plan': got an unexpected keyword argument 'level'", 21),
    ],
    ids=["too few", "too many", "unknown keyword"],
)
def test_a_call_that_does_not_fit_its_module_is_an_error_at_its_place(
    call: str, message: str, column: int
) -> None:
    with pytest.raises(SchemaError) as raised:
        compile_text(f"(defschema p (x g) {call})")
    (diagnostic,) = raised.value.diagnostics
    assert (diagnostic.filename, diagnostic.line, diagnostic.column) == ("calls.any", 1, column)
    assert diagnostic.message == message


def test_a_call_with_a_keyword_the_module_takes_compiles() -> None:
    compiled = compile_text("(defschema p (x g) (plan x g :levels 3))")
    assert run_program(compiled, {"x": Result("map", 1.0), "g": "goal"}, 10).result.value == (
        "map",
        "goal",
        3,
    )
