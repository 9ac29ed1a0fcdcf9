"""The layering rules of docs/architecture.md, checked on the source: every import statement
(at the top of a file or inside a function, absolute or relative) is read with `ast`.

The rule that a plugin imports only `anytime` and `anytime.plugin` (with its opt-in submodules)
is checked for the bundled plugins in tests/plugins/test_plugin_api.py; here it is checked for
the docs' example plugin, which docs/plugins.md tells readers to copy.
"""

from __future__ import annotations

import ast
import importlib
from itertools import pairwise
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FRAMEWORK = ROOT / "anytime"

#: The opt-in submodules of the plugin API, public as `anytime.plugin` is.
PLUGIN_SUBMODULES = (
    "anytime.plugin.cli",
    "anytime.plugin.figures",
    "anytime.plugin.compose",
    "anytime.plugin.solvers",
)

#: Top-level packages that are domains (plugins), never imported by the framework.
DOMAINS = ("anytime_navigation", "anytime_motion", "anytime_survey", "domains")


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
    """The files of `package`, a package (its whole tree) or a module (one file)."""
    path = FRAMEWORK.parent / package.replace(".", "/")
    module = path.with_suffix(".py")
    return [module] if module.is_file() else sorted(path.rglob("*.py"))


def parts() -> list[str]:
    """The framework's top-level parts: its subpackages and its modules (`cli`, `library`...),
    not the package's own `__init__`."""
    return sorted(
        path.stem if path.is_file() else path.name
        for path in FRAMEWORK.iterdir()
        if (path.suffix == ".py" and path.stem != "__init__")
        or (path.is_dir() and (path / "__init__.py").is_file())
    )


def above(*allowed: str) -> tuple[str, ...]:
    """Every top-level part of the framework but the lowest modules and `allowed`: what a
    layer that may import only those must not import."""
    below = {*LOWEST_PARTS, *allowed}
    return tuple(f"anytime.{part}" for part in parts() if part not in below)


#: What every layer may import (`LOWEST` below, and `files`, which imports only `errors`).
LOWEST_PARTS = ("errors", "text", "vocabulary", "clocks", "files")

#: The library's modules: the library, its entries, and where it finds them.
LIBRARY = ("library", "entries", "sources")

#: What sits above the measuring layer: nothing below it imports these.
TOP = ("anytime.cli", "anytime.launch", "anytime.plugin", "anytime.testing")


RULES = [
    ("the framework never imports a domain", "anytime", DOMAINS),
    ("the DSL imports nothing above it", "anytime.dsl", above("dsl")),
    ("profiles import nothing above them", "anytime.profiles", above("profiles")),
    (
        "the module protocol imports nothing above profiles",
        "anytime.modules",
        above("modules", "profiles"),
    ),
    (
        "the problem declarations import nothing above the module protocol",
        "anytime.problems",
        above("problems", "modules", "profiles"),
    ),
    *[
        (
            f"the library ({part}) imports neither the compiler, the runtime, measure nor the CLI",
            f"anytime.{part}",
            (
                "anytime.compiler",
                "anytime.runtime",
                "anytime.measure",
                "anytime.verification",
                *TOP,
            ),
        )
        for part in LIBRARY
    ],
    (
        "the compiler imports neither the runtime, measure nor the CLI",
        "anytime.compiler",
        ("anytime.runtime", "anytime.measure", "anytime.verification", *TOP),
    ),
    (
        "the runtime imports neither measure, the library nor the CLI",
        "anytime.runtime",
        ("anytime.measure", *(f"anytime.{part}" for part in LIBRARY), "anytime.verification", *TOP),
    ),
    (
        "measure imports neither verification nor the CLI",
        "anytime.measure",
        ("anytime.verification", *TOP),
    ),
    ("verification does not import the CLI", "anytime.verification", TOP),
]


