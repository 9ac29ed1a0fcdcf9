"""A compiled program saved and loaded back from Python: the same tables, the same runs, and a
clear error for a file that does not fit the library it is loaded against."""

from __future__ import annotations

from pathlib import Path

import attrs
import numpy as np
import pytest
import yaml
from choice_modules import TIME, gamble, library

from anytime.clocks import WorkClock
from anytime.compiler import (
    Code,
    CompiledProgram,
    CompileError,
    compile_file,
    load_compiled,
    save_compiled,
)
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.profiles.io import load_profile
from anytime.runtime import Budget, run_program

FILE = """(defschema pick (w)
  (best-of (when (left-clear? w) (steady)) (when (right-clear? w) (gamble))))

(defschema weather (w)
  (if (sunny? w) (steady) (gamble)))

(defschema outer (w)
  (pick w))
"""


def compiled(name: str, lib: AnytimeLibrary) -> CompiledProgram:
    programs = compile_file(parse_schemas(FILE, "choices.any"), lib, TIME, schema=name)
    return programs[-1]


@pytest.mark.parametrize("name", ["pick", "weather", "outer"])
def test_a_saved_program_loads_back_with_its_tables_and_runs_the_same(
    name: str, tmp_path: Path
) -> None:
    lib = library(steady=0.6, gamble=0.9)
    original = compiled(name, lib)
    path = tmp_path / f"{name}.yaml"
    save_compiled(original, path)
    loaded = load_compiled(path, lib)
    assert load_profile(path) == original.profile  # still a profile file
    np.testing.assert_array_equal(loaded.allocation, original.allocation)
    np.testing.assert_array_equal(loaded.expected, original.expected)
    assert (loaded.allocator, loaded.exact, loaded.dp_obstacle, loaded.warnings) == (
        original.allocator,
        original.exact,
        original.dp_obstacle,
        original.warnings,
    )
    assert (loaded.notes, loaded.note) == (original.notes, original.note)
    assert loaded.modules == original.modules
    for key, table in original.baselines.items():
        np.testing.assert_array_equal(loaded.baselines[key], table)
    for inputs in (["left right sun"], ["left"], ["right"], ["rain"]):
        for total in (0.0, 3.0, 10.0):
            again = run_program(loaded, inputs, Budget(total, clock=WorkClock()))
            first = run_program(original, inputs, Budget(total, clock=WorkClock()))
            assert (again.result, again.status, again.allocations) == (
                first.result,
                first.status,
                first.allocations,
            )


def test_a_changed_profile_is_refused(tmp_path: Path) -> None:
    lib = library()
    path = tmp_path / "pick.yaml"
    save_compiled(compiled("pick", lib), path)
    changed = library()
    entry = changed["gamble"]
    faster = attrs.evolve(gamble(), time=gamble().time * 2)
    changed.add(
        LibraryEntry.of_module(attrs.evolve(entry.module, profile_source=faster)), replace=True
    )
    with pytest.raises(CompileError) as raised:
        load_compiled(path, changed)
    assert (raised.value.where, str(raised.value)) == (
        str(path),
        "compiled.profiles.gamble: module 'gamble' has a profile other than the one the program "
        "was compiled against: compile it again",
    )


def test_a_plain_profile_is_not_a_compiled_program(tmp_path: Path) -> None:
    path = tmp_path / "steady.yaml"
    save_compiled(compiled("pick", library()), path)
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    del data["compiled"]
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(CompileError) as raised:
        load_compiled(path, library())
    assert str(raised.value) == (
        "compiled: missing (a profile, not a compiled program: expected a file written by "
        "`anytime compile -o` or save_compiled)"
    )


def test_a_file_saved_before_the_codes_loads_with_its_sentences(tmp_path: Path) -> None:
    """A file without `codes` (saved before them) has its notes as sentences only: its
    obstacle to dp is found again where it reads the same, any other sentence is kept."""
    lib = library()
    original = compiled("pick", lib)
    assert original.dp_obstacle is not None
    path = tmp_path / "pick.yaml"
    save_compiled(original, path)
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert data["compiled"]["dp_obstacle"] == original.dp_obstacle.message
    del data["compiled"]["codes"]
    data["compiled"]["warnings"] = ["a sentence of an older compiler"]
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    loaded = load_compiled(path, lib)
    assert (loaded.dp_obstacle, loaded.note) == (original.dp_obstacle, original.note)
    assert [(w.code, w.message) for w in loaded.warnings] == [
        (Code.TEXT, "a sentence of an older compiler")
    ]
    data["compiled"]["dp_obstacle"] = "an obstacle worded otherwise"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    obstacle = load_compiled(path, lib).dp_obstacle
    assert obstacle is not None
    assert (obstacle.code, obstacle.message) == (Code.TEXT, "an obstacle worded otherwise")
