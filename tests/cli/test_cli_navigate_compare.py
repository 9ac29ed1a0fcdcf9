"""`anytime navigate` runs the task once; the fixed policies min and max only with --compare."""

from __future__ import annotations

import json
from collections.abc import Callable

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]


def test_the_comparison_runs_only_when_asked(cli: Cli) -> None:
    code, out, err = cli("navigate", "--size", "16")
    assert (code, err) == (0, "")
    assert out.startswith("navigation task: 16x16 world, seed 0, policy monitored\n")
    assert "policy min" not in out and "policy max" not in out
    code, out, err = cli("navigate", "--size", "16", "--compare")
    assert (code, err) == (0, "")
    assert "\n  policy min       utility " in out and "\n  policy max       utility " in out


def test_the_comparison_in_json(cli: Cli) -> None:
    code, out, _ = cli("navigate", "--size", "16", "--json")
    assert code == 0 and "comparison" not in json.loads(out)
    code, out, _ = cli("navigate", "--size", "16", "--policy", "min", "--compare", "--json")
    assert code == 0
    data = json.loads(out)
    assert data["policy"] == "min" and set(data["comparison"]) == {"max"}
    assert data["comparison"]["max"]["policy"] == "max"


def test_help_says_what_compare_costs(cli: Cli) -> None:
    code, out, _ = cli("navigate", "--help")
    assert code == 0
    assert "--compare" in out and "each a whole run more" in " ".join(out.split())
