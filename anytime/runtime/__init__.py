"""The runtime: executing anytime modules and compiled programs under contracts and
interruption, and the frame monitor."""

from anytime.runtime.executor import RunRecord, Status, run
from anytime.runtime.monitor import (
    Adjustment,
    ContractDecision,
    CostModel,
    DeadlineValue,
    EventLog,
    Monitor,
    MonitorError,
    MonitorEvent,
    ValueModel,
)
from anytime.runtime.program import ProgramRecord, run_program

__all__ = [
    "Adjustment",
    "ContractDecision",
    "CostModel",
    "DeadlineValue",
    "EventLog",
    "Monitor",
    "MonitorError",
    "MonitorEvent",
    "ProgramRecord",
    "RunRecord",
    "Status",
    "ValueModel",
    "run",
    "run_program",
]
