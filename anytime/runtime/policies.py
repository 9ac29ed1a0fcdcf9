"""Stopping policies: when to stop an interruptible module, from what it shows while it runs.

The utility of stopping at time t with true quality q is U(q, t) = value(state, t, q) - cost(state,
t, q), the monitor's `ValueModel` and `CostModel` with the domain's state passed through. A policy
decides on the time grid of the module's dynamic performance profile (`DynamicProfile`): at each
look it is given the time and the quality the module reports (its true quality or its estimate,
as the profile's states are), and answers with a `Decision`: stop now, or go on, with the time of
the next look (`look_at`, infinite: never look again) and the time to stop at without looking
(`stop_at`).

- `FixedStopping` never looks: it stops at the time of best expected utility under the profile,
  the monitor's contract choice on a dynamic profile.
- `MyopicStopping` looks at every grid time and stops when one more step is expected to lose
  utility (Hansen & Zilberstein 2001, section 3: the myopic rule).
- `OptimalStopping` solves the stopping problem by backward induction over the profile's states
  (Hansen & Zilberstein 2001, sections 3-4), with the observation model P(true quality | state)
  when the state is an estimate. With a monitoring cost c per look it also chooses how long to run
  before the next look, or to stop later without looking:

      V(j, s) = max( U_stop(j, s),  max_i [ E V(i, s') - c ],  max_i E U_stop(i, s') ),  i > j,

  E over P(s' at i | s at j), the product of the profile's one-step transitions. Without a
  monitoring cost it looks at every grid time. On a profile whose state includes when the run
  entered its bin (`DynamicProfile.entered`), a look sees that only if the run was seen the step
  before: after skipped grid times the policy takes the most probable class, so the backward
  induction's value is then what a policy that saw the class would get, and the policy's
  `expected_utility` is instead the exact value of what it does on the model (`plan_outcome`).
  On a profile with ended states (`DynamicProfile.ends`) a run that enters one is over: every
  policy counts its utility there and never looks at it (`StoppingModel.banked`, `marginal` of
  the runs still in play).
- `ProjectedStopping` predicts the run's own curve online (Svegliato, Wray & Zilberstein 2018):
  it fits q(t) = a - b exp(-c t) to the qualities seen so far, by least squares, and stops once the
  projected best stopping time has come.

A policy never stops after the allocation: its grid ends at the last grid time within it.
`anytime.runtime.offline` evaluates policies on recorded traces and on the model.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import attrs
import numpy as np
from attrs import field, frozen
from numpy.typing import ArrayLike, NDArray

from anytime.modules import AnytimeModule, Result
from anytime.profiles.dynamic import DynamicProfile, Observed, QualityTraces
from anytime.profiles.profile import Array
from anytime.runtime.driving import describe
from anytime.runtime.monitor import TIE_TOLERANCE, CostModel, ValueModel, model_answer
from anytime.runtime.observe import Decision, Observer, PolicyError

# --- decisions and the protocol -------------------------------------------------------------


class StoppingPolicy(Protocol):
    """A stopping policy, consulted by `run(..., observer=Stopping(policy))` (and by `replay`).

    Attributes:
        name: how the event log names it.
        observed: what the quality it is given must be ("true", "estimate" or "none", as the
            module's `reports`), or None when any will do.
    """

    name: str
    observed: Observed | None

    def start(self, allocation: float) -> Decision:
        """Before the run, given its allocation (the deadline)."""
        ...

    def observe(self, time: float, quality: float | None) -> Decision:
        """At a look: the time since the start and the quality of the run's answer (None: no
        answer yet)."""
        ...


class Log(Protocol):
    """Where a stopping policy's decisions go: an `EventLog`, or anything that records."""

    def record(self, time: float, kind: str, data: Mapping[str, Any]) -> None: ...


