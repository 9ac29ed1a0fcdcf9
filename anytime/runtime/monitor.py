"""The meta-level monitor: how long to plan in each frame, and how fast to act meanwhile.

A task is a series of *frames*: sense, plan, execute, with the planning for the next frame
overlapping the execution of the current one (Zilberstein & Russell, "The run-time system").
The monitor knows nothing of the domain; it makes two decisions from a (compiled) program's
performance profile and two pluggable models.

*Inter-frame*: before a frame, choose its contract time

    t_c = argmax over the grid of  VOT(t, f_t, t_c) - COE(e_t, f_t, t_c)

where VOT is the expected value of the task and COE the expected cost (of energy), t the time
now, f_t the frames left and e_t the energy used so far. Both are expectations over the
profile's output-quality distribution at t_c: for grid times t_g and output bins k,

    U(t_g) = sum_k P(k | t_g) * (value(state, t_g, q_gk) - cost(state, t_g, q_gk)),

computed in one call of each model on arrays. The grid point of highest U wins; ties (within a
relative 1e-12) go to the smallest contract time.

*Intra-frame*: while the next plan is being computed, compare the plan's quality so far with
the profile's expected quality at the elapsed time (planning ahead or behind), and the
execution's progress with the share of the contract elapsed (execution ahead or behind). Planning
ahead and execution behind: spend more energy, go `FASTER`; planning behind and execution ahead:
go `SLOWER`, so that planning gets more time; otherwise `HOLD` (the papers' Figure 12).

How a domain plugs in:

- *state*: any object the domain defines and the monitor passes through untouched (the time
  now, frames left, energy used, remaining distance, speed...);
- a *value model* (`ValueModel`): `value(state, contract, quality)`, the value of the task if
  this frame's contract is `contract` and its plan has quality `quality`. `DeadlineValue` is a
  ready-made value of completion time;
- a *cost model* (`CostModel`): `cost(state, contract, quality)`, in the same units.

Both are vectorised: the monitor calls them with `contract` of shape (G, 1) (the grid) and
`quality` of shape (G, K) (the quality each output bin stands for at each grid time), and they
answer with anything that broadcasts to (G, K). The quality of a bin is its midpoint, shifted
per grid time by the difference between the profile's exact expected quality (its `mean` table,
when it has one) and the midpoints' average, so that a deterministic profile is evaluated at its
exact curve rather than at coarse bin midpoints.

Every decision is recorded, with the time it was given, in an optional `EventLog`: structured
records the caller can print, save as JSON lines or plot.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping, Sequence
from enum import Enum, StrEnum
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

import numpy as np
from attrs import Factory, cmp_using, define, field, frozen
from numpy.typing import ArrayLike

from anytime.errors import AnytimeError
from anytime.profiles.profile import Array, ConditionalPerformanceProfile
from anytime.vocabulary import array_field, read_only

#: Two utilities this close (relative to the best) are a tie, won by the smaller contract time.
TIE_TOLERANCE = 1e-12

S = TypeVar("S")
S_contra = TypeVar("S_contra", contravariant=True)


class MonitorError(AnytimeError, ValueError):
    """The monitor was given something out of range; the message says what and what was given."""


# --- pluggable models ---------------------------------------------------------------------------


class ValueModel(Protocol[S_contra]):
    """The value of the task (VOT), given the frame's contract time and the plan's quality."""

    def value(self, state: S_contra, contract: Array, quality: Array) -> ArrayLike:
        """Values for `contract` (G, 1) and `quality` (G, K); broadcastable to (G, K)."""
        ...


class CostModel(Protocol[S_contra]):
    """The cost (COE) of the task, in the value's units, given the contract time and quality."""

    def cost(self, state: S_contra, contract: Array, quality: Array) -> ArrayLike:
        """Costs for `contract` (G, 1) and `quality` (G, K); broadcastable to (G, K)."""
        ...


def _check_finite(name: str, value: float, minimum: float = -math.inf) -> None:
    if not (math.isfinite(value) and value >= minimum):
        bound = "" if minimum == -math.inf else f" >= {minimum:g}"
        raise MonitorError(f"{name} must be a finite number{bound}, got {value!r}")


def _finite(name: str, minimum: float = -math.inf) -> Any:
    """An attrs validator: `_check_finite` on the field's value."""

    def check(instance: object, attribute: object, value: float) -> None:
        _check_finite(name, value, minimum)

    return check


