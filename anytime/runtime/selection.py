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
from collections.abc import Sequence

import numpy as np
from attrs import frozen

from anytime.profiles.dynamic import DynamicProfile, QualityTraces
from anytime.profiles.profile import Array
from anytime.runtime.observe import PolicyError
from anytime.runtime.offline import scores
from anytime.runtime.policies import OptimalStopping, Utility

#: The candidate numbers of quality bins and of entry-time classes.
STATES = (1, 5, 10, 20)
ENTERED = (1, 4, 8, 16)
#: Cross-validation folds.
FOLDS = 5


@frozen
class Candidate:
    """One candidate state and what its policy realised on the runs it was not learned from."""

    states: int
    entered: int
    utility: float
    standard_error: float


@frozen
class FittedStopping:
    """The optimal policy on the chosen state, and its cross-validated promise.

    Attributes:
        policy: `OptimalStopping` on `profile`.
        profile: the dynamic profile of all the training traces on the chosen state.
        states: its number of quality bins (at most; quantile bins merge equal qualities).
        entered: its number of entry-time classes (1: the bin alone).
        utility: the chosen state's cross-validated mean utility (looks paid): the promise.
        standard_error: that mean's standard error.
        candidates: every candidate's, in the order tried.
    """

    policy: OptimalStopping
    profile: DynamicProfile
    states: int
    entered: int
    utility: float
    standard_error: float
    candidates: tuple[Candidate, ...]


def fit_optimal(
    training: QualityTraces,
    utility: Utility,
    *,
    monitoring_cost: float = 0.0,
    allocation: float | None = None,
    input_quality: Sequence[float] = (),
    states: Sequence[int] = STATES,
    entered: Sequence[int] = ENTERED,
    ends: bool | None = None,
    folds: int = FOLDS,
    seed: int = 0,
) -> FittedStopping:
    """`OptimalStopping` on the state the training traces' cross-validation chooses among
    `states` x `entered` (see the module docstring), for runs with `allocation` (default: the
    traces' last time). `ends` (default: whether some run ended by itself before the last grid
    time) gives the profiles ended states."""
    if not isinstance(training, QualityTraces):
        raise PolicyError(
            f"fit_optimal: expected QualityTraces to learn from, got {type(training).__name__}"
        )
    n = training.trials
    if not isinstance(folds, int) or isinstance(folds, bool) or not 2 <= folds <= n:
        raise PolicyError(
            f"fit_optimal: folds must be an integer from 2 to the {n} runs, got {folds!r}"
        )
    shapes = _candidates(states, entered)
    if ends is None:
        ends = training.finished is not None and bool(
            (training.end_index() < len(training.time) - 1).any()
        )
    fold = np.random.default_rng(seed).permutation(n) % folds
    realised = np.empty((len(shapes), n))  # each run's utility, scored by a policy without it
    for f in range(folds):
        learn, held = training.select(fold != f), training.select(fold == f)
        for c, (k, e) in enumerate(shapes):
            policy = _policy(_profile(learn, k, e, ends), utility, monitoring_cost, input_quality)
            realised[c, fold == f] = scores(
                policy, held, utility, allocation, monitoring_cost, input_quality
            )[0]
    mean, se = realised.mean(axis=1), realised.std(axis=1, ddof=1) / math.sqrt(n)
    best = int(np.argmax(mean))
    spread = (realised - realised[best]).std(axis=1, ddof=1) / math.sqrt(n)
    near = np.flatnonzero(mean >= mean[best] - spread)
    size = np.array([k * e for k, e in shapes])
    chosen = int(near[np.lexsort((-mean[near], size[near]))[0]])  # fewest states, then best
    k, e = shapes[chosen]
    profile = _profile(training, k, e, ends)
    return FittedStopping(
        policy=_policy(profile, utility, monitoring_cost, input_quality),
        profile=profile,
        states=k,
        entered=e,
        utility=float(mean[chosen]),
        standard_error=float(se[chosen]),
        candidates=tuple(
            Candidate(k_, e_, float(m), float(s))
            for (k_, e_), m, s in zip(shapes, mean, se, strict=True)
        ),
    )


def _candidates(states: Sequence[int], entered: Sequence[int]) -> list[tuple[int, int]]:
    """(bins, classes) pairs, each once; one bin has one class (it is never left)."""
    for name, values in (("states", states), ("entered", entered)):
        if not values or any(
            not isinstance(v, int | np.integer) or isinstance(v, bool) or v < 1 for v in values
        ):
            raise PolicyError(f"fit_optimal: {name} must be integers >= 1, got {list(values)!r}")
    return sorted({(int(k), 1 if k == 1 else int(e)) for k in states for e in entered})


def _profile(traces: QualityTraces, states: int, entered: int, ends: bool) -> DynamicProfile:
    bins: Array | None = np.array([0.0, 1.0]) if states == 1 else None
    return DynamicProfile.from_traces(traces, bins=bins, states=states, entered=entered, ends=ends)


def _policy(
    profile: DynamicProfile,
    utility: Utility,
    monitoring_cost: float,
    input_quality: Sequence[float],
) -> OptimalStopping:
    return OptimalStopping(
        profile,
        utility.value_model,
        utility.cost_model,
        utility.state,
        monitoring_cost=monitoring_cost,
        input_quality=input_quality,
    )
