"""The plugin's data files (schemas, profiles, maps), read as package resources, so that they
are found wherever the distribution is installed (a wheel, an editable checkout, a zip)."""

from __future__ import annotations

from importlib.resources import files
from importlib.resources.abc import Traversable

from anytime import SchemaFile, parse_schemas

__all__ = ["data_file", "load_schema_file"]


def data_file(*parts: str) -> Traversable:
    """The packaged file `parts` (e.g. `data_file("schemas", "navigation.any")`)."""
    return files(__package__ or "anytime_navigation").joinpath(*parts)


def load_schema_file(name: str) -> SchemaFile:
    """Parse and check the packaged schema file `schemas/NAME`; errors name its installed path."""
    resource = data_file("schemas", name)
    return parse_schemas(resource.read_text(encoding="utf-8"), str(resource))