@frozen
class DeadlineValue:
    """A value of completion time: `full` until `deadline`, then falling by `decay` per time
    unit late, never below 0. Call it on an array of completion times."""

    full: float = field(converter=float, validator=_finite("deadline value: full", 0.0))
    deadline: float = field(converter=float, validator=_finite("deadline value: deadline"))
    decay: float = field(converter=float, validator=_finite("deadline value: decay", 0.0))

    def __call__(self, completion: ArrayLike) -> Array:
        late = np.maximum(np.asarray(completion, dtype=np.float64) - self.deadline, 0.0)
        if self.decay == 0:  # no loss, even infinitely late (0 * inf is NaN)
            return np.full(late.shape, self.full)
        return np.maximum(self.full - self.decay * late, 0.0)


# --- structured events --------------------------------------------------------------------------


def _plain(value: Any) -> Any:
    """`value` as plain JSON-able Python: numpy scalars and arrays, enums and tuples unwrapped."""
    if isinstance(value, Enum):
        return _plain(value.value)
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    return value


def _event_data(data: Mapping[str, Any]) -> dict[str, Any]:
    plain: dict[str, Any] = _plain(data)
    reserved = sorted(set(plain) & {"time", "kind"})
    if reserved:
        raise MonitorError(f"event: data may not use the reserved key(s) {reserved}")
    return plain


def model_answer(name: str, answer: ArrayLike, shape: tuple[int, ...]) -> Array:
    """A value or cost model's answer as an array of `shape` (grid, bins), or a
    `MonitorError` naming the model when it does not broadcast there or is not finite (the
    monitor and the stopping policies check their models with it)."""
    array = np.asarray(answer, dtype=np.float64)
    try:
        array = np.broadcast_to(array, shape)
    except ValueError:
        raise MonitorError(
            f"monitor: the {name} model answered with shape {list(array.shape)},"
            f" which does not broadcast to (grid, bins) {list(shape)}"
        ) from None
    if not np.all(np.isfinite(array)):
        raise MonitorError(f"monitor: the {name} model answered with NaN or infinity")
    return array


@frozen
class MonitorEvent:
    """One decision of the monitor: when (task time), what kind, and its details.

    `data` holds plain JSON values (numpy values, tuples and enums are converted on the way in).
    """

    time: float = field(converter=float)
    kind: str
    data: dict[str, Any] = field(factory=dict, converter=_event_data, hash=False)

    def as_dict(self) -> dict[str, Any]:
        """A flat record: `time`, `kind`, then the data's keys."""
        return {"time": self.time, "kind": self.kind, **self.data}

    @classmethod
    def from_dict(cls, record: Mapping[str, Any]) -> MonitorEvent:
        data = {k: v for k, v in record.items() if k not in ("time", "kind")}
        return cls(record["time"], record["kind"], data)


@define
class EventLog:
    """The monitor's decisions, in the order made."""

    events: list[MonitorEvent] = Factory(list)

    def append(self, event: MonitorEvent) -> None:
        self.events.append(event)

    def record(self, time: float, kind: str, data: Mapping[str, Any]) -> MonitorEvent:
        """Append a new event and return it."""
        event = MonitorEvent(time, kind, dict(data))
        self.events.append(event)
        return event

    def __iter__(self) -> Iterator[MonitorEvent]:
        return iter(self.events)

    def __len__(self) -> int:
        return len(self.events)

    def __getitem__(self, index: int) -> MonitorEvent:
        return self.events[index]

    def of_kind(self, kind: str) -> list[MonitorEvent]:
        return [event for event in self.events if event.kind == kind]

    def as_dicts(self) -> list[dict[str, Any]]:
        """One flat record per event (see `MonitorEvent.as_dict`), ready for a table."""
        return [event.as_dict() for event in self.events]

    def to_jsonl(self) -> str:
        """JSON lines: one record per event, each line ending in a newline."""
        return "".join(json.dumps(record) + "\n" for record in self.as_dicts())

    def write_jsonl(self, path: str | Path) -> None:
        Path(path).write_text(self.to_jsonl(), encoding="utf-8")

    @classmethod
    def from_jsonl(cls, text: str) -> EventLog:
        lines = (line for line in text.splitlines() if line.strip())
        return cls([MonitorEvent.from_dict(json.loads(line)) for line in lines])

    @classmethod
    def read_jsonl(cls, path: str | Path) -> EventLog:
        return cls.from_jsonl(Path(path).read_text(encoding="utf-8"))


