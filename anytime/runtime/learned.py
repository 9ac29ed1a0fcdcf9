"""A stopping policy learned from recorded traces, on the run's whole history.

`OptimalStopping` is optimal on its model: a Markov chain on the binned quality the module
reports. When that state is not sufficient (the module reports an estimate, its runs differ in
kind, a run stalls, or ends by itself) the model is not the process: the policy optimises, and
promises, something else. `HistoryStopping` assumes no Markov state. It learns the rule from the
traces by regression on the history (least-squares Monte Carlo, Longstaff & Schwartz 2001, with
nearest neighbours as the regression), backward over the grid:

- at a look at grid time t_j, the value of each action for a run whose reports so far are h is
  the mean of what that action realised on the K training runs whose reports up to t_j are
  nearest to h (Euclidean, over every grid time up to t_j): an empirical posterior over the
  kinds of run, the runs that looked like this one so far;
- each training run's own decision at t_j is made without it (leave one out), and what it
  realises from t_j on follows the decisions so made.

Actions at a look: stop; go on and look at the next grid time; and, with a monitoring cost c per
look, stop at a later grid time without looking again. Before the run: look from the first grid
time on, or stop at a grid time without looking (the fixed policy), whichever the training runs
say is worth more, so that it is never worse than the fixed stop by more than sampling error.
A run that ends by itself (`QualityTraces.finished`) ends its trace there with its answer then,
and a run without an answer yet is not looked at (the executor waits for one), so runs that
converge, stall or start late are in the training as they happen.

`expected_utility` is not a model's number: it is the mean of the training runs' leave-one-out
realised utilities (looks paid), an estimate of what the policy realises on fresh runs from the
same distribution, with its `standard_error`; K is chosen among a few by that same estimate.
The rule assumes fresh runs are exchangeable with the training runs (the same module, inputs
from the same distribution) and enough training runs near each history: it is as good as its
traces, and the looks it takes, one at every grid time, are what it was trained on.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Callable, Sequence
from typing import Any, TypeVar, cast

import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from anytime.profiles.dynamic import Observed, QualityTraces
from anytime.profiles.profile import Array
from anytime.runtime.monitor import TIE_TOLERANCE
from anytime.runtime.observe import Decision, PolicyError
from anytime.runtime.policies import Utility, check_allocation, check_monitoring_cost, trace_cell

T = TypeVar("T")

#: The neighbour counts the policy chooses among (those below the number of training runs).
NEIGHBOURS = (5, 10, 20, 40, 80, 160)

#: Actions at a look (their columns): stop, look at the next grid time, and from BLIND on, stop
#: at the grid times after it without looking.
STOP, LOOK, BLIND = 0, 1, 2


@frozen
class HistoryTable:
    """`HistoryStopping`'s rule for one deadline (grid index `last`).

    Attributes:
        neighbours: K, the number of nearest training runs a decision rests on.
        follow: `(n, last + 2)` what each training run realises (looks paid) from a look due
            at each grid index on (column last + 1: none due, it stops at `last`).
        start: the decision before the run: (LOOK, 0) or (BLIND, the grid index to stop at).
        realised: `(n,)` what each training run realised under the rule, leave one out.
    """

    last: int
    neighbours: int
    follow: Array = field(eq=False)
    start: tuple[int, int]
    realised: Array = field(eq=False)

    @property
    def expected_utility(self) -> float:
        return float(self.realised.mean())

    @property
    def standard_error(self) -> float:
        n = len(self.realised)
        return float(self.realised.std(ddof=1) / math.sqrt(n)) if n > 1 else math.inf


class HistoryStopping:
    """Stopping learned from traces, on the run's history (see the module docstring).

    Args:
        training: recorded traces of the module (its runs on inputs like the one it is run on);
            the history is what it reports (`training.observed`), the utility its true quality's.
        utility: U(q, t).
        monitoring_cost: the utility a look costs.
        neighbours: K; default: chosen among `NEIGHBOURS` by the leave-one-out utility.
        input_quality: for traces over input-quality cells, the input qualities to learn at (the
            nearest grid cell).
    """

    name = "history"

    def __init__(
        self,
        training: QualityTraces,
        utility: Utility,
        *,
        monitoring_cost: float = 0.0,
        neighbours: int | None = None,
        input_quality: Sequence[float] = (),
    ) -> None:
        if not isinstance(training, QualityTraces):
            raise PolicyError(
                f"{self.name}: expected QualityTraces to learn from, got {type(training).__name__}"
            )
        cell = trace_cell(training, input_quality, self.name)
        n = training.trials
        if n < 2:
            raise PolicyError(f"{self.name}: expected at least 2 training traces, got {n}")
        if neighbours is not None and not (
            isinstance(neighbours, int) and not isinstance(neighbours, bool) and neighbours >= 1
        ):
            raise PolicyError(
                f"{self.name}: neighbours must be an integer >= 1, got {neighbours!r}"
            )
        self.monitoring_cost = check_monitoring_cost(self.name, monitoring_cost)
        self.observed: Observed | None = training.reports
        self.time = training.time
        self._scored = training.scored[cell]
        self._seen = training.observed[cell] * self._scored  # (n, m): 0 before an answer
        self._utility = utility(self.time, training.quality[cell].T).T  # (n, m)
        self._end = training.end_index()[cell]
        choices = (neighbours,) if neighbours is not None else NEIGHBOURS
        self._choices = tuple(sorted({min(k, n - 1) for k in choices}))
        self._near = _shared_neighbourhoods(training, cell, self._choices)
        self._tables: dict[int, HistoryTable] = {}
        self.allocation = math.inf
        self.last = len(self.time) - 1
        self._history = np.zeros(len(self.time))
        self._seen_to = -1

    # --- the run ---------------------------------------------------------------------------

    def start(self, allocation: float) -> Decision:
        self.allocation = check_allocation(self.name, allocation)
        self.last = self._last(self.allocation)
        self._history[:] = 0.0
        self._seen_to = -1
        if self.last < 0:
            return Decision.now("no grid time within the allocation")
        table = self.table(self.allocation)
        action, i = table.start
        worth = f"expected utility {table.expected_utility:.6g} (se {table.standard_error:.2g})"
        if action == BLIND:
            return Decision.later(math.inf, self.time[i], f"does not look: {worth}")
        return Decision.later(self._first_look(0), self.time[self.last], f"looks: {worth}")

    def observe(self, time: float, quality: float | None) -> Decision:
        j = int(
            np.clip(np.searchsorted(self.time, time * (1 + 1e-12), side="right") - 1, 0, self.last)
        )
        q = 0.0 if quality is None or self.observed == "none" else float(quality)
        # Grid times between looks (a module that reports its work coarsely) keep the last
        # report, as a run's best answer does.
        if self._seen_to >= 0:
            self._history[self._seen_to + 1 : j] = self._history[self._seen_to]
        self._history[j] = q
        self._seen_to = max(self._seen_to, j)
        if j >= self.last:
            return Decision.now("the last grid time within the allocation")
        table = self.table(self.allocation)
        members, _ = self._neighbourhood(j)
        if len(members) == 0:  # no training run was looked at here: look where one was
            return Decision.later(
                self._first_look(j + 1), self.time[self.last], "no training run was looked at here"
            )
        distance = ((self._seen[members, : j + 1] - self._history[: j + 1]) ** 2).sum(axis=1)
        k = min(table.neighbours, len(members))
        near = members[np.argsort(distance, kind="stable")[:k]]  # ties: the first run
        values = self._actions(near[None, :], j, table)[0].mean(axis=0)  # (actions,)
        column = int(_choose(values[None, :], self.monitoring_cost > 0)[0])
        on = f"on {k} nearest runs"
        if column == STOP:
            return Decision.now(f"stopping is worth {values[0]:.6g}, going on less ({on})")
        if column >= BLIND:
            at = self.time[j + column - 1]
            return Decision.later(
                math.inf,
                at,
                f"stopping at {at:g} without looking is worth {values[column]:.6g} ({on})",
            )
        return Decision.later(
            self.time[j + 1], self.time[self.last], f"going on is worth {values[1]:.6g} ({on})"
        )

    def expected_utility(self, allocation: float = math.inf) -> float:
        """What the policy is expected to realise on a fresh run (leave-one-out on the
        training runs, looks paid)."""
        return self._table_or_zero(allocation)[0]

    def standard_error(self, allocation: float = math.inf) -> float:
        """The standard error of `expected_utility`."""
        return self._table_or_zero(allocation)[1]

    # --- the learning ----------------------------------------------------------------------

    def table(self, allocation: float = math.inf) -> HistoryTable:
        """The rule for a deadline (learned once per deadline)."""
        last = self._last(check_allocation(self.name, allocation))
        if last < 0:
            raise PolicyError(f"{self.name}: no grid time within the allocation {allocation:g}")
        if last not in self._tables:
            tables = [self._learn(last, k) for k in self._choices]
            self._tables[last] = max(tables, key=lambda t: t.expected_utility)
        return self._tables[last]

    def _learn(self, last: int, neighbours: int) -> HistoryTable:
        """Backward induction over the grid with leave-one-out nearest-neighbour estimates."""
        n, c = len(self._utility), self.monitoring_cost
        rows = np.arange(n)
        end = self._end
        follow = np.empty((n, last + 2))
        over = end <= last  # runs that end by themselves within the deadline
        follow[:, last + 1] = np.where(over, self._utility[rows, np.minimum(end, last)], 0.0)
        follow[~over, last + 1] = self._utility[~over, last]
        table = HistoryTable(last, neighbours, follow, (LOOK, 0), np.zeros(n))
        for j in range(last, -1, -1):  # backward over the grid, vectorised over runs
            members, order = self._neighbourhood(j)
            after = follow[:, j + 1].copy()
            ended = end <= j
            after[ended] = self._utility[ended, end[ended]]
            if j == last or len(members) == 0:
                # At `last` the run ends: a look there could not change its answer.
                realised = self._utility[members, j] if j == last else after[members]
            else:
                k = min(neighbours, len(members) - 1) if len(members) > 1 else 1
                near = members[order[:, :k]] if len(members) > 1 else members[:, None]
                estimate = self._actions(near, j, table).mean(axis=1)  # (members, actions)
                taken = _choose(estimate, c > 0)
                own = self._actions(members, j, table)  # (members, actions)
                realised = own[np.arange(len(members)), taken] - c
            after[members] = realised
            follow[:, j] = after
        start = self._start(follow, last)
        blind_at = start[1]
        if start[0] == BLIND:
            stop = np.minimum(np.minimum(blind_at, end), last)
            realised = self._utility[rows, stop]
        else:
            realised = follow[:, 0]
        return HistoryTable(last, neighbours, follow, start, realised)

    def _start(self, follow: Array, last: int) -> tuple[int, int]:
        """Before the run: look from the start, or stop at the grid time of best mean utility
        without looking (the fixed policy), whichever the training runs say is worth more:
        looking only pays where what it shows is worth more than a fixed stop (and its looks'
        cost), which the leave-one-out estimate of the learned rule has to show."""
        stop = np.minimum(np.arange(last + 1)[None, :], self._end[:, None])
        blind = self._utility[np.arange(len(follow))[:, None], stop].mean(axis=0)
        best = int(np.argmax(blind))
        if follow[:, 0].mean() > blind[best] + TIE_TOLERANCE * max(1.0, abs(blind[best])):
            return LOOK, 0
        return BLIND, best

    def _actions(self, runs: NDArray[np.intp], j: int, table: HistoryTable) -> Array:
        """`(*runs.shape, actions)` what each action at a look at grid index j realises on the
        given training runs: stop, look at j + 1, then (with a monitoring cost) stop without
        looking at j + 1 .. last."""
        last = table.last
        stop = self._utility[runs, j]
        look = table.follow[runs, j + 1]
        if self.monitoring_cost == 0:  # blind stops are not chosen: do not gather them
            return np.stack([stop, look], axis=-1)
        later = np.arange(j + 1, last + 1)
        at = np.minimum(later, self._end[runs][..., None])
        blind = self._utility[runs[..., None], at]
        return np.concatenate([stop[..., None], look[..., None], blind], axis=-1)

    def _neighbourhood(self, j: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """The training runs looked at grid index j (running and with an answer there), and
        each one's nearest others among them, nearest first (up to the largest K)."""
        if j not in self._near:
            members = np.flatnonzero((self._end > j) & self._scored[:, j])
            history = self._seen[members, : j + 1]
            square = (history**2).sum(axis=1)
            distance = square[:, None] + square[None, :] - 2 * history @ history.T
            np.fill_diagonal(distance, np.inf)  # leave one out
            k = min(max(self._choices), len(members) - 1)
            if k < 1:
                order = np.zeros((len(members), 0), np.intp)
            else:
                # A stable sort, not a partition: runs whose reports are alike (quantised)
                # tie, and a partition's choice among them is numpy's (it changed between
                # versions, and so did the policy's promise); ties go to the first run.
                order = np.argsort(distance, axis=1, kind="stable")[:, :k]
            self._near[j] = (members, order)
        return self._near[j]

    def _first_look(self, j: int) -> float:
        """The first grid time from index j on where a training run was looked at (had an
        answer and was running): before it there is nothing to learn from."""
        for i in range(j, self.last + 1):
            if len(self._neighbourhood(i)[0]):
                return float(self.time[i])
        return float(self.time[self.last])

    def _table_or_zero(self, allocation: float) -> tuple[float, float]:
        if self._last(check_allocation(self.name, allocation)) < 0:
            return 0.0, 0.0
        table = self.table(allocation)
        return table.expected_utility, table.standard_error

    def _last(self, allocation: float) -> int:
        return int(np.searchsorted(self.time, allocation * (1 + 1e-12), side="right")) - 1


