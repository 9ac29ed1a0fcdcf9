"""The routing modules and their problem sets (how `anytime profile` measures them).

Every module reports its work as ticks of the work clock, one tick per vectorised batch: 20
orders read (`estimate-demand`), one k-means++ draw or one Lloyd iteration over all customers
(`cluster-stops`), one evaluation of every 2-opt or every Or-opt move of one tour
(`plan-tours`), one cheapest insertion into one tour (`insert-tours`). The interruptible ones
look at their remaining time before every batch and stop when it would not fit, so they never
pass their allocation: they declare a step of 0 (`anytime check` verifies it).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import cache
from typing import Any

import numpy as np

from anytime.plugin import (
    Context,
    Instance,
    Measurement,
    Result,
    contract,
    elementary,
    interruptible,
)

from .domain import (
    BATCH,
    Clustering,
    Depot,
    OrderLog,
    Sites,
    Tours,
    World,
    closed_length,
    clustering_quality,
    demand_quality,
    estimate_shares,
    optimal_length,
    random_world,
    reference_clustering,
    reference_delivery,
    tour_quality,
)
from .geometry import (
    EPS,
    FloatArray,
    IntArray,
    apply_or_opt,
    apply_two_opt,
    best_or_opt,
    best_two_opt,
    cheapest_insertion_step,
    distance_matrix,
    kmeans_cost,
    kmeans_plus_plus_step,
    lloyd_step,
    nearest_neighbour,
    one_tree_bound,
    tour_length,
)
from .program import compiled_program

__all__ = [
    "MODULES",
    "PROBLEM_SETS",
    "ClusteringInputs",
    "DemandInputs",
    "OrderLogs",
    "DepotInputs",
    "cluster_stops",
    "depots",
    "estimate_demand",
    "insert_tours",
    "plan_tour",
    "plan_tours",
    "route",
]

#: The modules' time grids (ticks), every 2 ticks: the compile lattice (resolution 2).
DEMAND_TIME = list(range(0, 41, 2))
CLUSTER_TIME = list(range(0, 25, 2))
TOUR_TIME = list(range(0, 49, 2))
#: One depot's tour (`plan-tour`): every tick, so that a loop's time splits finely.
DEPOT_TIME = list(range(0, 25))
#: Input-quality grids, finest where the upstream module's qualities lie (see README.md).
DEMAND_GRID = [0.25, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
CLUSTER_GRID = [0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95, 0.98, 1.0]
#: Clusterings of quality below 0.8 come (often enough) only from `cluster-stops` runs of at
#: most this many ticks (see `clustering_of_quality`).
LOW_CLUSTER_TICKS = 12
#: The schema whose upstream allocations make the clusterings `plan-tour` is measured on: the
#: loop's own (`deliver-each` gives the demand less time than `deliver` does, and clusterings
#: of one quality but other upstream times give other tours). `anytime profile --upstream`
#: measures a module called once, outside loops: not `plan-tour`, called in a `map`.
LOOPED = "deliver-each"
#: Most Lloyd iterations of one k-means restart.
MAX_ITERATIONS = 30


# --- estimate-demand --------------------------------------------------------------------------


@contract(
    "estimate-demand",
    inputs=[],
    profile="profiles/estimate-demand.yaml",
    reports="estimate",
    step=0,
)
def estimate_demand(ctx: Context, orders: OrderLog) -> Result:
    """Read 20 orders a tick for as many whole ticks as it is given, and estimate each
    customer's share of the demand (the posterior mean under a uniform prior: uniform with no
    time). Its quality is its own estimate: 1 - the expected L1 error of binomial shares."""
    batches = int(math.floor(ctx.allocation + 1e-9)) if math.isfinite(ctx.allocation) else 0
    ctx.tick(batches)
    counts = orders.read(batches * BATCH)
    shares = estimate_shares(counts)
    n = counts.sum() + len(counts)
    error = float(np.sqrt(2 / np.pi * shares * (1 - shares) / n).sum())
    return Result(shares, max(0.0, 1.0 - error))


# --- cluster-stops ----------------------------------------------------------------------------


@interruptible(
    "cluster-stops",
    inputs=["demand"],
    profile="profiles/cluster-stops.yaml",
    reports="estimate",
    step=0,
)
def cluster_stops(ctx: Context, demand: Result, sites: Sites) -> Iterator[Result]:
    """Demand-weighted k-means placing the depots: restarts from k-means++ seeds (one tick a
    centre drawn), Lloyd iterations (one tick each) to convergence; a result whenever the
    weighted cost beats the best so far. Its self-estimate: the demand's quality, discounted
    until two restarts have converged."""
    weights = np.asarray(demand.value, dtype=np.float64)
    points, k = sites.points, sites.depots
    best = math.inf
    converged = 0
    for restart in range(10_000):
        rng = np.random.default_rng(restart)
        start: list[FloatArray] = []
        for _ in range(k):
            if ctx.expired or ctx.remaining < 1:
                return
            ctx.tick()
            kmeans_plus_plus_step(points, weights, start, rng)
        centres = np.array(start)
        labels = np.full(len(points), -1, dtype=np.int64)
        for _ in range(MAX_ITERATIONS):
            if ctx.expired or ctx.remaining < 1:
                return
            ctx.tick()
            moved, new = lloyd_step(points, weights, centres)
            done = np.array_equal(new, labels) and np.allclose(moved, centres)
            centres, labels = moved, new
            cost = kmeans_cost(points, weights, centres, labels)
            if cost < best - EPS:
                best = cost
                confidence = 1.0 - 0.1 / (1 + converged)
                yield Result(Clustering(points, centres, labels), demand.quality * confidence)
            if done:
                break
        converged += 1


# --- plan-tours and insert-tours ------------------------------------------------------------


class _Tour:
    """One depot's tour being improved: node 0 the depot, 1.. its customers."""

    def __init__(self, clustering: Clustering, k: int) -> None:
        self.customers = clustering.members(k)
        self.dist = distance_matrix(clustering.nodes(k))
        self.order: IntArray = np.arange(len(self.dist), dtype=np.int64)
        self.bound = 0.0
        self.active = True

    @property
    def length(self) -> float:
        return tour_length(self.dist, self.order)

    def visits(self) -> IntArray:
        """The customers in visiting order, from the depot."""
        at = int(np.flatnonzero(self.order == 0)[0])
        rotated = np.roll(self.order, -at)
        return self.customers[rotated[1:] - 1]