@pytest.mark.parametrize(("rule", "package", "forbidden"), RULES, ids=[r[0] for r in RULES])
def test_layering_rule(rule: str, package: str, forbidden: tuple[str, ...]) -> None:
    files = sources(package)
    assert files, f"no source files for {package}"
    assert offenders(files, FRAMEWORK, forbidden) == []


def test_only_the_command_line_its_entry_point_and_the_plugin_api_import_the_cli() -> None:
    users = ("anytime/cli/", "anytime/plugin/", "anytime/plugin.py", "anytime/launch.py")
    files = [
        path for path in sources("anytime") if not str(path.relative_to(ROOT)).startswith(users)
    ]
    assert offenders(files, FRAMEWORK, ("anytime.cli",)) == []


#: The entry points, which import the command line on purpose (lazily, inside `main`) and are
#: the top of the graph, not a layer; the package's `__init__` (its lazy public names) is not a
#: part either.
ENTRY_POINTS = ("__main__", "launch")


def part_graph(root: Path) -> dict[str, dict[str, str]]:
    """part -> part it imports -> where (the first `file:line`), for the top-level parts of
    the package at `root` (its subpackages and modules), from every import of every file."""
    package = root.name
    names = {p.stem if p.is_file() else p.name for p in root.iterdir()}
    graph: dict[str, dict[str, str]] = {}
    for path in sorted(root.rglob("*.py")):
        source = path.relative_to(root).with_suffix("").parts[0]
        if source in ("__init__", *ENTRY_POINTS):
            continue
        edges = graph.setdefault(source, {})
        for line, module in imports(path, root):
            head, _, rest = module.partition(".")
            target = rest.split(".")[0]
            if head == package and target in names and target not in (source, *ENTRY_POINTS):
                edges.setdefault(target, f"{path.relative_to(root.parent)}:{line}")
    return graph


def find_cycle(graph: dict[str, dict[str, str]]) -> list[str]:
    """One cycle of `graph` as `a -> b (where)` edges, or [] when it is acyclic."""
    state: dict[str, str] = {}  # "open" while on the path, "done" after
    path: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = "open"
        path.append(node)
        for target in sorted(graph.get(node, {})):
            if state.get(target) == "open":
                cycle = [*path[path.index(target) :], target]
                return [f"{a} -> {b} ({graph[a][b]})" for a, b in pairwise(cycle)]
            if target not in state and (found := visit(target)):
                return found
        path.pop()
        state[node] = "done"
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


def test_no_cycle_among_the_frameworks_parts() -> None:
    graph = part_graph(FRAMEWORK)
    assert {"dsl", "profiles", "compiler", "runtime", "measure", "library", "cli"} <= set(graph)
    cycle = find_cycle(graph)
    assert cycle == [], "a cycle among anytime's parts:\n  " + "\n  ".join(cycle)


def test_the_cycle_finder_finds_a_cycle(tmp_path: Path) -> None:
    root = tmp_path / "pkg"
    (root / "low").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "low" / "__init__.py").write_text("")
    (root / "low" / "data.py").write_text("def f():\n    from pkg.high import g\n")
    (root / "high.py").write_text("from pkg.low.data import f\nimport os\n")
    (root / "other.py").write_text("from pkg import high\n")
    graph = part_graph(root)
    assert graph == {
        "high": {"low": "pkg/high.py:1"},
        "low": {"high": "pkg/low/data.py:2"},
        "other": {"high": "pkg/other.py:1"},
    }
    assert find_cycle(graph) == ["high -> low (pkg/high.py:1)", "low -> high (pkg/low/data.py:2)"]
    del graph["low"]
    assert find_cycle(graph) == []


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
    public = ("anytime", "anytime.plugin", *PLUGIN_SUBMODULES)
    exported = {f"{m}.{n}" for m in public for n in importlib.import_module(m).__all__}
    framework = [
        f"{path.name}:{line}: {module}"
        for path in files
        for line, module in imports(path, root)
        if module.split(".")[0] == "anytime"
        and module not in public
        and module not in exported  # `from anytime.plugin import Result`
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
