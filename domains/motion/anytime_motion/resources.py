"""The plugin's data files (schemas, profiles), read as package resources, so that they are
found wherever the distribution is installed (a wheel, an editable checkout, a zip)."""

from __future__ import annotations

from importlib.resources import files
from importlib.resources.abc import Traversable

from anytime import SchemaFile, parse_schemas

__all__ = ["SCHEMA_FILE", "data_file", "load_schema_file"]

#: The packaged schema file: the chain `move` and the DAG `move-best`.
SCHEMA_FILE = "motion.any"


def data_file(*parts: str) -> Traversable:
    """The packaged file `parts` (e.g. `data_file("schemas", "motion.any")`)."""
    return files(__package__ or "anytime_motion").joinpath(*parts)


def load_schema_file(name: str = SCHEMA_FILE) -> SchemaFile:
    """Parse and check the packaged schema file `schemas/NAME`; errors name its installed path."""
    resource = data_file("schemas", name)
    return parse_schemas(resource.read_text(encoding="utf-8"), str(resource))
