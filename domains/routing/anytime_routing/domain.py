"""The delivery problem: N customers in the unit square, each with a hidden share of the
demand, an order log drawn from those shares, and K depots to place and serve from. The values
that flow between the modules (demand shares, a clustering, tours), the true qualities, and the
references they are scored against."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .geometry import (
    FloatArray,
    IntArray,
    distance_matrix,
    held_karp,
    kmeans_cost,
    kmeans_plus_plus_step,
    lloyd_step,
    local_optimum,
    tour_length,
)

__all__ = [
    "BATCH",
    "CUSTOMERS",
    "DEPOTS",
    "EXACT_NODES",
    "Clustering",
    "Depot",
    "OrderLog",
    "ReferenceUnavailable",
    "Sites",
    "Tours",
    "World",
    "closed_length",
    "clustering_quality",
    "demand_quality",
    "estimate_shares",
    "optimal_length",
    "random_world",
    "reference_clustering",
    "reference_delivery",
    "reference_length",
    "run_kmeans",
    "tour_quality",
]

#: The measured problem distribution: 24 customers, 3 depots (the profiles are for these).
CUSTOMERS = 24
DEPOTS = 3
#: Demand shares are Dirichlet(CONCENTRATION): some customers order several times as much.
CONCENTRATION = 2.0
#: Orders read from the log per tick of `estimate-demand`.
BATCH = 20
#: Tours through up to this many nodes (a depot and its customers) are solved exactly by
#: Held-Karp; longer ones by LKH (`elkai`, the plugin's `measure` extra).
EXACT_NODES = 18
#: Restarts of the reference clustering (the modules get far fewer in their time).
REFERENCE_RESTARTS = 30
#: The reference delivery solves this many of its candidate clusterings exactly (the ones whose
#: 2-opt/Or-opt tours are shortest).
EXACT_CANDIDATES = 3


class ReferenceUnavailable(Exception):
    """A reference tour needs LKH (`pip install 'anytime-routing[measure]'`)."""


class OrderLog:
    """The order log: orders for the customers in proportion to their hidden shares (seeded:
    the same log reads the same orders)."""

    def __init__(self, shares: FloatArray, seed: int) -> None:
        self.shares = np.asarray(shares, dtype=np.float64)
        self.seed = int(seed)

    @property
    def customers(self) -> int:
        return len(self.shares)

    def read(self, orders: int) -> IntArray:
        """How many of the first `orders` orders each customer placed."""
        rng = np.random.default_rng(self.seed)
        return rng.multinomial(int(orders), self.shares).astype(np.int64)


class Sites:
    """Where the customers are, and how many depots to place among them."""

    def __init__(self, points: FloatArray, depots: int) -> None:
        self.points = np.asarray(points, dtype=np.float64)
        self.depots = int(depots)


class World:
    """One delivery problem: customers, their true shares, K depots, the order log's seed."""

    def __init__(self, points: FloatArray, shares: FloatArray, depots: int, seed: int) -> None:
        self.points = np.asarray(points, dtype=np.float64)
        self.shares = np.asarray(shares, dtype=np.float64)
        self.depots = int(depots)
        self.seed = int(seed)

    @property
    def orders(self) -> OrderLog:
        return OrderLog(self.shares, self.seed)

    @property
    def sites(self) -> Sites:
        return Sites(self.points, self.depots)


def random_world(
    rng: np.random.Generator, customers: int = CUSTOMERS, depots: int = DEPOTS
) -> World:
    """Customers uniform in the unit square, shares Dirichlet(CONCENTRATION)."""
    points = rng.random((customers, 2))
    shares = rng.dirichlet(np.full(customers, CONCENTRATION))
    return World(points, shares, depots, int(rng.integers(2**32)))


class Clustering:
    """Depots (the cluster centres) and which depot serves each customer."""

    def __init__(self, points: FloatArray, centres: FloatArray, labels: IntArray) -> None:
        self.points = points
        self.centres = np.asarray(centres, dtype=np.float64)
        self.labels = np.asarray(labels, dtype=np.int64)

    def members(self, k: int) -> IntArray:
        return np.flatnonzero(self.labels == k).astype(np.int64)

    def nodes(self, k: int) -> FloatArray:
        """Depot k then its customers: the nodes of its tour (node 0 is the depot)."""
        return np.vstack([self.centres[k][None, :], self.points[self.members(k)]])


class Depot:
    """One depot of a clustering, its customers to visit: an item of the collection that
    `(map plan-tour (depots clusters))` loops over."""

    def __init__(self, clustering: Clustering, index: int) -> None:
        self.clustering = clustering
        self.index = index

    def __repr__(self) -> str:
        return f"Depot({self.index}, {len(self.clustering.members(self.index))} customers)"


class Tours:
    """A closed tour per depot: `orders[k]` is the order in which depot k visits its
    customers (customer indices), from the depot and back."""

    def __init__(self, clustering: Clustering, orders: Sequence[IntArray]) -> None:
        self.clustering = clustering
        self.orders = tuple(np.asarray(o, dtype=np.int64) for o in orders)

    def route(self, k: int) -> FloatArray:
        """Depot k's closed route as coordinates, depot first and last."""
        c = self.clustering
        return np.vstack([c.centres[k], c.points[self.orders[k]], c.centres[k]])

    @property
    def length(self) -> float:
        c = self.clustering
        return sum(closed_length(c.centres[k], c.points[o]) for k, o in enumerate(self.orders))


