"""The runtime: executing anytime modules and compiled programs under contracts and
interruption."""

from anytime.runtime.executor import RunRecord, Status, run
from anytime.runtime.program import ProgramRecord, run_program

__all__ = ["ProgramRecord", "RunRecord", "Status", "run", "run_program"]