# --- decisions ----------------------------------------------------------------------------------


@frozen
class ContractDecision:
    """The inter-frame decision: the chosen contract time and what it is expected to bring.

    Attributes:
        contract: the chosen contract time t_c.
        expected_quality: the profile's expected output quality at t_c.
        expected_value, expected_cost: E[VOT] and E[COE] at t_c.
        expected_utility: their difference, the highest over the grid.
        grid: the contract times considered; the curves below are over it, for plotting.
    """

    contract: float
    expected_quality: float
    expected_value: float
    expected_cost: float
    expected_utility: float
    grid: Array = array_field()
    quality_curve: Array = array_field()
    value_curve: Array = array_field()
    cost_curve: Array = array_field()
    utility_curve: Array = array_field()


class Adjustment(StrEnum):
    """The intra-frame decision about the speed of execution."""

    FASTER = "faster"  # planning ahead, execution behind: spend more energy
    SLOWER = "slower"  # planning behind, execution ahead: give planning more time
    HOLD = "hold"  # anything else


def _pace(actual: float, expected: float, tolerance: float) -> str:
    if actual > expected + tolerance:
        return "ahead"
    if actual < expected - tolerance:
        return "behind"
    return "on-schedule"


def _grid(value: ArrayLike) -> Array:
    grid = read_only(value)
    if grid.ndim != 1 or grid.size == 0:
        raise MonitorError(
            f"monitor: grid must be a non-empty list of times, got shape {list(grid.shape)}"
        )
    if not np.all(np.isfinite(grid)) or np.any(grid < 0):
        raise MonitorError("monitor: grid times must be finite numbers >= 0")
    if np.any(np.diff(grid) <= 0):
        i = int(np.argmax(np.diff(grid) <= 0))
        raise MonitorError(
            f"monitor: grid must be increasing, got {grid[i]:g} then {grid[i + 1]:g}"
        )
    return grid


def _qualities(value: Sequence[float] | None) -> tuple[float, ...] | None:
    return None if value is None else tuple(float(q) for q in value)


