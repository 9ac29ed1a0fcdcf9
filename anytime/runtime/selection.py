"""The optimal policy's state, chosen on the traces by cross-validation, with an honest promise.

`OptimalStopping` is optimal on its model, and how good the model is depends on its state: more
quality bins and entry classes (`DynamicProfile.from_traces`, `states` and `entered`) come closer
to a Markov state, fewer are learned better from a few hundred runs. Too few, and the policy
cannot tell runs apart; too many, and it acts on transitions a handful of runs made, and its
model's value (`OptimalStopping.expected_utility`) promises what chance showed it.

`fit_optimal` tries each candidate state on the training traces by K-fold cross-validation:
the profile learned on K - 1 folds, the policy replayed (`assess`) on the runs of the fold left
out, so every training run is scored once by a policy that never saw it. It keeps the smallest
state whose cross-validated utility is within one standard error of the best (of the paired
difference, run by run: the one-standard-error rule, which prefers the state learned better
when the data cannot tell them apart), and builds the policy on all the traces.

The candidates are Markov states and, unless `history=False`, the run's whole history
(`HistoryStopping`: the decision learned from the training runs whose reports so far were
nearest, a belief over the kinds of run). The history is the richest state, so it is kept only
where it beats every Markov state by more than a standard error: where the report's level says
less than how it got there (a biased or quantised estimate the runs differ in), which no number
of bins recovers from a few thousand runs.

Its promise is that cross-validated utility, with its standard error: an estimate of what the
policy realises on fresh runs like the training ones that does not rest on the Markov
assumption (slightly low: each fold's policy learned from K - 1 folds of the runs). The model's
own number is `fit.policy.expected_utility(...)`; the gap between the two says how far the model
is from the process. One bin (`states` 1) is the monitor learning nothing from the report: its
optimal policy is the best fixed stop, so a report not worth looking at is not looked at (a run
that ends by itself still ends there).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from typing import Any

import numpy as np
from attrs import frozen
from numpy.typing import NDArray

from anytime.profiles.dynamic import DynamicProfile, QualityTraces
from anytime.profiles.profile import Array
from anytime.runtime.learned import HistoryStopping, kept_while_alive
from anytime.runtime.observe import PolicyError
from anytime.runtime.offline import scores
from anytime.runtime.policies import OptimalStopping, Utility

#: The candidate numbers of quality bins and of entry-time classes.
STATES = (1, 5, 10, 20)
ENTERED = (1, 4, 8, 16)
#: Cross-validation folds.
FOLDS = 5
#: The name of the history state.
HISTORY = "history"


@frozen
class Candidate:
    """One candidate state and what its policy realised on the runs it was not learned from.

    Attributes:
        states: quality bins (0: the history state).
        entered: entry-time classes (0: the history state).
        utility: the cross-validated mean utility (looks paid).
        standard_error: its standard error.
    """

    states: int
    entered: int
    utility: float
    standard_error: float

    @property
    def state(self) -> str:
        """`"history"`, or `"B bins x C classes"`."""
        return _name(self.states, self.entered)


@frozen
class FittedStopping:
    """The optimal policy on the chosen state, and its cross-validated promise.

    Attributes:
        policy: `OptimalStopping` on `profile`, or `HistoryStopping` on the training traces.
        profile: the dynamic profile of all the training traces on the chosen state (None for
            the history).
        states: its number of quality bins (at most; quantile bins merge equal qualities; 0
            for the history).
        entered: its number of entry-time classes (1: the bin alone; 0 for the history).
        utility: the chosen state's cross-validated mean utility (looks paid): the promise.
        standard_error: that mean's standard error.
        candidates: every candidate's, in the order tried.
    """

    policy: OptimalStopping | HistoryStopping
    profile: DynamicProfile | None
    states: int
    entered: int
    utility: float
    standard_error: float
    candidates: tuple[Candidate, ...]

    @property
    def state(self) -> str:
        """`"history"`, or `"B bins x C classes"`."""
        return _name(self.states, self.entered)


def fit_optimal(
    training: QualityTraces,
    utility: Utility,
    *,
    monitoring_cost: float = 0.0,
    allocation: float | None = None,
    input_quality: Sequence[float] = (),
    states: Sequence[int] = STATES,
    entered: Sequence[int] = ENTERED,
    history: bool = True,
    ends: bool | None = None,
    folds: int = FOLDS,
    seed: int = 0,
) -> FittedStopping:
    """`OptimalStopping` on the state the training traces' cross-validation chooses among
    `states` x `entered` and, with `history`, the run's history (see the module docstring), for
    runs with `allocation` (default: the traces' last time). `ends` (default: whether some run
    ended by itself before the last grid time) gives the profiles ended states."""
    if not isinstance(training, QualityTraces):
        raise PolicyError(
            f"fit_optimal: expected QualityTraces to learn from, got {type(training).__name__}"
        )
    n = training.trials
    if not isinstance(folds, int) or isinstance(folds, bool) or not 2 <= folds <= n:
        raise PolicyError(
            f"fit_optimal: folds must be an integer from 2 to the {n} runs, got {folds!r}"
        )
    shapes = _candidates(states, entered) + ([(0, 0)] if history else [])
    if ends is None:
        ends = training.finished is not None and bool(
            (training.end_index() < len(training.time) - 1).any()
        )
    fold, split = _folds(training, folds, seed)
    realised = np.empty((len(shapes), n))  # each run's utility, scored by a policy without it
    for f, (learn, held) in enumerate(split):
        for c, (k, e) in enumerate(shapes):
            policy = _policy(learn, k, e, ends, utility, monitoring_cost, input_quality)
            realised[c, fold == f] = scores(
                policy, held, utility, allocation, monitoring_cost, input_quality
            )[0]
    mean, se = realised.mean(axis=1), realised.std(axis=1, ddof=1) / math.sqrt(n)
    best = int(np.argmax(mean))
    spread = (realised - realised[best]).std(axis=1, ddof=1) / math.sqrt(n)
    near = np.flatnonzero(mean >= mean[best] - spread)
    size = np.array([k * e if k else math.inf for k, e in shapes])  # the history: the most
    chosen = int(near[np.lexsort((-mean[near], size[near]))[0]])  # fewest states, then best
    k, e = shapes[chosen]
    policy = _policy(training, k, e, ends, utility, monitoring_cost, input_quality)
    return FittedStopping(
        policy=policy,
        profile=policy.model.profile if isinstance(policy, OptimalStopping) else None,
        states=k,
        entered=e,
        utility=float(mean[chosen]),
        standard_error=float(se[chosen]),
        candidates=tuple(
            Candidate(k_, e_, float(m), float(s))
            for (k_, e_), m, s in zip(shapes, mean, se, strict=True)
        ),
    )


#: Each run's fold, and per fold the traces learned from and those held out.
Folds = tuple[NDArray[np.intp], list[tuple[QualityTraces, QualityTraces]]]
#: The folds of training traces (by identity, while they live), number and seed: fits of several
#: utilities to the same traces learn from the same fold objects, so the history policies share
#: their neighbourhoods (most of their learning's time).
_FOLDS: dict[tuple[Any, ...], tuple[weakref.ref[QualityTraces], Any]] = {}


def _folds(training: QualityTraces, folds: int, seed: int) -> Folds:
    """The folds of `training`, made once while it lives."""

    def make() -> Folds:
        fold = np.random.default_rng(seed).permutation(training.trials) % folds
        return fold, [
            (training.select(fold != f), training.select(fold == f)) for f in range(folds)
        ]

    return kept_while_alive(_FOLDS, training, (folds, seed), make)


def _name(states: int, entered: int) -> str:
    return HISTORY if states == 0 else f"{states} bins x {entered} classes"


def _candidates(states: Sequence[int], entered: Sequence[int]) -> list[tuple[int, int]]:
    """(bins, classes) pairs, each once; one bin has one class (it is never left)."""
    for name, values in (("states", states), ("entered", entered)):
        if not values or any(
            not isinstance(v, int | np.integer) or isinstance(v, bool) or v < 1 for v in values
        ):
            raise PolicyError(f"fit_optimal: {name} must be integers >= 1, got {list(values)!r}")
    return sorted({(int(k), 1 if k == 1 else int(e)) for k in states for e in entered})


def _policy(
    traces: QualityTraces,
    states: int,
    entered: int,
    ends: bool,
    utility: Utility,
    monitoring_cost: float,
    input_quality: Sequence[float],
) -> OptimalStopping | HistoryStopping:
    """The policy of a candidate state learned from `traces` (`states` 0: the history)."""
    if states == 0:
        return HistoryStopping(
            traces, utility, monitoring_cost=monitoring_cost, input_quality=input_quality
        )
    bins: Array | None = np.array([0.0, 1.0]) if states == 1 else None
    profile = DynamicProfile.from_traces(
        traces, bins=bins, states=states, entered=entered, ends=ends
    )
    return OptimalStopping(
        profile,
        utility.value_model,
        utility.cost_model,
        utility.state,
        monitoring_cost=monitoring_cost,
        input_quality=input_quality,
    )
