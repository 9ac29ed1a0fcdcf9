"""The docs run: every code block of README.md and docs/*.md is a test (collected with sybil).

What each fenced block is, by its info string:

- ```` ```python ````: run in-process; the blocks of one page share their names, in page order.
  A block that starts with `>>>` is a doctest, so what it shows printed is checked (`...`
  stands for any text).
- ```` ```console ````: a shell session. Each `$ COMMAND` line (continued by a trailing
  backslash) runs with bash in the page's working directory, the installed `anytime` (this
  Python's environment) first on the PATH. It must exit with status 0; the lines that follow it
  up to the next `$` are what it prints, standard output and error together, checked like a
  doctest's (`...` stands for any text; trailing spaces are ignored). A command shown without
  output is not checked for any.
- ```` ```LANG file=PATH ````: the whole content of the file PATH (any language). When the page's
  working directory already holds PATH (a copy of a repository file), the block must equal it;
  otherwise the block is written there, as a reader would save it.
- ```` ```lisp ````: a schema snippet; it must parse.
- Anything else (`text`, `yaml`, `toml`, `json` without `file=`) is shown, not run.

Each page gets a fresh temporary working directory holding a copy of the repository files the
pages name (`COPIED`), so that the examples run as they would from the root of a checkout and
leave nothing behind. Python blocks run there too.
A block that must not run is preceded by `<!-- skip: next "why" -->`, and the page says why.
Modules registered by a page's Python blocks are unregistered when the page ends.
"""

from __future__ import annotations

import doctest
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pytest
from sybil import Document, Example, Region, Sybil
from sybil.parsers.markdown import CodeBlockParser, PythonCodeBlockParser, SkipParser
from sybil.parsers.markdown.lexers import RawFencedCodeBlockLexer

ROOT = Path(__file__).resolve().parent

#: Repository files the pages' examples use, copied into each page's working directory.
COPIED = (
    "schemas",
    "docs/example-plugin",
    "domains/navigation/anytime_navigation/schemas",
    "domains/navigation/anytime_navigation/maps",
)

#: The `anytime` command the shell blocks run: the one installed beside this Python.
BIN = Path(sys.executable).parent

#: How long one shell command may take.
TIMEOUT = 300

FLAGS = doctest.ELLIPSIS
_DOCDIR = "__docdir__"
_SAVED = "__saved_registries__"


# --- shell sessions --------------------------------------------------------------------------


def commands(source: str) -> list[tuple[str, str]]:
    """The (command, expected output) pairs of a console block."""
    found: list[tuple[str, list[str]]] = []
    continued = False
    for line in source.splitlines():
        if continued:
            found[-1] = (found[-1][0] + "\n" + line, found[-1][1])
            continued = line.endswith("\\")
        elif line.startswith("$ "):
            found.append((line[2:], []))
            continued = line.endswith("\\")
        elif found:
            found[-1][1].append(line)
        elif line.strip():
            raise ValueError(f"a console block starts with '$ COMMAND', not {line!r}")
    return [(command, "\n".join(lines).strip("\n")) for command, lines in found]


def shell_environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    env["COLUMNS"] = "100"  # argparse wraps --help to the terminal's width
    env.pop("PYTHONPATH", None)
    return env


def run_console(example: Example) -> str | None:
    workdir = example.namespace[_DOCDIR]
    for command, want in commands(example.parsed):
        done = subprocess.run(
            ["bash", "-c", command],
            cwd=workdir,
            env=shell_environment(),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            timeout=TIMEOUT,
        )
        got = "\n".join(line.rstrip() for line in done.stdout.splitlines()).strip("\n")
        if done.returncode != 0:
            return f"$ {command}\nexited with status {done.returncode}; it printed:\n{got}"
        if want and not doctest.OutputChecker().check_output(want + "\n", got + "\n", FLAGS):
            return f"$ {command}\nExpected:\n{want}\nGot:\n{got}"
    return None


# --- files -----------------------------------------------------------------------------------


