"""The framework's shared words, one home each: time units, profile and module kinds, quality
reports, the read-only array field of its frozen classes, and the rule for a profile's first
useful time.

Like `errors` and `text`, this module imports nothing of the framework: every layer may use it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from attrs import cmp_using, field
from numpy.typing import ArrayLike, DTypeLike, NDArray

# --- words -----------------------------------------------------------------------------------

#: The unit of a clock and of a profile's time axis: reported units of work, or seconds.
Unit = Literal["ticks", "seconds"]
UNITS: tuple[Unit, ...] = ("ticks", "seconds")

#: What a profile describes: a module that may be interrupted, or one given a contract.
ProfileKind = Literal["interruptible", "contract"]
PROFILE_KINDS: tuple[ProfileKind, ...] = ("interruptible", "contract")

#: What a module is: a profile's two kinds, or an elementary function (no profile, no time).
ModuleKind = Literal["interruptible", "contract", "elementary"]
MODULE_KINDS: tuple[ModuleKind, ...] = ("interruptible", "contract", "elementary")

#: What a module's `Result.quality` is (and so what a dynamic profile's state is): its true
#: quality (as its problem set scores it), its own estimate of it (not calibrated), or nothing
#: to go by.
QualityReport = Literal["true", "estimate", "none"]
QUALITY_REPORTS: tuple[QualityReport, ...] = ("true", "estimate", "none")

# --- read-only arrays ------------------------------------------------------------------------


def read_only(value: ArrayLike, dtype: DTypeLike | None = np.float64) -> NDArray[Any]:
    """`value` as a new array that cannot be written (`dtype=None`: numpy's own choice)."""
    array: NDArray[Any] = np.array(value, dtype=dtype)
    array.setflags(write=False)
    return array


def read_only_or_none(value: ArrayLike | None) -> NDArray[np.float64] | None:
    return None if value is None else read_only(value)


def read_only_tuple(value: Sequence[ArrayLike]) -> tuple[NDArray[np.float64], ...]:
    return tuple(read_only(item) for item in value)


def _equal_or_none(a: NDArray[Any] | None, b: NDArray[Any] | None) -> bool:
    return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))


def _equal_tuples(a: tuple[NDArray[Any], ...], b: tuple[NDArray[Any], ...]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def array_field(*, dtype: DTypeLike | None = np.float64, **kwargs: Any) -> Any:
    """An attrs field holding a read-only array (a copy of what it is given, of `dtype`),
    compared by value and left out of the hash."""

    def convert(value: ArrayLike) -> NDArray[Any]:
        return read_only(value, dtype)

    return field(converter=convert, eq=cmp_using(eq=np.array_equal), hash=False, **kwargs)


def optional_array_field(**kwargs: Any) -> Any:
    """`array_field` of floats that may be None (its default)."""
    kwargs.setdefault("default", None)
    return field(converter=read_only_or_none, eq=cmp_using(eq=_equal_or_none), hash=False, **kwargs)


def arrays_field(**kwargs: Any) -> Any:
    """A field holding a tuple of read-only float arrays (a profile's input grids)."""
    return field(converter=read_only_tuple, eq=cmp_using(eq=_equal_tuples), hash=False, **kwargs)


# --- the first useful time -------------------------------------------------------------------

#: Expected qualities closer than this count as equal (the rounding of an interpolation).
QUALITY_TOLERANCE = 1e-12


def first_useful_time(time: ArrayLike, quality: ArrayLike, *, over_start: bool = False) -> float:
    """The first time of a profile's grid `time` at which its expected quality `quality` (one
    per time, with perfect inputs) is above 0: the least time that gives something. A profile
    that never gives anything has the last time of its grid.

    `over_start`: the first time at which the quality rises above what the profile gives at the
    grid's first time (and so with any less time); its first time if it never does. This is
    Romanenko's `T*`, the weight of his proportional split: a module that gives something with
    no time (a fallback answer) still needs time to improve, and a weight of 0 would give it
    none.
    """
    grid = np.asarray(time, dtype=np.float64)
    curve = np.asarray(quality, dtype=np.float64)
    if over_start:
        better = curve > curve[0] + QUALITY_TOLERANCE
        return float(grid[np.argmax(better)] if np.any(better) else grid[0])
    useful = curve > QUALITY_TOLERANCE
    return float(grid[np.argmax(useful)] if np.any(useful) else grid[-1])
