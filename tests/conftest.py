"""Shared fixtures: paths of the shipped files, the command run in-process, and the lab plugin
of tests/verify_modules.py installed."""

import importlib.metadata
import signal
from collections.abc import Callable
from pathlib import Path

import pytest
from anytime_navigation.resources import data_file

from anytime.cli import main
from anytime.library import PLUGIN_GROUP

#: Runs the `anytime` command in-process: (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

ROOT = Path(__file__).resolve().parent.parent


def pytest_configure(config: pytest.Config) -> None:
    """A background job of a non-interactive shell (`make test &`, a CI step's `cmd &`) starts
    with Ctrl-C ignored, and the commands the tests start would inherit that: the Ctrl-C tests
    (tests/cli/test_cli_interrupt.py) would wait for commands that never see it. Python's own
    handler is put back (it is reset to the default in a started command)."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def navigation_any() -> Path:
    return Path(str(data_file("schemas", "navigation.any")))


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]) -> Cli:
    def run(*argv: str) -> tuple[int, str, str]:
        try:
            code = main(list(argv))
        except SystemExit as exit:  # argparse exits for --help, --version and usage errors
            code = int(exit.code or 0)
        out, err = capsys.readouterr()
        return code, out, err

    return run


@pytest.fixture
def lab_plugin(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """The lab of tests/verify_modules.py as if installed (its entry point found by
    importlib.metadata, and no other plugin), in a fresh working directory (returned)."""
    found = [importlib.metadata.EntryPoint("lab", "verify_modules:plugin", PLUGIN_GROUP)]
    monkeypatch.setattr(
        importlib.metadata,
        "entry_points",
        lambda **selection: found if selection.get("group") == PLUGIN_GROUP else [],
    )
    monkeypatch.chdir(tmp_path)
    return tmp_path
