"""The motion plugin: the object the `anytime.plugins` entry point names (see pyproject.toml).
Importing it registers nothing; the framework reads what it lists."""

from __future__ import annotations

from anytime.plugin import Plugin

from .cli import add_commands
from .modules import MODULES, PROBLEM_SETS
from .program import PROGRAM_PROBLEMS

__all__ = ["PLUGIN"]

PLUGIN = Plugin(
    name="motion",
    modules=MODULES,
    problem_sets=PROBLEM_SETS,
    add_commands=add_commands,
    program_problems=PROGRAM_PROBLEMS,
)
