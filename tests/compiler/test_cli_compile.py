"""`anytime compile FILE`: the report as JSON and as a table, the compiled profile file, and the
errors, with the modules given as profile files in a directory."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import Cli

import anytime.library
from anytime.modules import Context, Registry, Result, interruptible
from anytime.profiles import tabulate
from anytime.profiles.io import load_profile, save_profile

TIME = np.arange(0, 41, 5.0)
SENSE_RATE, PLAN_RATE = 0.1, 0.05

SCHEMAS = """\
(defschema p (x)
  (plan (sense x)))
(defschema q (x)
  (plan (sens x)))
"""

BAD_GRID = (
    "anytime compile: error: argument --time-grid: expected START:STOP:STEP with 0 <= START"
    " <= STOP and STEP > 0, got {!r}\n"
)
NOT_A_GRID = (
    "anytime compile: error: argument --time-grid: expected START:STOP:STEP (three numbers),"
    " got {!r}\n"
)


@pytest.fixture
def registry(monkeypatch: pytest.MonkeyPatch) -> Registry:
    """The command's in-process registry: a fresh, empty one."""
    fresh = Registry()
    monkeypatch.setattr(anytime.library, "REGISTRY", fresh)
    return fresh


@pytest.fixture
def setup(tmp_path: Path, registry: Registry) -> tuple[Path, Path]:
    """(schema file, profile directory): `sense` (conditioned on its input x) and `plan`
    (conditioned on the map it is given), exponential in time and linear in input quality."""
    library = tmp_path / "lib"
    library.mkdir()
    save_profile(
        tabulate(
            lambda t, q: q * -np.expm1(-SENSE_RATE * t),
            TIME,
            input_grids=[[0.0, 0.5, 1.0]],
            inputs=["x"],
            module="sense",
        ),
        library / "sense.yaml",
    )
    save_profile(
        tabulate(
            lambda t, q: q * -np.expm1(-PLAN_RATE * t),
            TIME,
            input_grids=[[0.0, 1.0]],
            inputs=["map"],
            module="plan",
        ),
        library / "plan.yaml",
    )
    schemas = tmp_path / "p.any"
    schemas.write_text(SCHEMAS, encoding="utf-8")
    return schemas, library


def compile_p(cli: Cli, setup: tuple[Path, Path], *options: str) -> tuple[int, str, str]:
    schemas, library = setup
    return cli(
        "compile",
        str(schemas),
        "--schema",
        "p",
        "--profiles",
        str(library),
        "--no-plugins",
        *options,
    )


def optimum(q: float, total: float, dt: float) -> float:
    """The best product q (1 - e^{-a t1}) (1 - e^{-b (T - t1)}) over the lattice."""
    t1 = np.arange(0, total + dt / 2, dt)
    return float(np.max(q * -np.expm1(-SENSE_RATE * t1) * -np.expm1(-PLAN_RATE * (total - t1))))


def test_json_report_fields_and_shapes(cli: Cli, setup: tuple[Path, Path]) -> None:
    code, out, err = compile_p(
        cli, setup, "--time-grid", "0:40:10", "--input-quality", "0,0.5,1", "--json"
    )
    assert (code, err) == (0, "")
    report = json.loads(out)
    assert list(report) == [
        "schema",
        "allocator",
        "modules",
        "inputs",
        "time_unit",
        "time_grid",
        "input_grids",
        "budgets",
        "exhaustive_gap",
        "exact",
        "dp_obstacle",
        "approximations",
        "kept_smaller",
        "method_note",
        "warnings",
    ]
    assert report["schema"] == "p"
    assert report["allocator"] == "dp"
    assert report["modules"] == ["sense", "plan"]
    assert report["inputs"] == ["x"]
    assert report["time_grid"] == [0, 10, 20, 30, 40]
    assert report["time_unit"] == "ticks"
    assert report["input_grids"] == [[0, 0.5, 1]]
    rows = report["budgets"]  # one per input quality and budget, input quality outermost
    assert [(row["input_quality"], row["budget"]) for row in rows] == [
        ([q], t) for q in (0, 0.5, 1) for t in (0, 10, 20, 30, 40)
    ]
    assert list(rows[0]) == [
        "budget", "input_quality", "expected_quality", "expected_quality_se", "allocation",
        "baselines", "expected_quality_if_dependent",
    ]  # fmt: skip
    assert all(row["expected_quality_if_dependent"] is None for row in rows)  # no best-of
    expected = np.array([row["expected_quality"] for row in rows]).reshape(3, 5)
    assert all(list(row["allocation"]) == ["sense", "plan"] for row in rows)
    allocation = np.array([list(row["allocation"].values()) for row in rows]).reshape(3, 5, 2)
    assert all(set(row["baselines"]) == {"equal", "min", "max"} for row in rows)
    assert all(row["expected_quality_se"] == 0 for row in rows)
    for name in ("equal", "min", "max"):
        baseline = np.array([row["baselines"][name] for row in rows]).reshape(3, 5)
        assert (expected >= baseline - 1e-12).all()
    assert report["exhaustive_gap"] == 0
    assert report["warnings"] == []
    assert report["method_note"] == "dp: local compilation, exact for this tree of monotone modules"
    for i, q in enumerate([0, 0.5, 1]):
        for j, total in enumerate(range(0, 41, 10)):
            assert expected[i, j] == pytest.approx(optimum(q, total, 10), abs=1e-12)
    np.testing.assert_array_equal(allocation.sum(axis=-1), [[0, 10, 20, 30, 40]] * 3)


