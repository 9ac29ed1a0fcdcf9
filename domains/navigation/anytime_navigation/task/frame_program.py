"""The frame's program: `navigate` of `schemas/navigation.any` (sense, then plan), compiled
against the navigation plugin's modules and their measured profiles, with the planner traced so
that the monitor can compare its quality so far with the profile's expectation."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from anytime import (
    AnytimeLibrary,
    CompiledProgram,
    LibraryEntry,
    Observer,
    RunRecord,
    Status,
    Stopping,
    StoppingPolicy,
    compile_file,
)
from anytime.plugin import AnytimeModule, Clock, Result, tabulate
from anytime.plugin.compose import EventLog, VisionHyperbola, default_time_grid

from ..resources import data_file, load_schema_file
from .vision import Q_A, T_A, T_B

__all__ = ["SCHEMA_FILE", "PlanTrace", "navigation_library", "navigation_program"]

#: The schema file of the papers' program.
SCHEMA_FILE = data_file("schemas", "navigation.any")


def _stand_in_profiles() -> dict[str, Any]:
    """Analytic profiles on the real modules' time scale, used while the measured ones are
    missing: vision's hyperbola (T_A, Q_A, T_B) and a planner `q^2 (1 - exp(-t / 400))`."""
    t_v = np.arange(0.0, 1201.0, 50.0)
    t_p = np.arange(0.0, 2001.0, 100.0)
    q_grid = [0.6, 0.7, 0.8, 0.9, 0.95, 1.0]
    return {
        "get-domain-description": tabulate(
            VisionHyperbola(t_a=T_A, q_a=Q_A, t_b=T_B),
            t_v,
            module="get-domain-description",
            kind="contract",
        ),
        "find-path": tabulate(
            lambda t, q: q**2 * (1.0 - np.exp(-t / 400.0)),
            t_p,
            input_grids=[q_grid],
            inputs=["domain"],
            module="find-path",
        ),
    }


#: Makes the stopping policy of one planner run from the quality of the map it is given and the
#: program time at which it starts (the sensing time before it).
PolicyMaker = Callable[[float, float], StoppingPolicy]


class PlanTrace(Observer):
    """The planner's observer in a frame's program run (`run_program(..., observers=
    {"find-path": trace})`): the quality of each plan it registered, at program times (since
    the program started, `reset`), and, under a stopping policy (`stop_with`), the policy's
    decisions at program times (`decisions`) and the program time at which it stopped the
    planner (`stopped`; None: it did not). `dynamic` is the planner's dynamic profile, when
    the library has one."""

    label = "stopping policy"

    def __init__(self, dynamic: Any = None) -> None:
        self.dynamic = dynamic
        self.qualities: list[tuple[float, float]] = []
        self.decisions = EventLog()
        self.stopped: float | None = None
        self.policy: PolicyMaker | None = None
        self._clock: Clock | None = None
        self._origin = self._began = 0.0
        self._stopping: Stopping | None = None

    def reset(self, clock: Clock) -> None:
        """A program run starts now on `clock`: forget the last one."""
        self._clock, self._origin = clock, clock.now()
        self.qualities.clear()
        self.decisions.events.clear()
        self.stopped = None

    def stop_with(self, make: PolicyMaker | None) -> None:
        """Run the planner under the policy `make` builds (None: to its allocation)."""
        self.policy = make

    def started(self, module: AnytimeModule, args: Sequence[Any], allocation: float) -> Any:
        clock = self._clock
        self._began = 0.0 if clock is None else clock.now() - self._origin
        self._stopping = None
        if self.policy is None:
            return None
        domain = args[2]  # find-path(start, goal, domain)
        policy = self.policy(float(domain.quality), self._began)
        self._stopping = Stopping(policy, _Shifted(self.decisions, self._began))
        return self._stopping.started(module, args, allocation)

    def registered(self, elapsed: float, result: Result) -> None:
        self.qualities.append((self._began + elapsed, float(result.quality)))

    def look(self, elapsed: float, best: Result | None) -> Any:
        return None if self._stopping is None else self._stopping.look(elapsed, best)

    def ended(self, record: RunRecord) -> None:
        if self._stopping is not None and record.status == Status.STOPPED:
            self.stopped = self._began + record.time_used


class _Shifted:
    """An event log that records at program times what is recorded at planner times."""

    def __init__(self, log: EventLog, shift: float) -> None:
        self.log, self.shift = log, shift

    def record(self, time: float, kind: str, data: Any) -> None:
        self.log.record(self.shift + time, kind, data)


def navigation_library(
    profile_dirs: Sequence[str | Path] = (), *, warn: Callable[[str], None] | None = None
) -> tuple[AnytimeLibrary, PlanTrace]:
    """The library `navigate` is compiled against: the navigation plugin's two modules with
    their measured profiles (analytic stand-ins when those cannot be read, with a warning), and
    the planner's observer (`PlanTrace`, with its dynamic profile when there is one)."""
    from .. import modules as nav

    base = AnytimeLibrary.default(profile_dirs=profile_dirs, plugins=False)
    stand_ins = _stand_in_profiles()
    trace = PlanTrace()
    library = AnytimeLibrary()
    for module in (nav.get_domain_description, nav.find_path):
        entry = base.get(module.name) or LibraryEntry.of_module(module)
        try:
            profile = entry.profile
        except Exception as error:  # missing or malformed file: say so, use the stand-in
            if warn is not None:
                warn(f"{str(error).splitlines()[0]}; using an analytic stand-in profile")
            profile = stand_ins[module.name]
        assert profile is not None
        if module.name == "find-path":
            trace.dynamic = entry.dynamic_profile
        library.add(
            LibraryEntry.of_module(
                attrs.evolve(
                    module,
                    profile_source=profile,
                    inputs=tuple(profile.inputs) if profile.inputs else module.inputs,
                )
            )
        )
    return library, trace


def navigation_program(
    profile_dirs: Sequence[str | Path] = (), *, warn: Callable[[str], None] | None = None
) -> tuple[CompiledProgram, PlanTrace]:
    """`navigate` of `schemas/navigation.any`, compiled against `navigation_library`."""
    library, trace = navigation_library(profile_dirs, warn=warn)
    schemas = load_schema_file("navigation.any")
    grid = default_time_grid(schemas, library, "navigate")
    compiled = compile_file(schemas, library, grid, schema="navigate")
    return compiled[-1], trace
