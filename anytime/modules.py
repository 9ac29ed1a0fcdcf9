"""The module protocol: how an anytime module is written and declared.

Every value that flows between modules is a `Result(value, quality)`. A module receives a
`Context` as its first argument and reports its work with `ctx.tick(n)`:

- an **interruptible** module is a generator that yields successively better `Result`s (the
  papers' REGISTER-RESULT); whatever it yielded last is the answer when time runs out;
- a **contract** module reads its allocation from `ctx.allocation` and returns one `Result`, or
  None when it has none;
- an **elementary** function takes no context and no time; its output quality is a declared
  combination of its inputs' qualities (by default the minimum).

The decorators (one family: `anytime.interruptible` and `anytime.plugin.interruptible` are the
same function) check the function against what they declare and return the declared
`AnytimeModule`; they register it nowhere unless given a `registry`. A plugin lists its modules
in its `Plugin` object, so importing it changes nothing in the process; at the prompt,
`registry=REGISTRY` adds a module to the process's own registry, which
`AnytimeLibrary.default()` reads.
"""

from __future__ import annotations

import importlib
import inspect
import math
import numbers
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import attrs
import numpy as np
from attrs import field, frozen

from anytime.clocks import Clock, WorkClock
from anytime.errors import AnytimeError
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.vocabulary import QUALITY_REPORTS, ModuleKind, QualityReport

ProfileSource = ConditionalPerformanceProfile | str | os.PathLike[str] | None


class ModuleError(AnytimeError, TypeError):
    """A module's definition does not match what it declares; the message names the module."""


class RegistrationError(AnytimeError, ValueError):
    """Two different modules claim one name; the message names both origins."""


def _quality(value: float) -> float:
    q = float(value)
    if not 0.0 <= q <= 1.0 or math.isnan(q):
        raise ValueError(f"a Result's quality must be in [0, 1], got {value!r}")
    return q


class Missing:
    """The value a module that declares `accepts_missing` gets for an input whose producer
    registered no result (every other module is then not called: its step has no result)."""

    value = None
    quality = 0.0

    def __bool__(self) -> bool:
        return False

    def __repr__(self) -> str:
        return "MISSING"

    def __reduce__(self) -> str:
        return "MISSING"


#: The one `Missing` value.
MISSING = Missing()


@frozen
class Result:
    """A value and its quality in [0, 1]."""

    value: Any
    quality: float = field(converter=_quality)


_SLACK = 1e-9  # relative rounding tolerated when comparing elapsed time with an allocation


class Context:
    """What a running module sees of its time.

    Args:
        allocation: the time the module is given (in the clock's unit); infinite by default.
        clock: where time comes from (a fresh `WorkClock` by default).
        stop: set from outside to interrupt the module (it then reads `expired` as True).
    """

    def __init__(
        self,
        allocation: float = math.inf,
        clock: Clock | None = None,
        stop: threading.Event | None = None,
    ) -> None:
        self.allocation = float(allocation)
        self.clock: Clock = clock if clock is not None else WorkClock()
        self.stop = stop if stop is not None else threading.Event()
        self.start = self.clock.now()
        self.ticks = 0.0

    def tick(self, n: float = 1) -> None:
        """Report `n` units of work: a finite number, 0 or more (NaN would make every later
        time NaN and every deadline test false; negative work would turn the clock back)."""
        if not (n >= 0 and math.isfinite(n)):  # NaN fails both tests
            raise ValueError(f"ctx.tick({n!r}): work must be a finite number of units, 0 or more")
        self.ticks += n
        self.clock.advance(n)

    @property
    def elapsed(self) -> float:
        return self.clock.now() - self.start

    @property
    def remaining(self) -> float:
        """Time left; 0 once within rounding of the allocation (so that reporting the remainder
        as work always ends it, even where the clock's value is too large to move by it)."""
        left = self.allocation - self.elapsed
        if math.isinf(self.allocation):
            return left
        return left if left > _SLACK * max(1.0, abs(self.allocation)) else 0.0

    @property
    def expired(self) -> bool:
        """True once the allocation is spent or the module was asked to stop."""
        return self.stop.is_set() or self.remaining == 0.0