class Stopping(Observer):
    """A stopping policy as the observer of one run (`run(..., observer=Stopping(policy, log))`):
    asked before the run and at each look it schedules, with the quality of the run's answer
    then; its decisions are recorded in `log` (kind "stopping")."""

    label = "stopping policy"

    def __init__(self, policy: StoppingPolicy, log: Log | None = None) -> None:
        self.policy, self.log = policy, log
        self.allocation = math.inf

    def started(
        self, module: AnytimeModule, args: Sequence[Any], allocation: float
    ) -> Decision | None:
        if module.kind != "interruptible":
            raise PolicyError(
                f"run: a stopping policy needs an interruptible module; '{module.name}' is a"
                f" {module.kind} module (make_interruptible turns a contract into one)"
            )
        observed = self.policy.observed
        if observed is not None and observed != module.reports:
            raise PolicyError(
                f"run: policy '{self.policy.name}' reads {_REPORTS[observed]}, but module"
                f" '{module.name}' reports {_REPORTS[module.reports]}"
            )
        self.allocation = float(allocation)
        return self._follow(0.0, None, self.policy.start(self.allocation))

    def look(self, elapsed: float, best: Result | None) -> Decision | None:
        quality = None if best is None else best.quality
        return self._follow(elapsed, quality, self.policy.observe(elapsed, quality))

    def _follow(self, time: float, quality: float | None, decision: Decision) -> Decision:
        if not isinstance(decision, Decision):
            raise PolicyError(
                f"policy '{self.policy.name}' answered with {describe(decision)}, not a Decision"
            )
        if self.log is not None:
            self.log.record(
                time,
                "stopping",
                {
                    "policy": self.policy.name,
                    "quality": quality,
                    "decision": "stop" if decision.stop else "continue",
                    "look_at": None if decision.stop else _never(decision.look_at),
                    "stop_at": None
                    if decision.stop
                    else _never(min(decision.stop_at, self.allocation)),
                    "reason": decision.reason,
                },
            )
        return decision


_REPORTS = {
    "true": "the true quality",
    "estimate": "an estimate of the quality",
    "none": "nothing of the quality",
}


def _never(time: float) -> float | None:
    """A time for the log: None for never (JSON has no infinity)."""
    return None if time == math.inf else time


# --- utility and the Markov model -----------------------------------------------------------


@frozen
class Utility:
    """U(q, t) = value(state, t, q) - cost(state, t, q) of the monitor's models."""

    value_model: ValueModel[Any]
    cost_model: CostModel[Any]
    state: Any = None

    def __call__(self, time: ArrayLike, quality: ArrayLike) -> Array:
        """Utilities for times (G,) and qualities (G, K): (G, K)."""
        t = np.asarray(time, dtype=np.float64).reshape(-1, 1)
        q = np.asarray(quality, dtype=np.float64)
        q = q.reshape(len(t), -1)
        value = model_answer("value", self.value_model.value(self.state, t, q), q.shape)
        cost = model_answer("cost", self.cost_model.cost(self.state, t, q), q.shape)
        answer: Array = value - cost
        return answer


