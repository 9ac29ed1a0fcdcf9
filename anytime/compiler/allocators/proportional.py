"""`Proportional`: Romanenko's rule for sharing a decision time T_d among alternatives,
`T_i = T_d * T_i* / sum_j T_j*`, with `T_i*` a lower bound on the time module i needs: here the
least time at which its expected quality (with perfect inputs) rises above its value at no
time, i.e. its first variant. Applied to every anytime module (a multi-module alternative so
gets the sum of its modules' bounds). Kept as a baseline: it looks at no profile beyond that
first point.
"""

from __future__ import annotations

import numpy as np

from anytime.compiler.allocators.lattice import proportional_split
from anytime.compiler.allocators.memory import DEFAULT_MEMORY, expected_in_chunks, row_bytes
from anytime.compiler.allocators.protocol import Evaluates, nothing_to_allocate
from anytime.compiler.model import reserved_step
from anytime.profiles.profile import Array, ConditionalPerformanceProfile
from anytime.vocabulary import first_useful_time


def least_useful_time(profile: ConditionalPerformanceProfile) -> float:
    """Romanenko's `T*`: the first time on the profile's grid at which, with perfect inputs, its
    expected quality rises above what it gives with no time (its first variant; for a profile
    that never improves, its first time)."""
    curve = profile.expected(np.ones((len(profile.time), profile.n_inputs)), profile.time)
    return first_useful_time(profile.time, curve, over_start=True)


class Proportional:
    """Romanenko's proportional split: each module's share of T is proportional to `T*`."""

    name = "proportional"

    def __init__(self, memory: int = DEFAULT_MEMORY) -> None:
        self.memory = memory

    def memory_needed(self, evaluator: Evaluates, units: np.ndarray) -> int:
        return 8 * len(units) * (evaluator.n_modules + 2) + row_bytes(evaluator.model)

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        nodes = evaluator.model.anytime_nodes
        if not nodes:
            return nothing_to_allocate(evaluator, quality, units)
        star = np.array([least_useful_time(n.profile) + reserved_step(n) for n in nodes])
        allocation = proportional_split(units, star)
        return allocation, expected_in_chunks(evaluator, quality, allocation * dt, self.memory)
