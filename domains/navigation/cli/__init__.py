"""The navigation domain's subcommands, added to `anytime` through the `anytime.commands` entry
point (see pyproject.toml): `anytime plan` solves path-finding problems with A* or the ATP."""

from __future__ import annotations

import argparse

from . import navigate, plan

__all__ = ["add_commands"]


def add_commands(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    plan.add_command(commands)
    navigate.add_command(commands)
