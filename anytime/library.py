"""The anytime library: function names -> modules and their conditional performance profiles.

A library is fed by *sources*, each a small object with a `name` (for messages) and a `load()`
giving `LibraryEntry`s and any problems found:

- `RegistrySource`: modules registered in-process (`registry=` of a decorator, or `Registry.add`);
- `ProfileDirectory`: a directory of profile files (`*.yaml`), each a profile-only entry named by
  its `module` field (a module described by its profile alone: enough to compile a schema);
- `PluginSource`: installed plugins, found through the entry-point group `anytime.plugins`,
  each entry point naming a `Plugin` object (or a function returning one): its modules, how
  `anytime profile` measures them, its critical events and its subcommands.

A name defined by two sources is a `LibraryError` naming both origins, except when both reach
the same module object (a module registered in-process and also listed by a plugin): the entry
then keeps the more specific origin, the plugin's. A plugin that fails to load is
recorded in `problems` with its name and error, and the other plugins still load. Profile files
named by modules are read when a profile is first needed, then cached.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from pathlib import Path

import attrs

from anytime.entries import LibraryEntry, LibraryError, UnknownModuleError
from anytime.modules import REGISTRY, Registry
from anytime.problems import (
    Measurement,
    ProgramProblems,
    registered_measurements,
    registered_problems,
)
from anytime.profiles.dynamic_io import (
    DYNAMIC_SUFFIX,
    TRACES_SUFFIX,
)
from anytime.profiles.io import load_profile
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.sources import (
    PLUGIN_GROUP,
    CommandGroup,
    Loaded,
    Plugin,
    PluginSource,
    Source,
    discover_plugins,
    load_plugins,
)
from anytime.text import did_you_mean, suggest

__all__ = [
    "PLUGIN_GROUP",
    "AnytimeLibrary",
    "CommandGroup",
    "LibraryEntry",
    "LibraryError",
    "Loaded",
    "Plugin",
    "PluginSource",
    "ProfileDirectory",
    "RegistrySource",
    "Source",
    "UnknownModuleError",
    "discover_plugins",
    "load_plugins",
]


class RegistrySource:
    """Modules registered in-process (by default in the process-wide `REGISTRY`: a decorator
    given `registry=REGISTRY`, or `REGISTRY.add`)."""

    generic = True

    def __init__(self, registry: Registry | None = None, name: str = "in-process registry"):
        self.registry = registry if registry is not None else REGISTRY
        self.name = name

    def load(self) -> Loaded:
        entries = tuple(LibraryEntry.of_module(m) for m in self.registry)
        return Loaded(entries, measurements=registered_measurements())


class ProfileDirectory:
    """The profile files `*.yaml` in a directory, each a profile-only entry; a module's dynamic
    profile `NAME.dynamic.yaml` and traces `NAME.traces.yaml` are not profiles (the entry of
    `NAME.yaml` finds its dynamic profile beside it).

    Files are read when the source loads, since a file's `module` field names its entry; a
    malformed file raises its `ProfileError` then.
    """

    generic = False

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.name = f"profile directory {self.path}"

    def load(self) -> Loaded:
        if not self.path.exists():
            raise LibraryError(f"profile directory '{self.path}' does not exist")
        if not self.path.is_dir():
            raise LibraryError(f"profile directory '{self.path}' is not a directory")
        files = sorted(
            f
            for f in self.path.glob("*.yaml")
            if not f.name.endswith((DYNAMIC_SUFFIX, TRACES_SUFFIX))
        )
        return Loaded(tuple(LibraryEntry.of_profile(load_profile(f), f) for f in files))


class AnytimeLibrary:
    """Function name -> `LibraryEntry`, merged from sources when the library is made.

    Names are case-insensitive, as in the DSL. The sources are read once, in order; an entry
    point's plugin is imported then.

    Raises:
        LibraryError: a name is defined by two different modules or profiles.
    """

    def __init__(self, sources: Iterable[Source] = ()) -> None:
        self.sources = tuple(sources)
        self._entries: dict[str, LibraryEntry] = {}
        self._generic: set[str] = set()  # names whose entry came from a generic source
        self._measurements: dict[str, Measurement] = {}
        self._program_problems: dict[str, ProgramProblems] = {}
        problems: list[str] = []
        plugins: list[Plugin] = []
        for source in self.sources:
            loaded = source.load()
            problems.extend(loaded.problems)
            plugins.extend(loaded.plugins)
            for entry in loaded.entries:
                self._add(entry, generic=source.generic)
            for name, measurement in loaded.measurements.items():
                self._measurements.setdefault(name, measurement)
            for name, declared in loaded.program_problems.items():
                self._program_problems.setdefault(name, declared)
        self.problems = tuple(problems)
        self.plugins = tuple(plugins)

    @classmethod
    def default(
        cls,
        profile_dirs: Iterable[str | os.PathLike[str]] = (),
        registry: Registry | None = None,
        plugins: bool = True,
    ) -> AnytimeLibrary:
        """Installed plugins (unless `plugins` is False), then the in-process registry, then
        the profile directories."""
        registry = registry if registry is not None else REGISTRY
        sources: list[Source] = [PluginSource(registry=registry)] if plugins else []
        sources.append(RegistrySource(registry))
        sources.extend(ProfileDirectory(path) for path in profile_dirs)
        return cls(sources)

    def _add(self, entry: LibraryEntry, *, generic: bool) -> None:
        old = self._entries.get(entry.name)
        if old is not None and (old.module is None or old.module is not entry.module):
            raise LibraryError(
                f"module '{entry.name}' is defined twice: in {old.origin} and in {entry.origin}"
            )
        if old is not None and (generic or entry.name not in self._generic):
            return  # the same module again: keep the first specific origin
        self._entries[entry.name] = entry
        if generic:
            self._generic.add(entry.name)
        else:
            self._generic.discard(entry.name)

    def add(self, entry: LibraryEntry, *, replace: bool = False) -> None:
        """Add one entry (a compiled schema, say). A name already taken is a `LibraryError`,
        unless `replace` is set and the entry taking it has the same origin (a recompile)."""
        old = self._entries.get(entry.name)
        if replace and old is not None and old.origin == entry.origin:
            self._entries[entry.name] = entry
            return
        self._add(entry, generic=False)

    def get(self, name: str) -> LibraryEntry | None:
        return self._entries.get(name.lower())

    def __getitem__(self, name: str) -> LibraryEntry:
        entry = self.get(name)
        if entry is None:
            hint = suggest(name.lower(), self._entries)
            raise UnknownModuleError(f"no module named '{name}'{hint}")
        return entry

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.lower() in self._entries

    def __iter__(self) -> Iterator[LibraryEntry]:
        """The entries, by name."""
        return iter([self._entries[name] for name in self.names()])

    def __len__(self) -> int:
        return len(self._entries)

    def names(self) -> tuple[str, ...]:
        return tuple(sorted(self._entries))

    def known_functions(self) -> dict[str, int | None]:
        """Name -> arity (None: not checked), as `anytime.dsl.parse_schemas` takes it."""
        return {entry.name: entry.arity for entry in self}

    def measurement(self, name: str) -> Measurement:
        """How `anytime profile` measures module `name` (its problem set and grid).

        Raises:
            BuildError: no source declares one; the message lists those that do.
        """
        return registered_problems(name, self._measurements)

    def program_problems(self, schema: str) -> ProgramProblems:
        """The problems `anytime verify` runs schema `schema` on, as a plugin declares them
        (`Plugin.program_problems`; the first plugin's, by entry-point name, where two do).

        Raises:
            LibraryError: no plugin declares any; the message lists the schemas that have them.
        """
        found = self._program_problems.get(schema.lower())
        if found is not None:
            return found
        known = sorted(self._program_problems)
        head = f"no program problem set is declared for schema '{schema}'"
        hint = did_you_mean(schema.lower(), known)
        if hint:
            raise LibraryError(head + hint)
        listed = ", ".join(known) if known else "none"
        raise LibraryError(
            f"{head} (declared for: {listed}); a plugin declares them in Plugin.program_problems"
        )

    def profile(self, name: str) -> ConditionalPerformanceProfile | None:
        """The profile of `name` (read on first use); None for a module without one."""
        return self[name].profile

    def with_profile(self, name: str, profile: ConditionalPerformanceProfile) -> AnytimeLibrary:
        """A copy of the library in which module `name` has `profile` (a profile measured
        again, say); the sources are not read again."""
        entry = self[name]
        copy = object.__new__(AnytimeLibrary)
        copy.__dict__.update(self.__dict__)
        copy._entries = dict(self._entries)
        copy._generic = set(self._generic)
        copy._entries[entry.name] = attrs.evolve(entry, profile_source=profile, profile_file=None)
        return copy

    def __repr__(self) -> str:
        return f"<AnytimeLibrary of {len(self)} modules from {len(self.sources)} sources>"
