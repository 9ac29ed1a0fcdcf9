"""`--json` is valid JSON on every command that has it: strict JSON (no NaN or Infinity),
plain numbers (a numpy scalar made `anytime profile MODULE --json` crash for contract modules).

And the commands speak one vocabulary (docs/cli.md, "JSON output", issue 38): every key any
command prints is in the page's table of keys, with the type the table gives it, and the things
several commands report (a budget, an allocation, an expected quality, a module's name, ...)
are under one name and of one shape in all of them (`CONCEPTS`). A command that prints a key
the page does not list, or a shared thing under another name or in another shape, fails here;
so does a command with `--json` that `COMMANDS` does not run.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from anytime_navigation.resources import data_file

from anytime.cli import build_parser, main
from anytime.cli.common import allocation_json, json_text

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

MAPS = Path(str(data_file("maps")))
PAGE = Path(__file__).resolve().parents[2] / "docs" / "cli.md"

#: Every command with `--json`, run once each (in this order: a profile is converted after it
#: is measured), by an id: the command's name, then what the run is for.
COMMANDS: dict[str, list[str]] = {
    "parse": ["parse", "{any}"],
    "compile": ["compile", "{any}", "--schema", "navigate", "--time-grid", "0:1000:250"],
    "compile --explain": [
        "compile", "{any}", "--schema", "navigate", "--time-grid", "0:1000:250",
        "--explain", "250,1000",
    ],
    "compile of several schemas": ["compile", "{any}", "--time-grid", "0:1000:250"],
    "verify": [
        "verify", "{any}", "--schema", "navigate", "--runs", "2", "--budgets", "0,250", "--quiet",
    ],
    "library list": ["library", "list"],
    # an interruptible module with a dynamic profile, then a contract module without
    "library show": ["library", "show", "find-path"],
    "library show of a contract module": ["library", "show", "get-domain-description"],
    "profile": ["profile", "get-domain-description", "--trials", "1", "-o", "{tmp}/g.yaml"],
    "profile --dynamic": [
        "profile", "find-path", "--trials", "1", "-o", "{tmp}/f.yaml", "--dynamic",
        "--traces", "{tmp}/f.traces.yaml",
    ],
    "check": ["check", "get-domain-description", "--trials", "1"],
    "calibrate": ["calibrate", "get-domain-description", "--seconds", "0.02"],
    "calibrate --profile": [
        "calibrate", "get-domain-description", "--seconds", "0.02",
        "--profile", "{tmp}/g.yaml", "-o", "{tmp}/g-seconds.yaml",
    ],
    "navigate": ["navigate", "--size", "16", "--compare", "--quiet"],
    "plan": ["plan", "--map", str(MAPS / "arena.map"), "--limit", "2"],
    "plan --planner atp": [
        "plan", "--map", str(MAPS / "arena.map"), "--limit", "2", "--planner", "atp",
    ],
    "deliver": ["deliver", "--budget", "40"],
    "motion": ["motion", "--budget", "2000"],
}  # fmt: skip

#: The things several commands report, each under one key of one type: (concept, key, type as
#: the page writes it, where: "COMMAND-ID: PATH", PATH a dotted path from the output's top
#: ("" the top itself, "[]" every item of a list) to the objects that must hold the key).
CONCEPTS: list[tuple[str, str, str, list[str]]] = [
    ("a module's name", "module", "str", [
        "profile:", "profile --dynamic:", "check:", "calibrate:", "library list: []",
        "library show:", "compile --explain: explain[].margins[]",
    ]),
    ("a schema's name", "schema", "str", [
        "parse: schemas[]", "compile:", "compile of several schemas: schemas[]", "verify:",
        "deliver:", "motion:",
    ]),
    ("the total time given to a program", "budget", "number", [
        "compile: budgets[]", "compile --explain: explain[]", "verify: budgets[]", "deliver:",
        "motion:",
    ]),
    ("a row per budget", "budgets", "[object]", ["compile:", "verify:"]),
    ("the unit of the output's times", "time_unit", "str", [
        "compile:", "verify:", "navigate:", "deliver:", "motion:", "library show: profile",
        "library show: dynamic_profile",
    ]),
    ("the times of a table", "time_grid", "[number]", [
        "compile:", "library show: profile", "library show: dynamic_profile",
    ]),
    ("the input-quality grids", "input_grids", "[[number]]", [
        "compile:", "library show: profile",
    ]),
    ("a point of input qualities", "input_quality", "[number]", [
        "compile: budgets[]", "compile --explain: explain[]", "library show: dynamic_profile",
    ]),
    ("the quality-carrying inputs", "inputs", "[str]", [
        "compile:", "library list: []", "library show:",
    ]),
    ("every input", "parameters", "[str]", ["parse: schemas[]", "library show:"]),
    ("an allocation, {module: time}", "allocation", "{str: number}", [
        "compile: budgets[]", "compile --explain: explain[]", "deliver:", "motion:",
        "motion: comparison.even", "motion: comparison.planner",
    ]),
    ("what the compiled program expects", "expected_quality", "number", [
        "compile: budgets[]", "compile --explain: explain[]", "verify: budgets[]", "deliver:",
        "motion:",
    ]),
    ("its standard error", "expected_quality_se", "number", [
        "compile: budgets[]", "verify: budgets[]",
    ]),
    ("what the run achieved", "realised_quality", "number or null", [
        "verify: budgets[]", "deliver:", "motion:", "motion: comparison.even",
    ]),
    ("runs made", "runs", "int", [
        "profile:", "check:", "calibrate:", "verify: budgets[]",
    ]),
    ("instances per cell", "trials", "int", ["profile:", "check:"]),
    ("runs in which a module failed", "failures", "int", ["profile:", "verify: budgets[]"]),
    ("runs over their time", "overruns", "int", ["profile:", "verify: budgets[]"]),
    ("the root seed", "seed", "int", [
        "profile:", "check:", "calibrate:", "verify:", "navigate:", "deliver:", "motion:",
    ]),
    ("wall-clock seconds", "seconds", "number", [
        "profile:", "calibrate:", "verify:", "plan: problems[]", "plan: summary",
    ]),
    ("a verdict", "passed", "bool", ["check:", "verify:", "verify: budgets[]"]),
    ("a file written or read", "file", "str or null", [
        "profile:", "calibrate:", "calibrate --profile:", "library show: profile",
        "library show: dynamic_profile",
    ]),
    ("the length of the route followed", "route_length", "number", [
        "navigate:", "plan: problems[]",
    ]),
    ("the shortest route's length", "optimal_length", "number", [
        "navigate:", "plan: problems[]",
    ]),
]  # fmt: skip

#: Keys whose values are data the page describes elsewhere (a schema's steps: the DSL page).
OPAQUE = {"steps"}


def vocabulary() -> dict[str, str]:
    """The page's table of keys: key -> type."""
    section = PAGE.read_text(encoding="utf-8").split("\n## JSON output\n", 1)[1]
    section = section.split("\n## ", 1)[0]
    rows = re.findall(r"^\| `(\w+)` \| ([^|]+?) \| [^|]+ \| [^|]* \|$", section, re.MULTILINE)
    return dict(rows)


