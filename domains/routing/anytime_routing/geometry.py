"""The numerical kernels, vectorised with numpy: distances, tour lengths, the 2-opt and Or-opt
moves, nearest neighbour and cheapest insertion, the 1-tree lower bound, Held-Karp, and
demand-weighted k-means with k-means++ seeding. Nothing here knows about time: the modules
(`modules.py`) call these one batch at a time and report each batch as a tick."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "FloatArray",
    "IntArray",
    "assign",
    "best_or_opt",
    "best_two_opt",
    "apply_or_opt",
    "apply_two_opt",
    "cheapest_insertion_step",
    "distance_matrix",
    "held_karp",
    "kmeans_cost",
    "kmeans_plus_plus_step",
    "lloyd_step",
    "local_optimum",
    "nearest_neighbour",
    "one_tree_bound",
    "tour_length",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: A move must gain at least this much to count as an improvement (floating-point noise).
EPS = 1e-10


def distance_matrix(points: FloatArray) -> FloatArray:
    """Euclidean distances between the rows of `points` (n, 2)."""
    diff = points[:, None, :] - points[None, :, :]
    return np.asarray(np.sqrt((diff**2).sum(axis=-1)), dtype=np.float64)


def tour_length(dist: FloatArray, tour: Sequence[int] | IntArray) -> float:
    """The length of the closed tour visiting `tour` (indices into `dist`) in order."""
    t = np.asarray(tour, dtype=np.int64)
    if len(t) < 2:
        return 0.0
    return float(dist[t, np.roll(t, -1)].sum())


# --- construction -----------------------------------------------------------------------------


def nearest_neighbour(dist: FloatArray, start: int = 0) -> IntArray:
    """The nearest-neighbour tour of all nodes from `start`."""
    n = len(dist)
    tour = [start]
    free = np.ones(n, dtype=bool)
    free[start] = False
    for _ in range(n - 1):
        row = np.where(free, dist[tour[-1]], np.inf)
        nxt = int(np.argmin(row))
        tour.append(nxt)
        free[nxt] = False
    return np.array(tour, dtype=np.int64)


def cheapest_insertion_step(dist: FloatArray, tour: list[int], free: list[int]) -> None:
    """Insert the free node whose cheapest insertion into `tour` costs least, in place (one
    batch: every free node against every edge)."""
    t = np.asarray(tour, dtype=np.int64)
    u, v = t, np.roll(t, -1)
    f = np.asarray(free, dtype=np.int64)
    cost = dist[f][:, u] + dist[f][:, v] - dist[u, v][None, :]  # (free, edges)
    k, e = np.unravel_index(int(np.argmin(cost)), cost.shape)
    tour.insert(int(e) + 1, int(f[k]))
    free.pop(int(k))


# --- improvement ------------------------------------------------------------------------------


def best_two_opt(dist: FloatArray, tour: IntArray) -> tuple[float, int, int]:
    """The best 2-opt move of the closed `tour`: (gain, i, j), reversing `tour[i+1 : j+1]`
    shortens the tour by `gain` (<= EPS: no improving move). One batch of all n(n-3)/2 moves."""
    m = len(tour)
    if m < 4:
        return 0.0, 0, 0
    a, b = tour, np.roll(tour, -1)
    delta = dist[a[:, None], a[None, :]] + dist[b[:, None], b[None, :]]
    delta -= dist[a, b][:, None] + dist[a, b][None, :]
    i, j = np.triu_indices(m, k=2)
    keep = ~((i == 0) & (j == m - 1))
    i, j = i[keep], j[keep]
    values = delta[i, j]
    best = int(np.argmin(values))
    return float(-values[best]), int(i[best]), int(j[best])


def apply_two_opt(tour: IntArray, i: int, j: int) -> IntArray:
    out = tour.copy()
    out[i + 1 : j + 1] = tour[i + 1 : j + 1][::-1]
    return out


def best_or_opt(
    dist: FloatArray, tour: IntArray, longest: int = 3
) -> tuple[float, int, int, int, bool]:
    """The best Or-opt move: move a segment of 1 to `longest` consecutive nodes elsewhere in
    the tour, possibly reversed. Returns (gain, start, length, edge, reversed): the segment
    `tour[start : start + length]` (cyclically) goes between `tour[edge]` and the node after
    it. One batch of all segments against all edges."""
    m = len(tour)
    best: tuple[float, int, int, int, bool] = (0.0, 0, 0, 0, False)
    idx = np.arange(m)
    for length in range(1, min(longest, m - 3) + 1):
        s0 = tour[idx]
        s1 = tour[(idx + length - 1) % m]
        p = tour[(idx - 1) % m]
        q = tour[(idx + length) % m]
        removed = dist[p, s0] + dist[s1, q] - dist[p, q]  # (m,)
        u, v = tour, np.roll(tour, -1)  # edges e: (tour[e], tour[e+1])
        plain = dist[u[None, :], s0[:, None]] + dist[s1[:, None], v[None, :]]
        flipped = dist[u[None, :], s1[:, None]] + dist[s0[:, None], v[None, :]]
        inserted = np.minimum(plain, flipped) - dist[u, v][None, :]
        delta = inserted - removed[:, None]  # (start, edge)
        # an edge may not touch the segment: e in start-1 .. start+length-1 (cyclically)
        offset = (idx[None, :] - idx[:, None]) % m  # edge - start
        delta[(offset >= m - 1) | (offset <= length - 1)] = np.inf
        k = int(np.argmin(delta))
        start, edge = divmod(k, m)
        gain = float(-delta[start, edge])
        if gain > best[0]:
            best = (gain, start, length, edge, bool(flipped[start, edge] < plain[start, edge]))
    return best


def local_optimum(dist: FloatArray) -> IntArray:
    """Nearest neighbour from node 0, then the best 2-opt or (when none improves) Or-opt move
    until neither improves: `plan-tours` run to the end, without the clock."""
    tour = nearest_neighbour(dist)
    while True:
        gain, i, j = best_two_opt(dist, tour)
        if gain > EPS:
            tour = apply_two_opt(tour, i, j)
            continue
        gain, start, length, edge, reverse = best_or_opt(dist, tour)
        if gain <= EPS:
            return tour
        tour = apply_or_opt(tour, start, length, edge, reverse)


def apply_or_opt(tour: IntArray, start: int, length: int, edge: int, reverse: bool) -> IntArray:
    m = len(tour)
    positions = [(start + k) % m for k in range(length)]
    segment = [int(tour[p]) for p in positions]
    if reverse:
        segment.reverse()
    after = int(tour[edge])
    rest = [int(tour[p]) for p in range(m) if p not in positions]
    at = rest.index(after) + 1
    return np.array(rest[:at] + segment + rest[at:], dtype=np.int64)


# --- bounds and exact tours -----------------------------------------------------------------


def _mst_weight(dist: FloatArray, nodes: IntArray) -> float:
    """Prim's minimum spanning tree of `nodes`, O(n^2) with numpy rows."""
    n = len(nodes)
    if n < 2:
        return 0.0
    sub = dist[np.ix_(nodes, nodes)]
    inside = np.zeros(n, dtype=bool)
    inside[0] = True
    best = sub[0].copy()
    total = 0.0
    for _ in range(n - 1):
        row = np.where(inside, np.inf, best)
        k = int(np.argmin(row))
        total += float(row[k])
        inside[k] = True
        best = np.minimum(best, sub[k])
    return total


