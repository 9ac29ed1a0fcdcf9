"""Figures of profiles and compiled programs (`anytime.plot`) and `anytime plot`: the PNGs are
made at their size, bad input is one line and exit 1, and the framework imports no domain."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import Cli

import anytime.library
from anytime.compiler import compile_program
from anytime.dsl import parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Registry
from anytime.plot import (
    MISSING_MATPLOTLIB,
    MissingMatplotlibError,
    PlotError,
    new_figure,
    plot_allocation,
    plot_compiled,
    plot_profile,
    save_figure,
)
from anytime.profiles import PerformanceProfile, default_bins, tabulate
from anytime.profiles.io import save_profile
from anytime.profiles.profile import ConditionalPerformanceProfile

pytest.importorskip("matplotlib")

TIME = np.arange(0, 41, 5.0)
SCHEMAS = """\
(defschema p (x)
  (plan (sense x)))
(defschema q (x)
  (plan (sense x)))
"""


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) in pixels, from the PNG's IHDR chunk."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def exponential(rate: float = 0.1, inputs: int = 0) -> ConditionalPerformanceProfile:
    if inputs == 0:
        return tabulate(lambda t: -np.expm1(-rate * t), TIME, module="exp")
    return tabulate(
        lambda t, *q: np.prod(q, axis=0) * -np.expm1(-rate * t),
        TIME,
        input_grids=[[0.0, 0.5, 1.0]] * inputs,
        inputs=[f"in{i}" for i in range(inputs)],
        module="exp",
    )


def spread_profile(*, with_std: bool) -> PerformanceProfile:
    """A measured-looking profile: a histogram over two bins per time, with or without std."""
    bins = default_bins(4)
    probability = np.zeros((len(TIME), 4))
    probability[:, 1] = np.linspace(1, 0, len(TIME))
    probability[:, 3] = 1 - probability[:, 1]
    mean = probability @ ((bins[:-1] + bins[1:]) / 2)
    return PerformanceProfile(
        time=TIME,
        bins=bins,
        probability=probability,
        mean=mean,
        std=np.full(len(TIME), 0.1) if with_std else None,
        samples=np.full(len(TIME), 30.0) if with_std else None,
        module="measured",
    )


@pytest.mark.parametrize(
    "profile",
    [
        exponential(),
        spread_profile(with_std=True),
        spread_profile(with_std=False),
        exponential(inputs=1),
        exponential(inputs=2),
    ],
    ids=["deterministic", "std-band", "quantile-band", "one-input", "two-inputs"],
)
def test_plot_profile_writes_a_png_of_its_size(
    tmp_path: Path, profile: ConditionalPerformanceProfile
) -> None:
    out = tmp_path / "profile.png"
    plot_profile(profile, out)
    assert png_size(out) == (700, 450)


def test_profile_axes_name_the_unit_and_the_curves() -> None:
    from anytime.plot import draw_profile

    figure = new_figure(7, 4.5)
    ax = figure.add_subplot()
    draw_profile(ax, exponential(inputs=2))
    assert ax.get_xlabel() == "run time (ticks)"
    assert "in1 at quality 1" in ax.get_title()
    legend = ax.get_legend()
    assert legend is not None
    assert [t.get_text() for t in legend.get_texts()] == [
        "input quality 1",
        "input quality 0.5",
        "input quality 0",
    ]
    ax = figure.add_subplot()
    draw_profile(ax, spread_profile(with_std=True))
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["expected quality", "±1 std (30 trials per time)"]


@pytest.fixture
def registry(monkeypatch: pytest.MonkeyPatch) -> Registry:
    """The command's in-process registry: a fresh, empty one (no module of a plugin)."""
    fresh = Registry()
    monkeypatch.setattr(anytime.library, "REGISTRY", fresh)
    return fresh


@pytest.fixture
def setup(tmp_path: Path, registry: Registry) -> tuple[Path, Path]:
    """(schema file, profile directory): `sense`, conditioned on its input, then `plan`."""
    library = tmp_path / "lib"
    library.mkdir()
    sense = tabulate(
        lambda t, q: q * -np.expm1(-0.1 * t),
        TIME,
        input_grids=[[0.0, 0.5, 1.0]],
        inputs=["x"],
        module="sense",
        kind="contract",
    )
    plan = tabulate(
        lambda t, q: q * -np.expm1(-0.05 * t),
        TIME,
        input_grids=[[0.0, 1.0]],
        inputs=["map"],
        module="plan",
    )
    save_profile(sense, library / "sense.yaml")
    save_profile(plan, library / "plan.yaml")
    schemas = tmp_path / "p.any"
    schemas.write_text(SCHEMAS, encoding="utf-8")
    return schemas, library