@frozen
class StoppingModel:
    """A dynamic profile at one input-quality cell, with the utility of stopping in each state.

    Attributes:
        profile: the profile, without input axes.
        utility: U(q, t).
        marginal: `(m, K)` P(state at each time) under the profile's Markov chain, from its
            occupancy at the first grid time.
        stop_utility: `(m, K)` E[U(true quality, t_j) | state k at t_j].
        expected_true: `(m, K)` E[true quality | state k at t_j].
        stop_square: `(m, K)` E[U(true quality, t_j)^2 | state k at t_j], for the spread of
            what a policy realises.
        banked: `(m,)` with ended states (`DynamicProfile.ends`), the utility of the runs that
            ended before each time, counted where they ended (then `marginal` is of the runs
            still in play: running, or ending there); zeros without.
    """

    profile: DynamicProfile
    utility: Utility
    marginal: Array = field(eq=False)
    stop_utility: Array = field(eq=False)
    expected_true: Array = field(eq=False)
    stop_square: Array = field(eq=False)
    banked: Array = field(eq=False)

    def blind(self, last: int) -> Array:
        """`(last + 1,)` the expected utility of stopping at each grid time without looking (a
        run that ended before counts where it ended)."""
        n = last + 1
        curve: Array = np.einsum("jk,jk->j", self.marginal[:n], self.stop_utility[:n])
        return curve + self.banked[:n]

    @classmethod
    def of(
        cls, profile: DynamicProfile, utility: Utility, input_quality: Sequence[float] = ()
    ) -> StoppingModel:
        if not isinstance(profile, DynamicProfile):
            raise PolicyError(f"stopping: expected a DynamicProfile, got {type(profile).__name__}")
        cell = profile.at(input_quality)
        given, quality = cell.true_quality()  # (m, K, B) each
        m = len(cell.time)
        if not cell.per_state:  # one quality per bin: the utility of (m, B)
            worth = np.broadcast_to(utility(cell.time, cell.quality_mean)[:, None, :], given.shape)
        else:
            worth = utility(cell.time, quality.reshape(m, -1)).reshape(quality.shape)
        stop = (given * worth).sum(axis=-1)
        expected_true = (given * quality).sum(axis=-1)
        square = (given * worth**2).sum(axis=-1)
        # Runs in play at each time; a run that ends is counted (banked) where it ended.
        over = cell.ended
        marginal = np.empty_like(cell.occupancy)
        marginal[0] = cell.occupancy[0]
        banked = np.zeros(m)
        for j in range(m - 1):  # one vector-matrix product per time step
            banked[j + 1] = banked[j] + marginal[j][over] @ stop[j][over]
            marginal[j + 1] = np.where(over, 0.0, marginal[j]) @ cell.transition[j]
        return cls(cell, utility, marginal, stop, expected_true, square, banked)

    @property
    def time(self) -> Array:
        return self.profile.time

    def last(self, allocation: float) -> int:
        """The index of the last grid time within `allocation` (-1: none is)."""
        return int(np.searchsorted(self.time, allocation * (1 + 1e-12), side="right")) - 1

    def index(self, time: float, last: int) -> int:
        """The grid index a look at `time` is at: the last grid time not after it."""
        return int(
            np.clip(np.searchsorted(self.time, time * (1 + 1e-12), side="right") - 1, 0, last)
        )

    def bin(self, quality: float | None) -> int:
        """The bin of a reported quality (no answer: the bin of quality 0)."""
        bins = self.profile.bins
        q = 0.0 if quality is None or self.profile.observed == "none" else float(quality)
        return int(np.clip(np.searchsorted(bins, q, side="right") - 1, 0, len(bins) - 2))

    def state(self, quality: float | None, entry_class: int = 0) -> int:
        """The state of a reported quality, the run having entered its bin in `entry_class`
        (profiles with `entered` only; else there is one class)."""
        return self.bin(quality) * self.profile.classes + entry_class


def perceived_classes(
    model: StoppingModel, last_look: tuple[int, int, int] | None, j: int
) -> NDArray[np.intp]:
    """`(B,)` for a look at grid index `j` that sees each bin, the class a policy takes the run
    to have entered it in, where the profile tracks entry times (`DynamicProfile.entered`):
    the last look's (grid index, bin, class) if the bin is the same, this step's if the bin
    changed since the step before, else (looks skipped, or none yet) the most probable under
    the profile's chain from the last look (from the start: the marginal)."""
    profile = model.profile
    classes, bins = profile.classes, profile.n_bins
    if last_look is None:
        belief = model.marginal[j]
    else:
        belief = np.zeros(profile.n_states)
        belief[last_look[1] * classes + last_look[2]] = 1.0
        for step in range(last_look[0], j):  # a vector-matrix product per time step
            belief = belief @ profile.transition[step]
    running = belief[: profile.running_states].reshape(bins, classes)
    chosen: NDArray[np.intp] = np.argmax(running, axis=1)
    if last_look is not None:
        if j - last_look[0] <= 1:
            chosen[:] = profile.entry_class(j)
        chosen[last_look[1]] = last_look[2]
    return chosen


def trace_cell(traces: QualityTraces, input_quality: Sequence[float], name: str) -> tuple[int, ...]:
    """The index of the input-quality cell of `traces` nearest to `input_quality`: where a
    policy learned from traces learns."""
    grids = traces.input_grids
    if len(input_quality) != len(grids):
        raise PolicyError(
            f"{name}: the traces have {len(grids)} input-quality axes, got {len(input_quality)}"
            " input qualities"
        )
    return tuple(
        int(np.argmin(np.abs(np.asarray(g) - float(x))))
        for g, x in zip(grids, input_quality, strict=True)
    )


