"""The routing plugin (domains/routing, `anytime-routing`): its kernels' invariants, its
modules through the catalogue, its compiled schemas' promises on fresh problems, and `anytime
deliver`. Imports of the framework are the public API only."""

from __future__ import annotations

import json
import math
from pathlib import Path

import anytime_routing
import numpy as np
import pytest
from anytime_routing import geometry as G
from anytime_routing.domain import (
    Clustering,
    Depot,
    clustering_quality,
    demand_quality,
    random_world,
    reference_clustering,
    reference_delivery,
    reference_length,
    run_kmeans,
    tour_quality,
)
from anytime_routing.modules import (
    PROBLEM_SETS,
    DepotTour,
    cluster_stops,
    clustering_of_quality,
    demand_of_quality,
    depots,
    estimate_demand,
    insert_tours,
    plan_tour,
    plan_tours,
    route,
)
from anytime_routing.plugin import PLUGIN
from anytime_routing.program import (
    SCHEMAS,
    DeliveryProblems,
    compiled_program,
    deliver,
    depot_tour_quality,
    fresh_problems,
)
from anytime_routing.resources import load_schema_file
from conftest import Cli
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime import AnytimeLibrary, Context, Result, measure_upstream
from anytime.plugin import MISSING
from anytime.testing import assert_module_passes

PACKAGE = Path(anytime_routing.__file__).parent
#: Roots of the fresh problems' seeds, apart from the profile builder's SeedSequence(0, ...).
SEED = 20_250_114


# --- kernels: invariants ------------------------------------------------------------------

points = st.integers(min_value=4, max_value=12).flatmap(
    lambda n: st.lists(st.tuples(st.floats(0, 1), st.floats(0, 1)), min_size=n, max_size=n)
)


@settings(max_examples=60, deadline=None)
@given(points, st.integers(0, 2**32 - 1))
def test_a_two_opt_or_or_opt_move_never_lengthens_a_tour(coords: list, seed: int) -> None:
    dist = G.distance_matrix(np.array(coords))
    tour = np.random.default_rng(seed).permutation(len(coords)).astype(np.int64)
    before = G.tour_length(dist, tour)
    gain, i, j = G.best_two_opt(dist, tour)
    if gain > G.EPS:
        after = G.apply_two_opt(tour, i, j)
        assert sorted(after) == list(range(len(coords)))
        assert G.tour_length(dist, after) == pytest.approx(before - gain, abs=1e-9)
        assert G.tour_length(dist, after) < before
    gain, start, length, edge, reverse = G.best_or_opt(dist, tour)
    if gain > G.EPS:
        after = G.apply_or_opt(tour, start, length, edge, reverse)
        assert sorted(after) == list(range(len(coords)))
        assert G.tour_length(dist, after) == pytest.approx(before - gain, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(points)
def test_the_lower_bound_never_exceeds_a_tour_and_held_karp_is_optimal(coords: list) -> None:
    dist = G.distance_matrix(np.array(coords))
    optimum, tour = G.held_karp(dist)
    assert sorted(tour) == list(range(len(coords)))
    assert G.tour_length(dist, tour) == pytest.approx(optimum)
    assert G.one_tree_bound(dist) <= optimum + 1e-9
    assert optimum <= G.tour_length(dist, G.nearest_neighbour(dist)) + 1e-9


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.floats(0, 30))
def test_clusters_cover_every_customer_once(seed: int, depots: int, allocation: float) -> None:
    world = random_world(np.random.default_rng(seed), customers=12, depots=depots)
    demand = estimate_demand(Context(4), world.orders)
    assert demand is not None
    for answer in cluster_stops(Context(allocation), demand, world.sites):
        c: Clustering = answer.value
        members = np.sort(np.concatenate([c.members(k) for k in range(depots)]))
        assert members.tolist() == list(range(12))
        for tours in plan_tours(Context(40), answer):
            visited = np.sort(np.concatenate(tours.value.orders))
            assert visited.tolist() == list(range(12))
            assert 0 <= tours.quality <= 1


