"""The plugin's data files (schemas, profiles, maps), read as package resources, so that they
are found wherever the distribution is installed (a wheel, an editable checkout, a zip)."""

from __future__ import annotations

from importlib.resources import files
from importlib.resources.abc import Traversable
from pathlib import Path

from anytime import SchemaFile, parse_schemas

__all__ = ["data_file", "load_schema_file", "profile_file"]


def data_file(*parts: str) -> Traversable:
    """The packaged file `parts` (e.g. `data_file("schemas", "navigation.any")`)."""
    return files(__package__ or "anytime_navigation").joinpath(*parts)


def profile_file(name: str) -> str:
    """The packaged profile `profiles/NAME` for a module declared below the package's top (a
    relative `profile=` is read from the declaring module's own package): its path when the
    package is on the file system, else the path relative to a subpackage."""
    resource = data_file("profiles", name)
    return str(resource) if isinstance(resource, Path) else f"../profiles/{name}"


def load_schema_file(name: str) -> SchemaFile:
    """Parse and check the packaged schema file `schemas/NAME`; errors name its installed path."""
    resource = data_file("schemas", name)
    return parse_schemas(resource.read_text(encoding="utf-8"), str(resource))