def check_allocation(name: str, allocation: float) -> float:
    value = float(allocation)
    if math.isnan(value) or value < 0:
        raise PolicyError(f"{name}: allocation must be a number >= 0, got {allocation!r}")
    return value


def _best(candidates: Array) -> tuple[Array, Array]:
    """Per row, the highest value and the first column within the tie tolerance of it."""
    best = candidates.max(axis=-1)
    slack = TIE_TOLERANCE * np.maximum(1.0, np.abs(best))
    first = np.argmax(candidates >= (best - slack)[..., None], axis=-1)
    return best, first


class _GridPolicy(ABC):
    """What every policy on a dynamic profile shares: its model and the run's deadline."""

    name = "policy"

    def __init__(
        self,
        profile: DynamicProfile,
        value_model: ValueModel[Any],
        cost_model: CostModel[Any],
        state: Any = None,
        *,
        input_quality: Sequence[float] = (),
    ) -> None:
        self.model = StoppingModel.of(
            profile, Utility(value_model, cost_model, state), input_quality
        )
        self.observed: Observed | None = self.model.profile.observed
        self.allocation = math.inf
        self.last = len(self.model.time) - 1
        self._last_look: tuple[int, int, int] | None = None  # the last look: grid index, bin, class

    def start(self, allocation: float) -> Decision:
        self._last_look = None
        self.allocation = check_allocation(self.name, allocation)
        self.last = self.model.last(self.allocation)
        if self.last < 0:
            return Decision.now("no grid time within the allocation")
        return self._start()

    @abstractmethod
    def _start(self) -> Decision:
        """The decision before the run's first look, once the deadline is known."""

    @abstractmethod
    def observe(self, time: float, quality: float | None) -> Decision:
        """The decision at a look at `time`, the run's answer of `quality` (None: none yet)."""

    def _state(self, j: int, quality: float | None) -> int:
        """The state of a look at grid index `j` (see `perceived_classes`)."""
        model, profile = self.model, self.model.profile
        b, classes = model.bin(quality), profile.classes
        if classes == 1:
            return b
        klass = int(perceived_classes(model, self._last_look, j)[b])
        self._last_look = (j, b, klass)
        return b * classes + klass

    def _look_next(self, j: int, reason: str) -> Decision:
        """Go on to the next grid time and look there."""
        t = self.model.time
        return Decision.later(t[j + 1], min(self.allocation, t[self.last]), reason)


# --- the policies -----------------------------------------------------------------------------


class FixedStopping(_GridPolicy):
    """Stop at the grid time of best expected utility, without looking."""

    name = "fixed"
    _stop_at = math.inf

    def expected_utility(self, allocation: float = math.inf) -> float:
        last = self.model.last(check_allocation(self.name, allocation))
        return float(self._curve(last).max()) if last >= 0 else 0.0

    def _curve(self, last: int) -> Array:
        return self.model.blind(last)

    def _start(self) -> Decision:
        curve = self._curve(self.last)
        _, j = _best(curve[None, :])
        at = float(self.model.time[int(j[0])])
        reason = f"best expected utility {curve[int(j[0])]:.6g} at {at:g}"
        self._stop_at = at
        return Decision.later(math.inf, at, reason)

    def observe(self, time: float, quality: float | None) -> Decision:
        return Decision.later(math.inf, self._stop_at, "does not look")


def _every_step_value(
    model: StoppingModel, stop: Array, last: int, monitoring_cost: float
) -> float:
    """The expected utility of looking at every grid time from the first and stopping in the
    states `stop` (m, K) marks (at `last` in every state, where the run ends without a look),
    each look costing `monitoring_cost`."""
    alive = model.marginal[0].copy()
    total = looks = 0.0
    running = ~model.profile.ended
    for j in range(last + 1):  # forward over time steps, vectorised over states
        # The run ends at `last`: no look there; nor at a run that ended by itself.
        looks += alive[running].sum() if j < last else 0.0
        stopping = alive if j == last else alive * stop[j]
        total += stopping @ model.stop_utility[j]
        if j < last:
            alive = (alive - stopping) @ model.profile.transition[j]
    return float(total - monitoring_cost * looks)


