"""A plugin that cannot be imported: the library reports it and loads the others."""

import nope_not_installed  # noqa: F401
