"""The navigation plugin: the object the `anytime.plugins` entry point names (see
pyproject.toml). Importing it registers nothing; the framework reads what it lists."""

from __future__ import annotations

from anytime.plugin import Plugin

from . import modules
from .cli import add_commands
from .obstacles import overcoming_modules
from .obstacles.overcoming import obstacle_arrival
from .program_problems import PROGRAM_PROBLEMS

__all__ = ["PLUGIN"]

PLUGIN = Plugin(
    name="navigation",
    modules=(
        modules.get_domain_description,
        modules.find_path,
        modules.a_star,
        modules.better_plan,
        modules.execute_plan,
        *overcoming_modules.MODULES,
    ),
    problem_sets={**modules.PROBLEM_SETS, **overcoming_modules.PROBLEM_SETS},
    critical_events=(obstacle_arrival,),
    add_commands=add_commands,
    program_problems=PROGRAM_PROBLEMS,
)
