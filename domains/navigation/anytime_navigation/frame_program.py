"""The frame's program: `navigate` of `schemas/navigation.any` (sense, then plan), compiled
against the navigation plugin's modules and their measured profiles, with the planner traced so
that the monitor can compare its quality so far with the profile's expectation."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np
from attrs import field, frozen

from anytime import (
    AnytimeLibrary,
    Budget,
    CompiledProgram,
    LibraryEntry,
    Status,
    Stopping,
    StoppingPolicy,
    compile_file,
    run,
)
from anytime.plugin import AnytimeModule, Context, Result, tabulate
from anytime.plugin.compose import EventLog, VisionHyperbola, default_time_grid

from .resources import data_file, load_schema_file
from .vision import Q_A, T_A, T_B
from .world import Position

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


@frozen
class PlanTrace:
    """What the traced planner saw in its last run: the map it was given and the quality of
    each plan it yielded, with the program time (since the program started) of each.

    For a run under a stopping policy (`stop_with`): the policy's decisions, at program times
    (`decisions`), and the program time at which it stopped the planner (`stopped`; empty: it
    did not). `dynamic` holds the planner's dynamic profile when the library has one."""

    domain: list[Any] = field(factory=list)
    qualities: list[tuple[float, float]] = field(factory=list)
    origin: list[float] = field(factory=list)
    dynamic: list[Any] = field(factory=list)
    policy: list[PolicyMaker] = field(factory=list)
    decisions: EventLog = field(factory=EventLog)
    stopped: list[float] = field(factory=list)

    def reset(self, start: float) -> None:
        self.domain.clear()
        self.qualities.clear()
        self.origin[:] = [start]
        self.decisions.events.clear()
        self.stopped.clear()

    def stop_with(self, make: PolicyMaker | None) -> None:
        """Run the planner under the policy `make` builds (None: to its allocation)."""
        self.policy[:] = [] if make is None else [make]

    def quality_at(self, elapsed: float) -> float:
        """The best plan's quality at `elapsed` into the program (0 before the first plan)."""
        best = 0.0
        for t, q in self.qualities:
            if t <= elapsed + 1e-9:
                best = q
        return best


def navigation_library(
    profile_dirs: Sequence[str | Path] = (), *, warn: Callable[[str], None] | None = None
) -> tuple[AnytimeLibrary, PlanTrace]:
    """The library `navigate` is compiled against: the navigation plugin's two modules with
    their measured profiles (analytic stand-ins when those cannot be read, with a warning),
    `find-path` wrapped so that its plans' qualities are recorded in the returned trace."""
    from . import modules as nav

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
        function = module.function
        if module.name == "find-path":
            function = _traced(module, trace)
            trace.dynamic[:] = [] if entry.dynamic_profile is None else [entry.dynamic_profile]
        library.add(
            LibraryEntry.of_module(
                attrs.evolve(
                    module,
                    function=function,
                    profile_source=profile,
                    inputs=tuple(profile.inputs) if profile.inputs else module.inputs,
                )
            )
        )
    return library, trace


def _traced(module: AnytimeModule, trace: PlanTrace) -> Callable[..., Any]:
    """`module`'s function recording its plans' qualities in `trace`; under a policy (see
    `PlanTrace.stop_with`) the planner is run by the runtime executor with that policy, and its
    best plan is yielded when the policy stops it."""

    def recorded(ctx: Context, start: Position, goal: Position, domain: Result) -> Any:
        origin = trace.origin[0] if trace.origin else ctx.start
        for result in module.function(ctx, start, goal, domain):
            trace.qualities.append((ctx.clock.now() - origin, float(result.quality)))
            yield result

    watched = attrs.evolve(module, function=recorded)

    def find_path(ctx: Context, start: Position, goal: Position, domain: Result) -> Any:
        trace.domain[:] = [domain]
        if not trace.policy:
            yield from recorded(ctx, start, goal, domain)
            return
        began = ctx.clock.now() - (trace.origin[0] if trace.origin else ctx.start)
        policy = trace.policy[0](float(domain.quality), began)
        log = EventLog()
        record = run(
            watched,
            (start, goal, domain),
            budget=Budget(ctx.remaining, clock=ctx.clock, stop=ctx.stop),
            observer=Stopping(policy, log),
        )
        for event in log:  # at program times, as the trace's qualities
            trace.decisions.record(began + event.time, event.kind, event.data)
        if record.status == Status.STOPPED:
            trace.stopped[:] = [began + record.time_used]
        if record.result is not None:
            yield record.result

    return find_path


def navigation_program(
    profile_dirs: Sequence[str | Path] = (), *, warn: Callable[[str], None] | None = None
) -> tuple[CompiledProgram, PlanTrace]:
    """`navigate` of `schemas/navigation.any`, compiled against `navigation_library`."""
    library, trace = navigation_library(profile_dirs, warn=warn)
    schemas = load_schema_file("navigation.any")
    grid = default_time_grid(schemas, library, "navigate")
    compiled = compile_file(schemas, library, grid, schema="navigate")
    return compiled[-1], trace