def test_plot_compiled_draws_the_baselines_and_the_allocation(
    tmp_path: Path, setup: tuple[Path, Path]
) -> None:
    schemas, library = setup
    lib = AnytimeLibrary.default(profile_dirs=[library], plugins=False)
    compiled = compile_program(parse_schemas(SCHEMAS)["p"], lib, TIME, [0.0, 0.5, 1.0])
    out = tmp_path / "compiled.png"
    plot_compiled(compiled, out)
    assert png_size(out) == (700, 700)
    with pytest.raises(PlotError, match=r"allocation: expected shape \[3, 9, 2\].*got \[9, 2\]"):
        plot_allocation(compiled.profile, compiled.modules, compiled.allocation[-1], out)


def test_save_figure_refuses_an_unknown_format(tmp_path: Path) -> None:
    with pytest.raises(PlotError, match=r"unknown image format '\.yaml' \(expected one of .*\.png"):
        save_figure(new_figure(1, 1), tmp_path / "x.yaml")
    save_figure(new_figure(2, 1), tmp_path / "x")  # no suffix: PNG
    assert png_size(tmp_path / "x") == (200, 100)


def test_missing_matplotlib_is_one_clear_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, cli: Cli
) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    with pytest.raises(MissingMatplotlibError) as raised:
        plot_profile(exponential(), tmp_path / "x.png")
    assert str(raised.value) == MISSING_MATPLOTLIB
    assert "'anytime-compose[plot]'" in MISSING_MATPLOTLIB
    profile = tmp_path / "exp.yaml"
    save_profile(exponential(), profile)
    assert cli("plot", str(profile)) == (1, "", f"anytime: error: {MISSING_MATPLOTLIB}\n")
    assert not (tmp_path / "exp.png").exists()


