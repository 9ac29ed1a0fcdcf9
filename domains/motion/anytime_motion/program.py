"""The compiled motion programs and one run, as `anytime motion`, the tests and the benchmark
use them: compile a packaged schema (once per process per time grid), run it on a problem
under a budget on the work clock, with the compiled split or a fixed one, and score it on the
true obstacles."""

from __future__ import annotations

from functools import cache
from typing import Any

import attrs
import numpy as np
from attrs import frozen

from anytime import (
    AnytimeLibrary,
    Budget,
    CompiledProgram,
    ProgramRecord,
    compile_file,
    run_program,
)
from anytime.plugin import Instance, ProgramProblems, WorkClock

from .domain import OBSTACLES, OccupancyMap, Path, Query, Sensor, World, path_quality
from .modules import MotionReference, motion_problem
from .resources import load_schema_file

__all__ = [
    "PROGRAM_PROBLEMS",
    "RESOLUTIONS",
    "SCHEMAS",
    "SPLITS",
    "TIME_GRIDS",
    "Motion",
    "MotionProblems",
    "Problem",
    "compiled_program",
    "fixed_split",
    "move",
    "problem_for",
]

#: The packaged schemas: the chain and the DAG with a best-of.
SCHEMAS = ("move", "move-best")
#: The compiled totals (ticks) and the allocation lattice of each schema.
TIME_GRIDS = {
    "move": tuple(range(0, 8001, 500)),
    "move-best": tuple(range(0, 8001, 500)),
}
RESOLUTIONS = {"move": 250.0, "move-best": 250.0}
#: The splits `anytime motion` runs: the compiled one, MoveIt's even split among the modules,
#: and all the time to the planners (nothing to sensing and shortening).
SPLITS = ("compiled", "even", "planner")
PLANNERS = ("rrt-star", "bit-star")


@cache
def _library() -> AnytimeLibrary:
    return AnytimeLibrary.default()


@cache
def compiled_program(schema: str, time_grid: tuple[float, ...] | None = None) -> CompiledProgram:
    """The packaged `schema` compiled against the installed profiles over `time_grid` (default:
    its `TIME_GRIDS` entry) on its lattice."""
    grid = list(time_grid if time_grid is not None else TIME_GRIDS[schema])
    programs = compile_file(
        load_schema_file(), _library(), grid, schema=schema, resolution=RESOLUTIONS[schema]
    )
    (program,) = [p for p in programs if p.name == schema]
    return program


def split_of(program: CompiledProgram, split: str, budget: float) -> np.ndarray:
    """The allocation (ticks per module, in `program.modules`' order) of `split` at `budget`:
    the compiled table's, the even split (MoveIt's: the budget divided evenly among the
    modules), or all of it to the planners (evenly between a best-of's)."""
    modules = program.modules
    if split == "compiled":
        return np.asarray(program.allocation_at([], budget), dtype=np.float64)
    if split == "even":
        return np.full(len(modules), budget / len(modules))
    if split == "planner":
        planners = [m in PLANNERS for m in modules]
        return np.where(planners, budget / sum(planners), 0.0)
    raise ValueError(f"unknown split {split!r}: expected one of {SPLITS}")


def fixed_split(program: CompiledProgram, allocation: np.ndarray) -> CompiledProgram:
    """`program` with `allocation` (ticks per module) at every total of its table: run with
    any budget at least its sum, it spends that allocation."""
    table = np.broadcast_to(allocation, program.allocation.shape).copy()
    return attrs.evolve(program, allocation=table)


@frozen
class Problem:
    """One motion problem: the world, its sensor and query, and its reference path."""

    world: World
    sensor: Sensor
    query: Query
    reference: MotionReference


def problem_for(obstacles: int, dimension: int, seed: int) -> Problem:
    """The problem `anytime motion --seed S` solves."""
    return draw_problem(np.random.default_rng(seed), obstacles, dimension)


def draw_problem(
    rng: np.random.Generator, obstacles: int = OBSTACLES, dimension: int = 2
) -> Problem:
    world, query, reference = motion_problem(rng, obstacles, dimension)
    return Problem(world, Sensor(world, int(rng.integers(2**31))), query, reference)


@frozen
class Motion:
    """One run: the split it ran, the record, its path (None without a result), the sensed
    map the path was planned on, and the path's true quality (0: none, or it collides)."""

    split: str
    allocation: dict[str, float]
    record: ProgramRecord
    path: Path | None
    map: OccupancyMap | None
    quality: float
    reference_cost: float


def move(
    program: CompiledProgram, problem: Problem, budget: float, split: str = "compiled"
) -> Motion:
    """Run `program` on `problem` with `budget` ticks on the work clock, with `split`
    (`SPLITS`), and score its path on the true obstacles."""
    allocation = split_of(program, split, budget)
    runnable = program if split == "compiled" else fixed_split(program, allocation)
    record = run_program(
        runnable, [problem.sensor, problem.query], Budget(budget, clock=WorkClock())
    )
    path = record.result.value if record.result is not None else None
    quality = path_quality(path, problem.world, problem.reference.cost)
    map = path.map if isinstance(path, Path) else None
    used = dict(zip(program.modules, (float(a) for a in allocation), strict=True))
    return Motion(split, used, record, path, map, quality, problem.reference.cost)


class MotionProblems:
    """The problems the packaged schemas are promised for (`anytime verify`): a fresh world
    of the profiles' kind (10 obstacles in the unit square), its sensor and query; a path is
    scored by `path_quality` on the true obstacles against the world's reference path, and
    every module's result inside a program as the modules' problem sets score it
    (`score_step`)."""

    def instance(self, rng: np.random.Generator) -> Instance:
        problem = draw_problem(rng)
        return Instance((problem.sensor, problem.query), reference=problem.reference)

    def score(self, instance: Instance, value: Any) -> float:
        reference: MotionReference = instance.reference
        return path_quality(value, reference.world, reference.cost)

    def score_step(self, instance: Instance, module: str, value: Any) -> float:
        """The true quality of `module`'s result `value` (None: no result): a map by its
        coverage of the obstacles' surface, a path by `path_quality`."""
        reference: MotionReference = instance.reference
        if value is None:
            return 0.0
        if module == "sense-obstacles":
            return float(value.coverage(reference.world.surface))
        return path_quality(value, reference.world, reference.cost)


#: How `anytime verify` checks each packaged schema: on the totals and lattice it is compiled
#: for.
PROGRAM_PROBLEMS = {
    schema: ProgramProblems.of(
        MotionProblems(), time_grid=TIME_GRIDS[schema], resolution=RESOLUTIONS[schema]
    )
    for schema in SCHEMAS
}
