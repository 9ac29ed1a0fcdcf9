"""The frame program's profile in the task: what a frame's contract buys the robot, measured on
the task's own worlds.

The compiled `navigate` profile says what the planner's plan is worth on a whole 128 x 128 map
sensed at once (its measured profile: plan quality = optimal length / executed length on the
true map). In the task the robot senses only a window around itself, the rest of its map is
the prior or what it saw before, it walks only the first segment of each plan and plans again:
the plans' qualities at a contract are not the ones the compiled profile predicts (on 64 x 64
worlds it expects a route 1.006 times the shortest from 600 ticks on; the task walks 1.07
times it), and a frame covers less than the straight line to the window's edge that the model
assumed before any frame was seen (about 25 cells, not 32, with a radius of 16).

`measure` runs the task under a fixed contract on training worlds (seeds from 1000, apart from
the benchmark's, 0 to 99, and the tests') for each contract of a grid, and records per world the
route's quality, optimal length / route length, the progress of the first frame against the
model's straight-line estimate, and the first frame apart from the later ones: the cells it
walked, the distance it left, and how much the later frames stretched the rest of the route. The
first frame is another decision than the later ones: the robot waits for its plan (a later
frame's planning overlaps the walk of the segment before it), and it is made with nothing sensed
before; under a contract of 100 ticks the first plan is made on the prior map alone, which costs
that frame a few cells, while the later frames at 100 ticks never sense and stretch the rest of
the route by a fifth. A whole route's quality at 100 ticks charges the first frame with the
later frames' wandering; `TaskModel.first_choice` takes the first frame's own cost and the later
frames' at the contracts they will get. Every contract runs on the same worlds, so the
differences between contracts are measured pairwise: at 128 x 128, 1000 ticks (400 of them
sensing) walk routes 0.022 shorter per cell of the shortest than 400 ticks, with a standard
error of 0.007 over 150 worlds. `TaskCalibration.profile` is the profile the monitor plans with
(the distribution of route quality per contract: its `E[1 / q]` is how much the frames stretch
the route, `TaskModel.later_factor`), `progress` scales `TaskModel.first_step`. The shipped
calibrations are `profiles/task-<size>.json` (radius a quarter of the side); re-measure one with

    .venv/bin/python -m anytime_navigation.task.calibration --size 64 --worlds 150 --workers 2

(the shipped ones: 150 worlds, re-measured when the robot came to remember what it saw around
itself from frame to frame, `frames`, again when it came to give up a waypoint the way to
which turned long, `frames.GIVE_UP`, and when a frame whose vision reads nothing came to plan
on the robot's map rather than on the prior, `frames`: one world of 150 moved, at 200 ticks at
64 x 64, and when detours came to be planned on the robot's map where a plan crosses its own,
`frames.PENALTY`: mean route over shortest within 0.003 per contract; a few seconds of
processor time per world at 128 x 128, less at 64 x 64; the numbers are the same on any number
of workers). Speeds do not enter: the route a frame walks and its progress do not depend on how
fast the robot walks it.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from attrs import field, frozen

from anytime.plugin import ConditionalPerformanceProfile
from anytime.plugin.compose import DeadlineValue

from ..resources import data_file
from ..world import random_world
from .model import FirstFrame

__all__ = ["CONTRACTS", "FIRST_SEED", "TaskCalibration", "measure", "shipped"]

#: The contracts measured (ticks): every 100 up to 1000.
CONTRACTS = tuple(float(t) for t in range(100, 1001, 100))

#: The training worlds' first seed (the benchmark uses 0-29, the tests small seeds).
FIRST_SEED = 1000

#: The quality bins of the calibration's profile: every 0.01 from 0.5, so that `1 / q` at a
#: bin's midpoint is within 1% of its samples', and a few below for the rare routes on which the
#: robot wandered (up to 50 times the shortest on a training world): the monitor counts them
#: (`TaskModel` without a floor), they weigh on the mean utility more than their share.
BINS = np.concatenate([[0.0, 0.025, 0.05, 0.1, 0.2, 0.3, 0.4], np.linspace(0.5, 1.0, 51)])


def _floats(values: Any) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def _rows(values: Any) -> tuple[tuple[float, ...], ...]:
    return tuple(_floats(row) for row in values)


def _maybe_rows(values: Any) -> tuple[tuple[float, ...], ...] | None:
    return None if values is None else _rows(values)


@frozen
class TaskCalibration:
    """What the task's frames did under each fixed contract on the training worlds.

    Attributes:
        size, radius, movement: the worlds' side, the sensor's radius, the movement model.
        contracts: the contracts measured (ticks), increasing.
        quality: per contract, per world: optimal length / the route the robot walked.
        progress: per world, the first frame's progress on the robot's map (the shortest
            route to the goal before it minus after it, as the monitor learns it) over
            `TaskModel.first_step` at the start, under the middle contract of the grid (it
            hardly depends on the contract once the robot senses: 24 to 25 cells from 300
            ticks on at 64 x 64, but a plan on the prior map, every cell free, with no time
            to sense, turns once and leaves the window after about r cells).
        first_seed: the training worlds are seeds first_seed, first_seed + 1, ...
        first_walked, first_left, later_stretch: per contract, per world, the first frame
            apart from the later ones (the robot waits for its plan, which is made with
            nothing sensed before): the cells the first frame walked, the distance left after
            it on the robot's map as a fraction of the distance at the start (on the prior
            map), and how much the later frames stretched the rest of the route (the cells
            walked after the first frame over that distance left). None in a calibration
            measured without them.
    """

    size: int
    radius: int
    movement: int
    contracts: tuple[float, ...] = field(converter=_floats)
    quality: tuple[tuple[float, ...], ...] = field(converter=_rows)
    progress: tuple[float, ...] = field(converter=_floats)
    first_seed: int = FIRST_SEED
    first_walked: tuple[tuple[float, ...], ...] | None = field(default=None, converter=_maybe_rows)
    first_left: tuple[tuple[float, ...], ...] | None = field(default=None, converter=_maybe_rows)
    later_stretch: tuple[tuple[float, ...], ...] | None = field(default=None, converter=_maybe_rows)

    @property
    def worlds(self) -> int:
        return len(self.progress)

    @property
    def progress_ratio(self) -> float:
        """The mean first frame's progress over the straight-line estimate."""
        return float(np.mean(self.progress))

    def profile(self) -> ConditionalPerformanceProfile:
        """The route quality's distribution per contract (time 0: no plan, quality 0), with
        the exact means, for the monitor and `TaskModel`."""
        q = np.asarray(self.quality, dtype=np.float64)  # (contracts, worlds)
        k = np.clip(np.searchsorted(BINS, q, side="right") - 1, 0, BINS.size - 2)
        counts = np.zeros((q.shape[0], BINS.size - 1))
        np.add.at(counts, (np.arange(q.shape[0])[:, None], k), 1.0)
        nothing = np.eye(1, BINS.size - 1)  # quality 0 before any planning
        return ConditionalPerformanceProfile(
            input_grids=(),
            time=np.array([0.0, *self.contracts]),
            bins=BINS,
            probability=np.vstack([nothing, counts / q.shape[1]]),
            mean=np.array([0.0, *q.mean(axis=1)]),
            samples=np.full(q.shape[0] + 1, float(q.shape[1])),
            std=np.array([0.0, *q.std(axis=1)]),
            module="navigate-task",
            kind="contract",
        )

    def first_frame(self) -> FirstFrame | None:
        """The first frame's samples for `TaskModel` (None: not measured)."""
        if self.first_walked is None or self.first_left is None or self.later_stretch is None:
            return None
        return FirstFrame(
            np.asarray(self.contracts),
            np.asarray(self.first_walked),
            np.asarray(self.first_left),
            np.asarray(self.later_stretch),
        )

    def as_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "size": self.size,
            "radius": self.radius,
            "movement": self.movement,
            "first_seed": self.first_seed,
            "contracts": list(self.contracts),
            "quality": [list(row) for row in self.quality],
            "progress": list(self.progress),
        }
        for key in ("first_walked", "first_left", "later_stretch"):
            rows = getattr(self, key)
            if rows is not None:
                data[key] = [list(row) for row in rows]
        return data

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TaskCalibration:
        return cls(
            int(data["size"]),
            int(data["radius"]),
            int(data["movement"]),
            data["contracts"],
            data["quality"],
            data["progress"],
            int(data["first_seed"]),
            data.get("first_walked"),
            data.get("first_left"),
            data.get("later_stretch"),
        )


