"""The public plugin API: what a plugin declares its modules, problem sets and itself with.

A plugin is a distribution of its own whose `anytime.plugins` entry point names a `Plugin`
object (or a function returning one)::

    [project.entry-points."anytime.plugins"]
    my-domain = "my_domain:plugin"

Its modules are made with the decorators below, which declare a module and register it nowhere
(they are `anytime.interruptible` and the others: one family): importing a plugin changes
nothing in the process, and the framework sees the plugin only through its `Plugin` object (so
`--no-plugins` simply leaves it out).

A plugin imports from `anytime`, `anytime.plugin` and its opt-in submodules only; the rest of
the framework is internal and may change between releases:

- `anytime` (the top-level package): compiling and running programs (`AnytimeLibrary`,
  `compile_file`, `CompiledProgram`, `run`, `run_program`, `RunRecord`, `Status`, ...),
  schemas (`parse_schemas`, `SchemaFile`), `verify`, `explain`;
- `anytime.plugin.cli`: what a plugin's subcommands use (exit codes, `UsageError`, option
  types, `format_table`, `json_text`, `CommandGroup`, files written atomically, the progress
  bar); it imports the command line;
- `anytime.plugin.figures`: figures (`new_figure`, `save_figure`, `require_matplotlib`);
- `anytime.plugin.compose`: what a plugin that composes and runs programs of its own needs
  beyond `anytime` (deadlines from critical events, the monitor and its models, the event log,
  the compiler's default time grid, analytic profiles);
- `anytime.plugin.solvers`: external solvers as anytime modules (`resume` for a solver that
  runs for a limit of its own work and resumes, `Resumable`; `on_improvement` for one that calls
  back on each improvement, `Report`).

Importing this package imports none of those submodules, nor the command line, nor (until
`critical_event` or `CriticalEvent` is first used) the runtime.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from anytime.clocks import Clock, Unit, WallClock, WorkClock
from anytime.errors import AnytimeError, InputError, interrupt_behind
from anytime.library import Plugin
from anytime.modules import (
    MISSING,
    AnytimeModule,
    Context,
    Result,
    contract,
    elementary,
    interruptible,
)
from anytime.problems import Instance, Measurement, ProblemSet, ProgramProblems
from anytime.profiles import ConditionalPerformanceProfile, tabulate

if TYPE_CHECKING:
    from anytime.runtime.deadline import CriticalEvent, critical_event

__all__ = [
    # declaring modules
    "interruptible",
    "contract",
    "elementary",
    "AnytimeModule",
    "Result",
    "Context",
    "MISSING",
    # their profiles, when not a measured file
    "ConditionalPerformanceProfile",
    "tabulate",
    # time
    "Clock",
    "WorkClock",
    "WallClock",
    "Unit",
    # how `anytime profile` measures a module, and what a schema's promise is checked on
    "Instance",
    "ProblemSet",
    "Measurement",
    "ProgramProblems",
    # critical events
    "critical_event",
    "CriticalEvent",
    # the plugin object
    "Plugin",
    # errors
    "AnytimeError",
    "InputError",
    "interrupt_behind",
]

#: The names defined in the runtime, imported on first use (PEP 562): the runtime brings the
#: compiler and the DSL with it, which a plugin that only declares modules does not need.
_LAZY = {"critical_event": "anytime.runtime.deadline", "CriticalEvent": "anytime.runtime.deadline"}


def __getattr__(name: str) -> Any:
    where = _LAZY.get(name)
    if where is None:
        raise AttributeError(f"module 'anytime.plugin' has no attribute {name!r}")
    value = getattr(importlib.import_module(where), name)
    globals()[name] = value  # found once, then an ordinary attribute
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