def one_tree_bound(dist: FloatArray) -> float:
    """The best 1-tree lower bound on the optimal tour through all nodes of `dist`: over every
    special node v, the minimum spanning tree of the others plus v's two shortest edges. Exact
    for up to 3 nodes."""
    n = len(dist)
    if n <= 3:
        return tour_length(dist, np.arange(n))
    everyone = np.arange(n)
    bound = 0.0
    for v in range(n):
        others = everyone[everyone != v]
        two = np.sort(dist[v, others])[:2].sum()
        bound = max(bound, _mst_weight(dist, others) + float(two))
    return bound


def held_karp(dist: FloatArray) -> tuple[float, IntArray]:
    """The optimal closed tour through all nodes of `dist` (Held-Karp, O(2^n n^2), vectorised
    over the subsets of each size): its length and the tour from node 0."""
    n = len(dist)
    if n <= 3:
        tour = np.arange(n, dtype=np.int64)
        return tour_length(dist, tour), tour
    m = n - 1  # nodes 1..n-1 as bits 0..m-1
    full = 1 << m
    cost = np.full((full, m), np.inf)
    parent = np.full((full, m), -1, dtype=np.int64)
    for k in range(m):
        cost[1 << k, k] = dist[0, k + 1]
    masks = np.arange(full)
    popcount = np.array([bin(x).count("1") for x in range(full)])
    sub = dist[1:, 1:]
    for size in range(2, m + 1):
        sets = masks[popcount == size]
        for k in range(m):
            has = sets[(sets >> k) & 1 == 1]
            prev = has ^ (1 << k)
            c = cost[prev] + sub[:, k][None, :]  # (sets, j): come to k from j
            j = np.argmin(c, axis=1)
            cost[has, k] = c[np.arange(len(has)), j]
            parent[has, k] = j
    closing = cost[full - 1] + dist[1:, 0]
    last = int(np.argmin(closing))
    length = float(closing[last])
    path = [last]
    mask = full - 1
    while True:
        p = int(parent[mask, path[-1]])
        mask ^= 1 << path[-1]
        if p < 0:
            break
        path.append(p)
    order = [0] + [k + 1 for k in reversed(path)]
    return length, np.array(order, dtype=np.int64)


