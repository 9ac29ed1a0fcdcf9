"""What a plugin's subcommands use, opt-in: `from anytime.plugin.cli import ...`.

A plugin adds subcommands with `Plugin(add_commands=...)`, a function that receives a
`CommandGroup` and calls `add_command(name, help=..., run=...)` for each. `run(args)` returns
the exit status (`EXIT_OK`, ...); an `AnytimeError` it raises (`InputError` for what it checks
itself, `InputError(message, where=FILE)` to name a file) is printed as one line with exit
status 1, a `UsageError` with status 2. Option types check a number when argparse parses it;
`format_table` and `json_text` print as the framework's own commands do, and `allocation_json`
gives an allocation as every `--json` does, `{module: time}` (the keys the commands share are
listed in docs/cli.md, "JSON output"); output files are written whole or not at all
(`atomic_path`, `write_atomic`, `owned_directory`); input files are read with a size limit
(`read_input`).

This module imports the command line (`anytime.cli`); `anytime.plugin` does not import it.
"""

from __future__ import annotations

from anytime.cli.common import (
    EXIT_INPUT,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    allocation_json,
    float_in_range,
    format_table,
    int_in_range,
    json_text,
    positive_float,
    positive_int,
    random_seed,
)
from anytime.errors import InputError, UsageError
from anytime.files import InputFileError, atomic_path, read_input, write_atomic
from anytime.library import CommandGroup
from anytime.measure.progress import ProgressBar
from anytime.outdir import owned_directory

__all__ = [
    # the command and how it ends
    "CommandGroup",
    "EXIT_OK",
    "EXIT_INPUT",
    "EXIT_USAGE",
    "EXIT_INTERRUPTED",
    "InputError",
    "UsageError",
    # option types
    "positive_int",
    "positive_float",
    "int_in_range",
    "float_in_range",
    "random_seed",
    # output
    "format_table",
    "json_text",
    "allocation_json",
    "ProgressBar",
    # files
    "atomic_path",
    "write_atomic",
    "owned_directory",
    "read_input",
    "InputFileError",
]
