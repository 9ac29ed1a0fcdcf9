"""Re-splitting time during a run: `reallocate`, the compiler's own search on its lattice over
some positions of an allocation, the others kept and the nodes that have run at the qualities
seen. The runtime uses it to re-split a best-of's time among its applicable alternatives; to
re-plan adaptively it asks a model's `Replanner`, which runs the same search only where a new
split is worth more than the one kept, and remembers its answers."""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Hashable, Mapping, Sequence
from weakref import WeakKeyDictionary

import numpy as np
from numpy.typing import ArrayLike

from anytime.compiler.allocators.exhaustive import Exhaustive
from anytime.compiler.allocators.hill_climbing import HillClimbing
from anytime.compiler.allocators.lattice import compositions
from anytime.compiler.dist import NO_RESULT
from anytime.compiler.evaluate import Evaluator
from anytime.compiler.model import CompileModel
from anytime.profiles.profile import Array

#: Observed qualities are planned on rounded to this (so that the plans of one program's runs
#: recur and are looked up, not searched again).
QUANTUM = 0.01
#: The least gain in expected output quality for which a new split replaces the kept one (on
#: top of twice the evaluation's standard error where the shared results were sampled): below
#: it the two are the same plan up to rounding.
LEAST_GAIN = 1e-9
#: The most splits a re-plan evaluates in one call (beyond, the compiler's search runs).
ONE_CALL_ROWS = 20_000
#: Re-plans a `Replanner` remembers (the least recently used forgotten first).
CACHE_SIZE = 4096


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


def _search(
    evaluator: Evaluator,
    resolution: float,
    qualities: Sequence[float],
    allocation: Array,
    free: list[int],
    budget: float,
    observed: Mapping[int, float],
) -> Array:
    """`reallocate`'s answer, with a given evaluator."""
    new = np.array(allocation, dtype=np.float64)
    if not free:
        return new
    new[free] = 0.0
    if budget <= 0:
        return new
    units = np.array([int(np.floor(budget / resolution + 1e-9))])
    restricted = Restricted(evaluator, new, free, observed)
    q = np.asarray(qualities, dtype=np.float64).reshape(1, -1)
    search = Exhaustive() if Exhaustive.computable(units, len(free)) else HillClimbing()
    split, _ = search.allocate(restricted, q, units, resolution)
    new[free] = split[0] * resolution
    new[free[0]] += budget - units[0] * resolution
    return new


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
    re-split a best-of's time among its applicable alternatives."""
    return _search(
        Evaluator(model), resolution, qualities, allocation, list(free), budget, observed
    )


class Replanner:
    """The adaptive re-plans of one model: `reallocate`'s search, kept only where it beats the
    split already planned, and remembered by what it was asked (the plans of a program's runs
    recur: the same totals, the same outcomes of the same modules)."""

    def __init__(self, model: CompileModel, resolution: float) -> None:
        self.model, self.resolution = model, resolution
        self.evaluator = Evaluator(model)
        self.plans: OrderedDict[Hashable, tuple[float, ...] | None] = OrderedDict()
        self.asked = 0  # re-plans answered (looked up or searched)
        self.searches = 0  # searches run (the rest were looked up)
        self.gain = 0.0  # the expected gain of the last search's answer over the planned split
        # What the runtime measured its searches to cost and found them to gain, by the kind
        # of clock: (time, gain, searches).
        self.costs: dict[str, tuple[float, float, int]] = {}

    def plan(
        self,
        qualities: Sequence[float],
        allocation: Array,
        free: Sequence[int],
        budget: float,
        observed: Mapping[int, float],
        search: bool = True,
    ) -> Array | None:
        """The allocation to run from here: `allocation` with `budget` re-split among the
        positions `free` where the best split the search finds, given the qualities
        `observed` (rounded to `QUANTUM`), is expected to do better than the one `allocation`
        holds by more than `LEAST_GAIN` and the evaluation's error; else `allocation` as it
        is. None when the answer is not remembered and `search` is False."""
        # The lookup is on every re-plan of every run: plain Python on a few numbers.
        free = list(free)
        left = max(budget, 0.0)
        units = math.floor(left / self.resolution + 1e-9)
        planned = allocation.tolist()
        seen = {
            i: q if q == NO_RESULT else round(q / QUANTUM) * QUANTUM for i, q in observed.items()
        }
        key = (
            tuple(free),
            units,
            tuple([planned[i] for i in free]),
            tuple(seen.items()),  # in the order the nodes ran
            tuple(qualities),
        )
        try:
            split = self.plans[key]
            self.plans.move_to_end(key)
        except KeyError:  # not remembered (or forgotten meanwhile, by another thread's plan)
            if not search:
                return None
            split = self._better_split(qualities, allocation, free, units, seen)
            self.plans[key] = split
            while len(self.plans) > CACHE_SIZE:
                self.plans.popitem(last=False)
        self.asked += 1
        if split is not None:
            for i, t in zip(free, split, strict=True):
                planned[i] = t
            planned[free[0]] += left - units * self.resolution
        return np.array(planned, dtype=np.float64)

    def _better_split(
        self,
        qualities: Sequence[float],
        allocation: Array,
        free: list[int],
        units: int,
        observed: Mapping[int, float],
    ) -> tuple[float, ...] | None:
        """The searched split of `units` among `free` (in time), or None where it is not
        expected to beat the kept one."""
        self.gain = 0.0
        if not free:
            return None
        self.searches += 1
        kept = np.array(allocation, dtype=np.float64)
        if math.comb(units + len(free) - 1, len(free) - 1) <= ONE_CALL_ROWS:
            # Every split of the lattice and the kept one in one evaluation (its cost is
            # mostly per call): the exhaustive search's answer, and the same draws for both.
            splits = compositions(units, len(free)) * self.resolution
            rows = np.tile(kept, (len(splits) + 1, 1))
            rows[:-1, free] = splits
        else:
            budget = units * self.resolution
            found = _search(
                self.evaluator, self.resolution, qualities, allocation, free, budget, observed
            )
            rows = np.vstack([found, kept])
        dist = self.evaluator.evaluate(qualities, rows, dict(observed))
        value, error = dist.expected(), dist.standard_error
        best = int(np.argmax(value[:-1]))
        if value[best] - value[-1] <= LEAST_GAIN + 2.0 * float(max(error[best], error[-1])):
            return None
        self.gain = float(value[best] - value[-1])
        return tuple(rows[best, free].tolist())


_REPLANNERS: WeakKeyDictionary[CompileModel, Replanner] = WeakKeyDictionary()


def replanner(model: CompileModel, resolution: float) -> Replanner:
    """The model's `Replanner` (one per model and resolution, kept while the model lives)."""
    found = _REPLANNERS.get(model)
    if found is None or found.resolution != resolution:
        found = _REPLANNERS[model] = Replanner(model, resolution)
    return found
