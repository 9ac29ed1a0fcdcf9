"""What a plugin that composes and runs programs of its own needs beyond `anytime`, opt-in:
`from anytime.plugin.compose import ...`.

Compiling and running take their names from `anytime` itself (`AnytimeLibrary`,
`LibraryEntry`, `compile_file`, `compile_program`, `CompiledProgram`, `run`, `run_program`,
`RunRecord`, `ProgramRecord`, `Status`, ...). This module adds the rest a plugin uses when it
drives its own programs, each where the framework defines it:

- the time stock for deciding, from critical events (`deadline_from`, `Deadline`) and its split
  among the steps of a plan (`proportional_split`);
- the monitor, which chooses each frame's contract time (`Monitor`, its `ValueModel` and
  `CostModel` protocols, `DeadlineValue`, the `Adjustment` it makes), and the `EventLog` of a
  run;
- the compiler's `default_time_grid` for a schema;
- a profile from a formula: `VisionHyperbola` (an S-shaped quality curve, nothing before `t_a`)
  for `anytime.plugin.tabulate`, and `Array`, the type of a profile's tables.
"""

from __future__ import annotations

from anytime.compiler.compile import default_time_grid
from anytime.profiles.families import VisionHyperbola
from anytime.profiles.profile import Array
from anytime.runtime.deadline import Deadline, deadline_from, proportional_split
from anytime.runtime.monitor import (
    Adjustment,
    CostModel,
    DeadlineValue,
    EventLog,
    Monitor,
    ValueModel,
)

__all__ = [
    # deadlines
    "Deadline",
    "deadline_from",
    "proportional_split",
    # the monitor
    "Monitor",
    "ValueModel",
    "CostModel",
    "DeadlineValue",
    "Adjustment",
    "EventLog",
    # compiling
    "default_time_grid",
    # profiles from a formula
    "VisionHyperbola",
    "Array",
]