def test_the_self_estimate_of_plan_tours_is_a_bound_on_its_own_clustering() -> None:
    """Its 1-tree bound over the length never exceeds optimal over the length."""
    rng = np.random.default_rng([SEED, 1])
    for _ in range(20):
        world = random_world(rng)
        _, clustering = run_kmeans(world.points, world.shares, world.depots, seed=0)
        optimum = sum(
            G.held_karp(G.distance_matrix(clustering.nodes(k)))[0] for k in range(world.depots)
        )
        for result in plan_tours(Context(60), Result(clustering, 1.0)):
            assert result.quality <= optimum / result.value.length + 1e-9


def test_the_reference_delivery_is_no_longer_than_the_reference_clusterings_tours() -> None:
    """The tours' reference is the best of many candidate clusterings, exact: never longer than
    the optimal tours of the reference k-means clustering (one of its candidates), and no
    converged `plan-tours` run on the reference clustering beats it."""
    rng = np.random.default_rng([SEED, 4])
    for _ in range(5):
        world = random_world(rng)
        length, clustering = reference_delivery(world)
        _, kmeans = reference_clustering(world.points, world.shares, world.depots)
        assert length <= reference_length(kmeans) + 1e-9
        assert length == pytest.approx(reference_length(clustering))
        *_, tours = plan_tours(Context(), Result(kmeans, 1.0))
        assert tours.value.length >= length - 1e-9


def test_a_tour_per_depot_is_the_tour_plan_tours_makes_for_it() -> None:
    """`plan-tour` makes one depot's moves as `plan-tours` makes each of its tours' (round
    robin changes only the order of the ticks): run to convergence, the same tours, in as many
    ticks in all; `depots` and `route` take the clustering apart and put the tours together."""
    rng = np.random.default_rng([SEED, 5])
    for _ in range(10):
        world = random_world(rng)
        _, clustering = run_kmeans(world.points, world.shares, world.depots, seed=0)
        clusters = Result(clustering, 0.9)
        together = Context()
        *_, whole = plan_tours(together, clusters)
        items = depots(clusters)
        assert [item.index for item in items] == list(range(world.depots))
        tours, ticks = [], 0.0
        for item in items:
            alone = Context()
            *_, last = plan_tour(alone, Result(item, clusters.quality))
            assert isinstance(last.value, DepotTour) and last.quality <= 0.9
            tours.append(last.value)
            ticks += alone.elapsed
        joined = route(Result(tours, 0.9))
        assert [o.tolist() for o in joined.orders] == [o.tolist() for o in whole.value.orders]
        assert joined.length == pytest.approx(sum(tour.length for tour in tours))
        assert ticks == together.elapsed


def test_route_is_no_delivery_while_a_depot_has_no_tour() -> None:
    world = random_world(np.random.default_rng([SEED, 6]))
    _, clustering = run_kmeans(world.points, world.shares, world.depots, seed=0)
    *_, first = plan_tour(Context(), Result(Depot(clustering, 0), 1.0))
    assert route(Result([first.value, MISSING, first.value], 0.5)) is None
    assert route(Result([], 1.0)) is None


def test_a_depots_measured_quality_is_its_share_of_the_reference() -> None:
    """Scored against the depot's optimal tour scaled by how close the clustering's optimal
    tours come to the reference delivery: an optimal tour scores that scale, a longer one
    less, in proportion."""
    depot_inputs = PROBLEM_SETS["plan-tour"].problems
    rng = np.random.default_rng([SEED, 7])
    for _ in range(3):
        instance = depot_inputs.instance(rng, (0.9,))
        (given,) = instance.args
        scale, optimal = instance.reference
        assert 0 < scale <= 1 + 1e-9 and given.quality == 0.9
        *_, last = plan_tour(Context(), given)
        score = depot_inputs.score(instance, last.value)
        assert score == pytest.approx(min(1.0, scale * optimal / last.value.length))
        assert score <= scale + 1e-9
        assert depot_inputs.score(instance, None) == 0.0


# --- problem sets ---------------------------------------------------------------------------


@pytest.mark.parametrize("q", [0.3, 0.6, 0.9])
def test_a_demand_input_of_quality_q_is_estimate_demands_answer(q: float) -> None:
    rng = np.random.default_rng([SEED, 2])
    for _ in range(10):
        world, demand = demand_of_quality(rng, q)
        assert abs(demand_quality(demand.value, world.shares) - q) <= 0.01


