"""Loading the plugins, which every `anytime` command does (its parser lists their commands),
imports none of the heavy libraries the navigation domain needs only once it plans: numba
(the compiled searches) and scipy.ndimage (with scipy.sparse, which the abstraction's build
used until 3b629d1, about a second together: `anytime --help` took 3.2 s with them, 1.2 s
without)."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("numba", "scipy.ndimage", "scipy.sparse")
#: What planning loads (the check above would pass if the names were wrong): not scipy.sparse.
PLANNING = ("numba", "scipy.ndimage")

LOAD = f"""
import sys
from anytime.cli import build_parser
build_parser()
assert 'anytime_navigation.plugin' in sys.modules, 'the plugin was not loaded'
print([name for name in {HEAVY!r} if name in sys.modules])
"""


def test_loading_the_plugins_imports_no_heavy_library() -> None:
    done = subprocess.run(
        [sys.executable, "-c", LOAD], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_a_plan_imports_them() -> None:
    """The check above would pass if the module names were wrong: planning loads them."""
    plan = (
        "import sys\n"
        "from anytime_navigation.planning.planner import compile_searches\n"
        "compile_searches()\n"
        f"print([name for name in {PLANNING!r} if name not in sys.modules])\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", plan], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
