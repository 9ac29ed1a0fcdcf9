"""The public plugin API: everything a plugin imports, in one module.

A plugin is a distribution of its own whose `anytime.plugins` entry point names a `Plugin`
object (or a function returning one)::

    [project.entry-points."anytime.plugins"]
    my-domain = "my_domain:plugin"

The plugin's modules are made with the decorators below, which declare a module without
registering it anywhere: importing a plugin changes nothing in the process, and the framework
sees the plugin only through its `Plugin` object (so `--no-plugins` simply leaves it out). A
plugin imports from `anytime` and `anytime.plugin` only; the rest of the framework is internal
and may change between releases.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any

from anytime.cli.common import (
    EXIT_INPUT,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    InputError,
    UsageError,
    float_in_range,
    format_table,
    int_in_range,
    json_text,
    positive_float,
    positive_int,
    random_seed,
)
from anytime.clocks import Clock, Unit, WallClock, WorkClock
from anytime.compiler import compile_file, compile_program
from anytime.compiler.compile import CompiledProgram, default_time_grid
from anytime.compiler.explain import Explanation, ModuleMargin, Move, explain
from anytime.dsl import SchemaFile, load_schemas, parse_schemas
from anytime.errors import AnytimeError, ProfileError
from anytime.files import InputFileError, atomic_path, read_input, write_atomic
from anytime.isolation import Limits
from anytime.library import AnytimeLibrary, CommandGroup, LibraryEntry, Plugin
from anytime.measure.progress import ProgressBar
from anytime.modules import MISSING, AnytimeModule, Context, ProfileSource, QualityReport, Result
from anytime.modules import contract as _contract
from anytime.modules import elementary as _elementary
from anytime.modules import interruptible as _interruptible
from anytime.outdir import owned_directory
from anytime.plot import new_figure, require_matplotlib, save_figure
from anytime.problems import Instance, Measurement, ProblemSet, ProgramProblems
from anytime.profiles import ConditionalPerformanceProfile, VisionHyperbola, tabulate
from anytime.profiles.profile import Array
from anytime.runtime.deadline import (
    CriticalEvent,
    Deadline,
    deadline_from,
    proportional_split,
)
from anytime.runtime.deadline import critical_event as _critical_event
from anytime.runtime.executor import RunInterrupted, RunRecord, Status, run
from anytime.runtime.monitor import (
    Adjustment,
    CostModel,
    DeadlineValue,
    EventLog,
    Monitor,
    ValueModel,
)
from anytime.runtime.program import ProgramRecord, program_module, run_program
from anytime.verification import BudgetCheck, Verification, verify

__all__ = [
    "EXIT_INPUT",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_USAGE",
    "Adjustment",
    "AnytimeError",
    "AnytimeLibrary",
    "AnytimeModule",
    "Array",
    "BudgetCheck",
    "Clock",
    "CommandGroup",
    "CompiledProgram",
    "ConditionalPerformanceProfile",
    "Context",
    "CostModel",
    "CriticalEvent",
    "Deadline",
    "DeadlineValue",
    "EventLog",
    "Explanation",
    "InputError",
    "InputFileError",
    "Instance",
    "LibraryEntry",
    "Limits",
    "MISSING",
    "Measurement",
    "ModuleMargin",
    "Monitor",
    "Move",
    "ProgramProblems",
    "ProgramRecord",
    "Plugin",
    "ProblemSet",
    "ProfileError",
    "QualityReport",
    "ProgressBar",
    "Result",
    "RunInterrupted",
    "RunRecord",
    "SchemaFile",
    "Status",
    "Unit",
    "UsageError",
    "ValueModel",
    "Verification",
    "VisionHyperbola",
    "WallClock",
    "WorkClock",
    "atomic_path",
    "compile_file",
    "compile_program",
    "contract",
    "critical_event",
    "deadline_from",
    "default_time_grid",
    "elementary",
    "explain",
    "float_in_range",
    "format_table",
    "int_in_range",
    "interruptible",
    "json_text",
    "load_schemas",
    "new_figure",
    "parse_schemas",
    "positive_float",
    "positive_int",
    "program_module",
    "proportional_split",
    "require_matplotlib",
    "random_seed",
    "owned_directory",
    "read_input",
    "run",
    "run_program",
    "save_figure",
    "tabulate",
    "verify",
    "write_atomic",
]


def interruptible(
    name: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    profile: ProfileSource = None,
    accepts_missing: bool = False,
    reports: QualityReport = "true",
    step: float | None = None,
) -> Callable[[Callable[..., Iterator[Result]]], AnytimeModule]:
    """Declare a generator `f(ctx, *args)` that yields successively better `Result`s.

    As `anytime.interruptible`, but registers nothing: list the module in your `Plugin`.
    A relative `profile` path is a file of the defining module's package. `step`, if given, is
    the largest gap between its successive results (from its start to the first, from the last
    to its return), in its profile's time unit; `anytime profile` measures it otherwise.
    """
    return _interruptible(
        name,
        inputs=inputs,
        profile=profile,
        register=False,
        accepts_missing=accepts_missing,
        reports=reports,
        step=step,
    )


def contract(
    name: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    profile: ProfileSource = None,
    accepts_missing: bool = False,
    reports: QualityReport = "true",
    step: float | None = None,
) -> Callable[[Callable[..., Result | None]], AnytimeModule]:
    """Declare a function `f(ctx, *args) -> Result` that reads `ctx.allocation` up front (it
    returns None when it has no result).

    As `anytime.contract`, but registers nothing: list the module in your `Plugin`. `step`, if
    given, is the most it may use past its allocation.
    """
    return _contract(
        name,
        inputs=inputs,
        profile=profile,
        register=False,
        accepts_missing=accepts_missing,
        reports=reports,
        step=step,
    )


def elementary(
    name: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    combine: Callable[[Sequence[float]], float] | None = None,
    probability: float | None = None,
) -> Callable[[Callable[..., Any]], AnytimeModule]:
    """Declare a plain function `f(*args)` that takes no time and no context.

    As `anytime.elementary`, but registers nothing: list the module in your `Plugin`.
    """
    if combine is None:
        return _elementary(name, inputs=inputs, probability=probability, register=False)
    return _elementary(
        name, inputs=inputs, combine=combine, probability=probability, register=False
    )


def critical_event(
    name: str | None = None, *, cost_bound: float
) -> Callable[[Callable[..., float | None]], CriticalEvent]:
    """Declare `f(ctx, situation)` returning the time until its event, or None (no event).

    As `anytime.runtime.deadline.critical_event`, but registers nothing: list it in your
    `Plugin.critical_events` and give the object itself to `deadline_from`.
    """
    return _critical_event(name, cost_bound=cost_bound, register=False)