@pytest.mark.parametrize("q", [0.5, 0.9, 1.0])
def test_a_clustering_input_of_quality_q_is_cluster_stops_answer(q: float) -> None:
    rng = np.random.default_rng([SEED, 3])
    for _ in range(5):
        world, clustering = clustering_of_quality(rng, q)
        best, _ = reference_clustering(world.points, world.shares, world.depots)
        assert abs(clustering_quality(clustering.value, world.shares, best) - q) <= 0.01


def test_the_program_problems_score_each_modules_result_as_its_problem_set_does() -> None:
    """`score_step`, what `anytime profile --upstream` scores a module inside a program by
    (and its inputs' true qualities): a demand estimate, a clustering and its depots, tours, a
    depot's tour and the route, each as the modules' own problem sets and `score` do."""
    for schema in SCHEMAS:
        assert isinstance(PLUGIN.program_problems[schema].problems, DeliveryProblems)
    problems = DeliveryProblems()
    instance = problems.instance(np.random.default_rng([SEED, 8]))
    orders, sites = instance.args
    world = instance.reference.world
    length, _ = reference_delivery(world)
    best, _ = reference_clustering(world.points, world.shares, world.depots)
    demand = estimate_demand(Context(10), orders)
    assert demand is not None
    quality = problems.score_step(instance, "estimate-demand", demand.value)
    assert quality == demand_quality(demand.value, world.shares)
    *_, clusters = cluster_stops(Context(16), demand, sites)
    quality = clustering_quality(clusters.value, world.shares, best)
    assert problems.score_step(instance, "cluster-stops", clusters.value) == quality
    assert problems.score_step(instance, "depots", depots(clusters)) == quality
    for planner in (plan_tours, insert_tours):
        *_, tours = planner(Context(40), clusters)
        quality = tour_quality(tours.value, length)
        assert problems.score_step(instance, planner.name, tours.value) == quality
        assert problems.score(instance, tours.value) == quality
    *_, tour = plan_tour(Context(), Result(depots(clusters)[0], 0.9))
    quality = problems.score_step(instance, "plan-tour", tour.value)
    assert quality == depot_tour_quality(tour.value, length) and 0 < quality <= 1
    joined = route(Result([tour.value], 0.9))
    assert problems.score_step(instance, "route", joined) == tour_quality(joined, length)
    assert problems.score_step(instance, "cluster-stops", None) == 0.0
    with pytest.raises(ValueError, match="no true quality for module 'has-customers[?]'"):
        problems.score_step(instance, "has-customers?", True)


def test_plan_tour_in_the_loop_is_beyond_measuring_upstream() -> None:
    """`anytime profile --upstream` measures a module called once, outside loops: `plan-tour`,
    called in `deliver-each`'s `map`, keeps its own problem set (`DepotInputs`)."""
    library = AnytimeLibrary.default()
    with pytest.raises(ValueError, match="schema 'deliver-each' does not call module 'plan-tour'"):
        measure_upstream("plan-tour", load_schema_file(), "deliver-each", library, trials=1)


# --- the catalogue --------------------------------------------------------------------------

CATALOGUE = {  # a few cells per module: `anytime check MODULE` runs the full grids
    "estimate-demand": {"time": [0, 2, 10, 40]},
    "cluster-stops": {"time": [0, 4, 24], "input_grids": [[0.8]]},
    "plan-tours": {"time": [0, 4, 20], "input_grids": [[0.95]]},
    "insert-tours": {"time": [0, 24, 48], "input_grids": [[0.95]]},
    "plan-tour": {"time": [0, 1, 8], "input_grids": [[0.95]]},
}


@pytest.mark.parametrize("name", sorted(CATALOGUE))
def test_every_module_passes_the_catalogue(name: str) -> None:
    module = next(m for m in PLUGIN.modules if m.name == name)
    assert module.step == 0.0
    # 5 instances a cell (the tour modules take seconds each): `anytime check` runs 20
    assert_module_passes(module, PROBLEM_SETS[name].problems, trials=5, **CATALOGUE[name])


# --- promises -------------------------------------------------------------------------------


#: The compiled expectation's own error, which the runs' standard error does not see: the tour
#: profiles' sampling error (300 trials a cell, about 0.004) and their interpolation.
PROFILE_ERROR = 0.003


