"""A stopping rule with a guarantee: stop once a conformal bound says going on gains less than ε.

`ConformalStopping` is calibrated on recorded traces of the module (`QualityTraces`), split-
conformal style (Vovk et al.; the Mondrian, per-category form). At a look at grid time t_j the
run is in a *state*: the quality it reports, binned, and the time since its last improvement
(seen at the policy's looks), binned. Its *score* is what going on could still gain, up to the
allocation T:

    G_j = max_{j <= i <= T} v_i - v_j,

with v_i the true quality at t_i (or, given a `Utility`, U(q_i, t_i)), over the times the run was
still running. The bound at (t_j, state) is the conformal quantile of the scores of the
calibration traces that reached that look in that state:

    B_j(state) = the k-th smallest of their n scores,  k = ceil((n + 1)(1 - alpha))

(+inf when k > n), and the rule stops at the first look where B_j(state) < ε, at the last grid
time within the allocation at the latest.

The calibration traces that "reached" the look are those the rule itself did not stop before
(a forward pass over the looks replays the rule on them) and that had not ended by themselves:
the bound is computed on the runs that get to ask the question. Then, for a run exchangeable
with the calibration traces (the same module on inputs from the same distribution), at each
look P(G_j > B_j | the run reached look j in that state) <= alpha, and since a run stops once,
P(gain after the stop > ε) <= alpha. A state with fewer than `min_traces` calibration traces is
pooled with its neighbours (wider windows of quality bins at the same time since the last
improvement, then the same windows at any, at last every trace that reached the look); the
guarantee then holds for the pooled condition, not the exact state, which is what
`Decision.reason` says (how many traces the bound rests on, and where they were). The held-out
tests measure the coverage.

That promise is on average over draws of the calibration traces. With `delta`, the rank k is the
least with P(Binomial(n, 1 - alpha) >= k) <= delta (training-conditional conformal, Vovk 2012):
then, with probability 1 - delta over the calibration traces, each bound covers a fresh run's
gain with probability at least 1 - alpha.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from typing import Any

import numpy as np
from attrs import field, frozen
from numpy.typing import NDArray

from anytime.profiles.dynamic import Observed, QualityTraces, quantile_bins
from anytime.profiles.profile import Array
from anytime.runtime.observe import Decision, PolicyError
from anytime.runtime.policies import Utility, check_allocation, trace_cell

#: Default number of quality bins (states) of the conditioning.
DEFAULT_BINS = 20

#: Default least number of calibration traces a bound rests on before pooling with neighbours.
DEFAULT_MIN_TRACES = 100


@frozen
class ConformalTable:
    """`ConformalStopping`'s calibration for one deadline (grid index `last`).

    Attributes:
        looks: the grid indices it looks at (every `stride`-th, and `last`).
        bound: `(m, K, S)` the conformal bound on the gain at each grid time, quality bin and
            stall bin (inf: too few calibration runs looked there to bound it).
        traces: `(m, K, S)` how many calibration traces the bound rests on.
        level: `(m, K, S)` where they are: w < K the quality bins within w of the state's, in
            its stall bin; K + w the same in any stall bin (2K - 1: every trace that reached
            the look).
        stop_index: `(n,)` where the rule stopped each calibration trace.
        gain: `(n,)` the gain after that stop on each calibration trace.
    """

    last: int
    looks: NDArray[np.intp] = field(eq=False)
    bound: Array = field(eq=False)
    traces: NDArray[np.intp] = field(eq=False)
    level: NDArray[np.intp] = field(eq=False)
    stop_index: NDArray[np.intp] = field(eq=False)
    gain: Array = field(eq=False)


class ConformalStopping:
    """Stop as soon as the conformal bound on what going on could gain is below `epsilon`, at
    level 1 - `alpha` (see the module docstring).

    Args:
        calibration: recorded traces of the module (its runs on inputs like the one it is run
            on); the state is read from what it reports (`calibration.observed`), the gain from
            its true quality.
        epsilon: the gain that is worth going on for (in quality, or in utility with `utility`).
        alpha: the risk: the probability that a stopped run would have gained more than
            `epsilon` is at most alpha.
        utility: measure the gain in utility U(q, t) instead of quality (time's cost counted:
            going on can gain less than nothing).
        bins: the number of quality bins of the state (edges at quantiles of the calibration
            traces' reported qualities), or the edges themselves.
        stalled: edges of the time since the last improvement (on the grid's clock) that split
            the state; empty (default): it does not.
        min_traces: the least number of calibration traces a bound rests on before pooling
            with neighbouring states.
        stride: look at every `stride`-th grid time (and at the last one within the allocation).
        input_quality: for traces over input-quality cells, the input qualities to calibrate
            at (the nearest grid cell).
        delta: make each bound hold for the calibration traces at hand, not only on average
            over draws of them: with probability at least 1 - delta over the calibration
            traces, a bound's own miss rate is at most alpha (training-conditional, or PAC,
            conformal; its rank is a binomial quantile, so it needs more traces and stops
            later). None (default): the marginal guarantee.
    """

    name = "conformal"

    def __init__(
        self,
        calibration: QualityTraces,
        epsilon: float,
        alpha: float = 0.1,
        *,
        utility: Utility | None = None,
        bins: int | Sequence[float] = DEFAULT_BINS,
        stalled: Sequence[float] = (),
        min_traces: int = DEFAULT_MIN_TRACES,
        stride: int = 1,
        input_quality: Sequence[float] = (),
        delta: float | None = None,
    ) -> None:
        if not isinstance(calibration, QualityTraces):
            raise PolicyError(
                f"{self.name}: expected QualityTraces to calibrate on, got"
                f" {type(calibration).__name__}"
            )
        self.epsilon = _number(self.name, "epsilon", epsilon, positive=True)
        self.alpha = _number(self.name, "alpha", alpha)
        if not 0 < self.alpha < 1:
            raise PolicyError(f"{self.name}: alpha must be in (0, 1), got {alpha!r}")
        self.delta = None if delta is None else _number(self.name, "delta", delta)
        if self.delta is not None and not 0 < self.delta < 1:
            raise PolicyError(f"{self.name}: delta must be in (0, 1) or None, got {delta!r}")
        if not (isinstance(stride, int) and stride >= 1):
            raise PolicyError(f"{self.name}: stride must be an integer >= 1, got {stride!r}")
        if not (isinstance(min_traces, int) and min_traces >= 1):
            raise PolicyError(
                f"{self.name}: min_traces must be an integer >= 1, got {min_traces!r}"
            )
        self.utility, self.stride, self.min_traces = utility, stride, min_traces
        self.observed: Observed | None = calibration.reports
        self.time = calibration.time
        cell = trace_cell(calibration, input_quality, self.name)
        self._seen = calibration.observed[cell] * calibration.scored[cell]  # (n, m)
        self._true = calibration.quality[cell]
        self._end = calibration.end_index()[cell]
        self._scored = calibration.scored[cell]
        if isinstance(bins, int):
            if bins < 1:
                raise PolicyError(f"{self.name}: bins must be >= 1, got {bins!r}")
            self.bins = quantile_bins(self._seen[calibration.scored[cell]], bins)
        else:
            self.bins = np.asarray(bins, dtype=np.float64)
            if self.bins.ndim != 1 or len(self.bins) < 2 or np.any(np.diff(self.bins) <= 0):
                raise PolicyError(f"{self.name}: bins must be increasing edges, got {bins!r}")
        self.stalled = np.asarray(stalled, dtype=np.float64).reshape(-1)
        if np.any(np.diff(self.stalled) <= 0) or np.any(self.stalled <= 0):
            raise PolicyError(
                f"{self.name}: stalled must be increasing times > 0, got {list(stalled)!r}"
            )
        self._times, self._edges = self.time.tolist(), self.bins.tolist()
        self._stall_edges = self.stalled.tolist()
        self._tables: dict[int, ConformalTable] = {}
        self.allocation = math.inf
        self.last = len(self.time) - 1
        self._best = -math.inf
        self._improved = 0.0

    # --- the run ---------------------------------------------------------------------------

    def start(self, allocation: float) -> Decision:
        self.allocation = check_allocation(self.name, allocation)
        self.last = self._last(self.allocation)
        self._best, self._improved = -math.inf, 0.0
        if self.last < 0:
            return Decision.now("no grid time within the allocation")
        self.table(self.allocation)
        return Decision.later(self.time[0], self.time[self.last], self._schedule())

    def observe(self, time: float, quality: float | None) -> Decision:
        # Scalar lookups on lists (bisect): a look is a few microseconds, not a numpy call's tens.
        q = 0.0 if quality is None or self.observed == "none" else float(quality)
        j = min(max(bisect_right(self._times, time * (1 + 1e-12)) - 1, 0), self.last)
        if q > self._best:
            self._best, self._improved = q, self._times[j]
        if j >= self.last:
            return Decision.now("the last grid time within the allocation")
        table = self.table(self.allocation)
        b = min(max(bisect_right(self._edges, q) - 1, 0), len(self._edges) - 2)
        s = bisect_right(self._stall_edges, self._times[j] - self._improved + 1e-9)
        bound = float(table.bound[j, b, s])
        n, level = int(table.traces[j, b, s]), int(table.level[j, b, s])
        where = self._where(level)
        risk = f"{1 - self.alpha:.3g}"
        if self.delta is not None:
            risk += f" (with probability {1 - self.delta:.3g} over calibrations)"
        if bound < self.epsilon:
            return Decision.now(
                f"gain bound {bound:.4g} < {self.epsilon:g} at {risk}, on {n} traces ({where})"
            )
        following = table.looks[table.looks > j]
        at = float(self.time[following[0]]) if len(following) else float(self.time[self.last])
        shown = "inf (too few traces)" if bound == math.inf else f"{bound:.4g}"
        return Decision.later(
            at,
            self.time[self.last],
            f"gain bound {shown} >= {self.epsilon:g} at {risk}, on {n} traces ({where})",
        )

    # --- the calibration -------------------------------------------------------------------

    def table(self, allocation: float = math.inf) -> ConformalTable:
        """The calibration for a deadline (computed once per deadline)."""
        last = self._last(check_allocation(self.name, allocation))
        if last < 0:
            raise PolicyError(f"{self.name}: no grid time within the allocation {allocation:g}")
        if last not in self._tables:
            self._tables[last] = self._calibrate(last)
        return self._tables[last]

    def _calibrate(self, last: int) -> ConformalTable:
        t = self.time[: last + 1]
        n, m = self._true.shape[0], last + 1
        worth = self._true[:, :m]
        if self.utility is not None:
            worth = self.utility(t, worth.T).T
        # What going on can reach: the values up to the allocation and the run's own end.
        ahead = np.where(np.arange(m)[None, :] <= self._end[:, None], worth, -np.inf)
        gain = np.maximum.accumulate(ahead[:, ::-1], axis=1)[:, ::-1] - worth  # (n, m)
        looks = np.unique(np.r_[np.arange(0, m, self.stride), last]).astype(np.intp)
        k_bins, s_bins = len(self.bins) - 1, len(self.stalled) + 1
        bound = np.full((m, k_bins, s_bins), np.inf)
        count = np.zeros((m, k_bins, s_bins), np.intp)
        level = np.zeros((m, k_bins, s_bins), np.intp)
        stop = np.full(n, last, np.intp)
        alive = np.ones(n, bool)
        scored = self._scored[:, :m]
        due = np.zeros(n, np.intp)  # the grid index of each run's next look
        best = np.full(n, -np.inf)
        improved = np.zeros(n)
        for j in range(m):  # forward over the grid, vectorised over runs and states
            ended = alive & (self._end <= j)  # the run returned by itself: over there
            stop[ended] = self._end[ended]
            alive &= ~ended
            # A look is taken at the first grid time with an answer at or after the one asked
            # for, as `replay` and the executor take it; the state is what the looks saw.
            reach = alive & scored[:, j] & (due <= j)
            seen = self._seen[:, j]
            rose = reach & (seen > best)
            best[rose], improved[rose] = seen[rose], t[j]
            qbin, sbin = self._state(seen[reach], t[j] - improved[reach])
            bound[j], count[j], level[j] = self._bounds(gain[reach, j], qbin, sbin)
            stopping = np.zeros(n, bool)
            stopping[reach] = bound[j][qbin, sbin] < self.epsilon
            stopping |= alive & (j == last)
            stop[stopping] = j
            alive &= ~stopping
            due[reach] = looks[np.searchsorted(looks, j, side="right")] if j < last else m
        return ConformalTable(last, looks, bound, count, level, stop, gain[np.arange(n), stop])

    def _bounds(
        self, gain: Array, qbin: NDArray[np.intp], sbin: NDArray[np.intp]
    ) -> tuple[Array, NDArray[np.intp], NDArray[np.intp]]:
        """The conformal bound, its number of traces and pooling level for every state at one
        look, from the gains and states of the calibration traces that reached it."""
        k_bins, s_bins = len(self.bins) - 1, len(self.stalled) + 1
        n = len(gain)
        if n == 0:
            nothing = np.zeros((k_bins, s_bins), np.intp)
            return np.full((k_bins, s_bins), np.inf), nothing, nothing + 2 * k_bins - 1
        order = np.argsort(gain, kind="stable")
        sorted_gain = gain[order]
        # cum[r, b, s]: how many of the r smallest gains are in state (b, s); edges[r, b]: in
        # quality bins below b (any stall).
        onehot = np.zeros((n + 1, k_bins * s_bins), np.intp)
        onehot[np.arange(1, n + 1), qbin[order] * s_bins + sbin[order]] = 1
        cum = np.cumsum(onehot, axis=0).reshape(n + 1, k_bins, s_bins)
        # edges[r, b, s]: how many of them are in quality bins below b and stall bin s; the
        # last stall column: in any stall bin.
        edges = np.zeros((n + 1, k_bins + 1, s_bins + 1), np.intp)
        edges[:, 1:, :s_bins] = np.cumsum(cum, axis=1)
        edges[:, :, s_bins] = edges[:, :, :s_bins].sum(axis=2)
        # Neighbourhoods, narrowest first: level w < K the quality bins within w of the
        # state's bin, in its stall bin; level K + w the same in any stall bin (the widest,
        # 2K - 1: every trace that reached the look).
        centre = np.arange(k_bins)
        widths = np.arange(k_bins)[:, None]
        lo = np.clip(centre[None, :] - widths, 0, k_bins)  # (K widths, K bins)
        hi = np.clip(centre[None, :] + widths + 1, 0, k_bins)
        last = edges[-1]  # (K + 1, S + 1)
        own = last[hi][:, :, :s_bins] - last[lo][:, :, :s_bins]  # (K widths, K bins, S)
        anyone = np.broadcast_to((last[hi, s_bins] - last[lo, s_bins])[:, :, None], own.shape)
        enough = np.concatenate([own, anyone]) >= self.min_traces  # (2K, K, S)
        chosen = np.where(enough.any(axis=0), enough.argmax(axis=0), 2 * k_bins - 1)  # (K, S)
        width = chosen % k_bins
        bins = np.broadcast_to(centre[:, None], chosen.shape)
        stall = np.where(chosen < k_bins, np.arange(s_bins)[None, :], s_bins)
        picked = edges[:, hi[width, bins], stall] - edges[:, lo[width, bins], stall]
        count = picked[-1]
        rank = self._rank(count)
        finite = (rank <= count) & (count > 0)
        position = (picked >= np.maximum(rank, 1)[None]).argmax(axis=0) - 1
        bound = np.where(finite, sorted_gain[np.clip(position, 0, n - 1)], np.inf)
        return bound, count, chosen

    def _rank(self, count: NDArray[np.intp]) -> NDArray[np.intp]:
        """The rank of each bound among its `count` scores (> count: no bound)."""
        if self.delta is None:  # the conformal quantile: marginal coverage 1 - alpha
            rank = np.ceil((count + 1) * (1 - self.alpha) - 1e-9)
        else:
            # The k-th smallest of n scores covers a fresh one with probability C ~ Beta(k,
            # n - k + 1), and P(C < 1 - alpha) = P(Binomial(n, 1 - alpha) >= k): the least k
            # where that is at most delta.
            from scipy.stats import binom  # here: scipy.stats takes half a second to import

            rank = binom.ppf(1 - self.delta, count, 1 - self.alpha) + 1
        ranks: NDArray[np.intp] = np.asarray(rank).astype(np.intp)
        return ranks

    # --- helpers ---------------------------------------------------------------------------

    def _last(self, allocation: float) -> int:
        return int(np.searchsorted(self.time, allocation * (1 + 1e-12), side="right")) - 1

    def _state(self, quality: Array, stall: Array) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        qbin = np.clip(np.searchsorted(self.bins, quality, side="right") - 1, 0, len(self.bins) - 2)
        sbin = np.searchsorted(self.stalled, stall + 1e-9, side="right")
        return qbin.astype(np.intp), sbin.astype(np.intp)

    def _schedule(self) -> str:
        every = "every grid time" if self.stride == 1 else f"every {self.stride} grid times"
        return f"looks at {every}, stops when the gain bound is below {self.epsilon:g}"

    def _where(self, level: int) -> str:
        k_bins, stalls = len(self.bins) - 1, len(self.stalled) > 0
        width, own = level % k_bins, level < k_bins
        if level == 2 * k_bins - 1 or (width == k_bins - 1 and not stalls):
            return "every run at this look"
        near = "this quality bin" if width == 0 else f"quality bins within {width} of it"
        if not stalls:
            return "this state" if width == 0 else near
        if own:
            return "this state" if width == 0 else f"{near}, as long stalled"
        return f"{near}, any stall"


def _number(name: str, what: str, value: Any, positive: bool = False) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if not math.isfinite(number) or (positive and number <= 0):
        need = "a finite number > 0" if positive else "a finite number"
        raise PolicyError(f"{name}: {what} must be {need}, got {value!r}")
    return number
