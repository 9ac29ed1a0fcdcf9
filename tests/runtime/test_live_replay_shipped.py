"""Live runs of the shipped interruptible modules under a stopping policy keep the answer that
`replay` stops their recorded trace at, after the same looks.

The traces are recorded by the profile builder; each trial is then run again live, on the same
instance (made afresh from the trial's seed) and the same work clock, watched by the policy.
A policy that learned from the traces, and one on their dynamic profile, are both checked:
what the benchmark replays is what a run does.

This holds for modules that report their work at every grid time (the routing plugin's, a
tick a step), as `replay` says. It does not for the navigation planner, which reports its work a
whole search at a time (up to hundreds of ticks): a live look comes at the first report after
the grid time it was due at and sees the answer there, where the trace shows the answer at the
grid time, so it is not in this test.
"""

from __future__ import annotations

import numpy as np
import pytest

from anytime.library import AnytimeLibrary
from anytime.measure.builder import build_profile
from anytime.measure.trials import Chunk, trial_of
from anytime.problems import Grid
from anytime.profiles.dynamic import DynamicProfile
from anytime.runtime import (
    Budget,
    HistoryStopping,
    OptimalStopping,
    Stopping,
    Utility,
    replay,
    run,
)
from anytime.runtime.modes import SOFT


class Value:
    def value(self, state: object, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return np.asarray(quality) ** 2


class Cost:
    def __init__(self, rate: float) -> None:
        self.rate = rate

    def cost(self, state: object, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return self.rate * np.asarray(contract) * np.ones_like(quality)


CASES = [  # module, input quality, grid, cost per tick
    ("plan-tours", 0.9, np.arange(0.0, 31.0, 1.0), 0.01),
    ("cluster-stops", 0.8, np.arange(0.0, 21.0, 1.0), 0.01),
]


@pytest.mark.parametrize(("name", "input_quality", "time", "rate"), CASES)
def test_a_live_run_keeps_what_replay_stops_its_trace_at(
    name: str, input_quality: float, time: np.ndarray, rate: float
) -> None:
    library = AnytimeLibrary.default()
    module, problems = library[name].module, library.measurement(name).problems
    inputs = [[input_quality]] * len(module.inputs)
    trials = 12
    build = build_profile(
        module,
        problems,
        time=time,
        input_grids=inputs,
        trials=trials,
        seed=5,
        progress=False,
        traces=True,
        mode=SOFT,
    )
    traces = build.traces
    assert traces is not None
    utility = Utility(Value(), Cost(rate))
    quality = [input_quality] * len(module.inputs)
    makers = {
        "history": lambda: HistoryStopping(traces, utility, input_quality=quality, neighbours=5),
        "optimal": lambda: OptimalStopping(
            DynamicProfile.from_traces(traces, states=4),
            Value(),
            Cost(rate),
            input_quality=quality,
        ),
        # The state with when the run entered its bin, and ended runs apart: the policy tracks
        # the class from its looks, live as in replay.
        "optimal, entered and ends": lambda: OptimalStopping(
            DynamicProfile.from_traces(traces, states=3, entered=3, ends=True),
            Value(),
            Cost(rate),
            input_quality=quality,
        ),
        "optimal, entered, costly looks": lambda: OptimalStopping(
            DynamicProfile.from_traces(traces, states=3, entered=3),
            Value(),
            Cost(rate),
            input_quality=quality,
            monitoring_cost=0.002,
        ),
    }
    grid = Grid(time, inputs)  # the build's, so that trial i is made as the builder made it
    chunk = Chunk(module, problems, grid, "work", 5, trials, 0, trials, SOFT)
    cell = (0,) * len(module.inputs)
    observed, true = traces.observed[cell], traces.quality[cell]
    scored, ends = traces.scored[cell], traces.end_index()[cell]
    allocation = float(time[-1])
    for label, make in makers.items():
        for i in range(trials):
            trial = trial_of(chunk, i)
            instance, args = trial.problem()
            offline = replay(make(), time, observed[i], allocation, scored[i], int(ends[i]))
            record = run(
                module,
                args,
                budget=Budget(allocation, clock=trial.clock()),
                observer=Stopping(make()),
            )
            kept = 0.0 if record.result is None else trial.score(instance, record.result.value)
            expected = true[i, offline.stop_index] if scored[i, offline.stop_index] else 0.0
            assert (kept, record.looks) == (pytest.approx(expected), offline.looks), (label, i)