def test_json_of_every_schema_of_a_file(cli: Cli, setup: tuple[Path, Path], tmp_path: Path) -> None:
    _, library = setup
    path = tmp_path / "two.any"
    path.write_text("(defschema a (x) (sense x))\n(defschema b (x) (plan (a x)))\n")
    code, out, err = cli(
        "compile",
        str(path),
        "--profiles",
        str(library),
        "--no-plugins",
        "--json",
        "--time-grid",
        "0:20:5",
    )
    assert (code, err) == (0, "")
    reports = json.loads(out)["schemas"]
    assert [(r["schema"], r["modules"]) for r in reports] == [
        ("a", ["sense"]),
        ("b", ["a", "plan"]),
    ]


def test_table_report(cli: Cli, setup: tuple[Path, Path]) -> None:
    code, out, err = compile_p(cli, setup, "--time-grid", "0:40:10")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0] == "schema p: dp (table at input quality 1 of x)"
    assert lines[1] == "  T (ticks)  compiled  equal    min    max  allocation (sense, plan)"
    assert lines[2] == "          0     0.000  0.000  0.000  0.000  0, 0"
    assert lines[4].split()[:2] == ["20", f"{optimum(1.0, 20, 10):.3f}"]
    assert lines[-2:] == [
        "  gap to the exhaustive optimum: 0.00e+00",
        "  note: dp: local compilation, exact for this tree of monotone modules",
    ]
    assert len(lines) == 2 + 5 + 2


def test_output_file_is_a_loadable_compiled_profile(
    cli: Cli, setup: tuple[Path, Path], tmp_path: Path
) -> None:
    path = tmp_path / "OUT.yaml"
    code, out, err = compile_p(cli, setup, "--time-grid", "0:40:10", "-o", str(path))
    assert (code, err) == (0, "")
    assert out.endswith(f"wrote {path}\n")
    profile = load_profile(path)
    assert (profile.module, profile.kind, profile.inputs) == ("p", "contract", ("x",))
    np.testing.assert_array_equal(profile.time, [0, 10, 20, 30, 40])
    assert profile.mean is not None
    code, out, _ = compile_p(cli, setup, "--time-grid", "0:40:10", "--json")
    rows = json.loads(out)["budgets"]
    np.testing.assert_array_equal(
        profile.mean, np.reshape([row["expected_quality"] for row in rows], profile.mean.shape)
    )


def test_output_file_with_json_prints_only_json(
    cli: Cli, setup: tuple[Path, Path], tmp_path: Path
) -> None:
    path = tmp_path / "OUT.yaml"
    code, out, err = compile_p(cli, setup, "--time-grid", "0:40:10", "-o", str(path), "--json")
    assert (code, err) == (0, "")
    assert json.loads(out)["schema"] == "p"
    assert path.exists()


def test_time_grid_option(cli: Cli, setup: tuple[Path, Path]) -> None:
    code, out, err = compile_p(cli, setup, "--time-grid", "0:40:10", "--json")
    assert (code, err) == (0, "")
    assert json.loads(out)["time_grid"] == [0, 10, 20, 30, 40]
    code, out, err = compile_p(cli, setup, "--time-grid", "10:30:10", "--json")
    assert (code, err) == (0, "")
    assert json.loads(out)["time_grid"] == [10, 20, 30]


