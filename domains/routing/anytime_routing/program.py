"""The compiled routing programs and one delivery run, as `anytime deliver` and the tests use
them: compile a packaged schema (once per process per time grid), run it on a world under a
budget on the work clock, and score it against the reference."""

from __future__ import annotations

from functools import cache
from typing import Any

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

from .domain import (
    Clustering,
    Depot,
    ReferenceUnavailable,
    Tours,
    World,
    clustering_quality,
    demand_quality,
    optimal_length,
    random_world,
    reference_clustering,
    reference_delivery,
    tour_quality,
)
from .resources import load_schema_file

__all__ = [
    "PROGRAM_PROBLEMS",
    "RESOLUTIONS",
    "SCHEMAS",
    "TIME_GRIDS",
    "Delivery",
    "DeliveryProblems",
    "DeliveryReference",
    "compiled_program",
    "deliver",
    "reference_for",
    "world_for",
]

#: The packaged schemas: the chain, the DAG with a best-of, and the chain with a tour per depot
#: in a loop (`map`).
SCHEMAS = ("deliver", "deliver-best", "deliver-each")
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
        program, [world.orders, world.sites], Budget(budget, clock=WorkClock()), adaptive=adaptive
    )
    tours = record.result.value if record.result is not None else None
    clustering, length = reference if reference is not None else reference_for(world)
    quality = tour_quality(tours, length) if length is not None else None
    return Delivery(record, tours, clustering, length, quality)


class DeliveryReference:
    """What a delivery problem's results are scored against, each computed when first asked
    for (a problem drawn only to run the program up to a module's call, as `anytime profile
    --upstream` draws many, needs the clustering's reference at most): the world, the
    reference delivery's length (`reference_delivery`) and the reference clustering's cost
    (`reference_clustering`)."""

    def __init__(self, world: World) -> None:
        self.world = world
        self._length: float | None = None
        self._cost: float | None = None

    @property
    def length(self) -> float:
        """The length of the reference delivery's tours."""
        if self._length is None:
            self._length, _ = reference_delivery(self.world)
        return self._length

    @property
    def clustering_cost(self) -> float:
        """The demand-weighted k-means cost of the reference clustering (true shares)."""
        if self._cost is None:
            world = self.world
            self._cost, _ = reference_clustering(world.points, world.shares, world.depots)
        return self._cost


class DeliveryProblems:
    """The problems the packaged schemas are promised for (`anytime verify`) and measured on
    (`anytime profile --upstream`): a fresh world of the profiles' size (24 customers, 3
    depots), the inputs `orders customers`; a result is scored as `anytime deliver` scores it,
    against the world's reference delivery (its optimal tours over the best candidate
    clusterings, `reference_delivery`), and every module's result inside a program as the
    modules' problem sets score it (`score_step`)."""

    def instance(self, rng: np.random.Generator) -> Instance:
        world = random_world(rng)
        return Instance((world.orders, world.sites), reference=DeliveryReference(world))

    def score(self, instance: Instance, value: Tours | None) -> float:
        return tour_quality(value, instance.reference.length)

    def score_step(self, instance: Instance, module: str, value: Any) -> float:
        """The true quality of `value`, the result of `module` (None: no result), on the
        problem: a demand estimate by its L1 error against the true shares, a clustering (or
        its depots) by the reference clustering's cost over its own, tours (or the route) by
        the reference delivery's length over theirs, one depot's tour by its share of the
        reference (`modules.DepotInputs`)."""
        reference: DeliveryReference = instance.reference
        world = reference.world
        if value is None:
            return 0.0
        match module:
            case "estimate-demand":
                return demand_quality(value, world.shares)
            case "cluster-stops":
                return clustering_quality(value, world.shares, reference.clustering_cost)
            case "depots":
                if not value:
                    return 0.0
                first: Depot = value[0]
                return clustering_quality(first.clustering, world.shares, reference.clustering_cost)
            case "plan-tours" | "insert-tours" | "route":
                return tour_quality(value, reference.length)
            case "plan-tour":
                return depot_tour_quality(value, reference.length)
        raise ValueError(f"DeliveryProblems.score_step: no true quality for module '{module}'")


def depot_tour_quality(tour: Any, reference: float) -> float:
    """One depot's tour (a `modules.DepotTour`) scored by its share of the `reference`
    delivery's length: the depot's optimal tour over this one, times the reference over the
    clustering's optimal tours (at most 1; see `modules.DepotInputs`)."""
    clustering: Clustering = tour.depot.clustering
    optimal = [optimal_length(clustering.nodes(k)) for k in range(len(clustering.centres))]
    length = float(tour.length)
    share = reference / sum(optimal)
    return 1.0 if length <= 0 else min(1.0, share * optimal[tour.depot.index] / length)


#: How `anytime verify` checks each packaged schema, and `anytime profile --upstream` measures
#: a module where it puts it: on the totals and lattice it is compiled for (`TIME_GRIDS`,
#: `RESOLUTIONS`).
PROGRAM_PROBLEMS = {
    schema: ProgramProblems.of(
        DeliveryProblems(), time_grid=TIME_GRIDS[schema], resolution=RESOLUTIONS[schema]
    )
    for schema in SCHEMAS
}
