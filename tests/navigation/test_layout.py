"""The navigation plugin's layout: its subpackages are layered, the shared base (world, resources)
below planning, planning below the moving obstacles, both below the task; the plugin's face at
the top (plugin, modules, figures, cli) is imported by none of them at import time."""

from __future__ import annotations

import ast
from pathlib import Path

import anytime_navigation

PACKAGE = Path(anytime_navigation.__file__).parent

#: What each subpackage may import from the plugin at module level (besides itself).
ALLOWED = {
    "planning": {"world"},
    "obstacles": {"world", "resources", "planning"},
    "task": {"world", "resources", "planning", "obstacles"},
}


def _top_level_imports(path: Path, package: str) -> set[str]:
    """The plugin's modules or subpackages `path` (in `package`) imports at module level (not
    inside a function)."""
    found: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if not isinstance(node, ast.ImportFrom):
            continue
        module = node.module or ""
        if node.level == 1:
            found.add(package)
        elif node.level == 2:
            found.add(module.split(".")[0] if module else node.names[0].name)
        elif module.startswith("anytime_navigation."):
            found.add(module.split(".")[1])
    return found


def test_the_subpackages_are_layered() -> None:
    for package, allowed in ALLOWED.items():
        for path in sorted((PACKAGE / package).glob("*.py")):
            outside = _top_level_imports(path, package) - allowed - {package}
            assert not outside, f"{package}/{path.name} imports {sorted(outside)}"


def test_the_modules_are_grouped() -> None:
    top = {p.stem for p in PACKAGE.glob("*.py")}
    assert top == {
        "__init__",
        "figures",
        "modules",
        "movingai",
        "plugin",
        "program_problems",
        "resources",
        "world",
    }
    assert {p.name for p in PACKAGE.iterdir() if p.is_dir() and p.name != "__pycache__"} == {
        "cli",
        "maps",
        "obstacles",
        "planning",
        "profiles",
        "schemas",
        "task",
    }
