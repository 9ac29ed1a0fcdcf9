"""A tampered compiled file is refused by `load_compiled` with the rules `anytime plot` reads it
by: every table of the program's shape and of numbers, allocations finite and >= 0, baselines
qualities, standard errors finite and >= 0, a resolution > 0 with a bounded lattice, known
allocators. Each error is a `CompileError` whose `where` is the file and whose message names
the field and the first bad cell; nothing tampered is run."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import pytest
import yaml
from choice_modules import TIME, library
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.compiler import CompiledProgram, CompileError, compile_file, save_compiled
from anytime.compiler.storage import MAX_LATTICE, load_compiled
from anytime.dsl import parse_schemas
from anytime.errors import AnytimeError
from anytime.library import AnytimeLibrary

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

FILE = """(defschema pick (w)
  (best-of (when (left-clear? w) (steady)) (when (right-clear? w) (gamble))))

(defschema outer (w)
  (pick w))
"""


@cache
def _library() -> AnytimeLibrary:
    return library()


@cache
def _outer() -> CompiledProgram:
    """`outer` calls `pick`: its table (11 totals x 1 module) is the file's, `pick`'s (11 x 2)
    is nested under compiled.callees.pick."""
    return compile_file(parse_schemas(FILE, "choices.any"), _library(), TIME, schema="outer")[-1]


def _saved(directory: Path) -> tuple[Path, dict[str, Any]]:
    path = directory / "outer.yaml"
    save_compiled(_outer(), path)
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert (len(data["allocation"]), len(data["allocation"][0])) == (11, 1)
    return path, data


def _refused(path: Path, data: dict[str, Any]) -> tuple[str | None, str]:
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(CompileError) as raised:
        load_compiled(path, _library())
    return raised.value.where, str(raised.value)


def _set(data: dict[str, Any], keys: str, value: Any) -> None:
    """Set the entry at the dotted path `keys` (integers index lists)."""
    *parents, last = keys.split(".")
    node: Any = data
    for key in parents:
        node = node[int(key)] if isinstance(node, list) else node[key]
    node[int(last) if isinstance(node, list) else last] = value


NAN, INF = float("nan"), float("inf")

CASES = [
    ("allocation.3.0", NAN, "allocation[3][0]: expected a finite time >= 0, got .nan"),
    ("allocation.3.0", -1, "allocation[3][0]: expected a finite time >= 0, got -1"),
    ("allocation.10.0", INF, "allocation[10][0]: expected a finite time >= 0, got .inf"),
    (
        "allocation.3",
        [1, 2],
        "allocation: expected a table of numbers, got a ragged or non-numeric table",
    ),
    (
        "allocation.3.0",
        "one",
        "allocation: expected a table of numbers, got a ragged or non-numeric table",
    ),
    ("allocation", None, "allocation: expected a table of numbers, got nothing"),
    (
        "allocation",
        [[0]] * 10,
        "allocation: expected a table of shape [11, 1] (input grids, time, one per module),"
        " got [10, 1]",
    ),
    ("modules", INF, "modules: expected ['pick'] (the program's), got inf"),
    (
        "compiled.callees.pick.modules",
        True,
        "compiled.callees.pick.modules: expected ['steady', 'gamble'] (the program's), got True",
    ),
    (
        "compiled.callees.pick.allocation.4.1",
        NAN,
        "compiled.callees.pick.allocation[4][1]: expected a finite time >= 0, got .nan",
    ),
    (
        "compiled.callees.pick.allocation.4",
        [1],
        "compiled.callees.pick.allocation: expected a table of numbers, got a ragged or"
        " non-numeric table",
    ),
    (
        "compiled.baselines.equal.2",
        NAN,
        "compiled.baselines.equal[2]: expected a quality in [0, 1], got .nan",
    ),
    (
        "compiled.baselines.max.5",
        1.5,
        "compiled.baselines.max[5]: expected a quality in [0, 1], got 1.5",
    ),
    (
        "compiled.baselines.min",
        [0.5] * 3,
        "compiled.baselines.min: expected shape [11] (input grids, time), got [3]",
    ),
    (
        "compiled.resolution",
        -1,
        "compiled.resolution: expected a finite number > 0 (the allocations' time step), got -1",
    ),
    (
        "compiled.resolution",
        NAN,
        "compiled.resolution: expected a finite number > 0 (the allocations' time step), got .nan",
    ),
    (
        "compiled.resolution",
        "fine",
        "compiled.resolution: expected a finite number > 0 (the allocations' time step),"
        " got 'fine'",
    ),
    (
        "compiled.resolution",
        1e-300,
        "compiled.resolution: expected at most 1,000,000 multiples of it up to the largest"
        " total 10, got 1e-300 (1e+301 points)",
    ),
    (
        "compiled.callees.pick.resolution",
        0,
        "compiled.callees.pick.resolution: expected a finite number > 0 (the allocations'"
        " time step), got 0",
    ),
    (
        "compiled.standard_error",
        [0.0] * 10 + [NAN],
        "compiled.standard_error[10]: expected a finite number >= 0, got .nan",
    ),
    (
        "compiled.standard_error",
        [[0.0]],
        "compiled.standard_error: expected shape [11] (input grids, time), got [1, 1]",
    ),
    (
        "compiled.allocator",
        "oracle",
        "compiled.allocator: expected one of ['hill-climbing', 'exhaustive', 'dp',"
        " 'proportional', 'multi-start'], got 'oracle'",
    ),
    (
        "compiled.requested",
        7,
        "compiled.requested: expected one of ['auto', 'hill-climbing', 'exhaustive', 'dp',"
        " 'proportional', 'multi-start'], got 7",
    ),
    (
        "compiled.exhaustive_gap",
        INF,
        "compiled.exhaustive_gap: expected a finite number or null, got inf",
    ),
    (
        "compiled.kept_smaller",
        ["ten"],
        "compiled.kept_smaller: expected a table of numbers, got a ragged or non-numeric table",
    ),
    (
        "compiled.kept_smaller",
        [3, -2],
        "compiled.kept_smaller[1]: expected a finite total >= 0, got -2",
    ),
]


@pytest.mark.parametrize(("keys", "value", "message"), CASES)
def test_a_tampered_field_is_refused_naming_the_file_and_the_field(
    tmp_path: Path, keys: str, value: Any, message: str
) -> None:
    path, data = _saved(tmp_path)
    _set(data, keys, value)
    assert _refused(path, data) == (str(path), message)


def test_the_untampered_file_loads(tmp_path: Path) -> None:
    path, _ = _saved(tmp_path)
    loaded = load_compiled(path, _library())
    assert (loaded.resolution, loaded.allocator, sorted(loaded.baselines)) == (
        1.0,
        "exhaustive",
        ["equal", "max", "min"],
    )
    assert MAX_LATTICE == 1_000_000


def test_a_tampered_nested_profile_is_named_once(tmp_path: Path) -> None:
    path, data = _saved(tmp_path)
    data["compiled"]["callees"]["pick"]["profile"]["time"][5] = NAN
    where, message = _refused(path, data)
    assert (where, message) == (
        str(path),
        "compiled.callees.pick.profile: time[5]: expected a finite number, got .nan",
    )


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    return _saved(tmp_path_factory.mktemp("hostile"))


@settings(max_examples=25, deadline=None)
@given(
    row=st.integers(min_value=0, max_value=10),
    module=st.integers(min_value=0, max_value=1),
    bad=st.sampled_from([NAN, INF, -INF]) | st.floats(max_value=-1e-12, allow_nan=False),
)
def test_any_bad_cell_of_any_table_is_named(
    saved: tuple[Path, dict[str, Any]], row: int, module: int, bad: float
) -> None:
    """Whichever cell of the callee's allocation holds a non-finite or negative time, that
    cell is the one named."""
    path, original = saved
    data = yaml.safe_load(yaml.safe_dump(original))
    data["compiled"]["callees"]["pick"]["allocation"][row][module] = bad
    where, message = _refused(path, data)
    assert where == str(path)
    assert message.startswith(
        f"compiled.callees.pick.allocation[{row}][{module}]: expected a finite time >= 0, got "
    )


def test_plot_refuses_a_ragged_table_in_one_line(tmp_path: Path, cli: Cli) -> None:
    """The command line's reader of compiled files (`anytime plot`), the rules `load_compiled`
    now shares: exit status 1, one line naming the file and the field, no traceback."""
    path, data = _saved(tmp_path)
    data["allocation"][3] = [1, 2]
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    code, out, err = cli("plot", str(path), "-o", str(tmp_path / "plot.png"))
    assert (code, out, err) == (
        1,
        "",
        f"anytime: error: {path}: allocation: expected a table of shape [11, 1] (input grids,"
        " time, one per module), got a ragged or non-numeric table\n",
    )


def _leaves(node: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """The paths of every value in the document (lists and mappings included)."""
    found = [path] if path else []
    if isinstance(node, dict):
        for key, value in node.items():
            found += _leaves(value, (*path, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            found += _leaves(value, (*path, i))
    return found


JUNK = st.sampled_from(
    [None, "x", -1, 0, NAN, INF, 1e300, True, [], {}, [[1], [2, 3]], {"a": 1}, [NAN], "1e3"]
)


@settings(max_examples=60, deadline=None)
@given(data=st.data(), junk=JUNK)
def test_any_value_replaced_by_junk_loads_or_is_refused_as_bad_input(
    saved: tuple[Path, dict[str, Any]], data: st.DataObject, junk: Any
) -> None:
    """Whatever value of the file is replaced by whatever junk, `load_compiled` loads it or
    raises an error of the tree that names the file: never a raw ValueError or TypeError."""
    path, original = saved
    document = yaml.safe_load(yaml.safe_dump(original))
    paths = _leaves(document)
    fields = [path for path in paths if len(path) <= 4]  # the tables are most of the leaves
    where = data.draw(st.sampled_from(fields) | st.sampled_from(paths))
    node = document
    for key in where[:-1]:
        node = node[key]
    node[where[-1]] = junk
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    try:
        load_compiled(path, _library())
    except AnytimeError as error:
        assert error.where == str(path) or str(error).startswith(f"{path}:")
