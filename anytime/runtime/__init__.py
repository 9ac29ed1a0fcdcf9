"""The runtime: executing anytime modules and compiled programs under contracts and
interruption, the frame monitor, and deadlines from critical events."""

from anytime.runtime.deadline import (
    CostBoundError,
    CriticalEvent,
    Deadline,
    DeadlineError,
    UnknownEventError,
    critical_event,
    deadline_from,
    proportional_split,
)
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
from anytime.runtime.program import ExecutionError, ProgramRecord, program_module, run_program

__all__ = [
    "Adjustment",
    "ContractDecision",
    "CostBoundError",
    "CostModel",
    "CriticalEvent",
    "Deadline",
    "DeadlineError",
    "DeadlineValue",
    "EventLog",
    "ExecutionError",
    "Monitor",
    "MonitorError",
    "MonitorEvent",
    "ProgramRecord",
    "RunRecord",
    "Status",
    "UnknownEventError",
    "ValueModel",
    "critical_event",
    "deadline_from",
    "program_module",
    "proportional_split",
    "run",
    "run_program",
]
