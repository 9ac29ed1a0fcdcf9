"""Re-splitting time during a run: `reallocate`, the compiler's own search on its lattice over
some positions of an allocation, the others kept and the nodes that have run at the qualities
seen. The runtime uses it to re-split a best-of's time among its applicable alternatives and to
re-plan adaptively."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from anytime.compiler.allocators.exhaustive import Exhaustive
from anytime.compiler.allocators.hill_climbing import HillClimbing
from anytime.compiler.evaluate import Evaluator
from anytime.compiler.model import CompileModel
from anytime.profiles.profile import Array


class Restricted:
    """A program's evaluator with the allocation fixed except at the positions `free`, and
    some nodes' qualities fixed (`observed`)."""

    def __init__(
        self,
        evaluator: Evaluator,
        base: Array,
        free: Sequence[int],
        observed: Mapping[int, float],
    ) -> None:
        self.evaluator, self.base, self.free, self.observed = evaluator, base, list(free), observed

    @property
    def model(self) -> CompileModel:
        return self.evaluator.model

    @property
    def n_modules(self) -> int:
        return len(self.free)

    def expected(self, quality: ArrayLike, allocation: ArrayLike) -> Array:
        part = np.atleast_2d(np.asarray(allocation, dtype=np.float64))
        full = np.tile(self.base, (len(part), 1))
        full[:, self.free] = part
        return self.evaluator.expected(quality, full, dict(self.observed))


def reallocate(
    model: CompileModel,
    resolution: float,
    qualities: Sequence[float],
    allocation: Array,
    free: Sequence[int],
    budget: float,
    observed: Mapping[int, float],
) -> Array:
    """The best split of `budget` among the allocation positions `free` during a run, the
    others kept as in `allocation` and the nodes in `observed` at the qualities seen: the
    compiler's own search on its lattice (exhaustive where affordable, else hill-climbing),
    whatever the lattice cannot hold going to the first free position. Used by the runtime to
    re-split a best-of's time among its applicable alternatives and to re-plan adaptively."""
    new = np.array(allocation, dtype=np.float64)
    free = list(free)
    if not free:
        return new
    new[free] = 0.0
    if budget <= 0:
        return new
    units = np.array([int(np.floor(budget / resolution + 1e-9))])
    restricted = Restricted(Evaluator(model), new, free, observed)
    q = np.asarray(qualities, dtype=np.float64).reshape(1, -1)
    search = Exhaustive() if Exhaustive.computable(units, len(free)) else HillClimbing()
    split, _ = search.allocate(restricted, q, units, resolution)
    new[free] = split[0] * resolution
    new[free[0]] += budget - units[0] * resolution
    return new
