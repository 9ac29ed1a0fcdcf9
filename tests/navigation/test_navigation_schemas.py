"""Every schema of `schemas/navigation.any` compiles against the navigation plugin's modules
and measured profiles, and the hierarchical one runs end to end: plan with the compiled
`navigate`, then follow the plan in the world."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from anytime_navigation.resources import data_file
from anytime_navigation.task.execution import Execution
from anytime_navigation.task.vision import Sensor
from anytime_navigation.world import random_world

from anytime import AnytimeLibrary, compile_file, load_schemas
from anytime.runtime import run_program

SCHEMAS = Path(str(data_file("schemas", "navigation.any")))
GRID = np.arange(0.0, 2001.0, 250.0)


def test_every_schema_of_the_file_compiles() -> None:
    compiled = compile_file(load_schemas(SCHEMAS), AnytimeLibrary.default(), GRID)
    assert [c.name for c in compiled] == [
        "navigate",
        "navigate-nested",
        "navigate-two-planners",
        "sense-plan-act",
    ]
    by_name = {c.name: c for c in compiled}
    np.testing.assert_allclose(by_name["navigate"].expected, by_name["navigate-nested"].expected)
    assert by_name["navigate-two-planners"].modules == (
        "get-domain-description",
        "find-path",
        "a-star",
    )
    assert "DAG" in by_name["navigate-two-planners"].note
    for program in compiled:  # never worse with more time
        assert (np.diff(program.expected, axis=-1) >= -1e-12).all()


def test_sense_plan_act_plans_then_walks_to_the_goal() -> None:
    (navigate, act) = compile_file(
        load_schemas(SCHEMAS), AnytimeLibrary.default(), GRID, schema="sense-plan-act"
    )
    world = random_world(64, seed=5)
    sensor = Sensor(world.blocked, seed=5)
    result = run_program(act, [world.start, world.goal, sensor], 1000).result
    walked = result.value
    assert isinstance(walked, Execution)
    assert walked.reached and walked.route[0] == world.start and walked.route[-1] == world.goal
    assert 0.0 < result.quality <= 1.0