VOCABULARY = vocabulary()


def conforms(value: Any, kind: str) -> bool:
    """Whether a JSON value is of a type as the page writes it."""
    if kind.endswith(" or null"):
        return value is None or conforms(value, kind.removesuffix(" or null"))
    simple = {"int": (int,), "number": (int, float), "str": (str,), "bool": (bool,)}
    if kind in simple:  # a bool is no number here, though Python's bool is an int
        return type(value) in simple[kind]
    if kind == "object":
        return isinstance(value, dict)
    if kind == "table":
        if isinstance(value, list):
            return all(conforms(item, "table") for item in value)
        return conforms(value, "number or null")
    if kind.startswith("[") and kind.endswith("]"):
        return isinstance(value, list) and all(conforms(item, kind[1:-1]) for item in value)
    if kind.startswith("{str: ") and kind.endswith("}"):
        inner = kind[len("{str: ") : -1]
        return isinstance(value, dict) and all(conforms(v, inner) for v in value.values())
    raise AssertionError(f"the page writes a type the test does not know: {kind!r}")


def keys_of(data: Any, path: str = "") -> Iterator[tuple[str, str, Any]]:
    """(path, key, value) of every key of every object in `data`; the keys of a `{str: T}`
    value are data (module names, policies), not keys, but its values are walked."""
    if isinstance(data, list):
        for item in data:
            yield from keys_of(item, path + "[]")
    elif isinstance(data, dict):
        for key, value in data.items():
            yield path, key, value
            if key in OPAQUE:
                continue
            where = f"{path}.{key}" if path else key
            if VOCABULARY.get(key, "").startswith("{str: ") and isinstance(value, dict):
                for inner in value.values():
                    yield from keys_of(inner, where + "{}")
            else:
                yield from keys_of(value, where)


def objects_at(data: Any, path: str) -> list[Any]:
    """The objects at a dotted path ("" the top, "name[]" every item of a list)."""
    found = [data]
    for part in filter(None, path.split(".")):
        name, many = part.removesuffix("[]"), part.endswith("[]")
        step: list[Any] = []
        for item in found:
            value = item[name] if name else item
            step.extend(value if many else [value])
        found = step
    return found


def strict(text: str) -> Any:
    def refuse(constant: str) -> None:
        raise AssertionError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


@pytest.fixture(scope="module")
def printed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """What every command of `COMMANDS` prints with --json, run once for the module."""
    tmp = tmp_path_factory.mktemp("json")
    navigation = str(data_file("schemas", "navigation.any"))
    texts = {}
    for name, argv in COMMANDS.items():
        args = [a.format(any=navigation, tmp=tmp) for a in argv]
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([*args, "--json"])
        assert code == 0, (name, err.getvalue())
        texts[name] = out.getvalue()
    return texts


