"""anytime-compose: build real-time systems out of anytime algorithms.

Write a program schema in the DSL, describe its modules by conditional performance profiles,
compile it into a contract algorithm with optimal time allocation, and run it under a monitor.
"""

from anytime.clocks import WallClock, WorkClock
from anytime.compiler import CompiledProgram, compile_file, compile_program
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
from anytime.profiles import ConditionalPerformanceProfile, PerformanceProfile
from anytime.profiles.io import load_profile, save_profile

__version__ = "0.1.0"

__all__ = [
    "AnytimeError",
    "AnytimeLibrary",
    "AnytimeModule",
    "CompiledProgram",
    "ConditionalPerformanceProfile",
    "Context",
    "DataflowGraph",
    "Diagnostic",
    "LibraryEntry",
    "LibraryError",
    "ModuleError",
    "PerformanceProfile",
    "PluginSource",
    "ProfileDirectory",
    "ProfileError",
    "Program",
    "REGISTRY",
    "RegistrationError",
    "Registry",
    "RegistrySource",
    "Result",
    "SchemaError",
    "SchemaFile",
    "SchemaSyntaxError",
    "Step",
    "UnknownModuleError",
    "WallClock",
    "WorkClock",
    "__version__",
    "compile_file",
    "compile_program",
    "contract",
    "elementary",
    "format_program",
    "interruptible",
    "load_profile",
    "load_schemas",
    "parse_schemas",
    "save_profile",
]
