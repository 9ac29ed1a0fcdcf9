"""Where a library finds its entries (`Source`, what one gives: `Loaded`), and installed
plugins: the `Plugin` object a plugin's entry point names, and `PluginSource`, which finds and
loads them through the entry-point group `anytime.plugins`."""

from __future__ import annotations

import argparse
import types
from collections.abc import Callable, Iterable, Mapping
from importlib import metadata
from typing import Any, Protocol

from attrs import field, frozen

from anytime.entries import LibraryEntry
from anytime.modules import REGISTRY, AnytimeModule, Registry
from anytime.problems import (
    Measurement,
    ProgramProblems,
)

#: The entry-point group installed plugins register under.
PLUGIN_GROUP = "anytime.plugins"


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
            except (Exception, SystemExit, GeneratorExit) as error:  # a plugin's failure
                # (its sys.exit() at import too) must not break the others nor the command
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
