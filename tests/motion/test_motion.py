"""The motion plugin (domains/motion, OMPL): its world and score, its modules (improving results,
their budgets, interruption, the work clock's determinism), its problem sets, and `anytime
motion` (its JSON keys, exit codes and errors)."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from anytime_motion.domain import (
    OccupancyMap,
    Path,
    Query,
    Sensor,
    World,
    collides,
    path_quality,
    random_world,
)
from anytime_motion.modules import (
    PROBLEM_SETS,
    MapInputs,
    Scenes,
    bit_star,
    rrt_star,
    sense_obstacles,
    shorten_path,
)
from anytime_motion.planners import OmplPlanner, Shortcutter
from anytime_motion.plugin import PLUGIN
from anytime_motion.program import SCHEMAS, compiled_program, draw_problem, move

from anytime import Budget, Result, run
from anytime.plugin import Context, Instance, WorkClock

Cli = Callable[..., tuple[int, str, str]]


def _empty_world(dimension: int = 2) -> World:
    start = np.full(dimension, 0.1)
    goal = np.full(dimension, 0.9)
    none = np.zeros((0, dimension))
    return World(none, none, np.zeros(0, bool), start, goal, none)


def _one_ball() -> World:
    centres = np.array([[0.5, 0.5]])
    sizes = np.array([[0.2, 0.2]])
    world = _empty_world()
    world.centres, world.sizes, world.boxes = centres, sizes, np.array([False])
    return world


# --- the world and the score ----------------------------------------------------------------


def test_a_path_through_an_obstacle_scores_zero_and_a_free_one_its_cost_ratio() -> None:
    world = _one_ball()
    straight = Path(np.array([[0.1, 0.1], [0.9, 0.9]]))
    assert collides(straight, world) and path_quality(straight, world, 1.0) == 0.0
    around = Path(np.array([[0.1, 0.1], [0.1, 0.9], [0.9, 0.9]]))
    assert not collides(around, world)
    assert path_quality(around, world, 0.8) == pytest.approx(0.8 / 1.6)
    assert path_quality(around, world, 2.0) == 1.0  # clipped at 1
    assert path_quality(None, world, 1.0) == 0.0


@pytest.mark.parametrize("dimension", [2, 3])
def test_a_world_has_its_start_and_goal_free_and_rays_stop_at_obstacles(dimension: int) -> None:
    world = random_world(np.random.default_rng(3), 8, dimension)
    assert not world.inside(np.array([world.start, world.goal]), 0.05).any()
    directions = np.eye(dimension)
    distances = world.ray_distances(world.start, directions)
    for d, t in zip(directions, distances, strict=True):
        if np.isfinite(t):  # the point hit is on an obstacle's surface
            assert abs(float(world.distance(world.start + t * d)[0])) < 1e-9


def test_the_sensed_map_covers_more_of_the_obstacles_with_more_scans() -> None:
    world = random_world(np.random.default_rng(1))
    map = OccupancyMap(2)
    coverage = []
    for hits, _ in zip(Sensor(world, 0).scans(), range(40), strict=False):
        map.mark(hits)
        coverage.append(map.coverage(world.surface))
    assert coverage == sorted(coverage) and coverage[0] < 0.7 < coverage[-1]
    assert OccupancyMap.of_world(world).coverage(world.surface) == 1.0


# --- the modules ------------------------------------------------------------------------------


def _drive(module: Any, args: list[Any], budget: float) -> tuple[list[Result], float]:
    """Every result `module` registers with `budget` ticks, and the ticks it used; and the
    runtime's run of it keeps to the same budget, up to the module's step."""
    ctx = Context(budget)
    results = list(module.function(ctx, *args))
    record = run(module, args, budget=Budget(budget, clock=WorkClock()))
    assert record.time_used <= budget + module.step
    return results, ctx.elapsed


def _problem(seed: int = 5) -> tuple[World, Result, Query]:
    world = random_world(np.random.default_rng(seed))
    truth = OccupancyMap.of_world(world)
    return world, Result(truth, 1.0), Query(world.start, world.goal, seed)


def test_sensing_registers_better_maps_and_keeps_to_its_allocation() -> None:
    world = random_world(np.random.default_rng(2))
    results, used = _drive(sense_obstacles, [Sensor(world, 0)], 300)
    assert used <= 300
    scenes = Scenes()
    instance = Instance(args=(), reference=world)
    coverage = [scenes.score(instance, r.value) for r in results]
    assert coverage[0] == 0.0 and coverage[-1] > 0.5 and coverage == sorted(coverage)


@pytest.mark.parametrize("module", [rrt_star, bit_star], ids=lambda m: m.name)
def test_a_planner_registers_shorter_paths_within_its_budget_and_step(module: object) -> None:
    world, truth, query = _problem()
    results, used = _drive(module, [truth, query], 3000)
    costs = [r.value.cost for r in results]
    assert costs and costs == sorted(costs, reverse=True) and len(set(costs)) == len(costs)
    assert 3000 <= used <= 3000 + module.step  # type: ignore[attr-defined]
    assert not collides(results[-1].value, world)  # planned on the inflated truth
    estimate = results[-1].quality
    assert estimate == pytest.approx(query.straight / costs[-1])


@pytest.mark.parametrize("planner", ["rrt-star", "bit-star"])
def test_the_work_clock_makes_a_planner_deterministic(planner: str) -> None:
    """Same seed, same slices: the same path after the same checks, whatever ran before."""
    _, truth, query = _problem()

    def plan() -> tuple[list[float], list[float]]:
        solver = OmplPlanner(planner, truth.value, query)
        spent = [solver.advance(100) for _ in range(20)]
        best = solver.best()
        assert best is not None
        return spent, best.value.points.ravel().tolist()

    first = plan()
    OmplPlanner("rrt-star", truth.value, Query(query.start, query.goal, 99)).advance(500)
    assert plan() == first


def test_a_planner_stops_when_interrupted() -> None:
    _, truth, query = _problem()
    ctx = Context(5000)
    steps = rrt_star.function(ctx, truth, query)
    ctx.stop.set()
    assert list(steps) == [] and ctx.elapsed == 0


def test_shortening_never_lengthens_and_keeps_to_its_budget() -> None:
    world, truth, query = _problem()
    solver = OmplPlanner("rrt-star", truth.value, query)
    while solver.best() is None:
        solver.advance(200)
    found = solver.best()
    assert found is not None
    results, used = _drive(shorten_path, [found, query], 1000)
    costs = [r.value.cost for r in results]
    assert costs[0] == found.value.cost and costs == sorted(costs, reverse=True)
    assert len(costs) > 1 and used <= 1000 + (shorten_path.step or 0)
    assert not collides(results[-1].value, world)


def test_a_shortcutter_keeps_to_each_limit() -> None:
    _, truth, query = _problem()
    path = Path(np.array([query.start, [0.5, 0.02], query.goal]), truth.value)
    cutter = Shortcutter(path, query.straight, 0)
    assert all(cutter.advance(37) <= 37 for _ in range(10))


def test_a_map_input_has_the_coverage_asked_for() -> None:
    instance = MapInputs().instance(np.random.default_rng(0), (0.8,))
    given, _ = instance.args
    assert abs(given.value.coverage(instance.reference.world.surface) - 0.8) <= 0.02
    assert instance.reference.cost < np.inf


def test_the_plugin_declares_a_problem_set_for_every_anytime_module() -> None:
    assert set(PROBLEM_SETS) == {m.name for m in PLUGIN.modules}


# --- anytime motion ---------------------------------------------------------------------------


KEYS = [
    "schema", "budget", "time_unit", "allocation", "expected_quality", "realised_quality",
    "time_used", "status", "path_cost", "reference_cost", "comparison", "obstacles", "dimension",
    "seed",
]  # fmt: skip


def test_motion_json_has_exactly_its_keys(cli: Cli) -> None:
    code, out, err = cli("motion", "--json", "--budget", "2000")
    assert code == 0, err
    got = json.loads(out)
    assert list(got) == KEYS
    assert list(got["allocation"]) == ["sense-obstacles", "bit-star", "shorten-path"]
    assert sum(got["allocation"].values()) <= 2000
    assert list(got["comparison"]) == ["even", "planner"]
    assert got["comparison"]["planner"]["allocation"]["bit-star"] == 2000
    assert 0 <= got["realised_quality"] <= 1 and 0 < got["expected_quality"] <= 1


@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (["--budget", "333"], 1,
         "anytime: error: --budget 333: expected a multiple of 250 ticks (the allocation lattice"
         " of the compiled schema)\n"),
    ],
)  # fmt: skip
def test_motion_says_what_is_wrong(cli: Cli, args: list[str], status: int, message: str) -> None:
    code, _, err = cli("motion", *args)
    assert (code, err) == (status, message)


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--dimension", "4"], "argument --dimension: "),
        (["--obstacles", "-1"], "argument --obstacles: "),
        (["--schema", "nope"], "argument --schema: invalid choice: 'nope'"),
        (["--budget", "-2"], "argument --budget: "),
    ],
)
def test_motion_usage_errors_exit_2(cli: Cli, args: list[str], fragment: str) -> None:
    code, _, err = cli("motion", *args)
    assert code == 2 and fragment in err and "Traceback" not in err


def test_shortening_without_a_deadline_stops_when_interrupted() -> None:
    _, truth, query = _problem()
    path = Path(np.array([query.start, [0.5, 0.02], query.goal]), truth.value)
    ctx = Context()  # an infinite allocation
    steps = shorten_path.function(ctx, Result(path, 0.5), query)
    assert next(steps).value is path
    for _ in steps:
        if ctx.elapsed > 300:
            ctx.stop.set()
    assert ctx.elapsed < 1000


# --- the compiled promise (slow: `anytime verify` checks the same) ---------------------------


#: The compiled expectation's own error, which the runs' standard error does not see: the
#: planners' profiles have 100 trials a cell of qualities mostly 0 (a collision) or near 1,
#: a standard error of 0.03-0.045 a cell where collisions are common.
PROFILE_ERROR = 0.03


@pytest.mark.slow
@pytest.mark.parametrize("schema", SCHEMAS)
def test_the_compiled_promise_holds_on_fresh_problems(schema: str) -> None:
    """At every total of the compiled table, on 100 fresh problems: the realised mean within
    max(0.015, 3 se) of the expectation (se counting PROFILE_ERROR too) but at one total, and
    no run over its total."""
    program = compiled_program(schema)
    rng = np.random.default_rng([20_261_205, 1, SCHEMAS.index(schema)])
    problems = [draw_problem(rng) for _ in range(100)]
    outside, overruns = [], []
    for j, total in enumerate(program.profile.time):
        runs = [move(program, p, float(total)) for p in problems]
        quality = np.array([r.quality for r in runs])
        se = float(np.hypot(quality.std(ddof=1) / np.sqrt(len(quality)), PROFILE_ERROR))
        if abs(quality.mean() - program.expected[j]) > max(0.015, 3 * se):
            outside.append(f"T={total:g}: {quality.mean():.3f} against {program.expected[j]:.3f}")
        if max(r.record.time_used for r in runs) > total:
            overruns.append(f"T={total:g}")
    assert len(outside) <= 1 and overruns == [], (outside, overruns)