def _check_promises(
    schema: str, worlds: int, every: int, adaptive: bool = False
) -> tuple[list[str], list[str], list[str]]:
    """At every `every`-th total of the compiled grid from 0 up, on `worlds` fresh problems, the
    realised mean against the compiled expectation. Returns the totals outside max(0.01, 2 se),
    those outside max(0.015, 3 se), se counting PROFILE_ERROR too, and the runs over their
    total on the work clock."""
    program = compiled_program(schema)
    rng = np.random.default_rng([SEED, SCHEMAS.index(schema)])
    problems = fresh_problems(rng, worlds)
    outside_2, outside_3, overruns = [], [], []
    for j in range(0, len(program.profile.time), every):
        total = float(program.profile.time[j])
        qualities, used = [], []
        for world, reference in problems:
            run = deliver(program, world, total, adaptive, reference)
            assert run.quality is not None
            qualities.append(run.quality)
            used.append(run.record.time_used)
        mean = float(np.mean(qualities))
        se = math.hypot(float(np.std(qualities, ddof=1) / math.sqrt(worlds)), PROFILE_ERROR)
        promised = float(program.expected[j])
        line = f"T={total:g}: compiled {promised:.4f}, realised {mean:.4f} (se {se:.4f})"
        if abs(mean - promised) > max(0.01, 2 * se):
            outside_2.append(line)
        if abs(mean - promised) > max(0.015, 3 * se):
            outside_3.append(line)
        if max(used) > total:
            overruns.append(f"T={total:g}: a run used {max(used):g}")
    return outside_2, outside_3, overruns


@pytest.mark.parametrize("schema", SCHEMAS)
def test_each_total_delivers_what_the_compiler_expects(schema: str) -> None:
    """Within max(0.01, 2 se) at every sampled total but one (one in 20 falls outside by chance
    alone, and the totals share their problems, so their errors go together), within
    max(0.015, 3 se) at all, and no run over its total."""
    outside_2, outside_3, overruns = _check_promises(schema, worlds=50, every=3)  # slow: 400
    assert len(outside_2) <= 1, outside_2
    assert (outside_3, overruns) == ([], [])


@pytest.mark.slow
@pytest.mark.parametrize("adaptive", [False, True])
@pytest.mark.parametrize("schema", SCHEMAS)
def test_every_total_delivers_what_the_compiler_expects(schema: str, adaptive: bool) -> None:
    outside_2, outside_3, overruns = _check_promises(schema, 400, every=1, adaptive=adaptive)
    assert len(outside_2) <= 2, outside_2
    assert (outside_3, overruns) == ([], [])


# --- anytime deliver ------------------------------------------------------------------------


def test_deliver_json_has_exactly_its_keys(cli: Cli) -> None:
    code, out, err = cli("deliver", "--json", "--budget", "40")
    assert code == 0, err
    run = json.loads(out)
    assert list(run) == [
        "schema", "budget", "time_unit", "allocation", "expected_quality", "realised_quality",
        "time_used", "status", "customers", "depots", "seed",
    ]  # fmt: skip
    assert run["time_used"] <= run["budget"] == 40
    assert list(run["allocation"]) == ["estimate-demand", "cluster-stops", "plan-tours"]
    assert 0 < run["realised_quality"] <= 1


@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (["--depots", "5", "--customers", "3"], 1,
         "anytime: error: --depots 5: more depots than customers (3)\n"),
        (["--budget", "7"], 1,
         "anytime: error: --budget 7: expected a multiple of 2 ticks (the allocation lattice of"
         " the compiled schema)\n"),
    ],
)  # fmt: skip
def test_deliver_says_what_is_wrong(cli: Cli, args: list[str], status: int, message: str) -> None:
    code, _, err = cli("deliver", *args)
    assert (code, err) == (status, message)


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--customers", "0"], "argument --customers: "),
        (["--schema", "nope"], "argument --schema: invalid choice: 'nope'"),
        (["--budget", "-2"], "argument --budget: "),
    ],
)
def test_deliver_usage_errors_exit_2(cli: Cli, args: list[str], fragment: str) -> None:
    code, _, err = cli("deliver", *args)
    assert code == 2 and fragment in err and "Traceback" not in err


def test_the_repository_shows_the_packaged_schemas() -> None:
    shown = Path(__file__).resolve().parents[2] / "schemas" / "routing.any"
    assert shown.read_text() == (PACKAGE / "schemas" / "routing.any").read_text()
