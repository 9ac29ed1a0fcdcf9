"""Moving obstacles, the critical event of their arrival, and obstacle overcoming."""

import numpy as np
import pytest
from anytime_navigation.obstacles.crossing import simulate
from anytime_navigation.obstacles.moving import MovingObstacle, Plan, Traffic, random_obstacles
from anytime_navigation.obstacles.overcoming import (
    ObstacleSituation,
    decide_best,
    obstacle_arrival,
    side_clear,
)
from anytime_navigation.planning.search import find_path
from anytime_navigation.plugin import PLUGIN
from anytime_navigation.world import World, random_world

from anytime.clocks import WorkClock
from anytime.runtime.deadline import EVENTS, deadline_from


def _open(n: int = 16) -> World:
    return World(np.zeros((n, n), dtype=bool), (0, 0), (n - 1, n - 1))


def test_straight_motion_and_bounce_off_the_edge() -> None:
    world = _open(8)
    traffic = Traffic(world, [MovingObstacle((5.0, 2.0), (0.5, 0.0))])
    assert traffic.at(2)[0].position == (6.0, 2.0)
    assert traffic.cells_at(2) == {(6, 2)}
    assert traffic.cells_at(1) == {(5, 2), (6, 2)}
    # at x = 7 the next move would leave the map: the velocity turns round
    assert traffic.at(4)[0].position == (7.0, 2.0)
    assert traffic.at(5)[0].velocity == (-0.5, 0.0) and traffic.at(5)[0].position == (7.0, 2.0)
    assert traffic.at(7)[0].position == (6.0, 2.0)


def test_bounce_off_a_wall_and_determinism() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[4, 3] = True
    world = World(blocked, (0, 0), (7, 7))
    obstacle = MovingObstacle((3.0, 1.0), (0.0, 1.0))
    traffic = Traffic(world, [obstacle])
    assert [traffic.at(t)[0].position for t in range(5)] == [
        (3.0, 1.0),
        (3.0, 2.0),
        (3.0, 3.0),
        (3.0, 3.0),
        (3.0, 2.0),
    ]
    assert Traffic(world, [obstacle]).at(40) == traffic.at(40)
    with pytest.raises(ValueError, match="does not lie on free cells"):
        Traffic(world, [MovingObstacle((3.0, 4.0), (0.0, 0.0))])


def test_arrival_by_hand() -> None:
    world = _open(16)
    route = [(x, 5) for x in range(16)]
    # the robot is in cell (t // 2, 5) at tick t. A fast obstacle down column 6 has crossed
    # row 5 (ticks 4-6) before the robot gets near: no arrival without a safety radius.
    traffic = Traffic(world, [MovingObstacle((6.0, 0.0), (0.0, 1.0))])
    assert traffic.arrival(route, 0.5, 0.0, radius=0) is None
    # A slow one is at (6, t / 2); with radius 1 it reaches |dx| < 2, |dy| < 2: |5 - t / 2| < 2
    # for 7 <= t <= 13 and |6 - t // 2| < 2 from t = 10.
    slow = Traffic(world, [MovingObstacle((6.0, 0.0), (0.0, 0.5))])
    assert slow.arrival(route, 0.5, 0.0, radius=1) == 10.0
    # seen later, from tick 4 on the rest of the route
    assert slow.arrival(route[2:], 0.5, 4.0, radius=1) == 6.0
    assert slow.arrival(route, 0.5, 0.0, radius=1, horizon=9) is None


def test_the_estimator_is_the_plugins_and_sets_t_d() -> None:
    assert PLUGIN.critical_events == (obstacle_arrival,)
    assert EVENTS.get("obstacle-arrival") is None  # importing the plugin registers nothing
    world = _open(16)
    traffic = Traffic(world, [MovingObstacle((6.0, 0.0), (0.0, 0.5))])
    plan = Plan(0.0, [(x, 5) for x in range(16)], 0.5)
    clock = WorkClock()
    deadline = deadline_from(
        ObstacleSituation(traffic, plan, 0.0), [obstacle_arrival], clock, margin=2
    )
    assert deadline.event == "obstacle-arrival"
    cost = deadline.estimates[0].cost
    assert cost >= 1 and deadline.t_d == 10.0 - cost - 2


def test_preconditions_on_hand_built_maps() -> None:
    blocked = np.zeros((8, 8), dtype=bool)
    blocked[2, 4] = True  # a wall just north of (4, 3)
    world = World(blocked, (0, 3), (7, 3))
    cells = [(x, 3) for x in range(8)]  # heading east: left is north
    assert not side_clear(world, cells, 4, +1, 2)
    assert side_clear(world, cells, 4, -1, 2)
    # the map's edge on the right (south) of a route along the bottom row
    edge = [(x, 7) for x in range(8)]
    assert not side_clear(world, edge, 3, -1, 1) and side_clear(world, edge, 3, +1, 2)


def test_a_decision_chooses_a_valid_alternative_within_t_d() -> None:
    world = _open(16)
    route = [(x, 8) for x in range(16)]
    traffic = Traffic(world, [MovingObstacle((10.0, 8.0), (0.0, 0.0))])  # parked on the route
    plan = Plan(0.0, route, 0.1)
    clock = WorkClock()
    situation = ObstacleSituation(traffic, plan, 0.0)
    deadline = deadline_from(situation, [obstacle_arrival], clock, margin=20)
    decision = decide_best(situation, deadline, clock)
    assert decision.within and decision.chosen in ("detour-left", "detour-right")
    names = [o.name for o in decision.outcomes]
    assert names == ["detour-left", "detour-right", "wait"]
    wait = decision.outcomes[2]
    assert wait.applicable and wait.quality is None  # a parked obstacle never passes
    assert decision.plan is not None
    assert traffic.first_conflict(decision.plan, decision.plan.start, 1, 400) is None


def test_random_obstacles_are_reproducible_and_clear_of_start_and_goal() -> None:
    world = random_world(32, seed=3, density=0.1)
    obstacles = random_obstacles(world, 5, seed=7)
    assert obstacles == random_obstacles(world, 5, seed=7)
    for obstacle in obstacles:
        x, y = obstacle.position
        for gx, gy in (world.start, world.goal):
            assert max(abs(x - gx), abs(y - gy)) > 8
        assert obstacle.fits(world.blocked)


@pytest.mark.parametrize("seed", range(30), ids=lambda s: f"seed{s}")
def test_the_robot_never_collides_and_decides_within_t_d(seed: int) -> None:
    world = random_world(32, seed=seed, density=0.1)
    found = find_path(world.blocked, world.start, world.goal)
    assert found is not None
    report = simulate(world, random_obstacles(world, 2, seed), found.path, 0.1)
    assert report.reached_goal
    assert report.collisions == 0
    for decision in report.decisions:
        if decision.outcomes:  # deliberated (with no time left the robot keeps its plan)
            assert decision.within, decision
