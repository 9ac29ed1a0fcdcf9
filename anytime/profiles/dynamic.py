"""Quality traces and dynamic performance profiles: how a run's quality moves, not only where
it is on average.

A static profile gives, per input quality and time, the distribution of output quality over all
runs. Deciding *when to stop* a run needs more: given what this run shows now, where will it
be later? Hansen & Zilberstein ("Monitoring and control of anytime algorithms: a dynamic
programming approach", AIJ 2001) model it with a *dynamic* performance profile, the transition
probabilities P(q_{t+dt} | q_t) between quality levels from one time step to the next, and, for
an algorithm whose true quality cannot be seen while it runs, P(true quality | observed
feature, t).

`QualityTraces` are what the profile builder records of each trial: the scored (true) quality
at every grid time, whether the run had a result there, and the module's own report of its
quality (`Result.quality`) where that is an estimate. `DynamicProfile.from_traces` derives the
model from them. The model's *state* is what a monitor can see of a running module, binned:

- a module that reports its true quality: that quality;
- one that reports an estimate: the estimate, with `observation` P(true quality bin | estimate
  bin, t) to say what it is worth;
- one that reports nothing: one state only (the monitor sees nothing), so `observation` is the
  distribution of true quality at each time, the static profile again.

Tables (cells are the input-quality grid, as in a static profile; m grid times, K bins):

- `occupancy (*cells, m, K)`: P(state k at time j), from the trials;
- `transition (*cells, m - 1, K, K)`: P(state l at time j + 1 | state k at time j); a state no
  trial was in at time j stays where it is (the identity row), so every row is a distribution;
- `observation (*cells, m, K, K)`: P(true quality bin b | state k at time j) (None: the state
  is the true quality); rows of states no trial was in are the time's distribution of true
  quality;
- `quality_mean (*cells, m, K)`: the mean true quality of the trials in each true-quality bin at
  each time (the bin's midpoint where none is), so a stopped run's value is evaluated at the
  qualities the trials had, not at bin midpoints.

Transitions over more than one step are products of one-step ones (the Markov assumption of the
dynamic profile); `transition_over` computes them.

The binned report alone is often not a Markov state: a run's quality level says where it is, not
how fast it got there, and two runs at one level can be of kinds that go on very differently
(a quantised estimate that has sat at a level for long belongs to a slow run). With `entered`,
the state is the pair (bin, class of the grid time the run entered that bin): the time of the
last change of what the monitor sees, binned on `entered`'s edges (grid indices, geometric by
default: `entry_edges`), which is what a quantised or biased report says of the run's rate, and
what a stalled run looks like. States are numbered bin-major (state = bin * classes + class);
`observation` is then always given (P(true bin | state), a state no longer being a bin), and
`quality_mean` is per state and true bin (runs of one bin differ by class: the fast ones are
higher in it). A policy tracks the class from its looks.

A run may also end by itself (it converged and returned): the monitor has nothing more to
decide, and its answer is worth what it was worth when it ended. Learned with `ends` (from
traces that say when each run ended, `QualityTraces.finished`), the profile has one more state
per bin after the running ones, absorbing: "ended, in this bin". Transitions of running runs
then say how likely a run is to end at the next grid time (the hazard) and where, so a run
still running at a level is no longer averaged with the runs that ended there. A run's answer
counts when it ended (the first grid time at or after it returned, as `assess` and `replay`
count it): a policy's value collects a run's utility as it enters an ended state, and nothing
more of it after.

Bins default to quantiles of the observed qualities (`quantile_bins`), so that a module whose
quality lives in [0.9, 1] still gets K states that tell runs apart.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NoReturn

import numpy as np
from attrs import field, frozen
from numpy.typing import ArrayLike, NDArray

from anytime.errors import ProfileError
from anytime.profiles.profile import SUM_TOLERANCE, Array, axis_names, check_grid
from anytime.vocabulary import (
    QUALITY_REPORTS,
    UNITS,
    QualityReport,
    Unit,
    array_field,
    arrays_field,
    optional_array_field,
)

#: What a dynamic profile's state is, and what traces' reports are: a module's quality report.
Observed = QualityReport
OBSERVED = QUALITY_REPORTS

#: Default number of states of a dynamic profile.
DEFAULT_STATES = 20


@frozen
class QualityTraces:
    """Every trial's quality at every grid time.

    Attributes:
        module: the module's name.
        time: the grid times (increasing, >= 0).
        quality: `(*cells, trials, m)` the scored (true) quality of the run's answer at each
            time; 0 where it had none.
        scored: `(*cells, trials, m)` whether the run had a result at each time.
        estimate: `(*cells, trials, m)` the quality the module reported of its answer at each
            time (0 where it had none), for a module that reports an estimate; None for one
            that reports its true quality (then the report is `quality`) or nothing.
        reports: what the module's `Result.quality` is: "true", "estimate" or "none".
        input_grids, inputs: the input-quality grid of the cells, as in a static profile.
        time_unit: "ticks" or "seconds".
        finished: `(*cells, trials)` when each run ended: the time it returned (or failed) by
            itself, or the last grid time if it was still running there; None: not known
            (traces made before it was recorded). A run that ends by itself ends its trace: a
            monitor has nothing more to decide.
    """

    module: str
    scored: NDArray[np.bool_] = array_field(dtype=np.bool_)
    time: Array = array_field()
    quality: Array = array_field()
    estimate: Array | None = optional_array_field()
    reports: Observed = "true"
    input_grids: tuple[Array, ...] = arrays_field(default=())
    inputs: tuple[str, ...] = field(default=(), converter=axis_names)
    time_unit: Unit = "ticks"
    finished: Array | None = optional_array_field()

    def __attrs_post_init__(self) -> None:
        _validate_traces(self)

    @property
    def cell_shape(self) -> tuple[int, ...]:
        return tuple(len(g) for g in self.input_grids)

    @property
    def trials(self) -> int:
        return int(self.quality.shape[-2])

    @property
    def observed(self) -> Array:
        """What a monitor sees of each run at each time: the quality it reports (its true
        quality, or its estimate), or 0 for a module that reports nothing."""
        if self.reports == "estimate":
            assert self.estimate is not None
            return self.estimate
        if self.reports == "none":
            return np.zeros(self.quality.shape)
        return self.quality

    def select(self, trials: ArrayLike) -> QualityTraces:
        """The traces of some trials only (an index or mask on the trial axis): to split
        training and test traces."""
        index = np.asarray(trials)

        chosen = np.flatnonzero(index) if index.dtype == bool else index

        def take(table: Array) -> Array:
            return np.take(table, chosen, axis=-2)

        return QualityTraces(
            module=self.module,
            time=self.time,
            quality=take(self.quality),
            scored=np.take(self.scored, chosen, axis=-2),
            estimate=None if self.estimate is None else take(self.estimate),
            reports=self.reports,
            input_grids=self.input_grids,
            inputs=self.inputs,
            time_unit=self.time_unit,
            finished=None if self.finished is None else np.take(self.finished, chosen, axis=-1),
        )

    def end_index(self) -> NDArray[np.intp]:
        """`(*cells, trials)` the grid index at which each run's trace ends: the first grid
        time at or after it finished (the last grid time where that is not known)."""
        last = len(self.time) - 1
        if self.finished is None:
            return np.full(self.quality.shape[:-1], last, dtype=np.intp)
        index: NDArray[np.intp] = np.minimum(
            np.searchsorted(self.time, self.finished * (1 - 1e-12), side="left"), last
        )
        return index


def _check_axes(
    time: Array,
    input_grids: tuple[Array, ...],
    inputs: tuple[str, ...],
    time_unit: str,
    fail: Callable[[str, str], NoReturn],
) -> None:
    """What traces and dynamic profiles share: the time grid, the input grids and their names,
    the time unit."""
    check_grid(time, "time", fail, unit_interval=False)
    for i, grid in enumerate(input_grids):
        check_grid(grid, f"input_quality[{i}]", fail, unit_interval=True)
    if len(inputs) not in (0, len(input_grids)):
        fail("inputs", f"expected one name per input grid ({len(input_grids)}), got {len(inputs)}")
    if time_unit not in UNITS:
        fail("time_unit", f"expected 'ticks' or 'seconds', got {time_unit!r}")


def _validate_traces(t: QualityTraces) -> None:
    name = t.module or "traces"

    def fail(field_name: str, problem: str) -> NoReturn:
        raise ProfileError(f"{name}: {field_name}: {problem}")

    _check_axes(t.time, t.input_grids, t.inputs, t.time_unit, fail)
    if t.reports not in OBSERVED:
        fail("reports", f"expected one of {', '.join(OBSERVED)}, got {t.reports!r}")
    trials = t.quality.shape[-2] if t.quality.ndim == len(t.cell_shape) + 2 else -1
    expected = (*t.cell_shape, trials, len(t.time))  # -1: any number of trials
    if t.quality.shape != expected or trials < 1:
        fail(
            "quality",
            f"expected shape {list(expected)} with trials >= 1, got {list(t.quality.shape)}",
        )
    tables = (("quality", t.quality), ("estimate", t.estimate))
    for field_name, table in tables:
        if table is None:
            continue
        if table.shape != expected:
            fail(field_name, f"expected shape {list(expected)}, got {list(table.shape)}")
        bad = ~np.isfinite(table) | (table < 0) | (table > 1)
        if np.any(bad):
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            fail(
                field_name + "".join(f"[{i}]" for i in index),
                f"expected a quality in [0, 1], got {table[index]:.10g}",
            )
    if t.scored.shape != expected:
        fail("scored", f"expected shape {list(expected)}, got {list(t.scored.shape)}")
    if t.finished is not None:
        if t.finished.shape != expected[:-1]:
            fail("finished", f"expected shape {list(expected[:-1])}, got {list(t.finished.shape)}")
        bad = ~np.isfinite(t.finished) | (t.finished < 0) | (t.finished > t.time[-1])
        if np.any(bad):
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            fail(
                "finished" + "".join(f"[{i}]" for i in index),
                f"expected a time from 0 to the last grid time {t.time[-1]:g}, got"
                f" {t.finished[index]:.10g}",
            )
    if (t.estimate is None) != (t.reports != "estimate"):
        fail(
            "estimate",
            "expected a table of estimates exactly when the module reports an estimate"
            f" (reports: {t.reports}), got {'none' if t.estimate is None else 'one'}",
        )


def quantile_bins(qualities: ArrayLike, states: int = DEFAULT_STATES) -> Array:
    """Bin edges on [0, 1] at quantiles of `qualities`, at most `states` bins: each holds about
    as many observations as another, and equal qualities are never split."""
    q = np.asarray(qualities, dtype=np.float64).reshape(-1)
    if q.size == 0:
        return np.array([0.0, 1.0])
    inner = np.quantile(q, np.linspace(0, 1, states + 1)[1:-1])
    # An edge is a bin's lower end: put it just above a quality shared by many observations.
    edges = np.unique(np.round(np.concatenate(([0.0], inner, [1.0])), 12))
    edges = edges[(edges > 0) & (edges < 1)]
    return np.concatenate(([0.0], edges, [1.0]))


def entry_edges(times: int, classes: int) -> NDArray[np.intp]:
    """Edges over grid indices 0..`times` of at most `classes` classes of entry time, geometric
    (the rate a run's entry time says of it is relative: entering at 2 or 3 differ as much as
    at 20 or 30): the first classes are single grid indices."""
    if classes < 1 or times < 1:
        raise ProfileError(f"entry_edges: expected times and classes >= 1, got {times}, {classes}")
    inner = np.round(np.geomspace(1, times, classes)).astype(np.intp)
    edges: NDArray[np.intp] = np.unique(np.concatenate(([0], inner[:-1], [times])))
    return edges


def entry_index(state: NDArray[np.intp]) -> NDArray[np.intp]:
    """`(..., m)` states at each grid time -> the grid index at which each run entered the state
    it is in at each time (the last change)."""
    m = state.shape[-1]
    changed = np.ones(state.shape, dtype=bool)
    changed[..., 1:] = state[..., 1:] != state[..., :-1]
    entered: NDArray[np.intp] = np.maximum.accumulate(np.where(changed, np.arange(m), 0), axis=-1)
    return entered


def _bin_of(quality: Array, bins: Array) -> NDArray[np.intp]:
    """The bin holding each quality, as `point_mass` places it (1.0 in the last bin)."""
    index: NDArray[np.intp] = np.clip(
        np.searchsorted(bins, quality, side="right") - 1, 0, len(bins) - 2
    )
    return index


def _counts(index: NDArray[np.intp], k: int, weights: Array | None = None) -> Array:
    """`(*cells, trials, m)` indices in [0, k) -> `(*cells, m, k)` counts over the trials (or
    sums of `weights`), by one `bincount` over every cell and time (a one-hot table would take
    k times the memory of the traces)."""
    moved = np.moveaxis(index, -2, -1)  # (*cells, m, trials)
    lead = moved.shape[:-1]
    offsets = np.arange(int(np.prod(lead)), dtype=np.intp).reshape((*lead, 1)) * k
    flat_weights = None if weights is None else np.moveaxis(weights, -2, -1).ravel()
    counts = np.bincount(
        (moved + offsets).ravel(), weights=flat_weights, minlength=int(np.prod(lead)) * k
    )
    return counts.astype(np.float64).reshape((*lead, k))


def _joint_counts(
    state: NDArray[np.intp],
    true: NDArray[np.intp],
    shape: tuple[int, int],
    entering: NDArray[np.bool_] | None,
    weights: Array | None = None,
) -> Array:
    """`(*cells, m, K, B)` counts (or sums of `weights`) of the trials in each (state, true bin)
    at each time, for `shape` (K, B): of the trials marked `entering` where some in the state
    at that time are (all of them where None), else of every trial in it. An ended state's
    true quality is that of the runs that ended then, and of those that ended before where
    none did."""
    k, kb = shape
    index = state * kb + true
    every = _counts(index, k * kb, weights).reshape((*index.shape[:-2], -1, k, kb))
    if entering is None:
        return every
    mask = entering.astype(np.float64)
    fresh = _counts(index, k * kb, mask if weights is None else mask * weights)
    marked = _counts(index, k * kb, mask).reshape(every.shape).sum(axis=-1, keepdims=True)
    return np.where(marked > 0, fresh.reshape(every.shape), every)


@frozen
class DynamicProfile:
    """A module's dynamic performance profile (see the module docstring).

    Attributes:
        module: the module's name.
        time: the grid times, m of them.
        bins: K+1 edges of the states' quality bins (the same bins for true quality).
        occupancy: `(*cells, m, K)` P(state at each time).
        transition: `(*cells, m - 1, K, K)` P(state at time j + 1 | state at time j).
        quality_mean: `(*cells, m, B)` mean true quality of each true-quality bin at each time;
            with `entered` or `ends`, `(*cells, m, K, B)`: of the runs in each state and true
            bin.
        observation: `(*cells, m, K, K)` P(true quality bin | state) at each time, or None when
            the state is the true quality.
        observed: what the state is: the module's "true" quality, its "estimate", or "none".
        samples: the trials behind each cell.
        entered: edges over grid indices of the classes of the time a run entered its bin (the
            state is then (bin, class), see the module docstring), or None: the bin alone.
        ends: whether there is an absorbing "ended" state per bin after the running states,
            for runs that ended by themselves (see the module docstring).
        input_grids, inputs, time_unit: as in a static profile.
    """

    module: str
    time: Array = array_field()
    bins: Array = array_field()
    occupancy: Array = array_field()
    transition: Array = array_field()
    quality_mean: Array = array_field()
    observation: Array | None = optional_array_field()
    observed: Observed = "true"
    samples: int = 0
    input_grids: tuple[Array, ...] = arrays_field(default=())
    inputs: tuple[str, ...] = field(default=(), converter=axis_names)
    time_unit: Unit = "ticks"
    entered: Array | None = optional_array_field()
    ends: bool = False

    def __attrs_post_init__(self) -> None:
        _validate_dynamic(self)

    @property
    def per_state(self) -> bool:
        """Whether `quality_mean` is per state and true bin (with entry classes or ended
        states), not per true bin alone."""
        return self.entered is not None or self.ends

    @property
    def running_states(self) -> int:
        """The states of runs still running, numbered first: bin * classes + class."""
        return self.n_bins * self.classes

    @property
    def ended(self) -> NDArray[np.bool_]:
        """`(K,)` the ended states (with `ends`): a run there is over, its answer counted."""
        over: NDArray[np.bool_] = np.arange(self.n_states) >= self.running_states
        return over

    @property
    def state_bin(self) -> NDArray[np.intp]:
        """The quality bin of each state."""
        running = np.arange(self.running_states) // self.classes
        bins: NDArray[np.intp] = np.concatenate(
            [running, np.arange(self.n_bins) if self.ends else np.zeros(0, np.intp)]
        ).astype(np.intp)
        return bins

    @property
    def n_bins(self) -> int:
        return len(self.bins) - 1

    @property
    def classes(self) -> int:
        """Classes of entry time per bin (1: the state is the bin)."""
        return 1 if self.entered is None else len(self.entered) - 1

    @property
    def n_states(self) -> int:
        return self.running_states + (self.n_bins if self.ends else 0)

    def entry_class(self, index: int) -> int:
        """The class of entering a bin at grid index `index`."""
        if self.entered is None:
            return 0
        return int(np.searchsorted(self.entered, index, side="right")) - 1

    @property
    def cell_shape(self) -> tuple[int, ...]:
        return tuple(len(g) for g in self.input_grids)

    @classmethod
    def from_traces(
        cls,
        traces: QualityTraces,
        bins: ArrayLike | None = None,
        states: int = DEFAULT_STATES,
        entered: int | ArrayLike | None = None,
        ends: bool = False,
    ) -> DynamicProfile:
        """The dynamic profile of recorded traces, on `bins` (default: `states` quantile bins
        of what the monitor observes); with `entered` (a number of classes, or their edges over
        grid indices), the state is (bin, class of the time the run entered it); with `ends`,
        runs that ended by themselves are in ended states of their own."""
        observed = traces.observed
        if bins is not None:
            edges = np.asarray(bins, dtype=np.float64)
        elif traces.reports == "none":
            edges = np.array([0.0, 1.0])  # the monitor sees nothing: one state
        else:
            edges = quantile_bins(observed, states)
        m = len(traces.time)
        classes_edges: Array | None = None
        if isinstance(entered, int | np.integer):  # a number of classes (1: the bin alone)
            if entered > 1:
                classes_edges = entry_edges(m, int(entered)).astype(np.float64)
        elif entered is not None:
            classes_edges = np.asarray(entered, dtype=np.float64)
        kb = len(edges) - 1
        level = _bin_of(observed, edges)  # (*cells, N, m)
        entering: NDArray[np.bool_] | None = None
        state = level
        true = _bin_of(traces.quality, edges)
        if classes_edges is not None:
            classes = len(classes_edges) - 1
            since = np.searchsorted(classes_edges, entry_index(level), side="right") - 1
            state = level * classes + np.clip(since, 0, classes - 1)
        k = kb * (1 if classes_edges is None else len(classes_edges) - 1)
        if ends:
            if traces.finished is None:
                raise ProfileError(
                    f"{traces.module}: ends needs traces that say when each run ended (finished)"
                )
            end = traces.end_index()[..., None]  # (*cells, N, 1)
            # Over from its end on; a run cut by the last grid time did not end by itself.
            over = (np.arange(m) >= end) & (end < m - 1)
            at_end = np.take_along_axis(level, end, axis=-1)
            state = np.where(over, k + at_end, state)
            k += kb
            # A run that ended counts where it ended (the policies bank it as it enters its
            # ended state): what an ended state says of the true quality at a time is learned
            # from the runs entering it then, not from every run that ended before.
            entering = ~over | (np.arange(m) == end)
        n = traces.trials
        occupancy = _counts(state, k) / n
        # Pair counts of consecutive states: (*cells, m - 1, K, K), summed over trials.
        pair = state[..., :-1] * k + state[..., 1:]
        pairs = _counts(pair, k * k).reshape((*pair.shape[:-2], pair.shape[-1], k, k))
        seen = pairs.sum(axis=-1, keepdims=True)
        transition = np.where(seen > 0, pairs / np.maximum(seen, 1), np.eye(k))
        true_counts = _counts(true, kb)  # (*cells, m, K)
        sums = _counts(true, kb, weights=traces.quality)
        midpoints = (edges[:-1] + edges[1:]) / 2
        quality_mean = np.where(true_counts > 0, sums / np.maximum(true_counts, 1), midpoints)
        joint = _joint_counts(state, true, (k, kb), entering)  # (*cells, m, K, B)
        if classes_edges is not None or ends:  # per state and true bin: runs of one bin differ
            # by class, and the runs still running from those that ended
            state_sums = _joint_counts(state, true, (k, kb), entering, traces.quality)
            quality_mean = np.where(
                joint > 0, state_sums / np.maximum(joint, 1), quality_mean[..., None, :]
            )
        quality_mean = np.clip(quality_mean, np.r_[0.0, edges[1:-1]], np.r_[edges[1:-1], 1.0])
        observation = None
        if traces.reports != "true" or classes_edges is not None or ends:
            given = joint.sum(axis=-1, keepdims=True)
            marginal = true_counts[..., None, :] / n
            observation = np.where(given > 0, joint / np.maximum(given, 1), marginal)
        return cls(
            module=traces.module,
            time=traces.time,
            bins=edges,
            occupancy=occupancy,
            transition=transition,
            quality_mean=quality_mean,
            observation=observation,
            observed=traces.reports,
            samples=n,
            input_grids=traces.input_grids,
            inputs=traces.inputs,
            time_unit=traces.time_unit,
            entered=classes_edges,
            ends=ends,
        )

    def at(self, input_qualities: Sequence[float] = ()) -> DynamicProfile:
        """The profile at one point of the input-quality grid, without input axes: each table
        interpolated multilinearly between the grid's cells (clamped at its ends), so its rows
        stay distributions."""
        q = [float(x) for x in input_qualities]
        if len(q) != len(self.input_grids):
            raise ProfileError(
                f"{self.module or 'dynamic profile'}: expected {len(self.input_grids)} input"
                f" qualit{'y' if len(self.input_grids) == 1 else 'ies'}, got {len(q)}"
            )
        weights = np.ones(())
        for grid, x in zip(self.input_grids, q, strict=True):
            w = np.array([np.interp(x, grid, corner) for corner in np.eye(len(grid))])
            weights = np.multiply.outer(weights, w)
        axes = len(self.input_grids)

        def mix(table: Array) -> Array:
            return np.tensordot(weights, table, axes=axes) if axes else table

        return DynamicProfile(
            module=self.module,
            time=self.time,
            bins=self.bins,
            occupancy=mix(self.occupancy),
            transition=mix(self.transition),
            quality_mean=mix(self.quality_mean),
            observation=None if self.observation is None else mix(self.observation),
            observed=self.observed,
            samples=self.samples,
            time_unit=self.time_unit,
            entered=self.entered,
            ends=self.ends,
        )

    def transition_over(self, start: int, end: int) -> Array:
        """P(state at time index `end` | state at `start`), `(*cells, K, K)`: the product of the
        one-step transitions between them (the identity for end == start)."""
        if not 0 <= start <= end < len(self.time):
            raise ProfileError(
                f"{self.module or 'dynamic profile'}: expected 0 <= start <= end <"
                f" {len(self.time)}, got start {start}, end {end}"
            )
        product = np.broadcast_to(np.eye(self.n_states), (*self.cell_shape, *(2 * [self.n_states])))
        for j in range(start, end):  # one matrix product per time step, not per cell
            product = product @ self.transition[..., j, :, :]
        return np.array(product)

    def expected_quality(self) -> Array:
        """E[true quality | state k at time j], `(*cells, m, K)`."""
        probability, quality = self.true_quality()
        expected: Array = np.einsum("...kb,...kb->...k", probability, quality)
        return expected

    def expected_gain(self) -> Array:
        """The expected gain in true quality of one more step, `(*cells, m - 1, K)`:
        E[true quality at j + 1 | state k at j] - E[true quality at j | state k at j] (for a
        state no trial was in at time j, what staying in it gains)."""
        now = self.expected_quality()
        later = np.einsum("...jkl,...jl->...jk", self.transition, now[..., 1:, :])
        gain: Array = later - now[..., :-1, :]
        return gain

    def true_quality(self) -> tuple[Array, Array]:
        """What each state at each time says of the true quality: `(P, q)` with P `(*cells, m,
        K, B)` = P(true bin b | state k, time j) and q `(*cells, m, K, B)` the mean true quality
        of bin b at time j (of the runs in state k, where the profile says), so E[f(true
        quality) | state k, time j] = sum_b P[..., j, k, b] f(q[..., j, k, b])."""
        shape = (*self.occupancy.shape, self.n_bins)
        quality = self.quality_mean
        if not self.per_state:
            quality = quality[..., None, :]
        quality = np.array(np.broadcast_to(quality, shape))
        if self.observation is not None:
            return self.observation, quality
        identity = np.broadcast_to(np.eye(self.n_states), shape)
        return np.array(identity), quality


def check_entered(edges: Array, times: int, fail: Callable[[str, str], NoReturn]) -> None:
    """Entry-class edges are whole grid indices increasing from 0 to the number of times."""
    whole = bool(np.all(np.isfinite(edges)) and np.all(edges == np.round(edges)))
    if edges.ndim != 1 or len(edges) < 2 or not whole or edges[0] != 0 or edges[-1] != times:
        fail("entered", f"expected whole grid indices from 0 to {times}, got {_plain_list(edges)}")
    if np.any(np.diff(edges) <= 0):
        fail("entered", f"expected increasing edges, got {_plain_list(edges)}")


def _validate_dynamic(p: DynamicProfile) -> None:
    name = p.module or "dynamic profile"

    def fail(field_name: str, problem: str) -> NoReturn:
        raise ProfileError(f"{name}: {field_name}: {problem}")

    _check_axes(p.time, p.input_grids, p.inputs, p.time_unit, fail)
    check_grid(p.bins, "quality_bins", fail, unit_interval=True, minimum=2)
    if p.bins[0] != 0 or p.bins[-1] != 1:
        fail("quality_bins", f"expected edges from 0 to 1, got {p.bins[0]:g} to {p.bins[-1]:g}")
    if p.observed not in OBSERVED:
        fail("observed", f"expected one of {', '.join(OBSERVED)}, got {p.observed!r}")
    if not isinstance(p.ends, bool):
        fail("ends", f"expected true or false, got {p.ends!r}")
    if not isinstance(p.samples, int) or isinstance(p.samples, bool) or p.samples < 0:
        fail("samples", f"expected an integer >= 0, got {p.samples!r}")
    cells, m = p.cell_shape, len(p.time)
    if p.entered is not None:
        check_entered(p.entered, m, fail)
    k, kb = p.n_states, p.n_bins
    shapes = {
        "occupancy": (p.occupancy, (*cells, m, k), True),
        "transition": (p.transition, (*cells, m - 1, k, k), True),
        "quality_mean": (
            p.quality_mean,
            (*cells, m, k, kb) if p.per_state else (*cells, m, kb),
            False,
        ),
        "observation": (p.observation, (*cells, m, k, kb), True),
    }

    for field_name, (table, shape, distribution) in shapes.items():
        if table is None:
            continue
        if table.shape != shape:
            fail(field_name, f"expected shape {list(shape)}, got {list(table.shape)}")
        bad = ~np.isfinite(table) | (table < 0) | (table > 1 + SUM_TOLERANCE)
        if np.any(bad):
            index = tuple(int(i) for i in np.argwhere(bad)[0])
            fail(
                field_name + "".join(f"[{i}]" for i in index),
                f"expected a number in [0, 1], got {table[index]:.10g}",
            )
        if distribution and table.size:
            sums = table.sum(axis=-1)
            worst = np.unravel_index(np.argmax(np.abs(sums - 1)), sums.shape)
            if abs(sums[worst] - 1) > SUM_TOLERANCE:
                fail(
                    field_name + "".join(f"[{int(i)}]" for i in worst),
                    f"expected a row summing to 1 (within {SUM_TOLERANCE:g}), got"
                    f" {sums[worst]:.10g}",
                )
    if (p.observation is None) != (p.observed == "true" and p.entered is None and not p.ends):
        fail(
            "observation",
            "expected a table exactly when the state is not the true quality"
            f" (observed: {p.observed}, entered: {'none' if p.entered is None else 'given'},"
            f" ends: {str(p.ends).lower()}), got"
            f" {'none' if p.observation is None else 'one'}",
        )


def _plain_list(values: Array) -> list[float | int]:
    return [int(v) if float(v).is_integer() else float(v) for v in np.asarray(values).reshape(-1)]
