"""The `anytime` command as a user meets it: output, exit codes, no tracebacks."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import Cli

from anytime import __version__, parse_schemas


def test_version(cli: Cli) -> None:
    assert cli("--version") == (0, f"anytime {__version__}\n", "")


def test_help_lists_the_commands(cli: Cli) -> None:
    code, out, _ = cli("--help")
    assert code == 0
    assert "parse" in out
    code, out, _ = cli("parse", "--help")
    assert code == 0
    assert "--json" in out and "--dot" in out and "--schema NAME" in out


def test_no_command_is_a_usage_error(cli: Cli) -> None:
    code, _, err = cli()
    assert code == 2
    assert err.startswith("usage: anytime")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["parse"], "anytime parse: error: the following arguments are required: FILE\n"),
        (
            ["parse", "a.any", "--json", "--dot"],
            "anytime parse: error: argument --dot: not allowed with argument --json\n",
        ),
        (["parse", "a.any", "--bogus"], "anytime: error: unrecognized arguments: --bogus\n"),
        (["nope"], "anytime: error: argument COMMAND: invalid choice: 'nope' (choose from "),
        (
            ["compil"],
            "anytime: error: argument COMMAND: invalid choice: 'compil'; did you mean 'compile'?\n",
        ),
        (
            ["compile", "a.any", "--allocator", "dpp"],
            "anytime compile: error: argument"
            " --allocator: invalid choice: 'dpp'; did you mean 'dp'?\n",
        ),
    ],  # fmt: skip
    ids=[
        "missing-file",
        "json-and-dot",
        "unknown-option",
        "unknown-command",
        "mistyped-command",
        "mistyped-choice",
    ],  # fmt: skip
)
def test_usage_errors_exit_2_with_one_line(cli: Cli, argv: list[str], message: str) -> None:
    code, out, err = cli(*argv)
    assert (code, out) == (2, "")
    assert err.startswith(message) and err.count("\n") == 1


def test_parse_prints_straight_line_text_that_parses_back(cli: Cli, navigation_any: Path) -> None:
    code, out, err = cli("parse", str(navigation_any))
    assert (code, err) == (0, "")
    assert out.startswith("; navigate: chain, 2 steps\n(defschema navigate (start goal sensor)\n")
    assert "; navigate-two-planners: dag, 4 steps\n" in out
    again = parse_schemas(out)
    assert again.names == (
        "navigate",
        "navigate-nested",
        "navigate-two-planners",
        "sense-plan-act",
    )


def test_parse_json_field_by_field(cli: Cli, navigation_any: Path) -> None:
    code, out, _ = cli("parse", str(navigation_any), "--json")
    assert code == 0
    data = json.loads(out)
    assert list(data) == ["schemas"]
    schemas = {s["schema"]: s for s in data["schemas"]}
    assert list(schemas) == [
        "navigate",
        "navigate-nested",
        "navigate-two-planners",
        "sense-plan-act",
    ]
    nested = schemas["navigate-nested"]
    assert nested["parameters"] == ["start", "goal", "sensor"]
    assert nested["doc"] is None
    assert nested["steps"] == [
        {
            "target": "t1",
            "function": "get-domain-description",
            "kind": "call",
            "args": ["sensor"],
            "keywords": {},
        },
        {
            "target": "t2",
            "function": "find-path",
            "kind": "call",
            "args": ["start", "goal", "t1"],
            "keywords": {},
        },
    ]
    assert nested["output"] == "t2"
    assert nested["shape"] == "chain"
    assert [s["shape"] for s in schemas.values()] == ["chain", "chain", "dag", "chain"]


def test_parse_one_schema_as_dot(cli: Cli, navigation_any: Path) -> None:
    code, out, _ = cli("parse", str(navigation_any), "--schema", "Navigate", "--dot")
    assert code == 0
    assert out.count("subgraph cluster_") == 1
    assert 'label="navigate (chain)";' in out


def test_unknown_schema_is_an_input_error(cli: Cli, navigation_any: Path) -> None:
    code, out, err = cli("parse", str(navigation_any), "--schema", "fly")
    assert (code, out) == (1, "")
    assert err == (
        f"{navigation_any}: error: no schema named 'fly' (the file defines: navigate, "
        "navigate-nested, navigate-two-planners, sense-plan-act)\n"
    )


def test_missing_file_is_an_input_error(cli: Cli) -> None:
    code, _, err = cli("parse", "no/such/file.any")
    assert code == 1
    assert err == "anytime: error: cannot read 'no/such/file.any': No such file or directory\n"


def test_schema_errors_print_every_diagnostic(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "bad.any"
    path.write_text("(defschema p (x)\n  (setf a (f y))\n  (g a b))\n")
    code, out, err = cli("parse", str(path))
    assert (code, out) == (1, "")
    assert err == (
        f"{path}:2:14: error: undefined variable 'y'\n"
        "    (setf a (f y))\n"
        "               ^\n"
        f"{path}:3:8: error: undefined variable 'b'\n"
        "    (g a b))\n"
        "         ^\n"
    )


def test_bad_input_never_shows_a_traceback(tmp_path: Path) -> None:
    path = tmp_path / "bad.any"
    path.write_text("(defschema (x) x)\n")
    done = subprocess.run(
        [sys.executable, "-m", "anytime", "parse", str(path)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 1
    assert done.stdout == ""
    assert "Traceback" not in done.stderr
    assert done.stderr.startswith(f"{path}:1:12: error: missing schema name after 'defschema'\n")


def test_compile_shows_every_total_of_a_default_grid_and_says_when_it_thins(
    cli: Cli, navigation_any: Path
) -> None:
    """Up to 25 totals the table shows them all; a longer grid is thinned and says so, and
    --rows 0 shows every total."""
    args = ["compile", str(navigation_any), "--schema", "navigate"]
    code, out, _ = cli(*args, "--time-grid", "0:3000:250")
    assert code == 0
    rows = [line.split()[0] for line in out.splitlines()[2:] if line.split()[0].isdigit()]
    assert rows == [str(t) for t in range(0, 3001, 250)]  # 13 totals: 1500 among them
    assert "totals shown" not in out
    code, out, _ = cli(*args, "--time-grid", "0:3000:100")
    assert "  (25 of the 31 totals shown: --rows 0 shows every one, --json gives the whole" in out
    code, out, _ = cli(*args, "--time-grid", "0:3000:100", "--rows", "0")
    assert len([line for line in out.splitlines() if line.split()[0].isdigit()]) == 31
    assert "totals shown" not in out
    assert cli(*args, "--rows", "-1")[0] == 2
