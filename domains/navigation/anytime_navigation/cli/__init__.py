"""The navigation domain's subcommands, added to `anytime` by the plugin's `add_commands`:
`anytime plan` solves path-finding problems with A* or the ATP, `anytime navigate` runs the
frame-by-frame task under the monitor."""

from __future__ import annotations

from anytime.plugin.cli import CommandGroup

from . import navigate, plan

__all__ = ["add_commands"]


def add_commands(commands: CommandGroup) -> None:
    plan.add_command(commands)
    navigate.add_command(commands)