def _name(size: int) -> str:
    return f"task-{size}.json"


def shipped(size: int, radius: int, movement: int = 4) -> TaskCalibration | None:
    """The shipped calibration for worlds of `size` with this sensor `radius` and movement,
    or None (none measured there: the monitor plans with the compiled profile)."""
    resource = data_file("profiles", _name(size))
    if not resource.is_file():
        return None
    calibration = TaskCalibration.from_json(json.loads(resource.read_text(encoding="utf-8")))
    if (calibration.radius, calibration.movement) != (radius, movement):
        return None
    return calibration


def task_value(size: int) -> DeadlineValue:
    """The benchmark's value of completion time for worlds of `size` (the defaults of
    `NavigationTask` scaled with the side: 6000 ticks on a 128 map)."""
    return DeadlineValue(1000.0, 6000.0 * size / 128, 0.25 * 128 / size)


def measure(
    size: int,
    worlds: int,
    *,
    radius: int | None = None,
    contracts: Sequence[float] = CONTRACTS,
    first_seed: int = FIRST_SEED,
    on_world: Callable[[int], object] | None = None,
    workers: int = 1,
) -> TaskCalibration:
    """Run the task under each fixed contract on `worlds` training worlds (no calibration in
    the model: the one being measured must not depend on a previous one), on `workers`
    processes (the same numbers on any number)."""
    radius = radius or size // 4
    shape = (len(contracts), worlds)
    quality, walked, left, stretch = (np.zeros(shape) for _ in range(4))
    progress = np.zeros(worlds)
    run = partial(_measure_world, size, radius, tuple(contracts))
    seeds = range(first_seed, first_seed + worlds)
    with ExitStack() as stack:
        if workers > 1:
            pool = stack.enter_context(ProcessPoolExecutor(workers))
            results = pool.map(run, seeds)
        else:
            results = map(run, seeds)
        for w, (q, walk, rest, later, first) in enumerate(results):
            quality[:, w], walked[:, w], left[:, w], stretch[:, w] = q, walk, rest, later
            progress[w] = first
            if on_world is not None:
                on_world(w + 1)
    return TaskCalibration(
        size, radius, 4, contracts, quality, progress, first_seed, walked, left, stretch
    )


