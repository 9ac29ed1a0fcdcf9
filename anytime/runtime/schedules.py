"""Schedules of contract runs, and the acceleration ratio of the interruptible algorithm they make.

Running a contract algorithm with allocations t0, r t0, r^2 t0, ... and answering with the last
completed result makes it interruptible (Russell & Zilberstein 1991; Zilberstein & Russell, AIJ
1996, §2.1). Its *acceleration ratio* is the smallest c such that at every time c t it has
completed a contract of length >= t: the sup over t of `needed(t) / t`, where `needed(t)` is the
time by which a contract of length >= t has completed. The sup sits just above each contract
length L_{k-1}, where the next length L_k is needed: `finish(L_k) / L_{k-1}`.

Every schedule here hands contract k, of length `t0 * b^(k + U)`, to worker k mod m; each worker
runs its contracts back to back from time 0. Contract k then finishes at
`b^k t0 (b^m / (b^m - 1))` (less a vanishing head), so the worst case is `b^(m+1) / (b^m - 1)`:

- one worker, U = 0: r^2 / (r - 1), 4 at r = 2, the optimum for one processor;
- m workers, b = (m+1)^(1/m): (m+1)^((m+1)/m) / m = 4, 2.598, 2.117, 1.869 for m = 1..4, the
  optimum for one problem on m processors (Bernstein, Perkins, Zilberstein & Finkelstein, AAAI
  2002);
- U uniform on [0, 1), drawn once per run: for any fixed t, log_b(L / t) of the first length
  L >= t is uniform, so the expected ratio is `E[b^U] b^m / (b^m - 1) = (b - 1)/ln b * b^m /
  (b^m - 1)`, which is b / ln b on one worker, smallest (e) at b = e.

A schedule starts at t0 rather than at b^-inf, so its ratio approaches these limits from below
as t grows; below the first length nothing shorter is ever run and `needed(t) / t` grows without
bound, so ratios are taken over t >= the first length.
"""

from __future__ import annotations

import math

import numpy as np
from attrs import field, frozen
from numpy.typing import ArrayLike, NDArray

from anytime.errors import AnytimeError
from anytime.profiles.profile import Array
from anytime.vocabulary import array_field


class ScheduleError(AnytimeError, ValueError):
    """A schedule's parameters are out of range; the message says which and what was given."""