#: Neighbourhoods per training traces (by identity, while they live), cell and neighbour counts:
#: policies of several utilities learned from the same traces share them (they are most of the
#: learning's time).
_NEIGHBOURHOODS: dict[tuple[Any, ...], tuple[weakref.ref[QualityTraces], Any]] = {}


def _shared_neighbourhoods(
    training: QualityTraces, cell: tuple[int, ...], choices: tuple[int, ...]
) -> dict[int, tuple[NDArray[np.intp], NDArray[np.intp]]]:
    return kept_while_alive(_NEIGHBOURHOODS, training, (cell, choices), dict)


def kept_while_alive(
    store: dict[tuple[Any, ...], tuple[weakref.ref[QualityTraces], Any]],
    traces: QualityTraces,
    key: tuple[Any, ...],
    make: Callable[[], T],
) -> T:
    """What `make()` made for `traces` (by identity) and `key`, made once while the traces
    live: traces are arrays, not hashable, and a derived value must not keep them alive."""
    full = (id(traces), *key)
    kept = store.get(full)
    if kept is not None and kept[0]() is traces:
        return cast(T, kept[1])
    for stale in [k for k, (ref, _) in store.items() if ref() is None]:
        del store[stale]
    made = make()
    store[full] = (weakref.ref(traces), made)
    return made


def _choose(values: Array, blind: bool) -> NDArray[np.intp]:
    """Per row of action values at a look at grid index j (columns: stop, look at j + 1, then
    stop without looking at j + 1, j + 2, ..), the column of the best action: the first within
    the tie tolerance, so stopping before going on. Without a monitoring cost blind stops are
    not chosen (looking is free, and their estimates only add noise)."""
    candidates = values if blind else values[:, :2]
    best = candidates.max(axis=1)
    slack = TIE_TOLERANCE * np.maximum(1.0, np.abs(best))
    column: NDArray[np.intp] = np.argmax(candidates >= (best - slack)[:, None], axis=1)
    return column
