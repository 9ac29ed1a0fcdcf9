"""A library's entries: a module (or a profile alone) and its conditional performance
profile, read when first needed, with its dynamic profile and its steps."""

from __future__ import annotations

import inspect
import warnings
from pathlib import Path

import numpy as np
from attrs import field, frozen

from anytime.errors import AnytimeError, ProfileError
from anytime.modules import AnytimeModule
from anytime.profiles.dynamic import DynamicProfile
from anytime.profiles.dynamic_io import (
    dynamic_profile_path,
    load_dynamic_profile,
)
from anytime.profiles.io import load_profile
from anytime.profiles.profile import ConditionalPerformanceProfile


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
        stale = _other_build(dynamic, self.profile)
        if stale:  # measured apart: it describes some other run of the module than the profile
            warnings.warn(
                f"{path}: not from the build that measured {self.profile_file} (they differ"
                f" in their {stale}); measure both again with `anytime profile {self.name}"
                " --dynamic`",
                StaleProfileWarning,
                stacklevel=2,
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


class StaleProfileWarning(UserWarning):
    """A dynamic profile that is not from the build that measured the profile beside it."""


def _other_build(dynamic: DynamicProfile, profile: ConditionalPerformanceProfile | None) -> str:
    """What tells a dynamic profile from another build than the profile's ('' if nothing
    does): `anytime profile --dynamic` writes both from one build, on one grid; a profile
    measured again on another grid leaves the old dynamic profile beside it. (File times cannot
    tell: a checkout or a wheel sets them as it likes; the number of trials may differ on
    purpose.)"""
    if profile is None:
        return ""
    differ = []
    if not np.array_equal(dynamic.time, profile.time):
        differ.append("time grid")
    if len(dynamic.input_grids) != len(profile.input_grids) or not all(
        np.array_equal(a, b) for a, b in zip(dynamic.input_grids, profile.input_grids, strict=False)
    ):
        differ.append("input-quality grids")
    return " and ".join(differ)