class FileBlockParser:
    """```` ```LANG file=PATH ````: the content of a file, written or checked."""

    lexer = RawFencedCodeBlockLexer(
        info_pattern=re.compile(r"(?P<language>[\w-]+)[ \t]+file=(?P<file>\S+)[ \t]*$\n", re.M),
        mapping={"file": "file", "source": "source"},
    )

    def __call__(self, document: Document) -> Iterable[Region]:
        for region in self.lexer(document):
            region.parsed = (region.lexemes["file"], str(region.lexemes["source"]))
            region.evaluator = self.evaluate
            yield region

    @staticmethod
    def evaluate(example: Example) -> str | None:
        name, text = example.parsed
        path = Path(example.namespace[_DOCDIR]) / name
        if path.exists():
            actual = path.read_text(encoding="utf-8")
            if actual != text:
                return f"the block is not the content of {name}:\n" + "".join(
                    _diff(actual, text, name)
                )
            return None
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        return None


def _diff(actual: str, shown: str, name: str) -> Iterable[str]:
    import difflib

    return difflib.unified_diff(
        actual.splitlines(keepends=True),
        shown.splitlines(keepends=True),
        f"{name} (the file)",
        f"{name} (the page)",
    )


def parse_lisp(example: Example) -> str | None:
    from anytime import SchemaError, parse_schemas

    try:
        parse_schemas(str(example.parsed), f"{example.path}:{example.line}")
    except SchemaError as error:
        return f"the schema does not parse:\n{error}"
    return None


# --- one working directory per page ----------------------------------------------------------


def setup(namespace: dict[str, Any]) -> None:
    from anytime import REGISTRY, problems
    from anytime.runtime.deadline import EVENTS

    workdir = Path(tempfile.mkdtemp(prefix="anytime-docs-"))
    for name in COPIED:
        shutil.copytree(ROOT / name, workdir / name, ignore=shutil.ignore_patterns("*.egg-info"))
    namespace[_DOCDIR] = str(workdir)
    namespace["__name__"] = "__main__"  # as at the interactive prompt
    namespace[_SAVED] = (
        os.getcwd(),
        dict(REGISTRY._modules),
        dict(EVENTS._modules),
        dict(problems._MEASUREMENTS),
    )
    os.chdir(workdir)


def teardown(namespace: dict[str, Any]) -> None:
    from anytime import REGISTRY, problems
    from anytime.runtime.deadline import EVENTS

    cwd, modules, events, measurements = namespace.pop(_SAVED)
    os.chdir(cwd)
    for registry, saved in ((REGISTRY._modules, modules), (EVENTS._modules, events)):
        registry.clear()
        registry.update(saved)
    problems._MEASUREMENTS.clear()
    problems._MEASUREMENTS.update(measurements)
    shutil.rmtree(namespace.pop(_DOCDIR), ignore_errors=True)


pytest_collect_file = Sybil(
    parsers=[
        PythonCodeBlockParser(doctest_optionflags=FLAGS),
        CodeBlockParser(language="console", evaluator=run_console),
        CodeBlockParser(language="lisp", evaluator=parse_lisp),
        FileBlockParser(),
        SkipParser(),
    ],
    patterns=["README.md", "docs/*.md"],
    excludes=["docs/example-plugin/*"],
    setup=setup,
    teardown=teardown,
).pytest()


# --- parallel runs ---------------------------------------------------------------------------

#: Files of long, independent tests that `make test` spreads over its workers (see below).
SPREAD = frozenset(
    {
        "tests/compiler/test_multistart.py",
        "tests/compiler/test_shared_results.py",
        "tests/dsl/test_properties.py",
        "tests/profiles/test_crashed_trials.py",
        "tests/routing/test_routing.py",
    }
)


@pytest.hookimpl(optionalhook=True)  # a pytest-xdist hook: unknown without it (-p no:xdist)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """Under pytest-xdist's `--dist loadfile` (what `make test` runs), the tests of one file run
    on one worker, in file order (a page's blocks share their names; a module's fixtures are
    built once), but the tests of a file of `SPREAD` are scheduled one by one, so that one long
    file does not keep one worker busy after the others are done. The largest files start first,
    the spread tests last."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class Scheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return nodeid if path in SPREAD else path

    return Scheduling(config, log)
