"""The public API is small and explicit: every name in `__all__` resolves."""

import importlib

import pytest

import anytime


@pytest.mark.parametrize(
    "module",
    [
        "anytime",
        "anytime.compiler",
        "anytime.dsl",
        "anytime.profiles",
        "anytime.measure.builder",
        "anytime.plugin",
        "anytime.plugin.cli",
        "anytime.plugin.figures",
        "anytime.plugin.compose",
        "anytime.plugin.solvers",
    ],
)
def test_every_name_in_all_resolves(module: str) -> None:
    mod = importlib.import_module(module)
    missing = [name for name in mod.__all__ if not hasattr(mod, name)]
    assert missing == []
    assert len(set(mod.__all__)) == len(mod.__all__)


def test_version_is_the_distribution_version() -> None:
    from importlib.metadata import version

    assert anytime.__version__ == version("anytime-compose")


def test_errors_derive_from_the_builtins_they_resemble() -> None:
    assert issubclass(anytime.SchemaSyntaxError, SyntaxError)
    assert issubclass(anytime.SchemaSyntaxError, anytime.SchemaError)
    assert issubclass(anytime.SchemaError, anytime.AnytimeError)
