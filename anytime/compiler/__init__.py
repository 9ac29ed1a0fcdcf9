"""The compiler: optimal time allocation among a program's anytime modules."""

from anytime.compiler.allocators import (
    ALLOCATORS,
    DynamicProgramming,
    Exhaustive,
    HillClimbing,
    MultiStart,
    Proportional,
    dp_obstacle,
)
from anytime.compiler.compile import CompiledProgram, compile_file, compile_program
from anytime.compiler.dist import Dist
from anytime.compiler.evaluate import Evaluator
from anytime.compiler.model import CompileError, CompileModel
from anytime.compiler.outcomes import MESSAGES, Code, Note
from anytime.compiler.report import compiled_to_dict, format_report
from anytime.compiler.resolve import build_model
from anytime.compiler.result import BeyondTableWarning
from anytime.compiler.storage import load_compiled, save_compiled

__all__ = [
    "ALLOCATORS",
    "MESSAGES",
    "BeyondTableWarning",
    "Code",
    "CompileError",
    "CompileModel",
    "CompiledProgram",
    "Dist",
    "DynamicProgramming",
    "Evaluator",
    "Exhaustive",
    "HillClimbing",
    "MultiStart",
    "Note",
    "Proportional",
    "build_model",
    "compile_file",
    "compile_program",
    "compiled_to_dict",
    "dp_obstacle",
    "format_report",
    "load_compiled",
    "save_compiled",
]
