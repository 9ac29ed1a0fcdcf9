"""OMPL's planners as resumable solvers (`anytime.plugin.solvers.Resumable`) on a work clock of
validity checks, and shortcutting with a budget of checks.

The unit of work is one state validity check, counted by the checker OMPL calls: deterministic,
unlike seconds. `advance(limit)` calls OMPL's `solve` with a termination condition that tests
the count; OMPL tests it once an iteration, so an iteration may want more checks than the limit
leaves: the checker then answers "invalid" without counting (never wrong for the path: a
motion that is not checked is not taken), so a slice never spends more than its limit, and
the planner goes on where it stopped at the next `solve`. OMPL's random numbers are seeded
from the query's seed before every `solve` (every generator OMPL makes in it is seeded from
that stream), so a run depends on its seed and its slices only.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from anytime.plugin import Result

from .domain import FloatArray, OccupancyMap, Path, Query

__all__ = ["PLANNERS", "RESOLUTION", "OmplPlanner", "Shortcutter", "segment_checks"]

#: OMPL's validity-checking resolution of a motion, a fraction of the space's extent (sqrt D):
#: about one occupancy cell in 2-D.
RESOLUTION = 0.005


def _ompl() -> tuple[Any, Any, Any]:
    from ompl import base, geometric, util

    return base, geometric, util


#: The planners, by module name: OMPL's geometric planner class names.
PLANNERS = {"rrt-star": "RRTstar", "bit-star": "BITstar"}


class _Quiet:
    """OMPL's log silenced (its per-solve information, and its warning that the seed changes
    after random numbers were drawn, which is what is meant here), restored afterwards."""

    def __enter__(self) -> None:
        _, _, util = _ompl()
        self.level = util.getLogLevel()
        util.setLogLevel(util.LOG_NONE)

    def __exit__(self, *exc: object) -> None:
        _, _, util = _ompl()
        util.setLogLevel(self.level)


class _Counter:
    """The validity checker OMPL calls, counting its checks, and the termination condition's
    test (apart from the planner, so that OMPL's objects and the checker make no cycle)."""

    def __init__(self, map: OccupancyMap) -> None:
        self.map = map
        self.checks = 0
        self.stop = 0

    def spent(self) -> bool:
        return self.checks >= self.stop

    def valid(self, state: Any) -> bool:
        self.checks += 1
        return self.map.free(state)


class OmplPlanner:
    """An OMPL geometric planner (`PLANNERS`) on an occupancy map, minimising path length,
    from the query's start to its goal; its unit of work is one validity check.

    `best()` is the shortest exact solution so far, a `Path`, with the self-estimate the
    straight-line distance over its cost (a lower bound of how close it is to the shortest
    path on this map)."""

    def __init__(self, planner: str, map: OccupancyMap, query: Query) -> None:
        base, geometric, util = _ompl()
        self.map = map
        self.query = query
        self._counter = _Counter(map)
        self._best: Result | None = None
        self._cost = math.inf
        self._finished = False
        d = query.dimension
        with _Quiet():
            util.RNG.setSeed(query.seed)
            space = base.RealVectorStateSpace(d)
            bounds = base.RealVectorBounds(d)
            bounds.setLow(0.0)
            bounds.setHigh(1.0)
            space.setBounds(bounds)
            si = base.SpaceInformation(space)
            si.setStateValidityChecker(self._counter.valid)
            si.setStateValidityCheckingResolution(RESOLUTION)
            si.setup()
            start, goal = space.allocState(), space.allocState()
            for k in range(d):
                start[k] = float(query.start[k])
                goal[k] = float(query.goal[k])
            pdef = base.ProblemDefinition(si)
            pdef.setStartAndGoalStates(start, goal)
            pdef.setOptimizationObjective(base.PathLengthOptimizationObjective(si))
            solver = getattr(geometric, PLANNERS[planner])(si)
            solver.setProblemDefinition(pdef)
            solver.setup()
        self._space, self._si, self._pdef, self._solver = space, si, pdef, solver
        self._keep = (start, goal)  # OMPL holds copies; kept alive with the planner anyway

    def advance(self, limit: float) -> float:
        """Run `solve` for at most `limit` validity checks (at least one); the checks spent
        (0: it can do no more, its start or goal is not free on the map)."""
        if self._finished:
            return 0.0
        base, _, util = _ompl()
        counter = self._counter
        before = counter.checks
        counter.stop = before + max(1, int(limit))
        with _Quiet():
            util.RNG.setSeed(self.query.seed + before)
            # a fresh condition each time: one that has said "stop" says it for good
            status = self._solver.solve(base.PlannerTerminationCondition(counter.spent))
        name = str(status)
        if "Invalid" in name or "Abort" in name or "Crash" in name:
            self._finished = True
        if self._pdef.hasExactSolution():
            path = self._pdef.getSolutionPath()
            cost = float(path.length())
            if cost < self._cost - 1e-12:
                self._cost = cost
                d = self.query.dimension
                points = np.array([[s[k] for k in range(d)] for s in path.getStates()])
                estimate = min(1.0, self.query.straight / cost) if cost > 0 else 1.0
                self._best = Result(Path(points, self.map), estimate)
        return float(counter.checks - before)

    @property
    def checks(self) -> int:
        return self._counter.checks

    def best(self) -> Result | None:
        return self._best


def segment_checks(a: FloatArray, b: FloatArray) -> int:
    """The validity checks of the straight motion from a to b, as OMPL counts them: one state
    every RESOLUTION of the extent, the end included (the start is known valid)."""
    extent = math.sqrt(len(a))
    return max(1, int(math.ceil(float(np.linalg.norm(b - a)) / (RESOLUTION * extent))))


class Shortcutter:
    """Random shortcutting of a path on its map, a `Resumable` whose unit is one validity
    check: pick two points on the path (uniform in arc length), check the straight motion
    between them state by state (as OMPL checks a motion), and splice it in when it is free
    and shorter. Seeded; the self-estimate is the straight-line distance over the cost."""

    def __init__(
        self,
        path: Path,
        straight: float,
        seed: int,
        cap: float = 1.0,
        free: Callable[[FloatArray], np.ndarray] | None = None,
    ) -> None:
        self.points = path.points.copy()
        self.map = path.map
        self.straight = straight
        self.cap = cap
        self.rng = np.random.default_rng(seed)
        self.free = free or (self.map.free_points if self.map is not None else None)
        self.checks = 0
        self._pending: tuple[FloatArray, int, int, int] | None = None  # an attempt under way
        self._best: Result | None = None
        self._cost = Path(self.points).cost
        self._failures = 0

    def _estimate(self) -> float:
        cost = Path(self.points).cost
        return min(self.cap, 1.0 if cost <= 0 else min(1.0, self.straight / cost))

    def _attempt(self) -> tuple[FloatArray, int, int, int] | None:
        """A new shortcut to check: its states, and the indices it joins."""
        points = self.points
        lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
        total = float(lengths.sum())
        if len(points) < 3 or total <= 0:
            return None
        cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
        s, t = np.sort(self.rng.uniform(0, total, 2))
        i = int(np.searchsorted(cumulative, s, side="right")) - 1
        j = int(np.searchsorted(cumulative, t, side="right")) - 1
        i, j = min(i, len(lengths) - 1), min(j, len(lengths) - 1)
        if j <= i:
            return None  # both on one segment: nothing to cut
        a = points[i] + (s - cumulative[i]) / lengths[i] * (points[i + 1] - points[i])
        b = points[j] + (t - cumulative[j]) / lengths[j] * (points[j + 1] - points[j])
        n = segment_checks(a, b)
        states = a + (np.arange(1, n + 1)[:, None] / n) * (b - a)
        return np.vstack([a[None], states]), i, j, 0

    def advance(self, limit: float) -> float:
        """Check up to `limit` states (at least one) of the shortcuts under way; the checks
        spent (0: no shortcut left to try: 200 tries in a row found none to check)."""
        if self.free is None:
            return 0.0
        budget = max(1, int(limit))
        spent = 0
        while spent < budget:
            if self._pending is None:
                attempt = self._attempt()
                if attempt is None:
                    self._failures += 1
                    if self._failures > 200:
                        break
                    continue
                self._pending = attempt
            states, i, j, done = self._pending
            todo = states[1 + done : 1 + done + (budget - spent)]
            ok = self.free(todo)
            bad = np.flatnonzero(~ok)
            if len(bad):
                spent += int(bad[0]) + 1
                self._pending = None
                continue
            spent += len(todo)
            done += len(todo)
            if 1 + done < len(states):
                self._pending = (states, i, j, done)
                continue
            self._pending = None
            a, b = states[0], states[-1]
            self.points = np.vstack([self.points[: i + 1], a[None], b[None], self.points[j + 1 :]])
            self.points = _drop_repeats(self.points)
            cost = Path(self.points).cost
            if cost < self._cost - 1e-12:
                self._cost = cost
                self._failures = 0
                self._best = Result(Path(self.points.copy(), self.map), self._estimate())
        self.checks += spent
        return float(spent)

    def best(self) -> Result | None:
        return self._best


def _drop_repeats(points: FloatArray) -> FloatArray:
    keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-12])
    return np.asarray(points[keep])
