"""The catalogue every anytime module must pass, for a plugin's own test suite.

In a domain plugin's tests, run every module of the library that has a registered problem set::

    import pytest
    from anytime import AnytimeLibrary
    from anytime.testing import assert_module_passes, catalogue_cases

    CASES = catalogue_cases(AnytimeLibrary.default())

    @pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
    def test_catalogue(case):
        assert_module_passes(case.module, case.problems, trials=10)

`assert_module_passes` raises `AssertionError` with the whole report. From the command line:
`anytime check MODULE [--trials N]`. The checks and what each requires are described in
`anytime.measure.catalogue`, where they live; this module is the public name for them.
"""

from __future__ import annotations

from anytime.measure.catalogue import (
    CHECKS,
    CatalogueCase,
    CatalogueError,
    CatalogueReport,
    Check,
    assert_module_passes,
    catalogue_cases,
    check_module,
    check_seed,
)

__all__ = [
    "CHECKS",
    "CatalogueCase",
    "CatalogueError",
    "CatalogueReport",
    "Check",
    "assert_module_passes",
    "catalogue_cases",
    "check_module",
    "check_seed",
]