def _min_quality(qualities: Sequence[float]) -> float:
    return min(qualities, default=1.0)


def _as_float(value: Any) -> Any:
    """A real number (not a bool) as a float; anything else as given, for the validator."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_):
        return float(value)
    return value


def _check_step(module: AnytimeModule, _: attrs.Attribute[Any], step: object) -> None:
    """A declared step is a finite number >= 0 (or None); the message names the module."""
    if step is None:
        return
    if not (isinstance(step, float) and math.isfinite(step) and step >= 0):
        where = f"module '{module.name}' ({_qualified(module.function)})"
        got = f"{step:g}" if isinstance(step, float) else repr(step)
        raise ModuleError(
            f"{where}: step: expected a finite number >= 0 (the most time it uses before its"
            f" next result or its return; None: not declared), got {got}"
        )


@frozen(eq=False)
class AnytimeModule:
    """A registered module: its function, what it declares, and where it came from.

    Attributes:
        name: the function name schemas call it by (lower case).
        kind: "interruptible", "contract" or "elementary".
        function: the Python function.
        parameters: the function's positional parameters after the context.
        inputs: the quality-carrying inputs among them (the profile's input axes, in order).
        profile: the conditional performance profile, a path to its file, or None.
        combine: for an elementary function, how input qualities make the output's.
        origin: where it was defined, for messages ("python module x.y", "plugin nav", ...).
        accepts_missing: whether it is called when an input has no result (with `MISSING` for
            it); otherwise it is not called, and its step has no result either.
        reports: what its `Result.quality` is: "true" (its true quality, the one its profile
            was measured in), "estimate" (its own estimate) or "none". For a module that does
            not report its true quality the runtime decides by its profile instead: it keeps
            the latest result (not the one with the highest self-report), and a best-of's
            choice and adaptive re-allocation use the profile's prediction for the time used.
        step: the most time it can use past any moment before it next registers a result or
            returns, in its profile's time unit (ticks on the work clock), or None (not
            declared; its measured profile may know it). For an interruptible module the
            largest gap between successive results, counting from its start to the first and
            from the last to its end; for a contract module the most it may use past its
            allocation. It bounds how far a run can overshoot the time it is given.
    """

    name: str
    kind: ModuleKind
    function: Callable[..., Any]
    parameters: tuple[str, ...]
    inputs: tuple[str, ...]
    profile_source: ProfileSource = None
    combine: Callable[[Sequence[float]], float] = _min_quality
    origin: str = ""
    probability: float | None = None  # an elementary test's chance of being true (for `if`)
    accepts_missing: bool = False  # called with `MISSING` for an input that has no result
    reports: QualityReport = "true"
    step: float | None = field(default=None, converter=_as_float, validator=_check_step)

    @property
    def arity(self) -> int:
        return len(self.parameters)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.function(*args, **kwargs)

    def __repr__(self) -> str:
        return f"<{self.kind} module {self.name!r} from {self.origin}>"

    def __reduce__(self) -> tuple[Any, ...]:
        # Pickled by reference, as functions are, so that process pools and Dask workers get
        # the very module: the decorated name in its Python module is this object. A module
        # that is not importable by that name (one made by `make_interruptible`, say) pickles
        # by value, which works when its function does.
        where = (self.function.__module__, self.function.__qualname__)
        try:
            found = _import_object(*where)
        except Exception:  # not importable by that name: by value
            found = None
        if found is self:
            return (_import_object, where)
        return (_rebuild, (type(self), attrs.asdict(self, recurse=False)))


def _import_object(module: str, qualname: str) -> Any:
    target: Any = importlib.import_module(module)
    for part in qualname.split("."):
        target = getattr(target, part)
    return target


def _rebuild(kind: type[AnytimeModule], fields: dict[str, Any]) -> AnytimeModule:
    return kind(**fields)


class Registry:
    """Modules by name. Registering the same function again replaces it (a reloaded module);
    a different function under a taken name is a `RegistrationError` naming both origins."""

    def __init__(self) -> None:
        self._modules: dict[str, AnytimeModule] = {}
        self._lock = threading.Lock()  # the check and the write are one step (threads racing)

    def add(self, module: AnytimeModule) -> AnytimeModule:
        with self._lock:
            old = self._modules.get(module.name)
            if old is not None and _qualified(old.function) != _qualified(module.function):
                raise RegistrationError(
                    f"module '{module.name}' is defined twice: in {old.origin} and in"
                    f" {module.origin}"
                )
            self._modules[module.name] = module
        return module

    def remove(self, name: str) -> None:
        with self._lock:
            self._modules.pop(name.lower(), None)

    def get(self, name: str) -> AnytimeModule | None:
        return self._modules.get(name.lower())

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.lower() in self._modules

    def __iter__(self) -> Iterator[AnytimeModule]:
        return iter(list(self._modules.values()))

    def __len__(self) -> int:
        return len(self._modules)


#: The process's own registry, one of the sources of `AnytimeLibrary.default()`: the decorators
#: add a module to it when given `registry=REGISTRY` (never by default).
REGISTRY = Registry()


def _qualified(function: Callable[..., Any]) -> str:
    return f"{function.__module__}.{function.__qualname__}"


def _declare(
    function: Callable[..., Any],
    *,
    name: str | None,
    kind: ModuleKind,
    inputs: Sequence[str] | None,
    profile: ProfileSource,
    combine: Callable[[Sequence[float]], float] = _min_quality,
    registry: Registry | None,
    probability: float | None = None,
    accepts_missing: bool = False,
    reports: QualityReport = "true",
    step: float | None = None,
) -> AnytimeModule:
    module_name = (name or function.__name__.replace("_", "-")).lower()
    where = f"module '{module_name}' ({_qualified(function)})"
    signature = inspect.signature(function)
    positional = [
        p.name
        for p in signature.parameters.values()
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
    ]
    if reports not in QUALITY_REPORTS:
        raise ModuleError(
            f"{where}: reports must be one of {', '.join(QUALITY_REPORTS)}, got {reports!r}"
        )
    if kind == "interruptible" and not inspect.isgeneratorfunction(function):
        raise ModuleError(f"{where}: an interruptible module must be a generator (use yield)")
    if kind != "interruptible" and inspect.isgeneratorfunction(function):
        raise ModuleError(f"{where}: a {kind} module must return its Result, not yield")
    if kind != "elementary":
        if not positional or positional[0] != "ctx":
            raise ModuleError(f"{where}: the first parameter must be the context, 'ctx'")
        positional = positional[1:]
    declared = list(positional if inputs is None else inputs)
    for input_name in declared:
        if input_name not in positional:
            raise ModuleError(
                f"{where}: declared input '{input_name}' is not a parameter of the function "
                f"(parameters: {', '.join(positional) or 'none'})"
            )
    if len(set(declared)) != len(declared):
        raise ModuleError(f"{where}: an input is declared twice: {', '.join(declared)}")
    if profile is not None and not isinstance(profile, ConditionalPerformanceProfile):
        profile = _beside(function, Path(profile))
    module = AnytimeModule(
        name=module_name,
        kind=kind,
        function=function,
        parameters=tuple(positional),
        inputs=tuple(declared),
        profile_source=profile,
        combine=combine,
        origin=f"python module {function.__module__}",
        probability=probability,
        accepts_missing=accepts_missing,
        reports=reports,
        step=step,
    )
    return module if registry is None else registry.add(module)


def _beside(function: Callable[..., Any], path: Path) -> Path:
    """A relative profile path is relative to the defining module's package, read as a package
    resource (so that it is found in an installed wheel), else to the defining file."""
    if path.is_absolute():
        return path
    package = getattr(sys.modules.get(function.__module__), "__package__", None)
    if package:
        root = resources.files(package)
        if isinstance(root, Path):  # a package on the file system (not inside a zip)
            return root / path
    source = inspect.getsourcefile(function)
    return Path(source).parent / path if source is not None else path


def interruptible(
    name: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    profile: ProfileSource = None,
    accepts_missing: bool = False,
    reports: QualityReport = "true",
    step: float | None = None,
    registry: Registry | None = None,
) -> Callable[[Callable[..., Iterator[Result]]], AnytimeModule]:
    """Declare a generator `f(ctx, *args)` that yields successively better `Result`s.

    Args:
        name: the name schemas call it by (default: the function's, with '-' for '_').
        inputs: the quality-carrying parameters, in profile-axis order (default: all).
        profile: its conditional performance profile, or the path of its profile file (a
            relative path is a file of the defining module's package, else beside its file).
        accepts_missing: call it even when an input has no result, with `MISSING` for it
            (default: it is not called, and has no result either).
        reports: what its `Result.quality` is: "true" (default), "estimate" or "none" (see
            `AnytimeModule`).
        step: the largest gap between its successive results (from its start to the first,
            from the last to its return), in its profile's time unit, if known (see
            `AnytimeModule`; `anytime profile` measures it otherwise).
        registry: a `Registry` to add it to as well (default: none; a plugin lists its modules
            in its `Plugin` instead).
    """

    def decorate(function: Callable[..., Iterator[Result]]) -> AnytimeModule:
        return _declare(
            function,
            name=name,
            kind="interruptible",
            inputs=inputs,
            profile=profile,
            registry=registry,
            accepts_missing=accepts_missing,
            reports=reports,
            step=step,
        )

    return decorate


def contract(
    name: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    profile: ProfileSource = None,
    accepts_missing: bool = False,
    reports: QualityReport = "true",
    step: float | None = None,
    registry: Registry | None = None,
) -> Callable[[Callable[..., Result | None]], AnytimeModule]:
    """Declare a function `f(ctx, *args) -> Result` that reads `ctx.allocation` up front (it
    returns None when it has no result).

    Arguments as for `interruptible`, except `step`: the most it may use past its allocation.
    """

    def decorate(function: Callable[..., Result | None]) -> AnytimeModule:
        return _declare(
            function,
            name=name,
            kind="contract",
            inputs=inputs,
            profile=profile,
            registry=registry,
            accepts_missing=accepts_missing,
            reports=reports,
            step=step,
        )

    return decorate


def elementary(
    name: str | None = None,
    *,
    inputs: Sequence[str] | None = None,
    combine: Callable[[Sequence[float]], float] | None = None,
    probability: float | None = None,
    accepts_missing: bool = False,
    registry: Registry | None = None,
) -> Callable[[Callable[..., Any]], AnytimeModule]:
    """Declare a plain function `f(*args)` that takes no time and no context.

    Quality-carrying inputs arrive as `Result`s, as they do for anytime modules. It returns a
    plain value, whose quality is `combine` of its inputs' qualities (default: the minimum).
    `probability`, for a test used as the condition of an `if`, is the chance it is true.
    `registry` as for `interruptible`.
    """
    if probability is not None and not 0 <= probability <= 1:
        raise ModuleError(f"elementary '{name}': probability must be in [0, 1], got {probability}")

    def decorate(function: Callable[..., Any]) -> AnytimeModule:
        return _declare(
            function,
            name=name,
            kind="elementary",
            inputs=inputs,
            profile=None,
            combine=_min_quality if combine is None else combine,
            registry=registry,
            probability=probability,
            accepts_missing=accepts_missing,
        )

    return decorate
