"""The compiler: optimal time allocation among a program's anytime modules."""

from anytime.compiler.allocators import (
    DynamicProgramming,
    Exhaustive,
    HillClimbing,
    Proportional,
    dp_obstacle,
)
from anytime.compiler.compile import ALLOCATORS, CompiledProgram, compile_file, compile_program
from anytime.compiler.evaluate import Dist, Evaluator
from anytime.compiler.model import CompileError, CompileModel, build_model
from anytime.compiler.multistart import MultiStart
from anytime.compiler.report import compiled_to_dict, format_report
from anytime.compiler.storage import load_compiled, save_compiled

__all__ = [
    "ALLOCATORS",
    "CompileError",
    "CompileModel",
    "CompiledProgram",
    "Dist",
    "DynamicProgramming",
    "Evaluator",
    "Exhaustive",
    "HillClimbing",
    "MultiStart",
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