def test_the_framework_figures_import_no_domain(tmp_path: Path) -> None:
    code = textwrap.dedent(
        f"""
        import sys
        from anytime.plot import plot_profile
        from anytime.profiles import Constant, tabulate
        plot_profile(tabulate(Constant(0.5), [0, 1]), {str(tmp_path / "c.png")!r})
        print(sorted(m for m in sys.modules if m.startswith("anytime_navigation")))
        """
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout == "[]\n"
    assert (tmp_path / "c.png").stat().st_size > 0


# --- the command -----------------------------------------------------------------------------


def test_plot_a_profile_file_into_the_current_directory(
    tmp_path: Path, cli: Cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Not next to FILE: a shipped profile's directory is the installed package's."""
    profile = tmp_path / "profiles" / "exp.yaml"
    profile.parent.mkdir()
    save_profile(exponential(inputs=1), profile)
    monkeypatch.chdir(tmp_path)
    code, out, err = cli("plot", str(profile), "--title", "A title")
    assert (code, out, err) == (0, "wrote exp.png\n", "")
    assert png_size(tmp_path / "exp.png") == (700, 450)
    assert not (profile.parent / "exp.png").exists()


def test_plot_compiles_a_schema_as_compile_does(
    tmp_path: Path, cli: Cli, setup: tuple[Path, Path]
) -> None:
    """Every compile option reaches the figure: with --resolution it draws the table
    `anytime compile` prints with it; a profile file refuses them."""
    schemas, library = setup
    common = ["--schema", "p", "--profiles", str(library), "--no-plugins", "--time-grid", "0:40:10"]
    coarse = cli("compile", str(schemas), *common, "--resolution", "10")
    assert coarse[0] == 0, coarse
    code, out, err = cli(
        "plot", str(schemas), *common, "--resolution", "10", "-o", str(tmp_path / "s.png")
    )
    assert (code, out, err) == (0, f"wrote {tmp_path / 's.png'}\n", "")
    profile = tmp_path / "exp.yaml"
    save_profile(exponential(inputs=1), profile)
    code, out, err = cli("plot", str(profile), "--resolution", "2", "-o", str(tmp_path / "e.png"))
    assert (code, out, err) == (
        1,
        "",
        f"anytime: error: --resolution is for schema files (.any), and {profile} is read as a"
        " profile file\n",
    )


def test_plot_a_compiled_file_and_a_schema(
    tmp_path: Path, cli: Cli, setup: tuple[Path, Path]
) -> None:
    schemas, library = setup
    compiled = tmp_path / "p.yaml"
    code, _, err = cli(
        "compile", str(schemas), "--schema", "p", "--profiles", str(library), "--no-plugins",
        "--time-grid", "0:40:5", "-o", str(compiled),
    )  # fmt: skip
    assert (code, err) == (0, "")
    assert cli("plot", str(compiled), "-o", str(tmp_path / "c.png"))[:2] == (
        0,
        f"wrote {tmp_path / 'c.png'}\n",
    )
    assert png_size(tmp_path / "c.png") == (700, 700)
    code, out, err = cli(
        "plot", str(schemas), "--schema", "P", "--profiles", str(library), "--no-plugins",
        "--time-grid", "0:40:10", "-o", str(tmp_path / "p.png"),
    )  # fmt: skip
    assert (code, out, err) == (0, f"wrote {tmp_path / 'p.png'}\n", "")
    assert png_size(tmp_path / "p.png") == (700, 700)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["{any}"], "anytime: error: {any} defines 2 schemas: say which one to draw with "
         "--schema NAME (one of p, q)"),
        (["{any}", "--schema", "r"], "{any}: error: no schema named 'r' (the file defines: p, q)"),
        (["{dir}/nothing.yaml"], "anytime: error: {dir}/nothing.yaml: cannot read the file: "
         "No such file or directory"),
        (["{dir}/nothing.any"], "anytime: error: cannot read '{dir}/nothing.any': No such file "
         "or directory"),
        (["{dir}/bad.yaml"], "anytime: error: {dir}/bad.yaml: time: missing field (expected a "
         "list of times, got nothing)"),
        (["{dir}/lopsided.yaml"], "anytime: error: {dir}/lopsided.yaml: allocation: expected a "
         "table of shape [9, 2] (input grids, time, one per module), got [9, 3]"),
        (["{dir}/lib/plan.yaml", "--schema", "p"], "anytime: error: --schema is for schema files "
         "(.any), and {dir}/lib/plan.yaml is read as a profile file"),
        (["{dir}/bomb.yaml"], "anytime: error: {dir}/bomb.yaml:8:14: the document stands "
         "for more than 20,000,000 values (with its aliases expanded)"),
        (["{dir}/lib/plan.yaml", "-o", "{dir}/no/such/dir/x.png"], "anytime: error: cannot "
         "write '{dir}/no/such/dir/x.png': No such file or directory"),
        (["{dir}/lib/plan.yaml", "-o", "{dir}/x.txt"], "anytime: error: {dir}/x.txt: unknown "
         "image format '.txt' (expected one of "),
    ],
    ids=[
        "which-schema",
        "unknown-schema",
        "missing-profile",
        "missing-schema-file",
        "bad-profile",
        "bad-allocation",
        "schema-option-on-a-profile",
        "alias-bomb-allocation",
        "unwritable-output",
        "unknown-format",
    ],
)  # fmt: skip
def test_bad_input_is_one_line_and_exit_1(
    tmp_path: Path, cli: Cli, setup: tuple[Path, Path], argv: list[str], message: str
) -> None:
    schemas, library = setup
    (tmp_path / "bad.yaml").write_text("format: anytime-profile/1\n", encoding="utf-8")
    lopsided = {
        "format": "anytime-profile/1",
        "time": TIME.tolist(),
        "quality_bins": [0, 1],
        "expected": [0.5] * len(TIME),
        "modules": ["a", "b"],
        "allocation": [[1, 2, 3]] * len(TIME),
    }
    (tmp_path / "lopsided.yaml").write_text(yaml.safe_dump(lopsided), encoding="utf-8")
    # the issue's ~600 bytes in a compiled program's `allocation:` standing for 9**10 values
    bomb = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    bomb += [
        f"{b}: &{b} [" + ",".join([f"*{a}"] * 9) + "]"
        for a, b in zip("abcdefghi", "bcdefghij", strict=True)
    ]
    lopsided["allocation"] = "*j"
    (tmp_path / "bomb.yaml").write_text(
        "\n".join(bomb) + "\n" + yaml.safe_dump(lopsided).replace("'*j'", "*j"), encoding="utf-8"
    )
    fill = {"any": str(schemas), "dir": str(tmp_path)}
    args = [a.format(**fill) for a in argv]
    if args[0].endswith(".any"):
        args += ["--profiles", str(library), "--no-plugins"]
    code, out, err = cli("plot", *args)
    assert (code, out) == (1, "")
    assert err.startswith(message.format(**fill))
    assert err.count("\n") == 1
