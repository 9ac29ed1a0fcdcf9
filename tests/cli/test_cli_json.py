"""`--json` is valid JSON on every command that has it: strict JSON (no NaN or Infinity),
plain numbers (a numpy scalar made `anytime profile MODULE --json` crash for contract modules)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from anytime_navigation.resources import data_file

from anytime.cli.common import json_text

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

MAPS = Path(str(data_file("maps")))


def strict(text: str) -> Any:
    def refuse(constant: str) -> None:
        raise AssertionError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


COMMANDS = [
    ["parse", "{any}"],
    ["compile", "{any}", "--schema", "navigate"],
    ["library", "list"],
    ["library", "show", "find-path"],
    ["library", "show", "get-domain-description"],
    # a contract module, then an interruptible one
    ["profile", "get-domain-description", "--trials", "1", "-o", "{tmp}/g.yaml"],
    ["profile", "find-path", "--trials", "1", "-o", "{tmp}/f.yaml"],
    ["check", "get-domain-description", "--trials", "1"],
    ["calibrate", "get-domain-description", "--seconds", "0.02"],
    [
        "calibrate", "get-domain-description", "--seconds", "0.02",
        "--profile", "{tmp}/g.yaml", "-o", "{tmp}/g-seconds.yaml",
    ],
    ["navigate", "--size", "16"],
    ["plan", "--map", str(MAPS / "arena.map"), "--limit", "2"],
    ["plan", "--map", str(MAPS / "arena.map"), "--limit", "2", "--planner", "atp"],
]  # fmt: skip


@pytest.mark.parametrize("argv", COMMANDS, ids=lambda argv: " ".join(argv[:3]))
def test_json_output_parses(
    cli: Cli, navigation_any: Path, tmp_path: Path, argv: list[str]
) -> None:
    args = [a.format(any=navigation_any, tmp=tmp_path) for a in argv]
    if "--profile" in args:  # a profile to convert, in ticks
        assert cli("profile", "get-domain-description", "--trials", "1", "-o", args[-3])[0] == 0
    code, out, err = cli(*args, "--json")
    assert code == 0, err
    data = strict(out)
    assert isinstance(data, dict | list) and data


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