# --- clustering -------------------------------------------------------------------------------


def assign(points: FloatArray, centres: FloatArray) -> tuple[IntArray, FloatArray]:
    """Each point's nearest centre and its squared distance to it (one batch)."""
    d2 = ((points[:, None, :] - centres[None, :, :]) ** 2).sum(axis=-1)
    labels = np.argmin(d2, axis=1).astype(np.int64)
    return labels, d2[np.arange(len(points)), labels]


def kmeans_cost(
    points: FloatArray, weights: FloatArray, centres: FloatArray, labels: IntArray
) -> float:
    """Sum of weight times squared distance of each point to its labelled centre."""
    d2 = ((points - centres[labels]) ** 2).sum(axis=-1)
    return float((weights * d2).sum())


def kmeans_plus_plus_step(
    points: FloatArray, weights: FloatArray, centres: list[FloatArray], rng: np.random.Generator
) -> None:
    """Add one k-means++ centre, drawn with probability weight x squared distance to the
    nearest centre so far (the first by weight alone), in place (one batch)."""
    if not centres:
        p = weights
    else:
        _, d2 = assign(points, np.array(centres))
        p = weights * d2
    total = p.sum()
    if total <= 0:
        p, total = np.ones(len(points)), float(len(points))
    centres.append(points[int(rng.choice(len(points), p=p / total))].copy())


def lloyd_step(
    points: FloatArray, weights: FloatArray, centres: FloatArray
) -> tuple[FloatArray, IntArray]:
    """One Lloyd iteration of weighted k-means: assign, then move each centre to the weighted
    mean of its points (a centre left without points, or without weight, stays)."""
    labels, _ = assign(points, centres)
    k = len(centres)
    mass = np.bincount(labels, weights=weights, minlength=k)
    sums = np.stack(
        [np.bincount(labels, weights=weights * points[:, d], minlength=k) for d in range(2)],
        axis=1,
    )
    moved = centres.copy()
    has = mass > 0
    moved[has] = sums[has] / mass[has, None]
    return moved, labels
