"""What the stopping-policy tests share: a linear utility and random quality traces."""

from __future__ import annotations

from typing import Any

import numpy as np

from anytime.profiles.dynamic import QualityTraces


class Linear:
    """Value `worth` per unit of quality, cost `rate` per unit of time."""

    def __init__(self, worth: float, rate: float) -> None:
        self.worth, self.rate = worth, rate

    def value(self, state: Any, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return self.worth * quality

    def cost(self, state: Any, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return self.rate * contract


def traces(seed: int, m: int, trials: int, reports: str = "true") -> QualityTraces:
    """Non-decreasing random qualities (an anytime module's best answer so far) at ticks 0, 10,
    20, ..., with an estimate that is the quality plus noise when the module reports one."""
    rng = np.random.default_rng(seed)
    steps = rng.exponential(rng.uniform(0.05, 0.4, (trials, 1)), (trials, m))
    quality = np.minimum(np.cumsum(steps, axis=1), 1.0)
    estimate = None
    if reports == "estimate":
        estimate = np.clip(quality + rng.normal(0, 0.15, quality.shape), 0, 1)
    return QualityTraces(
        module="walk",
        time=np.arange(m) * 10.0,
        quality=quality,
        scored=np.ones(quality.shape, bool),
        estimate=estimate,
        reports=reports,  # type: ignore[arg-type]
    )


def ending(recorded: QualityTraces, seed: int) -> QualityTraces:
    """The traces with about half the runs ending by themselves at a random grid time after
    the first (their quality and estimate held from there on), the others running to the end."""
    rng = np.random.default_rng(seed)
    trials, m = recorded.quality.shape
    end = np.where(rng.random(trials) < 0.5, rng.integers(1, m, trials), m - 1)
    held = np.minimum(np.arange(m), end[:, None])
    rows = np.arange(trials)[:, None]
    estimate = None if recorded.estimate is None else recorded.estimate[rows, held]
    return QualityTraces(
        module=recorded.module,
        time=recorded.time,
        quality=recorded.quality[rows, held],
        scored=recorded.scored,
        estimate=estimate,
        reports=recorded.reports,
        finished=recorded.time[end],
    )
