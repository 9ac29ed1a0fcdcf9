"""Shared fixtures: paths of the shipped files."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def navigation_any() -> Path:
    return ROOT / "schemas" / "navigation.any"
