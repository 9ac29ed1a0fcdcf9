"""`anytime compile --explain`: why the splits, as text and in the JSON, and its bad values."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import Cli

from anytime.profiles import tabulate
from anytime.profiles.io import save_profile

TIME = np.arange(0, 41, 5.0)


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    """(schema file, profile directory): `sense` then `plan`, exponential in time (rates 0.1
    and 0.05, profiled up to 40 ticks) and linear in input quality."""
    library = tmp_path / "lib"
    library.mkdir()
    for name, rate, grid, axis in (("sense", 0.1, [0, 0.5, 1], "x"), ("plan", 0.05, [0, 1], "map")):
        profile = tabulate(
            lambda t, q, rate=rate: q * -np.expm1(-rate * t),
            TIME,
            input_grids=[grid],
            inputs=[axis],
            module=name,
        )
        save_profile(profile, library / f"{name}.yaml")
    schemas = tmp_path / "p.any"
    schemas.write_text("(defschema p (x)\n  (plan (sense x)))\n", encoding="utf-8")
    return schemas, library


#: The grids of every run: totals 0 to 80 (twice the profiles' longest time), three qualities.
GRIDS = ("--time-grid", "0:80:10", "--input-quality", "0,0.5,1", "--no-plugins")


def compile_p(cli: Cli, files: tuple[Path, Path], *options: str) -> tuple[int, str, str]:
    schemas, library = files
    return cli("compile", str(schemas), "--profiles", str(library), *GRIDS, *options)


EXPLAINED = """\
schema p: why these splits (one unit = 10 ticks; at input quality 1 of x)
  the change in expected quality with one unit more (+1) or less (-1) for a module
  T = 20 ticks: expected quality 0.24872
    module  share   +1 unit   -1 unit
    sense      10  +0.09150  -0.24872
    plan       10  +0.15086  -0.24872
    best move of one unit: sense -> plan, -0.24872 (no move of one unit gains)
  T = 80 ticks: expected quality 0.84883
    module  share   +1 unit   -1 unit
    sense      40  +0.00000  -0.02721  at its profile's ceiling: more time gains nothing
    plan       40  +0.00000  -0.08619  at its profile's ceiling: more time gains nothing
    best move of one unit: sense -> plan, -0.02721 (no move of one unit gains)
"""


def test_explain_follows_the_report(cli: Cli, files: tuple[Path, Path]) -> None:
    code, report, err = compile_p(cli, files)
    assert (code, err) == (0, "")
    code, out, err = compile_p(cli, files, "--explain", "20,80")
    assert (code, err) == (0, "")
    assert out == report + "\n" + EXPLAINED


def test_explain_without_totals_uses_a_quarter_half_and_all_of_the_grid(
    cli: Cli, files: tuple[Path, Path]
) -> None:
    code, out, err = compile_p(cli, files, "--explain")
    assert (code, err) == (0, "")
    assert [line.split(":")[0].strip() for line in out.splitlines() if "  T = " in line] == [
        "T = 20 ticks",
        "T = 40 ticks",
        "T = 80 ticks",
    ]


def test_explain_in_the_json(cli: Cli, files: tuple[Path, Path]) -> None:
    code, out, err = compile_p(cli, files, "--explain", "20", "--json")
    assert (code, err) == (0, "")
    (explained,) = json.loads(out)["explain"]
    assert explained["budget"] == 20
    assert explained["input_quality"] == [1]
    assert explained["unit"] == 10
    assert explained["expected_quality"] == pytest.approx(0.24872, abs=5e-6)
    assert explained["allocation"] == {"sense": 10, "plan": 10}
    assert [m["module"] for m in explained["margins"]] == ["sense", "plan"]
    sense = explained["margins"][0]
    assert list(sense) == ["module", "gain", "loss", "at_ceiling", "note"]
    assert (sense["at_ceiling"], sense["note"]) == (False, "")
    assert sense["gain"] == pytest.approx(0.09150, abs=5e-6)
    assert explained["best_move"]["from"] == "sense"
    assert explained["best_move"]["to"] == "plan"
    # Without --explain the JSON has no explain key (its keys are unchanged).
    code, out, err = compile_p(cli, files, "--json")
    assert "explain" not in json.loads(out)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("x", "expected totals separated by commas, got 'x'"),
        ("10,a", "expected totals separated by commas, got '10,a'"),
        (",", "expected at least one total"),
        ("-10", "expected finite totals >= 0, got '-10'"),
        ("nan", "expected finite totals >= 0, got 'nan'"),
    ],
)
def test_bad_totals_exit_2_with_one_line(
    cli: Cli, files: tuple[Path, Path], value: str, message: str
) -> None:
    code, out, err = compile_p(cli, files, f"--explain={value}")
    assert (code, out) == (2, "")
    assert err == f"anytime compile: error: argument --explain: {message}\n"


def test_a_total_off_the_grid_exits_1_with_one_line(cli: Cli, files: tuple[Path, Path]) -> None:
    code, out, err = compile_p(cli, files, "--explain", "20,25")
    assert (code, out) == (1, "")
    assert err == (
        f"{files[0]}: error: schema 'p': explain: expected a total of the table's time grid"
        " (0, 10, 20, 30, 40, 50, ... ticks; 9 totals up to 80), got 25\n"
    )
