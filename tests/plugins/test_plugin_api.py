"""The bundled plugins are written as a third party would write them: they import the framework
only through its public plugin API, and importing one registers nothing."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import anytime_navigation
import anytime_routing
import pytest

import anytime.plugin
from anytime import AnytimeLibrary
from anytime.library import Plugin, PluginSource

PUBLIC = {"anytime", "anytime.plugin"}
PLUGINS = {
    "navigation": Path(anytime_navigation.__file__).parent,
    "routing": Path(anytime_routing.__file__).parent,
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


def test_the_plugin_api_exports_what_it_lists() -> None:
    missing = [n for n in anytime.plugin.__all__ if not hasattr(anytime.plugin, n)]
    assert missing == []


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
