"""The compiled routing programs and one delivery run, as `anytime deliver` and the tests use
them: compile a packaged schema (once per process per time grid), run it on a world under a
budget on the work clock, and score it against the reference."""

from __future__ import annotations

from functools import cache

import numpy as np
from attrs import frozen

from anytime.plugin import (
    AnytimeLibrary,
    CompiledProgram,
    Instance,
    ProgramProblems,
    ProgramRecord,
    WorkClock,
    compile_file,
    run_program,
)

from .domain import (
    Clustering,
    ReferenceUnavailable,
    Tours,
    World,
    random_world,
    reference_clustering,
    reference_delivery,
    tour_quality,
)
from .resources import load_schema_file

__all__ = [
    "MEASURED_WITH",
    "PROGRAM_PROBLEMS",
    "RESOLUTIONS",
    "SCHEMAS",
    "TIME_GRIDS",
    "Delivery",
    "DeliveryProblems",
    "compiled_program",
    "deliver",
    "reference_for",
    "world_for",
]

#: The packaged schemas: the chain, the DAG with a best-of, and the chain with a tour per depot
#: in a loop (`map`).
SCHEMAS = ("deliver", "deliver-best", "deliver-each")
#: The schemas whose upstream allocations make the clusterings `plan-tours` and `insert-tours`
#: are measured on (`modules.upstream_times`; the loop's `plan-tour` on `deliver-each`'s).
MEASURED_WITH = ("deliver", "deliver-best")
#: The compiled totals (ticks) and the allocation lattice of each schema, both on the
#: profiles' time step (the DAG's four modules are searched by the multi-start allocator).
TIME_GRIDS = {
    "deliver": tuple(range(0, 101, 4)),
    "deliver-best": tuple(range(0, 65, 4)),
    "deliver-each": tuple(range(0, 101, 4)),
}
RESOLUTIONS = {"deliver": 2.0, "deliver-best": 2.0, "deliver-each": 2.0}


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


def world_for(customers: int, depots: int, seed: int) -> World:
    """The world `anytime deliver --seed S` solves."""
    return random_world(np.random.default_rng(seed), customers, depots)


@frozen
class Delivery:
    """One run: the record, the tours (None without a result), the reference clustering and
    length (None where no exact or LKH tour can be had), the true quality."""

    record: ProgramRecord
    tours: Tours | None
    reference: Clustering
    reference_length: float | None
    quality: float | None


def reference_for(world: World) -> tuple[Clustering, float | None]:
    """The world's reference delivery: its clustering and the length of its optimal tours
    (`reference_delivery`; None, with the reference k-means clustering, where a depot has more
    stops than Held-Karp takes and LKH is not installed)."""
    try:
        length, clustering = reference_delivery(world)
        return clustering, length
    except ReferenceUnavailable:
        _, clustering = reference_clustering(world.points, world.shares, world.depots)
        return clustering, None


def fresh_problems(
    rng: np.random.Generator, count: int
) -> list[tuple[World, tuple[Clustering, float | None]]]:
    """`count` random worlds, each with its reference (see `reference_for`)."""
    worlds = [random_world(rng) for _ in range(count)]
    return [(world, reference_for(world)) for world in worlds]


def deliver(
    program: CompiledProgram,
    world: World,
    budget: float,
    adaptive: bool = False,
    reference: tuple[Clustering, float | None] | None = None,
) -> Delivery:
    """Run `program` on `world` with `budget` ticks on the work clock and score it against
    `reference` (default: `reference_for(world)`)."""
    record = run_program(
        program, [world.orders, world.sites], budget, clock=WorkClock(), adaptive=adaptive
    )
    tours = record.result.value if record.result is not None else None
    clustering, length = reference if reference is not None else reference_for(world)
    quality = tour_quality(tours, length) if length is not None else None
    return Delivery(record, tours, clustering, length, quality)


class DeliveryProblems:
    """The problems the packaged schemas are promised for (`anytime verify`): a fresh world of
    the profiles' size (24 customers, 3 depots), the inputs `orders customers`; a result is
    scored as `anytime deliver` scores it, against the world's reference delivery (its optimal
    tours over the best candidate clusterings, `reference_delivery`)."""

    def instance(self, rng: np.random.Generator) -> Instance:
        world = random_world(rng)
        length, _ = reference_delivery(world)
        return Instance((world.orders, world.sites), reference=length)

    def score(self, instance: Instance, value: Tours | None) -> float:
        return tour_quality(value, instance.reference)


#: How `anytime verify` checks each packaged schema: on the totals and lattice it is compiled
#: for (`TIME_GRIDS`, `RESOLUTIONS`), the allocations whose clusterings the tour planners'
#: profiles were measured on.
PROGRAM_PROBLEMS = {
    schema: ProgramProblems.of(
        DeliveryProblems(), time_grid=TIME_GRIDS[schema], resolution=RESOLUTIONS[schema]
    )
    for schema in SCHEMAS
}
