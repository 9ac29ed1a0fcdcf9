"""One exception tree, and one place that turns errors into the command line's messages.

Every exception class of the framework (and of the bundled plugin) derives from `AnytimeError`;
no message raised anywhere carries the command line's `error:` prefix: `anytime.cli.describe`,
used by `main`, adds it.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
from pathlib import Path

import pytest
from conftest import Cli

import anytime.cli.schemas
from anytime.cli import describe
from anytime.cli.common import InputError, UsageError
from anytime.compiler import CompileError
from anytime.dsl import KnownFunctions, SchemaFile, load_schemas
from anytime.errors import AnytimeError, Diagnostic, ProfileError, SchemaError
from anytime.files import InputFileError

ROOT = Path(__file__).resolve().parent.parent
FRAMEWORK = ROOT / "anytime"
PLUGIN = ROOT / "domains" / "navigation" / "anytime_navigation"
#: The one module that formats errors for the command line.
MAIN = FRAMEWORK / "cli" / "__init__.py"


def python_files() -> list[Path]:
    return sorted([*FRAMEWORK.rglob("*.py"), *PLUGIN.rglob("*.py")])


def module_name(path: Path) -> str:
    root = FRAMEWORK.parent if path.is_relative_to(FRAMEWORK) else PLUGIN.parent
    return ".".join(path.relative_to(root).with_suffix("").parts).removesuffix(".__init__")


def test_no_module_but_the_command_lines_main_says_anytime_error() -> None:
    found = [
        f"{path.relative_to(ROOT)}:{number}"
        for path in python_files()
        if path != MAIN
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if "anytime: error" in line or re.search(r"anytime \w+: error", line)
    ]
    assert found == []


def _strings(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, text) of every string in the code, f-string pieces included, docstrings not."""
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    return [
        (node.lineno, node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str)
        if id(node) not in docstrings
    ]


def test_no_message_carries_an_error_prefix() -> None:
    """`FILE: error: ...`, `anytime: error: ...`: only the command line's main writes those,
    and a diagnostic (`FILE:LINE:COL: error: ...`, `Diagnostic.format`)."""
    allowed = {MAIN, FRAMEWORK / "errors.py"}
    found = [
        f"{path.relative_to(ROOT)}:{line}: {text!r}"
        for path in python_files()
        if path not in allowed
        for line, text in _strings(ast.parse(path.read_text(encoding="utf-8")))
        if re.search(r"(^|:\s*)error: ", text)
    ]
    assert found == []


def _exception_classes() -> list[type[BaseException]]:
    classes = []
    for path in python_files():
        if path.name == "__main__.py":
            continue
        module = importlib.import_module(module_name(path))
        for _, value in inspect.getmembers(module, inspect.isclass):
            if issubclass(value, BaseException) and value.__module__ == module.__name__:
                classes.append(value)
    return classes


#: Exceptions that are signals, not errors: A* reaching its expansion limit (the anytime
#: planner's deadline, caught where it is raised), the evaluator finding a DAG's joint outcomes
#: too many to enumerate (caught in `Evaluator.evaluate`, which samples them instead), and the
#: KeyboardInterrupts of a user's stop (SIGTERM to the command; an interrupted run carrying its
#: record to the caller), the stop `Report.check` raises into an external solver's callback (caught
#: by `on_improvement`); and warnings (a compiled program asked beyond its table, a dynamic
#: profile from another build than its profile).
SIGNALS = {
    "anytime.compiler.result.BeyondTableWarning",
    "anytime.entries.StaleProfileWarning",
    "anytime_navigation.planning.search.SearchLimit",
    "anytime.compiler.evaluate._Sample",
    "anytime.launch.Terminated",
    "anytime.runtime.records.RunInterrupted",
    "anytime.plugin.solvers._Stopped",
}


def test_every_exception_class_is_in_the_tree() -> None:
    classes = _exception_classes()
    assert len(classes) > 20  # the search finds them
    outside = {
        f"{c.__module__}.{c.__qualname__}" for c in classes if not issubclass(c, AnytimeError)
    }
    assert outside == SIGNALS


