"""The one place errors become messages (`anytime.cli.main`): whatever goes wrong is one line on
standard error, never a traceback; exit 1 for bad input, 2 for usage."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

import anytime.cli.schemas

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]


def anytime_process(*argv: str, **kwargs: object) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "anytime", *argv],
        stderr=subprocess.PIPE,
        text=True,
        **kwargs,
    )


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_an_error_writing_the_output(navigation_any: Path) -> None:
    with open("/dev/full", "w") as full:
        process = anytime_process("parse", str(navigation_any), stdout=full)
        _, err = process.communicate(timeout=60)
    assert (process.returncode, err) == (
        1,
        "anytime: error: cannot write the output: No space left on device\n",
    )


def test_a_reader_that_goes_away(navigation_any: Path) -> None:
    process = anytime_process("parse", str(navigation_any), "--json", stdout=subprocess.PIPE)
    assert process.stdout is not None
    process.stdout.close()  # as `anytime parse FILE | head -0` does
    _, err = process.communicate(timeout=60)
    assert (process.returncode, err) == (0, "")


def test_a_bug_is_one_line_too(
    cli: Cli, navigation_any: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(*args: object, **kwargs: object) -> None:
        raise ValueError("boom\nsecond line")

    monkeypatch.setattr(anytime.cli.schemas, "format_programs", broken)
    monkeypatch.delenv("ANYTIME_TRACEBACK", raising=False)
    code, out, err = cli("parse", str(navigation_any))
    assert (code, out) == (1, "")
    assert err == (
        "anytime: internal error: ValueError: boom (a bug; please report it;"
        " ANYTIME_TRACEBACK=1 shows the traceback)\n"
    )
    monkeypatch.setenv("ANYTIME_TRACEBACK", "1")
    with pytest.raises(ValueError, match="boom"):
        cli("parse", str(navigation_any))


def test_an_output_file_that_cannot_be_written(
    cli: Cli, navigation_any: Path, tmp_path: Path
) -> None:
    out = tmp_path / "no" / "such" / "navigate.yaml"
    code, stdout, err = cli(
        "compile", str(navigation_any), "--schema", "navigate", "--time-grid", "0:1000:250",
        "-o", str(out),
    )  # fmt: skip
    assert (code, stdout) == (1, "")
    assert err == f"anytime: error: cannot write '{out}': No such file or directory\n"
    code, stdout, err = cli("navigate", "--size", "16", "--out", str(navigation_any))
    assert (code, stdout) == (1, "")
    assert err == f"anytime: error: cannot write '{navigation_any}': File exists\n"
    assert err.count("\n") == 1


def test_an_output_that_is_an_input_is_refused(
    cli: Cli, navigation_any: Path, tmp_path: Path
) -> None:
    """`-o` naming the command's own input (by its path or another) is refused before any
    work, and the input is left as it was."""
    schema = tmp_path / "navigation.any"
    schema.write_text(navigation_any.read_text())
    link = tmp_path / "link.any"
    link.symlink_to(schema)
    before = schema.read_text()
    for output in (schema, link, tmp_path / "." / "navigation.any"):
        code, stdout, err = cli(
            "compile", str(schema), "--schema", "navigate", "--time-grid", "0:1000:250",
            "-o", str(output),
        )  # fmt: skip
        assert (code, stdout) == (1, "")
        assert err == (
            f"anytime: error: the output '{output}' is an input of this command; give another"
            " file\n"
        )
    assert schema.read_text() == before
    code, stdout, err = cli("plot", str(schema), "-o", str(schema))
    assert (code, stdout) == (1, "")
    assert err.startswith(f"anytime: error: the output '{schema}' is an input")


def test_an_output_that_is_a_library_profile_is_refused(
    cli: Cli, navigation_any: Path, tmp_path: Path
) -> None:
    """`compile -o` naming the profile file of a module the command reads (here from
    `--profiles DIR`) would replace the measured profile with the compiled program."""
    library = tmp_path / "lib"
    library.mkdir()
    profile = library / "find-path.yaml"
    profile.write_text(
        "format: anytime-profile/1\ntime: [0, 1]\nquality_bins: [0.0, 1.0]\nexpected: [0.0, 1.0]\n"
    )
    before = profile.read_bytes()
    code, stdout, err = cli(
        "compile", str(navigation_any), "--schema", "navigate", "--time-grid", "0:1000:250",
        "--profiles", str(library), "--no-plugins", "-o", f"{library}/./find-path.yaml",
    )  # fmt: skip
    assert (code, stdout) == (1, "")
    assert err == (
        f"anytime: error: the output '{library}/./find-path.yaml' is the profile file of module"
        " 'find-path', an input of this command; give another file\n"
    )
    assert profile.read_bytes() == before
