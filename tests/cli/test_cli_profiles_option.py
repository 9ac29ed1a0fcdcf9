"""One spelling of the profile-directory option: `--profiles DIR` (repeatable) on every command
that reads the library; `--library` is gone, parse's boolean check is `--check-calls`."""

from collections.abc import Callable

import pytest

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]

#: Every command that reads the anytime library, with its positional arguments.
LIBRARY_COMMANDS = [
    ["parse", "FILE"],
    ["compile", "FILE"],
    ["plot", "FILE"],
    ["library", "list"],
    ["library", "show", "NAME"],
    ["profile", "MODULE"],
    ["calibrate", "MODULE"],
    ["check", "MODULE"],
    ["navigate"],
]


@pytest.mark.parametrize("argv", LIBRARY_COMMANDS, ids=" ".join)
def test_every_library_command_takes_profiles_dir_repeatable(cli: Cli, argv: list[str]) -> None:
    code, out, _ = cli(*argv[:2], "--help") if argv[0] == "library" else cli(argv[0], "--help")
    assert code == 0
    assert "--profiles DIR" in out
    assert "--library" not in out


@pytest.mark.parametrize("command", ["compile", "plot"])
def test_library_dir_is_no_longer_an_option(cli: Cli, command: str) -> None:
    code, _, err = cli(command, "x.any", "--library", "dir")
    assert code == 2
    assert "unrecognized arguments: --library" in err


def test_parse_check_calls_is_the_boolean_check(cli: Cli) -> None:
    code, out, _ = cli("parse", "--help")
    assert code == 0
    assert "--check-calls" in out
    assert "check every called function against the anytime library" in out