def _result(clustering: Clustering, tours: list[_Tour], quality_in: float) -> Result:
    """The tours so far, with the self-estimate: the 1-tree bounds over the length (a lower
    bound of how close they are to optimal for this clustering), at most the input's
    quality."""
    length = sum(t.length for t in tours)
    bound = sum(t.bound for t in tours)
    value = Tours(clustering, [t.visits() for t in tours])
    return Result(value, _estimate(bound, length, quality_in))


def _estimate(bound: float, length: float, quality_in: float) -> float:
    """The tour planners' self-estimate: the 1-tree bound over the length, at most 1 and at
    most the input's quality."""
    return min(1.0 if length <= 0 else min(1.0, bound / length), quality_in)


@interruptible(
    "plan-tours",
    inputs=["clusters"],
    profile="profiles/plan-tours.yaml",
    reports="estimate",
    step=0,
)
def plan_tours(ctx: Context, clusters: Result) -> Iterator[Result]:
    """A tour per depot: nearest neighbour (one tick a depot, with its 1-tree bound), then
    2-opt and Or-opt, round robin over the depots: one tick evaluates every 2-opt move of a
    tour and makes the best; when none improves, one tick does the same for Or-opt (segments of
    1 to 3 stops); a depot with neither is done. A result after every improving move."""
    clustering: Clustering = clusters.value
    tours = []
    for k in range(len(clustering.centres)):
        if ctx.expired or ctx.remaining < 1:
            return
        ctx.tick()
        tour = _Tour(clustering, k)
        tour.order = nearest_neighbour(tour.dist)
        tour.bound = one_tree_bound(tour.dist)
        tours.append(tour)
    yield _result(clustering, tours, clusters.quality)
    while any(t.active for t in tours):
        for tour in tours:
            if not tour.active:
                continue
            moved = _improve(ctx, tour)
            if moved is None:
                return
            if moved:
                yield _result(clustering, tours, clusters.quality)


