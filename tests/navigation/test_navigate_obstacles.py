"""Navigation with moving obstacles, decided with the compiled schema `overcome-obstacle`
(issue 8, part 3): on 30 seeded worlds the robot never collides and every decision it
deliberates is made within T_d on the work clock; `anytime navigate --moving-obstacles` end to
end."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from anytime_navigation.obstacles.crossing import simulate
from anytime_navigation.obstacles.moving import random_obstacles
from anytime_navigation.obstacles.overcoming_modules import schema_decider
from anytime_navigation.planning.search import find_path
from anytime_navigation.world import random_world


@pytest.mark.parametrize("seed", range(30), ids=lambda s: f"seed{s}")
def test_no_collision_and_decisions_within_t_d_with_the_schema(seed: int) -> None:
    world = random_world(32, seed=seed, density=0.1)
    found = find_path(world.blocked, world.start, world.goal)
    assert found is not None
    obstacles = random_obstacles(world, 3, seed)
    report = simulate(world, obstacles, found.path, 0.1, schema_decider(), fallback=True)
    assert report.reached_goal
    assert report.collisions == 0
    for decision in report.decisions:
        if decision.outcomes:  # deliberated (with no time left the robot keeps its plan)
            assert decision.within, decision


def test_navigate_with_moving_obstacles_end_to_end() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "anytime", "navigate"]
        + ["--moving-obstacles", "3", "--size", "64", "--json"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["moving_obstacles"] == 3
    assert result["collisions"] == 0
    assert result["decisions"] >= 0
    assert result["route_length"] >= result["optimal_length"]