def _measure_world(
    size: int, radius: int, contracts: tuple[float, ...], seed: int
) -> tuple[Any, Any, Any, Any, float]:
    """One training world under each contract: the route's quality, the first frame's cells
    walked and distance left, the later frames' stretch (per contract), and the first frame's
    progress under the middle contract."""
    from .execution import route_length
    from .frame_program import navigation_program
    from .frames import _belief_distance, _TaskRun, _touch
    from .model import NavigationTask, TaskModel

    compiled, trace = navigation_program()
    quality, walked, left, stretch = (np.zeros(len(contracts)) for _ in range(4))
    progress = 0.0
    world = random_world(size, seed=seed)
    task = NavigationTask(world, radius=radius, value=task_value(size), seed=seed)
    straight = TaskModel(task).first_step(world.start)
    prior = _belief_distance(
        np.zeros_like(world.blocked, dtype=bool), world.start, world.goal, world.movement
    )
    for i, contract in enumerate(contracts):
        run = _TaskRun(task, compiled, trace, "fixed", contract, "work", (), None, False)
        r = run.run(200)
        quality[i] = r.optimal_length / r.route_length
        # The first frame, and the rest of the route after it, on the robot's map as `learn`
        # has it after the frame.
        first = r.records[0]
        end = first.route[-1]
        known = _touch(first.known, run.truth, first.route)
        after = (
            0.0 if end == world.goal else _belief_distance(known, end, world.goal, world.movement)
        )
        walked[i] = route_length(first.route)
        left[i] = after / prior
        stretch[i] = (r.route_length - walked[i]) / after if after > 0 else 1.0
        if i == len(contracts) // 2:
            progress = run.progress[0] / straight
    return quality, walked, left, stretch, progress


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Measure the task's calibration for a size.")
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--worlds", type=int, default=150)
    parser.add_argument("--out", type=Path, help="default: the package's profiles/task-SIZE.json")
    parser.add_argument("--workers", type=int, default=1, help="processes running the worlds")
    args = parser.parse_args(argv)
    calibration = measure(
        args.size,
        args.worlds,
        on_world=lambda n: print(n, end=" ", flush=True),
        workers=args.workers,
    )
    print()
    out = args.out or Path(str(data_file("profiles", _name(args.size))))
    out.write_text(json.dumps(calibration.as_json()) + "\n", encoding="utf-8")
    profile = calibration.profile()
    assert profile.mean is not None
    pairs = zip(calibration.contracts, profile.mean[1:], strict=True)
    stretch = ", ".join(f"{c:g}: {1 / max(q, 1e-9):.3f}" for c, q in pairs)
    print(f"wrote {out}: 1 / mean quality {stretch}; progress {calibration.progress_ratio:.3f}")


if __name__ == "__main__":
    main()