def test_errors_resemble_a_builtin_where_they_did_before_the_tree() -> None:
    from anytime.measure.calibrate import CalibrationError
    from anytime.runtime.deadline import DeadlineError, UnknownEventError

    for error, builtin in [
        (CalibrationError, ValueError),
        (DeadlineError, ValueError),
        (UnknownEventError, KeyError),
        (CompileError, ValueError),
        (ProfileError, ValueError),
        (InputFileError, OSError),
    ]:
        assert issubclass(error, AnytimeError) and issubclass(error, builtin), error


# --- describe: the messages main prints ---------------------------------------------------------


def test_describe_a_schema_error_is_its_diagnostics() -> None:
    error = SchemaError([Diagnostic("p.any", 2, 4, "unknown function 'f'", "  (f x)", 1)])
    assert describe(error, "compile") == "p.any:2:4: error: unknown function 'f'\n    (f x)\n     ^"


def test_describe_a_usage_error_names_the_command() -> None:
    assert describe(UsageError("--a needs --b"), "plan") == "anytime plan: error: --a needs --b"
    assert describe(UsageError("--a needs --b")) == "anytime: error: --a needs --b"


def test_describe_an_error_about_a_file_names_it_first() -> None:
    error = CompileError("time grid: expected increasing times", where="p.any")
    assert describe(error) == "p.any: error: time grid: expected increasing times"
    assert describe(InputError("bad", where="m.map:6")) == "m.map:6: error: bad"


def test_describe_any_other_error() -> None:
    assert describe(InputError("no module named 'x'")) == "anytime: error: no module named 'x'"
    assert describe(ProfileError("p.yaml: time: missing field")) == (
        "anytime: error: p.yaml: time: missing field"
    )
    assert describe(InputFileError("f.any", "not a regular file (a FIFO)")) == (
        "anytime: error: cannot read 'f.any': not a regular file (a FIFO)"
    )
    assert describe(FileNotFoundError(2, "No such file or directory", "f.any")) == (
        "anytime: error: cannot read 'f.any': No such file or directory"
    )
    assert describe(OSError(28, "No space left on device")) == (
        "anytime: error: cannot write the output: No space left on device"
    )
    assert describe(MemoryError()) == "anytime: error: out of memory"
    assert describe(ZeroDivisionError("division by zero\nmore")) == (
        "anytime: internal error: ZeroDivisionError: division by zero (a bug; please report it;"
        " ANYTIME_TRACEBACK=1 shows the traceback)"
    )


def test_where_survives_pickling() -> None:
    """Errors cross process boundaries (the profile builder's workers)."""
    import pickle

    error = pickle.loads(pickle.dumps(CompileError("m", where="p.any")))
    assert (type(error), str(error), error.where) == (CompileError, "m", "p.any")


@pytest.mark.parametrize("command", ["parse", "compile"])
def test_a_bad_file_is_reported_from_what_was_read_once(
    cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str
) -> None:
    """The place and the caret come from the text the file was parsed from: the file is
    deleted as soon as it is read, so reading it again to report the error would fail."""
    path = tmp_path / "bad.any"
    path.write_text("(defschema p (scene)\n  (find-pth scene))\n")
    reads: list[str] = []

    def load_once(file: str, known: KnownFunctions | None = None) -> SchemaFile:
        reads.append(file)
        try:
            return load_schemas(file, known)
        finally:
            path.unlink()

    monkeypatch.setattr(anytime.cli.schemas, "load_schemas", load_once)
    options = ["--check-calls"] if command == "parse" else ["--time-grid", "0:1000:250"]
    code, out, err = cli(command, str(path), *options)
    assert (code, out, reads) == (1, "", [str(path)])
    assert err == (
        f"{path}:2:4: error: unknown function 'find-pth'; did you mean 'find-path'?\n"
        "    (find-pth scene))\n"
        "     ^~~~~~~~\n"
    )