def _improve(ctx: Context, tour: _Tour) -> bool | None:
    """One improving move of `tour`: a tick evaluates every 2-opt move and makes the best;
    when none improves, a tick does the same for Or-opt. True when it moved, False when
    neither improves (the tour is done: no longer `active`), None when the time ran out
    first."""
    if ctx.expired or ctx.remaining < 1:
        return None
    ctx.tick()
    gain, i, j = best_two_opt(tour.dist, tour.order)
    if gain > EPS:
        tour.order = apply_two_opt(tour.order, i, j)
        return True
    if ctx.expired or ctx.remaining < 1:
        return None
    ctx.tick()
    gain, start, length, edge, reverse = best_or_opt(tour.dist, tour.order)
    if gain > EPS:
        tour.order = apply_or_opt(tour.order, start, length, edge, reverse)
        return True
    tour.active = False
    return False


# --- one depot's tour: the body of a map over the depots ----------------------------------


class DepotTour:
    """One depot's tour: the customers in visiting order, from the depot and back."""

    def __init__(self, depot: Depot, visits: IntArray) -> None:
        self.depot = depot
        self.visits = visits

    @property
    def length(self) -> float:
        clustering, k = self.depot.clustering, self.depot.index
        return closed_length(clustering.centres[k], clustering.points[self.visits])

    def __repr__(self) -> str:
        return f"DepotTour({self.depot.index}, {len(self.visits)} stops, {self.length:.4f})"


@elementary("depots")
def depots(clusters: Result) -> list[Depot]:
    """The clustering's depots, each with its customers: the collection a map over the
    depots loops over (its quality the clustering's)."""
    clustering: Clustering = clusters.value
    return [Depot(clustering, k) for k in range(len(clustering.centres))]


@interruptible(
    "plan-tour",
    inputs=["depot"],
    profile="profiles/plan-tour.yaml",
    reports="estimate",
    step=0,
)
def plan_tour(ctx: Context, depot: Result) -> Iterator[Result]:
    """One depot's tour, made as `plan-tours` makes each of its tours: nearest neighbour (a
    tick, with its 1-tree bound), then 2-opt and Or-opt moves (a tick each), a result after
    every improving move; self-estimate: the 1-tree bound over the length, at most the
    depot's (its clustering's) quality. Its quality as measured: the depot's optimal tour
    over this one, times how close its clustering's optimal tours come to the reference
    delivery (`DepotInputs`), so that the mean over the depots stands for the route's."""
    item: Depot = depot.value
    if ctx.expired or ctx.remaining < 1:
        return
    ctx.tick()
    tour = _Tour(item.clustering, item.index)
    tour.order = nearest_neighbour(tour.dist)
    tour.bound = one_tree_bound(tour.dist)
    yield _depot_result(item, tour, depot.quality)
    while True:
        moved = _improve(ctx, tour)
        if not moved:
            return
        yield _depot_result(item, tour, depot.quality)


def _depot_result(depot: Depot, tour: _Tour, quality_in: float) -> Result:
    return Result(DepotTour(depot, tour.visits()), _estimate(tour.bound, tour.length, quality_in))


@elementary("route")
def route(tours: Result) -> Tours | None:
    """The depots' tours (a map's list) as one delivery; None while a depot has none (no
    delivery: it scores 0)."""
    found = list(tours.value)
    if not found or any(not isinstance(tour, DepotTour) for tour in found):
        return None
    return Tours(found[0].depot.clustering, [tour.visits for tour in found])


@interruptible(
    "insert-tours",
    inputs=["clusters"],
    profile="profiles/insert-tours.yaml",
    reports="estimate",
    step=0,
)
def insert_tours(ctx: Context, clusters: Result) -> Iterator[Result]:
    """A tour per depot by cheapest insertion from a random first customer (one tick an
    insertion, every free customer against every edge), restarted with new first customers;
    a result whenever a restart's tours are shorter in total than the best so far."""
    clustering: Clustering = clusters.value
    shapes = [_Tour(clustering, k) for k in range(len(clustering.centres))]
    for tour in shapes:
        tour.bound = one_tree_bound(tour.dist)  # counted in the first insertion's tick
    best = math.inf
    for restart in range(10_000):
        rng = np.random.default_rng(restart)
        built = []
        for shape in shapes:
            n = len(shape.dist)
            first = int(rng.integers(1, n)) if n > 1 else 0
            order = [0, first] if n > 1 else [0]
            free = [v for v in range(1, n) if v != first]
            if ctx.expired or ctx.remaining < 1:
                return
            ctx.tick()  # the first customer (and, once, the bound)
            while free:
                if ctx.expired or ctx.remaining < 1:
                    return
                ctx.tick()
                cheapest_insertion_step(shape.dist, order, free)
            built.append(np.array(order, dtype=np.int64))
        length = sum(tour_length(s.dist, o) for s, o in zip(shapes, built, strict=True))
        if length < best - EPS:
            best = length
            for shape, made in zip(shapes, built, strict=True):
                shape.order = made
            yield _result(clustering, shapes, clusters.quality)