def closed_length(depot: FloatArray, stops: FloatArray) -> float:
    """The length of the closed route from `depot` through `stops` in order and back."""
    route = np.vstack([depot, stops, depot])
    return float(np.sqrt(((route[1:] - route[:-1]) ** 2).sum(axis=1)).sum())


# --- true qualities -------------------------------------------------------------------------


def estimate_shares(counts: IntArray) -> FloatArray:
    """The posterior mean of the shares under a uniform Dirichlet(1) prior: uniform with no
    orders, the order counts' proportions with many."""
    return np.asarray((counts + 1.0) / (counts.sum() + len(counts)), dtype=np.float64)


def demand_quality(estimate: FloatArray | None, shares: FloatArray) -> float:
    """1 - the L1 error of the estimated shares (clipped at 0); 0 for no estimate."""
    if estimate is None:
        return 0.0
    return max(0.0, 1.0 - float(np.abs(np.asarray(estimate) - shares).sum()))


def clustering_quality(clustering: Clustering | None, shares: FloatArray, best: float) -> float:
    """The reference clustering's cost over this one's, both weighted by the true shares."""
    if clustering is None:
        return 0.0
    cost = kmeans_cost(clustering.points, shares, clustering.centres, clustering.labels)
    return 1.0 if cost <= best else best / cost


def tour_quality(tours: Tours | None, reference: float) -> float:
    """The reference length (`reference_delivery`'s) over this one's (clipped at 1: a run may
    find a clustering the reference's candidates missed); 0 for no tours."""
    if tours is None:
        return 0.0
    length = tours.length
    return 1.0 if length <= reference else reference / length


# --- references -----------------------------------------------------------------------------


def run_kmeans(
    points: FloatArray, weights: FloatArray, k: int, seed: int, max_iterations: int = 100
) -> tuple[float, Clustering]:
    """One weighted k-means run from a k-means++ start, to convergence."""
    rng = np.random.default_rng(seed)
    start: list[FloatArray] = []
    for _ in range(k):
        kmeans_plus_plus_step(points, weights, start, rng)
    centres = np.array(start)
    labels = np.zeros(len(points), dtype=np.int64)
    for _ in range(max_iterations):
        moved, new = lloyd_step(points, weights, centres)
        done = np.array_equal(new, labels) and np.allclose(moved, centres)
        centres, labels = moved, new
        if done:
            break
    clustering = Clustering(points, centres, labels)
    return kmeans_cost(points, weights, centres, labels), clustering


def reference_clustering(
    points: FloatArray, shares: FloatArray, k: int, restarts: int = REFERENCE_RESTARTS
) -> tuple[float, Clustering]:
    """The best of `restarts` k-means runs on the true shares (seeds apart from the
    module's)."""
    runs = [run_kmeans(points, shares, k, seed=10_000 + r) for r in range(restarts)]
    return min(runs, key=lambda run: run[0])


def optimal_length(nodes: FloatArray) -> float:
    """The optimal closed tour through `nodes`: Held-Karp (exact) up to EXACT_NODES nodes,
    LKH through `elkai` above."""
    dist = distance_matrix(nodes)
    if len(nodes) <= EXACT_NODES:
        return held_karp(dist)[0]
    try:
        import elkai
    except ImportError:
        raise ReferenceUnavailable(
            f"a reference tour through {len(nodes)} stops needs LKH (more than {EXACT_NODES}"
            " are not solved exactly): pip install 'anytime-routing[measure]'"
        ) from None
    tour = elkai.DistanceMatrix(np.rint(dist * 1e6).astype(int).tolist()).solve_tsp()
    return tour_length(dist, tour[:-1])


def reference_length(clustering: Clustering) -> float:
    """The optimal tours of a clustering, summed over its depots."""
    return sum(optimal_length(clustering.nodes(k)) for k in range(len(clustering.centres)))


def reference_delivery(world: World) -> tuple[float, Clustering]:
    """The shortest delivery found offline, and its clustering: the tours' reference. The depots
    serve whichever customers make the tours shortest, and a tour's length does not depend on
    demand, so the candidates are the distinct clusterings of REFERENCE_RESTARTS k-means runs on
    the true shares and as many on uniform weights (the depots at plain centroids); each is
    screened by its 2-opt/Or-opt tours, and the EXACT_CANDIDATES shortest are solved exactly
    (Held-Karp; LKH for depots with more than EXACT_NODES - 1 customers)."""
    uniform = np.full(len(world.shares), 1.0 / max(len(world.shares), 1))
    candidates: dict[tuple[int, bytes], Clustering] = {}
    for kind, weights in enumerate((world.shares, uniform)):
        for r in range(REFERENCE_RESTARTS):
            _, clustering = run_kmeans(world.points, weights, world.depots, seed=10_000 + r)
            candidates.setdefault((kind, clustering.labels.tobytes()), clustering)

    def screened(clustering: Clustering) -> float:
        tours = (distance_matrix(clustering.nodes(k)) for k in range(len(clustering.centres)))
        return sum(tour_length(dist, local_optimum(dist)) for dist in tours)

    shortlist = sorted(candidates.values(), key=screened)[:EXACT_CANDIDATES]
    return min(((reference_length(c), c) for c in shortlist), key=lambda pair: pair[0])
