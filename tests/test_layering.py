"""The layering rules of docs/architecture.md, checked on the source: every import statement
(at the top of a file or inside a function, absolute or relative) is read with `ast`.

The rule that a plugin imports only `anytime` and `anytime.plugin` is checked for the bundled
navigation plugin in tests/plugins/test_plugin_api.py; here it is checked for the docs' example
plugin, which docs/plugins.md tells readers to copy.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FRAMEWORK = ROOT / "anytime"

#: Top-level packages that are domains (plugins), never imported by the framework.
DOMAINS = ("anytime_navigation", "anytime_survey", "domains")


def imports(path: Path, root: Path) -> list[tuple[int, str]]:
    """(line, module) of every import in `path`, a file of the package tree under `root`;
    relative imports are resolved, and `from pkg import name` counts as importing `pkg.name`
    too (it may be a submodule)."""
    package = list(path.relative_to(root.parent).with_suffix("").parts)[:-1]
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                module = ".".join([*base, *([node.module] if node.module else [])])
            else:
                module = node.module or ""
            found.append((node.lineno, module))
            found.extend((node.lineno, f"{module}.{alias.name}") for alias in node.names)
    return found


def offenders(files: list[Path], root: Path, forbidden: tuple[str, ...]) -> list[str]:
    bad = []
    for path in files:
        for line, module in imports(path, root):
            if any(module == f or module.startswith(f + ".") for f in forbidden):
                bad.append(f"{path.relative_to(root.parent)}:{line}: imports {module}")
    return sorted(set(bad))


def sources(package: str) -> list[Path]:
    return sorted((FRAMEWORK.parent / package.replace(".", "/")).rglob("*.py"))


RULES = [
    ("the framework never imports a domain", "anytime", DOMAINS),
    ("the compiler never imports the runtime", "anytime.compiler", ("anytime.runtime",)),
    (
        "profiles import neither the compiler nor the library",
        "anytime.profiles",
        ("anytime.compiler", "anytime.library"),
    ),
    (
        "the DSL imports neither profiles nor the library",
        "anytime.dsl",
        ("anytime.profiles", "anytime.library"),
    ),
]


@pytest.mark.parametrize(("rule", "package", "forbidden"), RULES, ids=[r[0] for r in RULES])
def test_layering_rule(rule: str, package: str, forbidden: tuple[str, ...]) -> None:
    files = sources(package)
    assert files, f"no source files for {package}"
    assert offenders(files, FRAMEWORK, forbidden) == []


#: The lowest modules, which every layer imports: they import nothing of the framework but
#: the lowest modules listed before them (the clocks' unit is the vocabulary's).
LOWEST = ("errors.py", "text.py", "vocabulary.py", "clocks.py")


@pytest.mark.parametrize("name", LOWEST)
def test_the_lowest_modules_import_nothing_of_the_framework(name: str) -> None:
    below = tuple(f"anytime.{n.removesuffix('.py')}" for n in LOWEST[: LOWEST.index(name)])
    bad = offenders([FRAMEWORK / name], FRAMEWORK, ("anytime",))
    allowed = offenders([FRAMEWORK / name], FRAMEWORK, below) if below else []
    assert sorted(set(bad) - set(allowed)) == []


def test_the_example_plugin_imports_only_the_public_api() -> None:
    root = ROOT / "docs" / "example-plugin" / "anytime_survey"
    files = sorted(root.rglob("*.py"))
    assert files
    framework = [
        f"{path.name}:{line}: {module}"
        for path in files
        for line, module in imports(path, root)
        if module.split(".")[0] == "anytime"
        and module not in ("anytime", "anytime.plugin")
        and not module.startswith("anytime.plugin.")  # `from anytime.plugin import Result`
    ]
    assert framework == []


def test_the_checker_sees_what_it_should(tmp_path: Path) -> None:
    package = tmp_path / "pkg" / "sub"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    module = package / "mod.py"
    module.write_text(
        "import os\n"
        "from . import sibling\n"
        "from .. import runtime\n"
        "def f():\n"
        "    from anytime.runtime.executor import run\n"
    )
    found = {name for _, name in imports(module, tmp_path / "pkg")}
    assert {"os", "pkg.sub.sibling", "pkg.runtime", "anytime.runtime.executor"} <= found
    assert offenders([module], tmp_path / "pkg", ("pkg.runtime",)) != []
