"""The runtime: executing anytime modules and compiled programs under contracts and
interruption, the frame monitor, stopping policies, and deadlines from critical events."""

from anytime.isolation import WATCHDOG, IsolationError, Limits
from anytime.runtime.conformal import ConformalStopping, ConformalTable
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
from anytime.runtime.executor import RunInterrupted, RunRecord, Status, run
from anytime.runtime.learned import HistoryStopping, HistoryTable
from anytime.runtime.modes import Budget, Hard, Isolated, RunMode, Soft
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
from anytime.runtime.observe import Decision, Observer, PolicyError
from anytime.runtime.offline import (
    Assessment,
    Evaluation,
    Replay,
    assess,
    clairvoyant,
    evaluate,
    replay,
)
from anytime.runtime.policies import (
    FixedStopping,
    MyopicStopping,
    OptimalStopping,
    ProjectedStopping,
    Stopping,
    StoppingModel,
    StoppingPlan,
    StoppingPolicy,
    Utility,
)
from anytime.runtime.program import ExecutionError, ProgramRecord, program_module, run_program
from anytime.runtime.selection import Candidate, FittedStopping, fit_optimal

__all__ = [
    "Observer",
    "Stopping",
    "Soft",
    "RunMode",
    "Isolated",
    "Hard",
    "Budget",
    "Adjustment",
    "ConformalStopping",
    "ConformalTable",
    "HistoryStopping",
    "Candidate",
    "FittedStopping",
    "fit_optimal",
    "Assessment",
    "assess",
    "HistoryTable",
    "ContractDecision",
    "CostBoundError",
    "CostModel",
    "CriticalEvent",
    "Deadline",
    "DeadlineError",
    "DeadlineValue",
    "Decision",
    "Evaluation",
    "EventLog",
    "ExecutionError",
    "FixedStopping",
    "IsolationError",
    "Limits",
    "Monitor",
    "MonitorError",
    "MonitorEvent",
    "MyopicStopping",
    "OptimalStopping",
    "PolicyError",
    "ProgramRecord",
    "ProjectedStopping",
    "Replay",
    "RunInterrupted",
    "RunRecord",
    "Status",
    "StoppingModel",
    "StoppingPlan",
    "StoppingPolicy",
    "UnknownEventError",
    "Utility",
    "ValueModel",
    "WATCHDOG",
    "clairvoyant",
    "critical_event",
    "deadline_from",
    "evaluate",
    "program_module",
    "proportional_split",
    "replay",
    "run",
    "run_program",
]
