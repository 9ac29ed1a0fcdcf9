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

import argparse
import inspect
import os
import types
from collections.abc import Callable, Iterable, Iterator, Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, Protocol

import attrs
from attrs import field, frozen

from anytime.errors import AnytimeError, ProfileError
from anytime.modules import REGISTRY, AnytimeModule, Registry
from anytime.problems import (
    Measurement,
    ProgramProblems,
    registered_measurements,
    registered_problems,
)
from anytime.profiles.dynamic import DynamicProfile
from anytime.profiles.dynamic_io import (
    DYNAMIC_SUFFIX,
    TRACES_SUFFIX,
    dynamic_profile_path,
    load_dynamic_profile,
)
from anytime.profiles.io import load_profile
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.text import did_you_mean, suggest

#: The entry-point group installed plugins register under.
PLUGIN_GROUP = "anytime.plugins"


class LibraryError(AnytimeError, ValueError):
    """The library's sources disagree (a name defined twice) or one cannot be read."""


class UnknownModuleError(LibraryError, KeyError):
    """No module of the library has the name asked for; the message suggests the closest."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


@frozen(eq=False)
class LibraryEntry:
    """One function of the library: a module with code, or a profile alone.

    Attributes:
        name: the function name schemas call it by (lower case).
        kind: "interruptible", "contract" or "elementary".
        inputs: the quality-carrying inputs (the profile's input axes, in order).
        parameters: the positional parameters a call passes (none known for a profile-only
            entry).
        arity: the number of positional arguments a call must pass, or None when it may vary
            (a parameter with a default, `*args`) or is unknown (a profile-only entry).
        origin: where it was defined, for messages: "plugin 'navigation' (anytime_navigation)",
            "python module tests.x", "profile file profiles/a.yaml".
        module: the module, or None for a profile-only entry.
        profile_source: the profile, the path of its file, or None.
        profile_file: the file the profile comes from, if it is not built in memory.
        step: (a property) the module's step, declared or else measured (see `step`).
        dynamic_profile: (a property) its dynamic profile, the file `NAME.dynamic.yaml` beside
            its profile file `NAME.yaml`, or None.
    """

    name: str
    kind: str
    inputs: tuple[str, ...]
    parameters: tuple[str, ...]
    arity: int | None
    origin: str
    module: AnytimeModule | None = None
    profile_source: ConditionalPerformanceProfile | Path | None = None
    profile_file: Path | None = None
    _cache: dict[str, ConditionalPerformanceProfile] = field(factory=dict, init=False, repr=False)
    _dynamic: list[DynamicProfile | None] = field(factory=list, init=False, repr=False)

    @classmethod
    def of_module(cls, module: AnytimeModule, origin: str | None = None) -> LibraryEntry:
        """The entry of a module with code (`origin` defaults to the module's own)."""
        source = module.profile_source
        file = None
        if source is not None and not isinstance(source, ConditionalPerformanceProfile):
            source = file = Path(source)
        return cls(
            name=module.name.lower(),
            kind=module.kind,
            inputs=module.inputs,
            parameters=module.parameters,
            arity=_arity(module),
            origin=origin if origin is not None else module.origin,
            module=module,
            profile_source=source,
            profile_file=file,
        )

    @classmethod
    def of_profile(cls, profile: ConditionalPerformanceProfile, path: Path) -> LibraryEntry:
        """A profile-only entry, from the profile file at `path`."""
        return cls(
            name=profile.module.lower(),
            kind=profile.kind,
            inputs=profile.inputs,
            parameters=(),
            arity=None,
            origin=f"profile file {path}",
            profile_source=profile,
            profile_file=path,
        )

    @property
    def profile(self) -> ConditionalPerformanceProfile | None:
        """The conditional performance profile, read from its file on first use.

        Raises:
            ProfileError: the file is missing or malformed, or does not describe this module
                (another module's name, another kind, other inputs); the message names the file.
        """
        if self.profile_source is None:
            return None
        cached = self._cache.get("profile")
        if cached is None:
            cached = self._load()
            self._cache["profile"] = cached
        return cached

    @property
    def dynamic_profile(self) -> DynamicProfile | None:
        """The dynamic profile, the file `NAME.dynamic.yaml` beside the profile file `NAME.yaml`
        (in a profile directory or a plugin's package data), read on first use; None when the
        profile is not a file or has no such file beside it.

        Raises:
            ProfileError: the file is malformed or does not describe this module (another
                module's name, other inputs); the message names the file.
        """
        if not self._dynamic:  # read once, even when there is none
            self._dynamic.append(self._load_dynamic())
        return self._dynamic[0]

    def _load_dynamic(self) -> DynamicProfile | None:
        if self.profile_file is None:
            return None
        path = dynamic_profile_path(self.profile_file)
        if not path.is_file():
            return None
        dynamic = load_dynamic_profile(path)
        if dynamic.module.lower() != self.name:
            raise ProfileError(
                f"{path}: module: expected '{self.name}' (the module it is the dynamic profile"
                f" of), got '{dynamic.module}'"
            )
        if len(dynamic.input_grids) != len(self.inputs) or (
            dynamic.inputs and dynamic.inputs != self.inputs
        ):
            given = list(dynamic.inputs) or f"{len(dynamic.input_grids)} unnamed"
            raise ProfileError(
                f"{path}: inputs: expected the module's inputs {list(self.inputs)}, got {given}"
            )
        return dynamic

    @property
    def declared_step(self) -> float | None:
        """The step the module declares (`step=` of its decorator), or None."""
        return None if self.module is None else self.module.step

    @property
    def measured_step(self) -> float | None:
        """The step its profile records (measured by the profile builder), or None: no
        profile, or one without a step (a file written before profiles had one, a compiled
        program's, a tabulated one). Reads the profile like `profile`, with its errors."""
        profile = self.profile
        return None if profile is None else profile.step

    @property
    def step(self) -> float | None:
        """The most time the module can use past any moment before it next registers a result
        or returns (interruptible), or past its allocation (contract), in its profile's time
        unit: its declared step if it declares one, else its profile's measured step, else None
        (unknown). Reads the profile when the module declares none (its `ProfileError`s)."""
        declared = self.declared_step
        return declared if declared is not None else self.measured_step

    def _load(self) -> ConditionalPerformanceProfile:
        source = self.profile_source
        if isinstance(source, ConditionalPerformanceProfile):
            if self.module is not None:
                _check_axes(source, self, f"module '{self.name}' ({self.origin}): profile")
            return source
        assert source is not None  # `profile` returns None first
        if not source.exists():
            raise ProfileError(
                f"{source}: no such profile file (the profile of module '{self.name}',"
                f" from {self.origin})"
            )
        profile = load_profile(source)
        if profile.module and profile.module.lower() != self.name:
            raise ProfileError(
                f"{source}: module: expected '{self.name}' (the module it is the profile of),"
                f" got '{profile.module}'"
            )
        if self.kind != "elementary" and profile.kind != self.kind:
            raise ProfileError(
                f"{source}: kind: expected '{self.kind}' (module '{self.name}' is {self.kind}),"
                f" got '{profile.kind}'"
            )
        _check_axes(profile, self, str(source))
        return profile


def _check_axes(profile: ConditionalPerformanceProfile, entry: LibraryEntry, where: str) -> None:
    """A module's profile has one input axis per declared input, named alike when named."""
    if profile.n_inputs != len(entry.inputs) or (
        profile.inputs and tuple(profile.inputs) != entry.inputs
    ):
        n = profile.n_inputs
        given = f"{n} unnamed input {'axis' if n == 1 else 'axes'}" if n else "no input axis"
        if profile.inputs:
            given = f"[{', '.join(profile.inputs)}]"
        raise ProfileError(
            f"{where}: inputs: expected [{', '.join(entry.inputs)}] (the inputs of module"
            f" '{entry.name}'), got {given}"
        )


def _arity(module: AnytimeModule) -> int | None:
    """How many positional arguments a call passes, when that is fixed."""
    try:
        signature = inspect.signature(module.function)
    except (TypeError, ValueError):
        return None
    for parameter in signature.parameters.values():
        if parameter.kind is parameter.VAR_POSITIONAL:
            return None
        if parameter.name in module.parameters and parameter.default is not parameter.empty:
            return None
    return module.arity


class CommandGroup(Protocol):
    """Where a plugin adds its subcommands (`Plugin.add_commands` receives one)."""

    def add_command(
        self,
        name: str,
        *,
        help: str,
        run: Callable[[argparse.Namespace], int],
        description: str | None = None,
    ) -> argparse.ArgumentParser:
        """Add `anytime NAME`: returns its parser, to add arguments to. `run(args)` returns the
        exit status; an `AnytimeError` it raises is printed as one line (exit 1), a
        `UsageError` too (exit 2)."""
        ...


def _as_tuple(values: Iterable[Any]) -> tuple[Any, ...]:
    return tuple(values)


def _check_modules(_: Any, attribute: Any, values: tuple[Any, ...]) -> None:
    for index, value in enumerate(values):
        if not isinstance(value, AnytimeModule):
            raise TypeError(
                f"Plugin.{attribute.name}[{index}]: expected an anytime module, got"
                f" {value!r} ({type(value).__name__})"
            )


def _check_measurements(_: Any, attribute: Any, values: Mapping[str, Any]) -> None:
    for name, value in values.items():
        if not isinstance(value, Measurement):
            raise TypeError(
                f"Plugin.problem_sets[{name!r}]: expected a Measurement (Measurement.of(problems,"
                f" time=...)), got {type(value).__name__}"
            )


def _check_program_problems(_: Any, attribute: Any, values: Mapping[str, Any]) -> None:
    for name, value in values.items():
        if not isinstance(value, ProgramProblems):
            raise TypeError(
                f"Plugin.program_problems[{name!r}]: expected ProgramProblems"
                f" (ProgramProblems.of(problems)), got {type(value).__name__}"
            )


def _lower_keys(values: Mapping[str, Any]) -> Mapping[str, Any]:
    return types.MappingProxyType({name.lower(): m for name, m in values.items()})


@frozen
class Plugin:
    """What a plugin gives the framework; the object its `anytime.plugins` entry point names.

    Attributes:
        name: the plugin's name, for messages.
        modules: its anytime modules (made with `anytime.plugin`'s decorators, which register
            nothing by themselves).
        problem_sets: module name -> how `anytime profile` / `check` / `calibrate` measure it.
        critical_events: its critical-event estimators (made with `critical_event`).
        add_commands: a function adding the plugin's subcommands to a `CommandGroup`.
        program_problems: schema name -> the problems `anytime verify` runs the compiled
            schema on (`ProgramProblems.of(problems)`, see `anytime.problems`).
    """

    name: str
    modules: tuple[AnytimeModule, ...] = field(
        default=(), converter=_as_tuple, validator=_check_modules
    )
    problem_sets: Mapping[str, Measurement] = field(
        factory=dict, converter=_lower_keys, validator=_check_measurements
    )
    critical_events: tuple[AnytimeModule, ...] = field(
        default=(), converter=_as_tuple, validator=_check_modules
    )
    add_commands: Callable[[CommandGroup], None] | None = None
    program_problems: Mapping[str, ProgramProblems] = field(
        factory=dict, converter=_lower_keys, validator=_check_program_problems
    )


@frozen
class Loaded:
    """What one source gave: its entries, the measurements of its modules, the plugins it
    loaded, the program problem sets of its schemas, and the problems it reported instead of
    raising."""

    entries: tuple[LibraryEntry, ...] = ()
    problems: tuple[str, ...] = ()
    measurements: Mapping[str, Measurement] = field(factory=dict)
    plugins: tuple[Plugin, ...] = ()
    program_problems: Mapping[str, ProgramProblems] = field(factory=dict)


class Source(Protocol):
    """Where a library finds entries."""

    @property
    def name(self) -> str:
        """What the source is called in messages."""
        ...

    #: True when an entry's origin yields to another source's that reaches the same module
    #: (the in-process registry holds the modules that plugins registered on import).
    generic: bool

    def load(self) -> Loaded:
        """Read the source now."""
        ...


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


class PluginSource:
    """Installed plugins: the entry points of group `anytime.plugins`.

    An entry point's object is a `Plugin`, or a function returning one. For plugins written
    before `Plugin` existed it may also be a Python module (its top-level `AnytimeModule`s and
    those its import added to `registry` are the plugin's), a callable returning anytime
    modules, or one `AnytimeModule`. A plugin that fails to import, raises, or gives anything
    else is reported as a problem naming it, and the others still load.

    Args:
        entry_points: the entry points to load (default: those installed, found when loading).
        registry: the registry an old-style plugin's import may fill (default: the process-wide
            one).
    """

    generic = False
    name = "installed plugins"

    def __init__(
        self,
        entry_points: Iterable[metadata.EntryPoint] | None = None,
        registry: Registry | None = None,
    ) -> None:
        self.entry_points = None if entry_points is None else tuple(entry_points)
        self.registry = registry if registry is not None else REGISTRY

    def load(self) -> Loaded:
        found = self.entry_points
        if found is None:
            found = discover_plugins()
        entries: list[LibraryEntry] = []
        problems: list[str] = []
        measurements: dict[str, Measurement] = {}
        program_problems: dict[str, ProgramProblems] = {}
        plugins: list[Plugin] = []
        for entry_point in found:
            label = f"plugin '{entry_point.name}' ({entry_point.value})"
            try:
                plugin = self._plugin(entry_point)
            except Exception as error:  # a plugin's failure must not break the others
                problems.append(f"{label}: {type(error).__name__}: {_one_line(error)}")
                continue
            plugins.append(plugin)
            entries.extend(LibraryEntry.of_module(m, origin=label) for m in plugin.modules)
            measurements.update(plugin.problem_sets)
            for name, declared in plugin.program_problems.items():
                program_problems.setdefault(name, declared)
        return Loaded(
            tuple(entries), tuple(problems), measurements, tuple(plugins), program_problems
        )

    def _plugin(self, entry_point: metadata.EntryPoint) -> Plugin:
        before = set(map(id, self.registry))
        loaded: Any = entry_point.load()
        if isinstance(loaded, Plugin):
            return loaded
        found: Iterable[Any]
        if isinstance(loaded, AnytimeModule):
            found = [loaded]
        elif isinstance(loaded, types.ModuleType):
            attributes = [v for v in vars(loaded).values() if isinstance(v, AnytimeModule)]
            found = [*attributes, *(m for m in self.registry if id(m) not in before)]
        elif callable(loaded):
            found = loaded()
            if isinstance(found, Plugin):
                return found
        else:
            raise TypeError(
                f"expected a Plugin, a function returning one, a Python module or anytime"
                f" modules, got {type(loaded).__name__}"
            )
        modules: dict[int, AnytimeModule] = {}
        for item in found:
            if not isinstance(item, AnytimeModule):
                raise TypeError(f"expected anytime modules, got {item!r} ({type(item).__name__})")
            modules.setdefault(id(item), item)
        return Plugin(entry_point.name, tuple(modules.values()))


def load_plugins() -> tuple[tuple[Plugin, ...], tuple[str, ...]]:
    """The installed plugins, and the problems of those that failed to load."""
    loaded = PluginSource().load()
    return loaded.plugins, loaded.problems


def discover_plugins(group: str = PLUGIN_GROUP) -> tuple[metadata.EntryPoint, ...]:
    """The installed entry points of `group`, sorted by name."""
    return tuple(sorted(metadata.entry_points(group=group), key=lambda ep: ep.name))


def _one_line(error: BaseException) -> str:
    text = str(error).strip()
    return " ".join(text.split()) if text else "(no message)"


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