# --- elementary -------------------------------------------------------------------------------


@elementary("has-customers?", inputs=[])
def has_customers(sites: Sites) -> bool:
    """The tour planners' precondition: there are customers to visit."""
    return len(sites.points) > 0


# --- problem sets -----------------------------------------------------------------------------


class OrderLogs:
    """Problems for `estimate-demand`: a world's order log; the truth is its shares."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        world = random_world(rng)
        return Instance(args=(world.orders,), reference=world.shares)

    def score(self, instance: Instance, value: Any) -> float:
        return demand_quality(value, instance.reference)


#: Inputs of a given quality are accepted within this much of it.
TOLERANCE = 0.01
#: Most draws before giving up on an input quality (none of the grids' needs nearly so many).
MAX_DRAWS = 20_000


def demand_of_quality(rng: np.random.Generator, q: float) -> tuple[World, Result]:
    """A world and an `estimate-demand` answer of true quality within TOLERANCE of `q`, made
    by the module itself: draw a world and an allocation on its grid (below quality 0.4 the
    uniform prior's, 0 ticks: the only one that gives them), run it, keep the first whose
    quality is close enough (rejection sampling: the answer is distributed as the module's
    real answers of that quality)."""
    times = DEMAND_TIME if q >= 0.4 else [0]
    for _ in range(MAX_DRAWS):
        world = random_world(rng)
        allocation = float(rng.choice(times))
        result = estimate_demand(Context(allocation), world.orders)
        assert result is not None
        if abs(demand_quality(result.value, world.shares) - q) <= TOLERANCE:
            return world, result
    raise RuntimeError(f"estimate-demand gave no answer of quality {q} in {MAX_DRAWS} draws")


class DemandInputs:
    """Problems for `cluster-stops`: a world and a demand estimate of the quality asked for
    (`demand_of_quality`); the truth is the best of 30 k-means restarts on the true shares."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (q,) = input_qualities
        world, demand = demand_of_quality(rng, q)
        cost, _ = reference_clustering(world.points, world.shares, world.depots)
        given = Result(demand.value, q)  # the grid's quality, as the builder asks
        return Instance(args=(given, world.sites), reference=(world.shares, cost))

    def score(self, instance: Instance, value: Any) -> float:
        shares, cost = instance.reference
        return clustering_quality(value, shares, cost)


#: The (`estimate-demand`, `cluster-stops`) allocations the tour planners' own problem set
#: draws clusterings with: every pair of their grids' times at which `cluster-stops` runs.
GRID_TIMES = tuple((float(d), float(c)) for d in DEMAND_TIME for c in CLUSTER_TIME if c > 0)


@cache
def loop_times(schema: str = LOOPED) -> tuple[tuple[float, float], ...]:
    """The (`estimate-demand`, `cluster-stops`) allocations the packaged loop `schema` gives
    at its compiled budgets under the installed profiles, those at which `cluster-stops` runs:
    the clusterings the loop actually hands to `plan-tour` (one call per depot in a `map`,
    which `anytime profile --upstream` does not reach) are made with these."""
    program = compiled_program(schema)
    demand, clusters = (program.modules.index(m) for m in ("estimate-demand", "cluster-stops"))
    quality = [1.0] * program.profile.n_inputs
    pairs = set()
    for total in program.profile.time:
        split = program.allocation_at(quality, float(total))
        if split[clusters]:
            pairs.add((float(split[demand]), float(split[clusters])))
    return tuple(sorted(pairs))


def clustering_of_quality(
    rng: np.random.Generator, q: float, times: tuple[tuple[float, float], ...] = GRID_TIMES
) -> tuple[World, Result]:
    """A world and a `cluster-stops` answer of true quality within TOLERANCE of `q`, made by
    the two upstream modules themselves: draw a world, then (up to 20 times on it) one of the
    (`estimate-demand`, `cluster-stops`) allocations `times` (default: any pair of their grids'
    times; below quality 0.8 those with at most LOW_CLUSTER_TICKS for `cluster-stops`, the only
    ones at which such clusterings occur often), run both with it, and keep the first answer
    close enough (no result is not an input: the module would not be called)."""
    if q < 0.8:
        times = tuple(t for t in times if t[1] <= LOW_CLUSTER_TICKS)
    for _ in range(MAX_DRAWS // 20):
        world = random_world(rng)
        best, _ = reference_clustering(world.points, world.shares, world.depots)
        for _ in range(20):
            demand_time, cluster_time = times[int(rng.integers(len(times)))]
            demand = estimate_demand(Context(demand_time), world.orders)
            assert demand is not None
            answer = None
            for result in cluster_stops(Context(cluster_time), demand, world.sites):
                answer = result
            if answer is None:  # no result: not an input (the module would not be called)
                continue
            if abs(clustering_quality(answer.value, world.shares, best) - q) <= TOLERANCE:
                return world, answer
    raise RuntimeError(f"cluster-stops gave no answer of quality {q} in {MAX_DRAWS} draws")


class ClusteringInputs:
    """Problems for `plan-tours` and `insert-tours` on their own: a clustering of the quality
    asked for (`clustering_of_quality`, upstream allocations drawn from the modules' grids);
    the truth is the world's reference delivery (`reference_delivery`: the shortest optimal
    tours over many candidate clusterings, exact). Their packaged profiles are measured where
    the programs put them (`anytime profile --upstream`, on `DeliveryProblems`); this problem
    set measures the input cells the programs never reach."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (q,) = input_qualities
        world, clustering = clustering_of_quality(rng, q)
        given = Result(clustering.value, q)  # the grid's quality, as the builder asks
        length, _ = reference_delivery(world)
        return Instance(args=(given,), reference=length)

    def score(self, instance: Instance, value: Any) -> float:
        return tour_quality(value, instance.reference)


class DepotInputs:
    """Problems for `plan-tour`: one depot, drawn at random, of a clustering of the quality
    asked for (`clustering_of_quality`, with `deliver-each`'s upstream allocations,
    `loop_times`). The
    truth: the depot's optimal tour over this one, times the reference delivery over the
    clustering's optimal tours (at most 1), so that the mean over a clustering's depots is
    close to the route's quality (`tour_quality`): exactly that where the depots' tours are
    equally close to optimal, the reference over the tours' total length being their
    length-weighted (harmonic) mean."""

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        (q,) = input_qualities
        world, clustering = clustering_of_quality(rng, q, loop_times())
        length, _ = reference_delivery(world)
        value: Clustering = clustering.value
        optimal = [optimal_length(value.nodes(k)) for k in range(len(value.centres))]
        k = int(rng.integers(len(optimal)))
        given = Result(Depot(value, k), q)  # the grid's quality, as the builder asks
        return Instance(args=(given,), reference=(length / sum(optimal), optimal[k]))

    def score(self, instance: Instance, value: Any) -> float:
        if not isinstance(value, DepotTour):
            return 0.0
        clustering_share, optimal = instance.reference
        length = value.length
        return 1.0 if length <= 0 else min(1.0, clustering_share * optimal / length)


MODULES = (
    estimate_demand,
    cluster_stops,
    plan_tours,
    insert_tours,
    plan_tour,
    has_customers,
    depots,
    route,
)

PROBLEM_SETS = {
    "estimate-demand": Measurement.of(OrderLogs(), time=DEMAND_TIME),
    "cluster-stops": Measurement.of(DemandInputs(), time=CLUSTER_TIME, input_grids=[DEMAND_GRID]),
    "plan-tours": Measurement.of(ClusteringInputs(), time=TOUR_TIME, input_grids=[CLUSTER_GRID]),
    "insert-tours": Measurement.of(ClusteringInputs(), time=TOUR_TIME, input_grids=[CLUSTER_GRID]),
    "plan-tour": Measurement.of(DepotInputs(), time=DEPOT_TIME, input_grids=[CLUSTER_GRID]),
}