@frozen
class Monitor(Generic[S]):
    """The frame monitor of one (compiled) program.

    Attributes:
        profile: the program's performance profile (conditional on its quality-carrying inputs).
        value_model, cost_model: the domain's VOT and COE (see the module docstring).
        grid: the contract times to choose from (default: the profile's time grid).
        input_quality: one quality per input of the profile (None when it has none); a call
            may pass its own when the inputs change from frame to frame.
        log: where decisions are recorded (None: not recorded).
    """

    profile: ConditionalPerformanceProfile
    value_model: ValueModel[S]
    cost_model: CostModel[S]
    grid: Array = field(
        default=Factory(lambda self: self.profile.time, takes_self=True),
        converter=_grid,
        eq=cmp_using(eq=np.array_equal),
        hash=False,
    )
    input_quality: tuple[float, ...] | None = field(default=None, converter=_qualities)
    log: EventLog | None = field(default=None, eq=False)

    def __attrs_post_init__(self) -> None:
        self._inputs(self.input_quality)

    def _inputs(self, given: Sequence[float] | None) -> Array:
        """The input qualities to condition on, checked against the profile's inputs."""
        m = self.profile.n_inputs
        if given is None:
            given = self.input_quality
        if given is None:
            if m:
                raise MonitorError(
                    f"monitor: the profile has {m} quality-carrying input(s);"
                    " input_quality must give one quality each"
                )
            return np.zeros(0)
        q = np.array(given, dtype=np.float64).reshape(-1)
        if q.size != m:
            raise MonitorError(f"monitor: expected {m} input quality(ies), got {q.size}")
        if not np.all((q >= 0) & (q <= 1)):
            raise MonitorError(f"monitor: input qualities must be in [0, 1], got {q.tolist()}")
        return q

    def choose_contract(
        self, state: S, *, now: float = 0.0, input_quality: Sequence[float] | None = None
    ) -> ContractDecision:
        """Inter-frame: the contract time of highest expected VOT - COE over the grid.

        Args:
            state: passed to the models untouched.
            now: the task time of the decision, for the log.
            input_quality: the inputs' qualities for this frame (default: the monitor's).
        """
        q_in = self._inputs(input_quality)
        grid = self.grid
        g, k = grid.size, self.profile.n_bins
        q = np.broadcast_to(q_in, (g, q_in.size))
        dist = self.profile.distribution(q, grid)  # (G, K)
        expected = self.profile.expected(q, grid)  # (G,)
        centres = self.profile.values
        shift = expected - dist @ centres  # 0 unless the profile knows exact means
        quality = np.clip(centres[None, :] + shift[:, None], 0.0, 1.0)
        contract = grid[:, None]
        values = model_answer("value", self.value_model.value(state, contract, quality), (g, k))
        costs = model_answer("cost", self.cost_model.cost(state, contract, quality), (g, k))
        value_curve = np.einsum("gk,gk->g", dist, values)
        cost_curve = np.einsum("gk,gk->g", dist, costs)
        utility = value_curve - cost_curve
        best = utility.max()
        i = int(np.argmax(utility >= best - TIE_TOLERANCE * max(1.0, abs(best))))
        decision = ContractDecision(
            contract=float(grid[i]),
            expected_quality=float(expected[i]),
            expected_value=float(value_curve[i]),
            expected_cost=float(cost_curve[i]),
            expected_utility=float(utility[i]),
            grid=grid,
            quality_curve=expected,
            value_curve=value_curve,
            cost_curve=cost_curve,
            utility_curve=utility,
        )
        if self.log is not None:
            self.log.record(
                now,
                "contract",
                {
                    "contract": decision.contract,
                    "expected_quality": decision.expected_quality,
                    "expected_value": decision.expected_value,
                    "expected_cost": decision.expected_cost,
                    "expected_utility": decision.expected_utility,
                    "input_quality": q_in,
                },
            )
        return decision

    def adjust(
        self,
        elapsed: float,
        plan_quality: float,
        progress: float,
        contract: float,
        *,
        tolerance: float = 0.05,
        now: float | None = None,
        input_quality: Sequence[float] | None = None,
    ) -> Adjustment:
        """Intra-frame: whether execution should go faster, slower, or hold its pace.

        Args:
            elapsed: time since the frame began (planning for the next frame began with it).
            plan_quality: the quality of the best plan so far, in [0, 1].
            progress: the fraction of this frame's execution done, in [0, 1].
            contract: the frame's contract time (> 0); execution is on schedule when its
                progress is the fraction of the contract elapsed (1 once the contract is over).
            tolerance: how far from expectation (in quality and in progress) still counts as
                on schedule.
            now: the task time of the check, for the log (default: `elapsed`).
            input_quality: the inputs' qualities for this frame (default: the monitor's).
        """
        elapsed, plan_quality, progress, contract, tolerance = (
            float(x) for x in (elapsed, plan_quality, progress, contract, tolerance)
        )
        _check_finite("monitor: elapsed", elapsed, 0.0)
        _check_finite("monitor: tolerance", tolerance, 0.0)
        if not (math.isfinite(contract) and contract > 0):
            raise MonitorError(f"monitor: contract must be a finite number > 0, got {contract!r}")
        if not 0 <= plan_quality <= 1:
            raise MonitorError(f"monitor: plan_quality must be in [0, 1], got {plan_quality!r}")
        if not 0 <= progress <= 1:
            raise MonitorError(f"monitor: progress must be in [0, 1], got {progress!r}")
        q_in = self._inputs(input_quality)
        expected = float(self.profile.expected(q_in, elapsed))
        scheduled = min(elapsed / contract, 1.0)
        planning = _pace(plan_quality, expected, tolerance)
        execution = _pace(progress, scheduled, tolerance)
        if planning == "ahead" and execution == "behind":
            adjustment = Adjustment.FASTER
        elif planning == "behind" and execution == "ahead":
            adjustment = Adjustment.SLOWER
        else:
            adjustment = Adjustment.HOLD
        if self.log is not None:
            self.log.record(
                elapsed if now is None else now,
                "adjust",
                {
                    "elapsed": elapsed,
                    "contract": contract,
                    "plan_quality": plan_quality,
                    "expected_quality": expected,
                    "planning": planning,
                    "progress": progress,
                    "scheduled_progress": scheduled,
                    "execution": execution,
                    "adjustment": adjustment,
                    "tolerance": tolerance,
                },
            )
        return adjustment
