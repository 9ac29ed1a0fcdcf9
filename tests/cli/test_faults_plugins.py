"""Issue 37, item 7: a plugin that calls `sys.exit()` or hangs at import breaks no command.
Its `SystemExit` is a warning naming it; `--no-plugins` imports no plugin at all (plugin
commands neither); a plugin still importing after `anytime.cli.PLUGIN_SECONDS` is warned about
by name and the command (`--help` too) goes on without it and the plugins after it. The plugins
are real distributions on the path of a fresh interpreter (a hanging import cannot be undone in
this one)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

PLUGINS = {
    "exits": "import sys\nsys.exit(3)\n",
    "hangs": "import time\ntime.sleep(600)\n",
}


def _installed(tmp_path: Path, names: list[str]) -> Path:
    """A directory holding the plugins `names` and a distribution whose entry points name them;
    each plugin leaves a file named after it in the directory when it is imported."""
    site = tmp_path / "site"
    info = site / "faulty_plugins-0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: faulty-plugins\nVersion: 0\n")
    lines = ["[anytime.plugins]"] + [f"{name} = faulty_{name}" for name in names]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    for name in names:
        mark = f"open({str(site / ('imported-' + name))!r}, 'w').close()\n"
        (site / f"faulty_{name}.py").write_text(mark + PLUGINS[name])
    return site


def _anytime(site: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    code = (
        "import sys, anytime.cli as cli; cli.PLUGIN_SECONDS = 2;"
        f" sys.exit(cli.main({list(argv)!r}))"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), *sys.path]))
    return subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,  # only a hang reaches it
    )


HUNG = (
    "anytime: warning: plugin 'hangs' (faulty_hangs) did not finish importing in 2 s: it and"
    " the plugins after it are left out (--no-plugins runs without plugins)\n"
)


def test_a_plugin_that_exits_at_import_is_a_warning_naming_it(tmp_path: Path) -> None:
    site = _installed(tmp_path, ["exits"])
    done = _anytime(site, "library", "list")
    assert done.returncode == 0, done.stderr
    assert "find-path" in done.stdout  # the other plugins' modules are there
    warning = "anytime: warning: plugin 'exits' (faulty_exits): SystemExit: 3\n"
    assert warning in done.stderr
    assert (site / "imported-exits").exists()


@pytest.mark.parametrize("names", [["exits"], ["exits", "hangs"]])
def test_no_plugins_imports_no_plugin(tmp_path: Path, names: list[str]) -> None:
    site = _installed(tmp_path, names)
    done = _anytime(site, "library", "list", "--no-plugins")
    assert (done.returncode, done.stderr) == (0, "")
    assert list(site.glob("imported-*")) == []


def test_help_goes_on_without_a_plugin_that_hangs_at_import(tmp_path: Path) -> None:
    site = _installed(tmp_path, ["exits", "hangs"])
    done = _anytime(site, "--help")
    assert done.returncode == 0
    assert done.stdout.startswith("usage: anytime")
    assert done.stderr == HUNG
    assert "navigate" not in done.stdout  # the navigation plugin comes after it, by name


def test_a_command_goes_on_without_a_plugin_that_hangs_at_import(tmp_path: Path) -> None:
    site = _installed(tmp_path, ["hangs"])
    done = _anytime(site, "library", "list")
    assert (done.returncode, done.stderr) == (0, HUNG)
    assert "find-path" not in done.stdout  # navigation, after it by name, is left out too


def test_help_with_no_plugins_lists_no_plugin_command(tmp_path: Path) -> None:
    site = _installed(tmp_path, ["hangs"])
    done = _anytime(site, "profile", "--help", "--no-plugins")
    assert (done.returncode, done.stderr) == (0, "")
    assert list(site.glob("imported-*")) == []
