"""Stopping policies offline: on recorded traces, and exactly on a dynamic profile's model.

`replay` runs a policy on one recorded trace as the executor would run it on the module;
`clairvoyant` is the best utility a trace allowed (the yardstick of regret); `assess` replays a
policy on every trace of a recording (runs it was not built from: the check of what it promises);
`evaluate` computes
any policy's expected utility exactly on a profile's Markov chain, by enumerating the chain's
state paths (for small models: a policy may read the whole history, so nothing smaller is
exact), which is how the tests check that the optimal policy is optimal on its own model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.profiles.dynamic import QualityTraces
from anytime.profiles.profile import Array
from anytime.runtime.observe import PolicyError
from anytime.runtime.policies import (
    StoppingModel,
    StoppingPolicy,
    Utility,
    check_allocation,
    check_monitoring_cost,
    trace_cell,
)

#: How many state paths `evaluate` enumerates at most.
MAX_PATHS = 200_000


@frozen
class Replay:
    """Where a policy stopped a recorded trace: the grid index and how many looks it took."""

    stop_index: int
    looks: int


def replay(
    policy: StoppingPolicy,
    time: ArrayLike,
    observed: ArrayLike,
    allocation: float | None = None,
    scored: ArrayLike | None = None,
    ended: int | None = None,
) -> Replay:
    """Run `policy` on one recorded trace, as the executor would: it is consulted at the first
    grid time with an answer at or after each `look_at` and stops there, or at the first grid
    time at or after `stop_at`, never after `allocation` (default: the trace's last time); a
    look due where the run ends anyway (its stop time, or a deadline on the grid) is not
    taken, since it could not change the answer. A
    run whose module reports its work at every grid time makes the same looks and decisions
    live (`run(..., observer=Stopping(policy))`): the executor looks at the report of work that
    reaches the time asked, once the run has an answer.

    Args:
        time: the trace's grid times (m,).
        observed: the quality the module reported at each (m,).
        scored: whether it had an answer there (default: everywhere).
        ended: the grid index where the run ended by itself (`QualityTraces.end_index`): the
            run is over there, whatever the policy would do next (default: it never did).
    """
    t = np.asarray(time, dtype=np.float64)
    q = np.asarray(observed, dtype=np.float64)
    had = np.ones(len(t), bool) if scored is None else np.asarray(scored, dtype=bool)
    if q.shape != t.shape or had.shape != t.shape or t.ndim != 1 or len(t) == 0:
        raise PolicyError(
            f"replay: expected time, observed and scored of one shape (m,), got"
            f" {list(t.shape)}, {list(q.shape)} and {list(had.shape)}"
        )
    deadline = float(t[-1]) if allocation is None else float(allocation)
    last = int(np.searchsorted(t, deadline * (1 + 1e-12), side="right")) - 1
    decision = policy.start(deadline)
    looks = 0
    if decision.stop or last < 0:
        return Replay(0, 0)
    for j in range(last + 1):  # one step of the run per grid time
        if ended is not None and j >= ended:
            return Replay(j, looks)  # the module returned: the run is over
        if t[j] >= decision.stop_at or j == last and t[j] >= deadline:
            return Replay(j, looks)  # the run ends here: a look could not change its answer
        if had[j] and t[j] >= decision.look_at:  # the executor looks at results only
            decision = policy.observe(float(t[j]), float(q[j]))
            looks += 1
            if decision.stop or t[j] >= decision.stop_at:
                return Replay(j, looks)
    return Replay(last, looks)


@frozen
class Evaluation:
    """A policy's expected utility (looks paid for) and expected number of looks on a model."""

    expected_utility: float
    expected_looks: float


def evaluate(
    policy: StoppingPolicy,
    model: StoppingModel,
    allocation: float = math.inf,
    monitoring_cost: float = 0.0,
    max_paths: int = MAX_PATHS,
) -> Evaluation:
    """The exact expected utility of any policy on `model`'s Markov chain: every state path up
    to the deadline with its probability, replayed (a state is reported as its mean true quality
    when the state is the true quality, else as its bin's midpoint). For small models only."""
    c = check_monitoring_cost("evaluate", monitoring_cost)
    last = model.last(check_allocation("evaluate", allocation))
    if last < 0:
        return Evaluation(0.0, 0.0)
    k, n = model.profile.n_states, last + 1
    if k**n > max_paths:
        raise PolicyError(
            f"evaluate: the model has {k}^{n} state paths, more than max_paths ({max_paths})"
        )
    paths = np.stack(np.unravel_index(np.arange(k**n), (k,) * n), axis=1)  # (P, n)
    probability = model.marginal[0][paths[:, 0]]
    for j in range(n - 1):
        probability = probability * model.profile.transition[j][paths[:, j], paths[:, j + 1]]
    keep = probability > 0
    paths, probability = paths[keep], probability[keep]
    bins = model.profile.bins
    # What a path's state shows: its bin's (a state is a bin, or a bin and an entry class).
    level = model.profile.state_bin
    shown = (
        model.profile.true_quality()[1][:n, np.arange(k), level]
        if model.profile.observed == "true"
        else ((bins[:-1] + bins[1:]) / 2)[np.broadcast_to(level, (n, k))]
    )
    # A path in an ended state is a run that ended there: the executor consults no policy.
    over = paths >= model.profile.running_states
    ends = np.where(over.any(axis=1), np.argmax(over, axis=1), n)
    t = model.time[:n]
    utility = np.empty(len(paths))
    looks = np.empty(len(paths))
    for p, path in enumerate(paths):  # a policy may read the whole history: replay each path
        result = replay(
            policy,
            t,
            shown[np.arange(n), path],
            allocation=min(allocation, t[-1]),
            ended=int(ends[p]) if ends[p] < n else None,
        )
        utility[p] = model.stop_utility[result.stop_index, path[result.stop_index]]
        looks[p] = result.looks
    expected_looks = float(probability @ looks)
    return Evaluation(float(probability @ utility) - c * expected_looks, expected_looks)


def clairvoyant(time: ArrayLike, true_quality: ArrayLike, utility: Utility) -> Array:
    """The best utility each trace allowed: max over its grid times of U(q_j, t_j), for traces
    `true_quality` (..., m) at `time` (m,)."""
    t = np.asarray(time, dtype=np.float64)
    q = np.asarray(true_quality, dtype=np.float64)
    flat = q.reshape(-1, len(t))
    best: Array = utility(t, flat.T).max(axis=0).reshape(q.shape[:-1])
    return best


@frozen
class Assessment:
    """What a policy realised on recorded runs.

    Attributes:
        utility: the mean utility, looks paid for.
        standard_error: that mean's standard error.
        clairvoyant: the mean of the best utility each run allowed.
        looks: the mean number of looks.
        runs: how many runs.
    """

    utility: float
    standard_error: float
    clairvoyant: float
    looks: float
    runs: int

    @property
    def fraction(self) -> float:
        """The mean utility as a fraction of the clairvoyant's."""
        return self.utility / self.clairvoyant if self.clairvoyant else math.nan


def assess(
    policy: StoppingPolicy,
    traces: QualityTraces,
    utility: Utility,
    allocation: float | None = None,
    monitoring_cost: float = 0.0,
    input_quality: Sequence[float] = (),
) -> Assessment:
    """Replay `policy` on every run of `traces` (as the executor would run it: see `replay`,
    each run ending where it ended by itself) and score it: U(true quality, time) at its stop,
    less `monitoring_cost` per look. On runs the policy was not built from, this is the check
    of what it promises (its `expected_utility`)."""
    got, best, looks = scores(policy, traces, utility, allocation, monitoring_cost, input_quality)
    n = len(got)
    se = float(got.std(ddof=1) / math.sqrt(n)) if n > 1 else math.inf
    return Assessment(float(got.mean()), se, float(best.mean()), float(looks.mean()), n)


def scores(
    policy: StoppingPolicy,
    traces: QualityTraces,
    utility: Utility,
    allocation: float | None = None,
    monitoring_cost: float = 0.0,
    input_quality: Sequence[float] = (),
) -> tuple[Array, Array, Array]:
    """What `assess` averages, run by run: `(utility, clairvoyant, looks)`, each `(trials,)`.
    A policy started afresh decides the same on the same trace, so runs that showed the monitor
    the same (reports, answers and end) are replayed once."""
    c = check_monitoring_cost("assess", monitoring_cost)
    cell = trace_cell(traces, input_quality, "assess")
    t = traces.time
    deadline = float(t[-1]) if allocation is None else check_allocation("assess", allocation)
    last = int(np.searchsorted(t, deadline * (1 + 1e-12), side="right")) - 1
    if last < 0:
        raise PolicyError(f"assess: no grid time within the allocation {deadline:g}")
    observed, scored = traces.observed[cell], traces.scored[cell]
    quality, ends = traces.quality[cell][:, : last + 1], traces.end_index()[cell]
    seen = np.column_stack([observed, scored, ends])
    _, first, inverse = np.unique(seen, axis=0, return_index=True, return_inverse=True)
    runs = [  # one replay per distinct trace: a policy may read the whole history
        replay(policy, t, observed[i], deadline, scored[i], int(ends[i])) for i in first
    ]
    inverse = inverse.reshape(-1)
    stop = np.array([r.stop_index for r in runs], dtype=np.intp)[inverse]
    looks = np.array([r.looks for r in runs], dtype=np.float64)[inverse]
    worth = utility(t[: last + 1], quality.T).T
    got: Array = worth[np.arange(len(stop)), stop] - c * looks
    # What each run allowed: up to the allocation and its own end.
    reach = np.arange(last + 1)[None, :] <= ends[:, None]
    best: Array = np.where(reach, worth, -np.inf).max(axis=1)
    return got, best, looks