@pytest.mark.parametrize(
    ("grid", "message"),
    [
        ("10:0:5", BAD_GRID),
        ("a:b:c", NOT_A_GRID),
        ("0:10:0", BAD_GRID),
        ("0:10:-5", BAD_GRID),
        ("-5:10:5", BAD_GRID),
        ("0:10", NOT_A_GRID),
        ("0:10:5:1", NOT_A_GRID),
        ("", NOT_A_GRID),
    ],
)
def test_bad_time_grids_exit_2_with_one_line(
    cli: Cli, setup: tuple[Path, Path], grid: str, message: str
) -> None:
    code, out, err = compile_p(cli, setup, f"--time-grid={grid}")
    assert (code, out) == (2, "")
    assert err == message.format(grid)


def test_unknown_function_names_its_place(cli: Cli, setup: tuple[Path, Path]) -> None:
    schemas, library = setup
    code, out, err = cli(
        "compile", str(schemas), "--schema", "q", "--profiles", str(library), "--no-plugins"
    )
    assert (code, out) == (1, "")
    assert err == (
        f"{schemas}:4:10: error: unknown function 'sens'; did you mean 'sense'?\n"
        "    (plan (sens x)))\n"
        "           ^~~~\n"
    )


def test_module_without_a_profile(
    cli: Cli, setup: tuple[Path, Path], registry: Registry, tmp_path: Path
) -> None:
    @interruptible("guess", inputs=[], registry=registry)
    def guess(ctx: Context, x: Any) -> Iterator[Result]:
        yield Result(None, 0.0)

    _, library = setup
    path = tmp_path / "guess.any"
    path.write_text("(defschema g (x)\n  (plan (guess x)))\n")
    code, out, err = cli("compile", str(path), "--profiles", str(library), "--no-plugins")
    assert (code, out) == (1, "")
    assert err.splitlines()[0] == (
        f"{path}:2:10: error: module 'guess' has no performance profile (python module "
        f"{__name__}): the compiler cannot allocate time to it"
    )


def test_time_unit_must_be_the_profiles_unit(cli: Cli, setup: tuple[Path, Path]) -> None:
    schemas, _ = setup
    code, out, err = compile_p(cli, setup, "--time-grid", "0:40:10", "--time-unit", "seconds")
    assert (code, out) == (1, "")
    assert err == (
        f"{schemas}: error: schema 'p': the time grid is in seconds but its modules' profiles "
        "are in ticks\n"
    )
    code, _, err = compile_p(cli, setup, "--time-grid", "0:40:10", "--time-unit", "ticks")
    assert (code, err) == (0, "")


def test_the_shipped_navigation_schema_compiles_exactly(
    cli: Cli, navigation_any: Path, registry: Registry
) -> None:
    code, out, err = cli(
        "compile",
        str(navigation_any),
        "--schema",
        "navigate",
        "--json",
    )
    assert (code, err) == (0, "")
    report = json.loads(out)
    assert report["schema"] == "navigate"
    assert report["modules"] == ["get-domain-description", "find-path"]
    # The navigation plugin's measured profiles are stochastic, so dp is not exact; two
    # modules make the exhaustive search affordable.
    assert report["allocator"] == "exhaustive"
    assert report["exhaustive_gap"] == 0
    # The vision module's profile has no input axis, so no program input's quality conditions
    # the output: the table has one row per budget, none per input quality.
    assert (report["inputs"], report["input_grids"]) == ([], [])
    rows = report["budgets"]
    assert [row["budget"] for row in rows] == report["time_grid"]
    for row in rows:
        assert row["input_quality"] == []
        assert list(row["allocation"]) == ["get-domain-description", "find-path"]
        assert all(row["expected_quality"] >= b - 1e-12 for b in row["baselines"].values())


def test_strict_refuses_a_table_that_leans_on_a_clamped_profile(
    cli: Cli, setup: tuple[Path, Path]
) -> None:
    """`plan` measured on maps of quality 0.5 to 1 only: the table feeds it worse maps, which
    its profile clamps (a warning), and with --strict the compilation is refused (exit 1)."""
    _, library = setup
    narrow = tabulate(
        lambda t, q: q * -np.expm1(-PLAN_RATE * t),
        TIME,
        input_grids=[[0.5, 1.0]],
        inputs=["map"],
        module="plan",
    )
    save_profile(narrow, library / "plan.yaml")
    code, out, err = compile_p(cli, setup, "--time-grid", "0:40:10")
    assert (code, err) == (0, "")
    warning = next(line for line in out.splitlines() if line.startswith("  warning: "))
    assert warning.startswith("  warning: module 'plan': input 'map' receives qualities 0 to")
    code, out, err = compile_p(cli, setup, "--time-grid", "0:40:10", "--strict")
    assert (code, out) == (1, "")
    assert err == f"{setup[0]}: error: schema 'p' (--strict): {warning[11:]}\n"