def _check_unit(instance: Schedule, attribute: object, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ScheduleError(f"schedule: t0 must be a finite number > 0, got {value!r}")


def _check_base(instance: Schedule, attribute: object, value: float) -> None:
    if not (math.isfinite(value) and value > 1):
        raise ScheduleError(f"schedule: the base (ratio r or b) must be > 1, got {value!r}")


def _check_workers(instance: Schedule, attribute: object, value: int) -> None:
    if value < 1:
        raise ScheduleError(f"schedule: workers must be >= 1, got {value!r}")


@frozen
class Schedule:
    """Contract k has length `unit * base^(k + U)` and runs on worker k mod `workers`.

    Attributes:
        unit: t0, the first contract's length (in the contract profile's time unit).
        base: the ratio between successive lengths (r, or b).
        workers: m, the number of processors; contracts are handed out round-robin.
        randomised: U is drawn uniform on [0, 1) once per run (else U = 0).
        name: what the schedule is called in tables ("geometric", "round-robin", ...).
    """

    unit: float = field(converter=float, validator=_check_unit)
    base: float = field(converter=float, validator=_check_base)
    workers: int = field(default=1, converter=int, validator=_check_workers)
    randomised: bool = False
    name: str = "geometric"

    @property
    def worst_case_ratio(self) -> float:
        """`b^(m+1) / (b^m - 1)`: the sup over t as the schedule grows (for every U)."""
        b, m = self.base, self.workers
        return float(b ** (m + 1) / (b**m - 1))

    @property
    def expected_ratio(self) -> float:
        """`(b - 1)/ln b * b^m / (b^m - 1)`: the ratio at any fixed t, averaged over U (b / ln b
        on one worker). Only a randomised schedule has it."""
        if not self.randomised:
            raise ScheduleError(f"schedule: a {self.name} schedule has no random offset")
        b, m = self.base, self.workers
        return float((b - 1) / math.log(b) * b**m / (b**m - 1))

    @property
    def theory_ratio(self) -> float:
        """What the analysis promises: the expected ratio for a randomised schedule, else the
        worst case."""
        return self.expected_ratio if self.randomised else self.worst_case_ratio

    def draw(self, rng: np.random.Generator) -> float:
        """The offset U for one run: uniform on [0, 1) when randomised, else 0."""
        return float(rng.random()) if self.randomised else 0.0

    def length(self, k: int, offset: float = 0.0) -> float:
        """The length of contract k (0-based)."""
        return float(self.unit * self.base ** (k + offset))

    def count(self, horizon: float) -> int:
        """How many contracts `contracts(horizon)` lists: every one that starts before
        `horizon`, and one of length >= `horizon`.

        Contract k starts after worker k mod m ran contract k - m, of length >= t0 b^(k-m), so
        one starting before the horizon has k < log_b(horizon / t0) + m; and contract
        ceil(log_b(horizon / t0)) already has length >= horizon."""
        if not horizon > 0:
            return 1
        steps = max(0, math.ceil(math.log(horizon / self.unit, self.base) + 1e-9))
        return steps + self.workers + 1

    def contracts(self, horizon: float, offset: ArrayLike = 0.0) -> Contracts:
        """The contracts that matter up to `horizon` (see `count`), for one offset U or a batch
        of them (arrays then have a leading axis per offset axis)."""
        u = np.asarray(offset, dtype=np.float64)
        n = self.count(horizon)
        m = self.workers
        padded = -(-n // m) * m  # whole rounds, so the per-worker sums are one reshape
        k = np.arange(padded, dtype=np.float64)
        lengths = self.unit * self.base ** (k + u[..., None])
        rounds = lengths.reshape((*u.shape, padded // m, m))
        finish = np.cumsum(rounds, axis=-2).reshape((*u.shape, padded))
        return Contracts(
            length=lengths[..., :n],
            finish=finish[..., :n],
            worker=np.arange(n) % m,
        )


@frozen
class Contracts:
    """Contracts in order of issue, for one schedule realisation or a batch of them.

    Attributes:
        length: shape (..., K), increasing along the last axis.
        finish: when each completes, shape (..., K) (workers start at time 0).
        worker: which worker runs each, shape (K,).
    """

    length: Array = array_field(dtype=None)
    finish: Array = array_field(dtype=None)
    worker: NDArray[np.intp] = array_field(dtype=None)

    @property
    def start(self) -> Array:
        return self.finish - self.length

    def per_worker(self, worker: int) -> tuple[Array, Array]:
        """The (start, finish) times of one worker's contracts."""
        mine = self.worker == worker
        return self.start[..., mine], self.finish[..., mine]

    def longest_completed(self, t: ArrayLike) -> Array:
        """The longest contract completed by each time in `t` (0 where none has): shape
        (..., *t.shape)."""
        t_arr = np.asarray(t, dtype=np.float64)
        done = self.finish[..., None, :] <= t_arr.reshape(-1, 1)
        best: Array = np.where(done, self.length[..., None, :], 0.0).max(axis=-1)
        return best.reshape((*self.length.shape[:-1], *t_arr.shape))

    def needed(self, t: ArrayLike) -> Array:
        """The time by which a contract of length >= t has completed (inf when no listed
        contract is that long): shape (..., *t.shape)."""
        t_arr = np.asarray(t, dtype=np.float64)
        long_enough = self.length[..., None, :] >= t_arr.reshape(-1, 1)
        first: Array = np.where(long_enough, self.finish[..., None, :], np.inf).min(axis=-1)
        return first.reshape((*self.length.shape[:-1], *t_arr.shape))

    def ratio(self, t: ArrayLike) -> Array:
        """`needed(t) / t`: how much longer the interruptible algorithm needs than the
        contract algorithm to reach the contract's quality at t."""
        return self.needed(t) / np.asarray(t, dtype=np.float64)

    def worst_ratio(self, up_to: float | None = None) -> Array:
        """The exact sup of `ratio(t)` over t in [first length, up_to] (default: the longest
        listed length), shape (...,). See `worst_ratio`."""
        return worst_ratio(self.length, self.finish, up_to)


def worst_ratio(length: ArrayLike, finish: ArrayLike, up_to: float | None = None) -> Array:
    """The acceleration ratio of completed contracts (lengths increasing along the last axis,
    with their finish times), as the exact sup of `needed(t) / t` over t in
    [length[0], up_to] (default: the longest length).

    On (L_{i-1}, L_i] the time needed is the earliest finish among contracts i, i+1, ..., and
    the ratio falls with t, so the sup over that interval is its right-limit at L_{i-1}. Works
    for measured runs too: pass the lengths and the observed completion times.
    """
    lengths = np.asarray(length, dtype=np.float64)
    finishes = np.asarray(finish, dtype=np.float64)
    if lengths.shape[-1] == 0:
        return np.full(lengths.shape[:-1], np.inf)
    if np.any(np.diff(lengths, axis=-1) <= 0):
        raise ScheduleError("worst_ratio: contract lengths must increase in order of issue")
    earliest = np.minimum.accumulate(finishes[..., ::-1], axis=-1)[..., ::-1]
    limit = lengths[..., -1] if up_to is None else np.asarray(up_to, dtype=np.float64)
    at_first = earliest[..., 0] / lengths[..., 0]
    jumps = earliest[..., 1:] / lengths[..., :-1]
    # A length equal to the limit up to rounding (t0 * r**k computed two ways) is not below it:
    # the jump just above it lies beyond the limit.
    inside = lengths[..., :-1] < np.asarray(limit)[..., None] * (1.0 - 1e-12)
    worst: Array = np.maximum(at_first, np.where(inside, jumps, 0.0).max(axis=-1, initial=0.0))
    return worst


# --- the schedules of the issue -----------------------------------------------------------------


def geometric(t0: float = 1.0, r: float = 2.0) -> Schedule:
    """t0, r t0, r^2 t0, ... on one processor: ratio r^2 / (r - 1), 4 at r = 2 (optimal)."""
    return Schedule(unit=t0, base=r, workers=1, name="geometric")


def optimal_base(m: int) -> float:
    """b = (m + 1)^(1/m): the base of the optimal round-robin schedule on m workers."""
    if m < 1:
        raise ScheduleError(f"schedule: workers must be >= 1, got {m!r}")
    return float((m + 1) ** (1 / m))


def optimal_ratio(m: int) -> float:
    """(m + 1)^((m + 1)/m) / m: the optimal acceleration ratio for one problem on m workers
    (Bernstein et al., AAAI 2002): 4, 2.598, 2.117, 1.869 for m = 1..4."""
    return float((m + 1) ** ((m + 1) / m) / m)


def round_robin(m: int, t0: float = 1.0, b: float | None = None) -> Schedule:
    """Lengths t0 b^k, contract k to worker k mod m, b = (m + 1)^(1/m) unless given."""
    base = optimal_base(m) if b is None else b
    return Schedule(unit=t0, base=base, workers=m, name="round-robin")


def randomised(b: float = math.e, t0: float = 1.0, workers: int = 1) -> Schedule:
    """Lengths t0 b^(k + U), U uniform on [0, 1) per run: expected ratio b / ln b on one
    worker, e at b = e (its minimum). `Schedule.draw(rng)` gives a run's U."""
    return Schedule(unit=t0, base=b, workers=workers, randomised=True, name="randomised")
