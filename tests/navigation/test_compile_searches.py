"""`compile_searches` loads every compiled search `anytime plan`'s options reach, so no
problem's time holds a search loaded from numba's cache (issue 36: the first problem of a
process took 13-15 ms, the next ones 0.2-0.6 ms, until the direct route's jump point search,
called from Python, was among those it loads)."""

from __future__ import annotations

import subprocess
import sys

PLAN = """
import numba
from pathlib import Path
from anytime.plugin import Context
from anytime_navigation.resources import data_file
from anytime_navigation.movingai import load_problems
from anytime_navigation.planning import corridor_search, following, search
from anytime_navigation.planning.abstraction import Pyramid
from anytime_navigation.planning.components import Components
from anytime_navigation.planning.planner import atp, compile_searches, map_options

compile_searches()

def signatures():
    return {
        (module.__name__, name): len(value.signatures)
        for module in (corridor_search, following, search)
        for name, value in vars(module).items()
        if isinstance(value, numba.core.dispatcher.Dispatcher)
    }

loaded = signatures()
assert sum(loaded.values()) > 10, loaded
maps = Path(str(data_file("maps")))
for name in ("random512-10-0.map", "8room_000.map", "maze512-1-0.map"):
    blocked, _, _, problems = load_problems(maps / name)
    options = dict(map_options(blocked))
    pyramid = Pyramid.build(blocked)
    components = Components.build(blocked, 8, top=options["top"])
    longest = sorted(problems, key=lambda p: -p.optimal)[:4]
    for problem in problems[:30] + longest:  # short ones (the direct route) and long ones
        plans = atp(
            Context(), problem.start, problem.goal, pyramid, movement=8,
            components=components, **options,
        )
        assert list(plans)
now = signatures()
print(sorted(key for key in now if now[key] != loaded[key]))
"""


def test_planning_after_compile_searches_loads_no_search() -> None:
    done = subprocess.run(
        [sys.executable, "-c", PLAN], capture_output=True, text=True, timeout=600, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
