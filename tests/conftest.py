"""Shared fixtures: paths of the shipped files, and the command run in-process."""

from collections.abc import Callable
from pathlib import Path

import pytest
from anytime_navigation.resources import data_file

from anytime.cli import main

#: Runs the `anytime` command in-process: (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

ROOT = Path(__file__).resolve().parent.parent


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
