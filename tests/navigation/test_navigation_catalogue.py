"""The navigation plugin's anytime modules pass the module catalogue (`anytime.testing`), on
their registered problem sets, as `anytime check MODULE` runs it."""

from __future__ import annotations

import numpy as np
import pytest
from anytime_navigation.modules import PROBLEM_SETS, find_path, get_domain_description

from anytime.testing import assert_module_passes


def test_vision_passes_the_catalogue() -> None:
    problems = PROBLEM_SETS["get-domain-description"].problems
    report = assert_module_passes(get_domain_description, problems, trials=4)
    assert report.passed


def test_the_planner_passes_the_catalogue_on_a_coarse_grid() -> None:
    """A few times and map qualities keep it fast; `make slow` runs the registered grid."""
    problems = PROBLEM_SETS["find-path"].problems
    report = assert_module_passes(
        find_path,
        problems,
        trials=3,
        time=np.array([0.0, 300.0, 800.0, 2000.0]),
        input_grids=[[0.6, 0.9, 1.0]],
        tolerance=0.2,
    )
    assert report.passed


@pytest.mark.slow
def test_the_planner_passes_the_catalogue_on_its_registered_grid() -> None:
    problems = PROBLEM_SETS["find-path"].problems
    assert_module_passes(find_path, problems, trials=10)
