"""The schema of the situation "obstacle overcoming" (`schemas/obstacles.any`): it parses,
compiles with the compiler's split and with Romanenko's proportional one (the compiled split
never worse in expected quality), decides a hand-built situation within T_d, and its
alternatives are measured on the encounters its program problem set draws."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from anytime_navigation.obstacles.moving import MovingObstacle, Plan, Traffic
from anytime_navigation.obstacles.overcoming import (
    Candidate,
    ObstacleSituation,
    encounter_at,
    obstacle_arrival,
)
from anytime_navigation.obstacles.overcoming_modules import (
    PROBLEM_SETS,
    SCHEMA_FILE,
    Attempt,
    all_applicable,
    can_wait,
    left_clear,
    overcoming_program,
    right_clear,
    schema_decider,
)
from anytime_navigation.program_problems import PROGRAM_PROBLEMS
from anytime_navigation.world import World

from anytime.clocks import WorkClock
from anytime.dsl import BestOf, Var, load_schemas
from anytime.runtime.deadline import deadline_from


def test_the_schema_parses() -> None:
    program = load_schemas(SCHEMA_FILE)["overcome-obstacle"]
    assert program.inputs == ("situation",)
    (choice,) = program.steps
    assert isinstance(choice, BestOf)
    assert [(a.precondition and a.precondition.function, a.value) for a in choice.alternatives] == [
        ("left-clear?", Var("t5")), ("right-clear?", Var("t6")), ("can-wait?", Var("t7")),
    ]  # fmt: skip
    assert [s.target for s in program.walk()] == ["t2", "t3", "t4", "t5", "t6", "t7", "t1"]


def test_it_compiles_and_the_compiled_split_is_never_worse_than_proportional() -> None:
    auto = overcoming_program("auto")
    proportional = overcoming_program("proportional")
    assert set(auto.modules) == {"detour-left", "detour-right", "wait"}
    np.testing.assert_allclose(auto.allocation.sum(axis=-1), auto.profile.time, atol=1e-9)
    assert np.all(auto.expected >= proportional.expected - 1e-9)
    assert np.all(auto.expected >= auto.baselines["equal"] - 1e-9)


def test_anytime_compile_works_on_the_file() -> None:
    for extra in ([], ["--allocator", "proportional"]):
        done = subprocess.run(
            [sys.executable, "-m", "anytime", "compile", str(SCHEMA_FILE)]
            + ["--schema", "overcome-obstacle", *extra],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr
        assert "overcome-obstacle" in done.stdout


def test_the_schema_decides_a_parked_obstacle_within_t_d() -> None:
    world = World(np.zeros((16, 16), dtype=bool), (0, 0), (15, 15))
    traffic = Traffic(world, [MovingObstacle((10.0, 8.0), (0.0, 0.0))])  # parked on the route
    plan = Plan(0.0, [(x, 8) for x in range(16)], 0.1)
    clock = WorkClock()
    situation = ObstacleSituation(traffic, plan, 0.0)
    deadline = deadline_from(situation, [obstacle_arrival], clock, margin=20)
    encounter = encounter_at(situation, deadline)
    assert left_clear(encounter) and right_clear(encounter) and not can_wait(encounter)
    decision = schema_decider()(situation, deadline, clock)
    assert decision.within and decision.chosen in ("detour-left", "detour-right")
    assert [o.name for o in decision.outcomes] == ["detour-left", "detour-right", "wait"]
    assert not decision.outcomes[2].applicable
    assert decision.plan is not None
    assert traffic.first_conflict(decision.plan, decision.plan.start, 1, 400) is None


def test_the_alternatives_are_measured_on_the_program_problem_sets_encounters() -> None:
    """Each alternative's problem set draws what the program problem set of
    `overcome-obstacle` draws from the same seed (an encounter where every alternative
    applies: the compiled best-of is promised for those), and the program problem set scores
    an alternative's result as the alternative's own does. (An encounter may be shared: the
    alternatives write nothing into it, their outcomes are in the program's record.)"""
    program = PROGRAM_PROBLEMS["overcome-obstacle"].problems
    assert set(PROBLEM_SETS) == {"detour-left", "detour-right", "wait"}
    for seed in range(3):
        (drawn,) = program.instance(np.random.default_rng(seed)).args
        assert all_applicable(drawn)
        for measurement in PROBLEM_SETS.values():
            (own,) = measurement.problems.instance(np.random.default_rng(seed), ()).args
            assert (own.conflict, own.plan) == (drawn.conflict, drawn.plan)
    instance = program.instance(np.random.default_rng(0))
    plan = instance.args[0].plan
    for name, measurement in PROBLEM_SETS.items():
        for value in (Attempt(name, Candidate(plan, 0.7)), Attempt(name, None), None):
            assert program.score_step(instance, name, value) == measurement.problems.score(
                instance, value
            )
    assert program.score_step(instance, "wait", Attempt("wait", Candidate(plan, 0.7))) == 0.7
    with pytest.raises(ValueError, match="no true quality for module 'left-clear\\?'"):
        program.score_step(instance, "left-clear?", True)
