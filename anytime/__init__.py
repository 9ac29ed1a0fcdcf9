"""anytime-compose: build real-time systems out of anytime algorithms.

Write a program schema in the DSL, describe its modules by conditional performance profiles,
compile it into a contract algorithm with optimal time allocation, and run it under a monitor.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from anytime.clocks import WallClock, WorkClock
    from anytime.compiler import (
        CompiledProgram,
        compile_file,
        compile_program,
        load_compiled,
        save_compiled,
    )
    from anytime.compiler.explain import Explanation, ModuleMargin, Move, explain
    from anytime.dsl import (
        DataflowGraph,
        Program,
        SchemaFile,
        Step,
        format_program,
        load_schemas,
        parse_schemas,
    )
    from anytime.errors import (
        AnytimeError,
        Diagnostic,
        ProfileError,
        SchemaError,
        SchemaSyntaxError,
        interrupt_behind,
    )
    from anytime.library import (
        AnytimeLibrary,
        LibraryEntry,
        LibraryError,
        PluginSource,
        ProfileDirectory,
        RegistrySource,
        UnknownModuleError,
    )
    from anytime.measure.upstream import measure_upstream
    from anytime.modules import (
        REGISTRY,
        AnytimeModule,
        Context,
        ModuleError,
        RegistrationError,
        Registry,
        Result,
        contract,
        elementary,
        interruptible,
    )
    from anytime.problems import ProgramProblems
    from anytime.profiles import ConditionalPerformanceProfile, PerformanceProfile
    from anytime.profiles.io import load_profile, save_profile
    from anytime.runtime import (
        Budget,
        ConformalStopping,
        Decision,
        FixedStopping,
        Hard,
        Isolated,
        MyopicStopping,
        Observer,
        OptimalStopping,
        ProgramRecord,
        ProjectedStopping,
        RunRecord,
        Soft,
        Status,
        Stopping,
        StoppingPolicy,
        program_module,
        run,
        run_program,
    )
    from anytime.verification import BudgetCheck, Verification, verify

__version__ = "0.1.0"

__all__ = [
    "AnytimeError",
    "AnytimeLibrary",
    "AnytimeModule",
    "Budget",
    "BudgetCheck",
    "CompiledProgram",
    "ConditionalPerformanceProfile",
    "ConformalStopping",
    "Context",
    "DataflowGraph",
    "Decision",
    "Diagnostic",
    "Explanation",
    "FixedStopping",
    "Hard",
    "Isolated",
    "LibraryEntry",
    "LibraryError",
    "ModuleError",
    "ModuleMargin",
    "Move",
    "MyopicStopping",
    "Observer",
    "OptimalStopping",
    "PerformanceProfile",
    "PluginSource",
    "ProfileDirectory",
    "ProfileError",
    "Program",
    "ProgramProblems",
    "ProgramRecord",
    "ProjectedStopping",
    "REGISTRY",
    "RegistrationError",
    "Registry",
    "RegistrySource",
    "Result",
    "RunRecord",
    "SchemaError",
    "SchemaFile",
    "SchemaSyntaxError",
    "Soft",
    "Status",
    "Step",
    "Stopping",
    "StoppingPolicy",
    "UnknownModuleError",
    "Verification",
    "WallClock",
    "WorkClock",
    "__version__",
    "compile_file",
    "compile_program",
    "contract",
    "elementary",
    "explain",
    "format_program",
    "interrupt_behind",
    "interruptible",
    "load_compiled",
    "load_profile",
    "load_schemas",
    "measure_upstream",
    "parse_schemas",
    "program_module",
    "run",
    "run_program",
    "save_compiled",
    "save_profile",
    "verify",
]

#: Where each public name is defined: `import anytime` imports none of them until one is used
#: (PEP 562), so that the command line starts fast and a Ctrl-C during start-up is caught.
_WHERE = {
    "WallClock": "anytime.clocks",
    "WorkClock": "anytime.clocks",
    "CompiledProgram": "anytime.compiler",
    "compile_file": "anytime.compiler",
    "compile_program": "anytime.compiler",
    "load_compiled": "anytime.compiler",
    "save_compiled": "anytime.compiler",
    "Explanation": "anytime.compiler.explain",
    "ModuleMargin": "anytime.compiler.explain",
    "Move": "anytime.compiler.explain",
    "explain": "anytime.compiler.explain",
    "DataflowGraph": "anytime.dsl",
    "Program": "anytime.dsl",
    "SchemaFile": "anytime.dsl",
    "Step": "anytime.dsl",
    "format_program": "anytime.dsl",
    "load_schemas": "anytime.dsl",
    "parse_schemas": "anytime.dsl",
    "AnytimeError": "anytime.errors",
    "Diagnostic": "anytime.errors",
    "ProfileError": "anytime.errors",
    "SchemaError": "anytime.errors",
    "SchemaSyntaxError": "anytime.errors",
    "interrupt_behind": "anytime.errors",
    "AnytimeLibrary": "anytime.library",
    "LibraryEntry": "anytime.library",
    "LibraryError": "anytime.library",
    "PluginSource": "anytime.library",
    "ProfileDirectory": "anytime.library",
    "RegistrySource": "anytime.library",
    "UnknownModuleError": "anytime.library",
    "REGISTRY": "anytime.modules",
    "AnytimeModule": "anytime.modules",
    "Context": "anytime.modules",
    "ModuleError": "anytime.modules",
    "RegistrationError": "anytime.modules",
    "Registry": "anytime.modules",
    "Result": "anytime.modules",
    "contract": "anytime.modules",
    "elementary": "anytime.modules",
    "interruptible": "anytime.modules",
    "ConditionalPerformanceProfile": "anytime.profiles",
    "PerformanceProfile": "anytime.profiles",
    "Budget": "anytime.runtime",
    "Soft": "anytime.runtime",
    "Hard": "anytime.runtime",
    "Isolated": "anytime.runtime",
    "Observer": "anytime.runtime",
    "Stopping": "anytime.runtime",
    "Decision": "anytime.runtime",
    "ConformalStopping": "anytime.runtime",
    "FixedStopping": "anytime.runtime",
    "MyopicStopping": "anytime.runtime",
    "OptimalStopping": "anytime.runtime",
    "ProjectedStopping": "anytime.runtime",
    "StoppingPolicy": "anytime.runtime",
    "ProgramRecord": "anytime.runtime",
    "RunRecord": "anytime.runtime",
    "Status": "anytime.runtime",
    "program_module": "anytime.runtime",
    "run": "anytime.runtime",
    "run_program": "anytime.runtime",
    "load_profile": "anytime.profiles.io",
    "save_profile": "anytime.profiles.io",
    "ProgramProblems": "anytime.problems",
    "BudgetCheck": "anytime.verification",
    "Verification": "anytime.verification",
    "verify": "anytime.verification",
    "measure_upstream": "anytime.measure.upstream",
}


def __getattr__(name: str) -> Any:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'anytime' has no attribute {name!r}")
    value = getattr(importlib.import_module(where), name)
    globals()[name] = value  # found once, then an ordinary attribute
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
