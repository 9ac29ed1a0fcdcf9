"""The plugin API is narrow and cheap to import, and the bundled plugins are written as a third
party would write them: they import the framework only through `anytime` and `anytime.plugin`
(with its opt-in submodules), and importing one registers nothing."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import anytime_motion
import anytime_navigation
import anytime_routing
import pytest

import anytime.plugin
from anytime import AnytimeLibrary
from anytime.library import Plugin, PluginSource

#: The opt-in submodules of `anytime.plugin`.
SUBMODULES = (
    "anytime.plugin.cli",
    "anytime.plugin.figures",
    "anytime.plugin.compose",
    "anytime.plugin.solvers",
)
PUBLIC = {"anytime", "anytime.plugin", *SUBMODULES}
PLUGINS = {
    "navigation": Path(anytime_navigation.__file__).parent,
    "routing": Path(anytime_routing.__file__).parent,
    "motion": Path(anytime_motion.__file__).parent,
    # The test plugin, read where it lives (its tests install it as a user would).
    "estimation": Path(__file__).parent / "estimation_plugin" / "anytime_estimation",
}


def _framework_imports(path: Path) -> list[tuple[int, str]]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        found.extend((node.lineno, n) for n in names if n.split(".")[0] == "anytime")
    return found


@pytest.mark.parametrize("name", sorted(PLUGINS))
def test_a_bundled_plugin_imports_only_the_public_api(name: str) -> None:
    offenders = [
        f"{path.relative_to(PLUGINS[name])}:{line}: {module}"
        for path in sorted(PLUGINS[name].rglob("*.py"))
        for line, module in _framework_imports(path)
        if module not in PUBLIC
    ]
    assert offenders == []


@pytest.mark.parametrize("module", ["anytime.plugin", *SUBMODULES])
def test_the_plugin_api_exports_what_it_lists(module: str) -> None:
    api = importlib.import_module(module)
    missing = [n for n in api.__all__ if not hasattr(api, n)]
    assert missing == []
    assert len(set(api.__all__)) == len(api.__all__)


def test_the_plugin_api_is_narrow() -> None:
    """What a plugin declares with, no more; each name has one home (`InputError` is also
    where a command's other helpers are)."""
    assert len(anytime.plugin.__all__) <= 30
    assert {
        "interruptible",
        "contract",
        "elementary",
        "critical_event",
        "Result",
        "Context",
        "Instance",
        "ProblemSet",
        "Plugin",
        "CriticalEvent",
        "InputError",
    } <= set(anytime.plugin.__all__)
    homes: dict[str, list[str]] = {}
    for module in ["anytime.plugin", *SUBMODULES]:
        for name in importlib.import_module(module).__all__:
            homes.setdefault(name, []).append(module)
    assert {n: m for n, m in homes.items() if len(m) > 1} == {
        "InputError": ["anytime.plugin", "anytime.plugin.cli"]
    }


def test_importing_the_plugin_api_loads_no_command_line_and_no_figures() -> None:
    """`import anytime.plugin` (in a fresh process) imports no `anytime.cli` module, none of its
    opt-in submodules, not the runtime (the critical events are imported on first use), and
    neither matplotlib nor scipy.optimize."""
    code = (
        "import sys\n"
        "import anytime.plugin\n"
        "print(len(anytime.plugin.__all__))\n"
        "heavy = ('anytime.cli', 'anytime.plugin.', 'anytime.runtime',"
        " 'matplotlib', 'scipy.optimize')\n"
        "print(' '.join(sorted(m for m in sys.modules if m.startswith(heavy))))\n"
        "from anytime.plugin import CriticalEvent, critical_event\n"
        "print(critical_event.__module__, CriticalEvent.__module__)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    count, loaded, lazy = done.stdout.splitlines()
    assert int(count) <= 30
    assert loaded == ""
    assert lazy == "anytime.runtime.deadline anytime.runtime.deadline"


def test_importing_the_navigation_plugin_registers_nothing() -> None:
    code = (
        "import anytime_navigation.plugin\n"
        "from anytime import REGISTRY\n"
        "from anytime.runtime.deadline import EVENTS\n"
        "from anytime.measure.builder import registered_measurements\n"
        "print(len(REGISTRY), len(EVENTS), len(registered_measurements()))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout == "0 0 0\n"


def test_the_entry_point_gives_the_navigation_plugin_with_its_problem_sets() -> None:
    loaded = PluginSource().load()
    (plugin,) = [p for p in loaded.plugins if p.name == "navigation"]
    assert isinstance(plugin, Plugin)
    names = {m.name for m in plugin.modules}
    assert {"get-domain-description", "find-path", "a-star", "detour-left", "wait"} <= names
    measured = {m.name for m in plugin.modules if m.kind != "elementary"}
    assert set(plugin.problem_sets) == measured
    library = AnytimeLibrary.default()
    assert library.measurement("find-path") is plugin.problem_sets["find-path"]
    assert AnytimeLibrary.default(plugins=False).get("find-path") is None


def test_a_plugin_names_what_is_wrong_with_it() -> None:
    with pytest.raises(TypeError) as error:
        Plugin("p", modules=(42,))  # type: ignore[arg-type]
    assert str(error.value) == "Plugin.modules[0]: expected an anytime module, got 42 (int)"
    with pytest.raises(TypeError) as error:
        Plugin("p", problem_sets={"m": 42})  # type: ignore[dict-item]
    assert str(error.value) == (
        "Plugin.problem_sets['m']: expected a Measurement (Measurement.of(problems, time=...)),"
        " got int"
    )