def json_commands(parser: argparse.ArgumentParser, prefix: str = "") -> Iterator[str]:
    """The commands (`library list` for a subcommand's) whose parser takes --json."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from json_commands(sub, f"{prefix} {name}".strip())
        elif "--json" in action.option_strings:
            yield prefix


def test_every_command_with_json_is_run() -> None:
    ran = {" ".join(argv[:2]) if argv[0] == "library" else argv[0] for argv in COMMANDS.values()}
    assert set(json_commands(build_parser())) == ran


@pytest.mark.parametrize("name", COMMANDS)
def test_json_output_parses(printed: dict[str, str], name: str) -> None:
    data = strict(printed[name])
    assert isinstance(data, dict | list) and data
    # one writer for every command: json_text, indented alike
    assert printed[name] == json_text(data) + "\n"


@pytest.mark.parametrize("name", COMMANDS)
def test_every_key_is_in_the_pages_table_with_its_type(printed: dict[str, str], name: str) -> None:
    for path, key, value in keys_of(strict(printed[name])):
        where = f"{name}: {path or 'top'}: {key!r}"
        assert key in VOCABULARY, f"{where} is not in docs/cli.md's table of JSON keys"
        kind = VOCABULARY[key]
        assert conforms(value, kind), f"{where} is {value!r}, not {kind} as the page says"


@pytest.mark.parametrize("concept", CONCEPTS, ids=lambda concept: concept[1])
def test_each_shared_thing_has_one_name_and_one_type(
    printed: dict[str, str], concept: tuple[str, str, str, list[str]]
) -> None:
    what, key, kind, places = concept
    assert VOCABULARY[key] == kind, f"{key}: the page says {VOCABULARY[key]}, the test {kind}"
    for place in places:
        name, path = place.split(":")
        objects = objects_at(strict(printed[name]), path.strip())
        assert objects, place
        for found in objects:
            assert key in found, f"{what}: {place} has no {key!r} (it has {list(found)})"
            assert conforms(found[key], kind), f"{what}: {place}: {found[key]!r} is not {kind}"


def test_the_page_lists_each_commands_keys(printed: dict[str, str]) -> None:
    """Each command's bullet in the JSON section names every key at the top of its output
    (for a list, of its items)."""
    section = PAGE.read_text(encoding="utf-8").split("\n## JSON output\n", 1)[1]
    bullets = {
        m[1]: m[2] for m in re.finditer(r"^- `([a-z ]+)`: (.*?)(?=^- |^\n)", section, re.M | re.S)
    }
    for name, argv in COMMANDS.items():
        command = " ".join(argv[:2]) if argv[0] == "library" else argv[0]
        data = strict(printed[name])
        if name == "compile of several schemas":
            data = data["schemas"][0]
        for key in data[0] if isinstance(data, list) else data:
            assert f"`{key}`" in bullets[command], f"{command}: the page does not list {key!r}"


def test_profile_upstream_speaks_the_same(cli: Cli, lab_plugin: Path) -> None:
    """`profile --upstream` (too slow on the navigation plugin: the lab's instead)."""
    import verify_modules as lab

    (lab_plugin / "lab.any").write_text(lab.SCHEMAS)
    code, out, err = cli(
        "profile", "polish", "--upstream", "lab.any", "--schema", "low", "--trials", "5",
        "--rounds", "1", "-o", "polish.yaml", "--json",
    )  # fmt: skip
    assert code == 0, err
    data = strict(out)
    assert list(data) == ["module", "file", "schema", "trials", "seed", "rounds", "converged"]
    for _, key, value in keys_of(data):
        assert key in VOCABULARY and conforms(value, VOCABULARY[key]), key


def test_an_allocation_keeps_a_repeated_modules_shares() -> None:
    assert allocation_json(["sense", "plan", "plan"], [1.0, 2.0, 3.0]) == {
        "sense": 1.0,
        "plan#1": 2.0,
        "plan#2": 3.0,
    }


def test_profile_json_counts_are_plain_numbers(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "g.yaml"
    code, text, err = cli(
        "profile", "get-domain-description", "--trials", "2", "-o", str(out), "--json"
    )
    assert code == 0, err
    data = strict(text)
    assert data["module"] == "get-domain-description" and data["file"] == str(out)
    assert (data["trials"], data["runs"], data["failures"], data["overruns"]) == (2, 50, 0, 0)


def test_json_text_writes_null_for_what_json_cannot_say() -> None:
    assert json_text({"a": [1.5, float("nan"), float("inf")], "b": (1,)}, indent=None) == (
        '{"a": [1.5, null, null], "b": [1]}'
    )
    np = pytest.importorskip("numpy")
    with pytest.raises(TypeError):  # a numpy scalar is a bug where it is made
        json_text({"n": np.int64(1)})