class MyopicStopping(_GridPolicy):
    """Look at every grid time; stop when one more step's expected gain (the utility at the next
    grid time, from the transition at the state seen, less the cost of looking again) is below
    zero."""

    name = "myopic"

    def __init__(self, *args: Any, monitoring_cost: float = 0.0, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.monitoring_cost = check_monitoring_cost(self.name, monitoring_cost)

    def gain(self) -> Array:
        """`(m - 1, K)` the expected gain of one more step in each state at each time."""
        m = self.model
        ahead = np.einsum("jkl,jl->jk", m.profile.transition, m.stop_utility[1:])
        gain: Array = ahead - m.stop_utility[:-1] - self.monitoring_cost
        return gain

    def stops(self) -> Array:
        """`(m, K)` where the rule stops (always at the last grid time)."""
        over = self.model.profile.ended
        return np.vstack([(self.gain() < 0) | over, np.ones((1, len(over)), bool)])

    def expected_utility(self, allocation: float = math.inf) -> float:
        last = self.model.last(check_allocation(self.name, allocation))
        if last < 0:
            return 0.0
        return _every_step_value(self.model, self.stops(), last, self.monitoring_cost)

    def _start(self) -> Decision:
        return Decision.later(self.model.time[0], self.model.time[self.last], "looks every step")

    def observe(self, time: float, quality: float | None) -> Decision:
        j = self.model.index(time, self.last)
        s = self._state(j, quality)
        if j == self.last:
            return Decision.now("the last grid time within the allocation")
        gain = float(self.gain()[j, s])
        if gain < 0:
            return Decision.now(f"one more step is expected to lose {-gain:.6g}")
        return self._look_next(j, f"one more step is expected to gain {gain:.6g}")


def check_monitoring_cost(name: str, cost: float) -> float:
    value = float(cost)
    if not (math.isfinite(value) and value >= 0):
        raise PolicyError(f"{name}: monitoring_cost must be a finite number >= 0, got {cost!r}")
    return value


@frozen
class StoppingPlan:
    """`OptimalStopping`'s solution for one deadline.

    Attributes:
        value: `(n, K)` V(j, s), the expected utility from a look at grid time j in state s.
        action: `(n, K)` what to do there: 0 stop now, 1 stop at `target` without looking,
            2 look again at `target`.
        target: `(n, K)` the grid index of that later stop or look.
        expected_utility: the value of the whole run, before any look.
        first: the start's action (1 stop at, 2 look at) and its grid index.
    """

    value: Array = field(eq=False)
    action: Array = field(eq=False)
    target: Array = field(eq=False)
    expected_utility: float
    first: tuple[int, int]


STOP, STOP_AT, LOOK_AT = 0, 1, 2


def solve(
    model: StoppingModel, last: int, monitoring_cost: float, skips: bool = True
) -> StoppingPlan:
    """Backward induction over the model's states up to grid index `last` (see the module
    docstring); without a monitoring cost the only choice at a look is to stop or look at the
    next grid time. Without `skips`, looks, once begun, come at every grid time from the first
    (so a look always sees a run's entry class)."""
    c = monitoring_cost
    n, k = last + 1, model.profile.n_states
    over = model.profile.ended
    u = model.stop_utility[:n]
    value, action, target = u.copy(), np.zeros((n, k), int), np.zeros((n, k), int)
    # Columns i = j + 1 .. last: E[V(i, s')] and E[U_stop(i, s')] from each state at j.
    looks, stops = np.zeros((k, 0)), np.zeros((k, 0))
    for j in range(n - 2, -1, -1):  # one matrix product per time step
        step = model.profile.transition[j]
        if c == 0:
            candidates = np.column_stack([u[j], step @ value[j + 1]])
            kinds, targets = np.array([STOP, LOOK_AT]), np.array([j, j + 1])
        else:
            ahead_look = np.column_stack([value[j + 1], looks])
            ahead_stop = np.column_stack([u[j + 1], stops])
            # A run that ends at j + 1 is over there: worth its answer then, and not looked at.
            ahead_look[over] = u[j + 1, over, None] + c
            ahead_stop[over] = u[j + 1, over, None]
            looks, stops = step @ ahead_look, step @ ahead_stop
            later = np.arange(j + 1, n)
            seen = later if skips else later[:1]
            candidates = np.column_stack([u[j], stops, looks[:, : len(seen)] - c])
            kinds = np.r_[STOP, np.full(len(later), STOP_AT), np.full(len(seen), LOOK_AT)]
            targets = np.r_[j, later, seen]
        value[j], chosen = _best(candidates)
        action[j], target[j] = kinds[chosen], targets[chosen]
        # A run in an ended state is over: nothing is decided there, it is worth its answer.
        value[j, over], action[j, over], target[j, over] = u[j, over], STOP, j
    # The start sees nothing: the first look's value under the occupancy there (a run that
    # ended before counts where it ended; one ending there is not looked at).
    running = model.marginal[:n, ~over].sum(axis=1)
    reach = np.einsum("jk,jk->j", model.marginal[:n], value) + model.banked[:n] - c * running
    if c == 0:
        return StoppingPlan(value, action, target, float(reach[0]), (LOOK_AT, 0))
    blind = model.blind(last)
    best, chosen = _best(np.concatenate([blind, reach if skips else reach[:1]])[None, :])
    i = int(chosen[0])
    first = (STOP_AT, i) if i < n else (LOOK_AT, i - n)
    return StoppingPlan(value, action, target, float(best[0]), first)


@frozen
class Outcome:
    """What following a plan is worth on its model: the expected utility (looks paid), and E[U]
    and E[U^2] at the stop (looks not paid), for the spread of what a run realises."""

    value: float
    mean: float
    square: float


def plan_outcome(model: StoppingModel, plan: StoppingPlan, last: int, cost: float) -> Outcome:
    """The exact outcome of the policy that follows `plan` on the model's chain, as the policy
    acts: at each look it takes the state it perceives (`perceived_classes`: the entry class
    is known only when the run was seen the step before), while the chain moves on from the
    true one. The mass of runs at each look is kept per (true state, perceived state) and
    carried, a group of perceived states per (action, target), to the look or stop their
    action names; a run that ends on the way stops where it ends."""
    n, k = last + 1, model.profile.n_states
    classes, over = model.profile.classes, model.profile.ended
    level = model.profile.state_bin
    looking: dict[int, Array] = {}
    stopping = np.zeros((n, k))
    looks = 0.0

    def carry(moved: Array, j: int, i: int) -> Array:
        """Runs (states x columns) from grid index j to i, those that end on the way stopping
        where they end (those that end at i too)."""
        for step in range(j, i):  # a matrix product per time step
            stopping[step] += np.where(over[:, None], moved, 0.0).sum(axis=1)
            moved = model.profile.transition[step].T @ np.where(over[:, None], 0.0, moved)
        stopping[i] += np.where(over[:, None], moved, 0.0).sum(axis=1)
        return np.where(over[:, None], 0.0, moved)

    def look(mass: Array, i: int, perceived: list[NDArray[np.intp]]) -> None:
        """Runs (states x columns) arriving at a look at i, column c taking bin b for state
        perceived[c][b]."""
        nonlocal looks
        table = looking.setdefault(i, np.zeros((k, k)))
        looks += float(mass.sum())
        running = np.flatnonzero(~over)
        for column in range(mass.shape[1]):
            seen = perceived[column][level[running]]
            np.add.at(table, (running, seen), mass[running, column])

    def seen_as(last_look: tuple[int, int, int] | None, i: int) -> NDArray[np.intp]:
        """State perceived at a look at i, per bin."""
        bins: NDArray[np.intp] = np.arange(model.profile.n_bins)
        if classes == 1:
            return bins
        return bins * classes + perceived_classes(model, last_look, i)

    action, at = plan.first
    start = carry(model.marginal[0][:, None], 0, at)
    if action == STOP_AT:
        stopping[at] += start[:, 0]
    else:
        look(start, at, [seen_as(None, at)])
    for j in range(n):
        if j not in looking:
            continue
        mass = looking.pop(j)
        acts, targets = plan.action[j], plan.target[j]
        stopping[j] += mass[:, acts == STOP].sum(axis=1)
        groups = {(int(a), int(i)) for a, i in zip(acts, targets, strict=True) if a != STOP}
        for a, i in sorted(groups):
            columns = np.flatnonzero((acts == a) & (targets == i) & (mass.sum(axis=0) > 0))
            if not len(columns):
                continue
            moved = carry(mass[:, columns], j, i)
            if a == STOP_AT:
                stopping[i] += moved.sum(axis=1)
            else:
                perceived = [seen_as((j, int(level[p]), int(p % classes)), i) for p in columns]
                look(moved, i, perceived)
    mean = float(np.sum(stopping * model.stop_utility[:n]))
    square = float(np.sum(stopping * model.stop_square[:n]))
    return Outcome(mean - cost * looks, mean, square)


class OptimalStopping(_GridPolicy):
    """The optimal stopping policy of the profile's Markov model (see the module docstring).

    Its `expected_utility` is the model's value, and the model is learned from the profile's
    `samples` runs: `standard_error` says how far that value may be from what the policy
    realises on fresh runs when the model's state is sufficient (the spread of the utility at
    its stops over the square root of the runs; the spread of the number of looks is left out).
    Where the state is not sufficient (a binned estimate of runs that differ in kind) the value
    can be off by more: a profile with `entered` tracks when a run entered its bin, which is
    what such reports say of a run's rate (see `DynamicProfile`).

    Args:
        monitoring_cost: the utility a look costs (0: look at every grid time).
    """

    name = "optimal"

    def __init__(self, *args: Any, monitoring_cost: float = 0.0, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.monitoring_cost = check_monitoring_cost(self.name, monitoring_cost)
        self._plans: dict[int, StoppingPlan] = {}

    def plan(self, allocation: float = math.inf) -> StoppingPlan:
        """The solution for a deadline (computed once per deadline). Where a look after skipped
        grid times cannot see a run's entry class, the backward induction's value of looking
        is what a policy that could would get: the plan's `expected_utility` is then the exact
        value of the policy as it acts (`plan_outcome`), and where looking at every grid time
        once it looks (or never) is worth more, that is the plan."""
        last = self.model.last(check_allocation(self.name, allocation))
        if last < 0:
            raise PolicyError(f"{self.name}: no grid time within the allocation {allocation:g}")
        if last not in self._plans:
            plan = solve(self.model, last, self.monitoring_cost)
            if self.model.profile.classes > 1 and self.monitoring_cost > 0:
                # Skipping looks as planned, valued as the policy acts, against looking at every
                # grid time once it looks (exact: every look sees the class) or not at all.
                acting = plan_outcome(self.model, plan, last, self.monitoring_cost).value
                every = solve(self.model, last, self.monitoring_cost, skips=False)
                if every.expected_utility >= acting:
                    plan = every
                else:
                    plan = attrs.evolve(plan, expected_utility=acting)
            self._plans[last] = plan
        return self._plans[last]

    def value_function(self, allocation: float = math.inf) -> Array:
        return self.plan(allocation).value

    def expected_utility(self, allocation: float = math.inf) -> float:
        return self.plan(allocation).expected_utility

    def standard_error(self, allocation: float = math.inf) -> float:
        """The standard error of `expected_utility` from the profile's sampling (infinite for
        a profile that does not say how many runs it was learned from)."""
        samples = self.model.profile.samples
        if samples <= 0:
            return math.inf
        last = self.model.last(check_allocation(self.name, allocation))
        outcome = plan_outcome(self.model, self.plan(allocation), last, self.monitoring_cost)
        return math.sqrt(max(outcome.square - outcome.mean**2, 0.0) / samples)

    def _start(self) -> Decision:
        plan = self.plan(self.allocation)
        action, i = plan.first
        return self._act(action, i, f"expected utility {plan.expected_utility:.6g}")

    def observe(self, time: float, quality: float | None) -> Decision:
        plan = self.plan(self.allocation)
        j = self.model.index(time, self.last)
        s = self._state(j, quality)
        action, i = int(plan.action[j, s]), int(plan.target[j, s])
        if action == STOP:
            return Decision.now(f"stopping now is worth {plan.value[j, s]:.6g}, going on less")
        return self._act(action, i, f"going on is worth {plan.value[j, s]:.6g}")

    def _act(self, action: int, i: int, reason: str) -> Decision:
        at = float(self.model.time[i])
        if action == STOP_AT:
            return Decision.later(math.inf, at, reason)
        return Decision.later(at, float(self.model.time[self.last]), reason)


def _saturating_fit(time: Array, quality: Array, rates: Array) -> tuple[float, float, float]:
    """The least-squares fit of q(t) = a - b exp(-c t) with c among `rates` (given c, a and b
    are a linear fit, solved for every c at once)."""
    basis = np.exp(-rates[:, None] * time)  # (C, points)
    centred = basis - basis.mean(axis=1, keepdims=True)
    spread = np.maximum((centred**2).sum(axis=1), 1e-300)
    b = -(centred @ (quality - quality.mean())) / spread
    a = quality.mean() + b * basis.mean(axis=1)
    error = ((a[:, None] - b[:, None] * basis - quality) ** 2).sum(axis=1)
    best = int(np.argmin(error))
    return float(a[best]), float(b[best]), float(rates[best])


class ProjectedStopping(_GridPolicy):
    """Look at every grid time, fit the run's own qualities so far to q(t) = a - b exp(-c t),
    and stop once the projected best stopping time argmax_t U(q_hat(t), t) has come. With fewer
    than `points` answers seen it projects the profile's expected curve instead. For a module
    that reports an estimate, the projected estimate is read through the observation model."""

    name = "projected"

    #: The rates c tried, per unit of the grid's span (the fit is linear in a and b given c).
    RATES = np.geomspace(0.05, 50, 64)

    def __init__(self, *args: Any, points: int = 3, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if self.model.profile.observed == "none":
            raise PolicyError(
                f"{self.name}: the profile's module reports nothing of its quality; there is"
                " no trace to project"
            )
        if points < 2:
            raise PolicyError(f"{self.name}: points must be >= 2, got {points!r}")
        self.points = points
        self._seen: list[tuple[float, float]] = []

    def _start(self) -> Decision:
        self._seen = []
        return Decision.later(self.model.time[0], self.model.time[self.last], "looks every step")

    def projection(self) -> Array:
        """The projected true quality at each grid time up to the deadline."""
        m, n = self.model, self.last + 1
        t = m.time[:n]
        if len(self._seen) < self.points:
            expected: Array = np.einsum("jk,jk->j", m.marginal[:n], m.expected_true[:n])
            return expected
        seen_t, seen_q = np.array(self._seen).T
        span = max(float(t[-1] - t[0]), 1e-12)
        coarse = self.RATES / span
        a, b, rate = _saturating_fit(seen_t, seen_q, coarse)
        ratio = coarse[1] / coarse[0]  # then finer, between the coarse neighbours of the best
        a, b, rate = _saturating_fit(seen_t, seen_q, rate * np.geomspace(1 / ratio, ratio, 33))
        curve: Array = np.clip(a - b * np.exp(-rate * t), 0.0, 1.0)
        if m.profile.observed == "true":
            return curve
        # A projected estimate is worth what the observation model says its state is worth.
        bins = m.profile.bins
        index = np.clip(np.searchsorted(bins, curve, side="right") - 1, 0, len(bins) - 2)
        worth: Array = m.expected_true[np.arange(n), index]
        return worth

    def observe(self, time: float, quality: float | None) -> Decision:
        j = self.model.index(time, self.last)
        if quality is not None:
            self._seen.append((float(time), float(quality)))
        if j == self.last:
            return Decision.now("the last grid time within the allocation")
        projected = self.model.utility(self.model.time[: self.last + 1], self.projection()[:, None])
        _, best = _best(projected[:, 0][None, :])
        at = int(best[0])
        if at <= j:
            return Decision.now(
                f"the projected best stopping time {self.model.time[at]:g} has come"
            )
        return self._look_next(j, f"the projected best stopping time is {self.model.time[at]:g}")
