"""`fit_optimal`: the optimal policy's state chosen by cross-validation on the traces.

Its promise (the cross-validated utility) must be what fresh runs realise where the model's own
value is not; it must choose a richer state where the data show one pays (the history where no
Markov state matches it), the smallest where nothing tells the candidates apart, and one bin
must be the best fixed stop.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from stopping_models import Linear
from test_learned import kinds, realised

from anytime.profiles.dynamic import DynamicProfile, QualityTraces
from anytime.runtime import (
    FixedStopping,
    HistoryStopping,
    OptimalStopping,
    PolicyError,
    Utility,
    fit_optimal,
)


class Convex:
    """Value 100 q^4 (a near-perfect answer is worth much more than a fair one), cost 0.4 a
    tick."""

    def value(self, state: object, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return 100 * quality**4

    def cost(self, state: object, contract: np.ndarray, quality: np.ndarray) -> np.ndarray:
        return 0.4 * contract


def quantised(seed: int, trials: int) -> QualityTraces:
    """Runs q(t) = 1 - exp(-rate t) with a log-uniform rate per run, reporting q floored to
    quarters: the level does not say how fast the run is, when it reached it does."""
    rng = np.random.default_rng(seed)
    time = np.arange(0.0, 101.0, 5.0)
    rate = np.exp(rng.uniform(np.log(0.005), np.log(0.2), (trials, 1)))
    quality = 1 - np.exp(-rate * time)
    return QualityTraces(
        module="quantised",
        time=time,
        quality=quality,
        scored=np.ones(quality.shape, bool),
        estimate=np.floor(quality * 4) / 4,
        reports="estimate",
    )


def test_its_promise_is_what_fresh_runs_realise_where_the_models_is_not() -> None:
    training, fresh = quantised(1, 400), quantised(2, 400)
    model = Convex()
    markov = fit_optimal(
        training, Utility(model, model), states=(1, 4, 8), entered=(1, 4), history=False
    )
    values = realised(markov.policy, fresh, model)  # type: ignore[arg-type]
    se = values.std(ddof=1) / math.sqrt(len(values))
    assert abs(markov.utility - values.mean()) < 2 * math.hypot(se, markov.standard_error)
    assert markov.entered > 1  # when the run reached its level is worth knowing here
    assert markov.state == f"{markov.states} bins x {markov.entered} classes"
    # The Markov model on the level alone promises what it does not deliver.
    level = OptimalStopping(DynamicProfile.from_traces(training, states=4), model, model)
    assert level.expected_utility() - realised(level, fresh, model).mean() > 5 * se
    assert values.mean() > realised(level, fresh, model).mean() + 2 * se
    # How fast the run climbed the quarters says more than when it entered the last one: the
    # history is chosen, and keeps its promise too.
    fit = fit_optimal(training, Utility(model, model), states=(1, 4, 8), entered=(1, 4))
    assert (fit.state, fit.states, fit.entered, fit.profile) == ("history", 0, 0, None)
    assert isinstance(fit.policy, HistoryStopping)
    history = realised(fit.policy, fresh, model)  # type: ignore[arg-type]
    assert abs(fit.utility - history.mean()) < 2 * math.hypot(se, fit.standard_error)
    assert fit.utility > markov.utility + fit.standard_error
    assert fit.candidates[-1].state == "history"


def test_a_richer_state_is_chosen_where_it_tells_runs_apart() -> None:
    """The stalled and the late runs of `HistoryStopping`'s tests: the level cannot tell them
    apart, the time the run reached it can, and the cross-validation sees it."""
    stalled = [0.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5]
    late = [0.0, 0.2, 0.3, 0.5, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0]
    recorded = kinds([stalled, late], 20)
    model = Linear(1.0, 0.03)
    fit = fit_optimal(recorded, Utility(model, model), states=(1, 3), entered=(1, 4))
    assert (fit.states, fit.entered) == (3, 4)
    best = (0.5 - 0.03 + 1.0 - 0.03 * 7) / 2
    assert fit.utility == pytest.approx(best)
    assert realised(fit.policy, recorded, model).mean() == pytest.approx(best)
    assert [c.state for c in fit.candidates] == [
        "1 bins x 1 classes",
        "3 bins x 1 classes",
        "3 bins x 4 classes",
        "history",
    ]


def test_the_smallest_state_is_chosen_where_nothing_tells_them_apart() -> None:
    """Runs all alike: every state realises the same, so the fewest states are kept."""
    recorded = kinds([[0.0, 0.4, 0.7, 0.8, 0.82, 0.84]], 10)
    model = Linear(1.0, 0.05)
    fit = fit_optimal(recorded, Utility(model, model), folds=2)
    assert (fit.states, fit.entered) == (1, 1)
    assert fit.utility == pytest.approx(0.8 - 0.05 * 3)
    assert fit.standard_error == pytest.approx(0.0)
    assert [c.utility for c in fit.candidates] == pytest.approx([0.8 - 0.05 * 3] * 14)


def test_one_bin_is_the_best_fixed_stop() -> None:
    """With one bin the report says nothing: the policy stops every run where the mean
    utility of the training runs is highest, as the fixed policy does."""
    training = quantised(3, 200)
    model = Linear(1.0, 0.004)
    utility = Utility(model, model)
    fit = fit_optimal(training, utility, states=(1,), history=False)
    mean = utility(training.time, training.quality.T).T.mean(axis=0)
    values = realised(fit.policy, training, model)
    assert values == pytest.approx(utility(training.time, training.quality.T).T[:, mean.argmax()])
    fixed = FixedStopping(DynamicProfile.from_traces(training), model, model)
    assert fixed.start(math.inf).stop_at == training.time[mean.argmax()]


def test_bad_arguments_are_named() -> None:
    recorded = quantised(4, 10)
    model = Linear(1.0, 0.0)
    utility = Utility(model, model)
    with pytest.raises(PolicyError) as error:
        fit_optimal("traces", utility)  # type: ignore[arg-type]
    assert str(error.value) == "fit_optimal: expected QualityTraces to learn from, got str"
    for folds in (1, 11, True, 2.5):
        with pytest.raises(PolicyError) as error:
            fit_optimal(recorded, utility, folds=folds)  # type: ignore[arg-type]
        assert str(error.value) == (
            f"fit_optimal: folds must be an integer from 2 to the 10 runs, got {folds!r}"
        )
    with pytest.raises(PolicyError) as error:
        fit_optimal(recorded, utility, states=(0, 4))
    assert str(error.value) == "fit_optimal: states must be integers >= 1, got [0, 4]"
    with pytest.raises(PolicyError) as error:
        fit_optimal(recorded, utility, entered=())
    assert str(error.value) == "fit_optimal: entered must be integers >= 1, got []"
    with pytest.raises(PolicyError) as error:
        fit_optimal(recorded, utility, monitoring_cost=-1)
    assert str(error.value) == "optimal: monitoring_cost must be a finite number >= 0, got -1"
