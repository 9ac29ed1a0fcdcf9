"""The protocol the compiler uses of an allocator, and of what it evaluates allocations with.

An allocator is made with a memory cap in bytes (`AllocatorClass`); the compiler asks it for
the least memory its search holds for a table's totals (`memory_needed`, so that a table that
cannot fit is refused before it starts) and then for the table (`allocate`): for rows of
program input qualities `quality (C, m)` and totals `units (C,)` in lattice units of `dt`, the
allocations `(C, n)` in units and their expected output qualities `(C,)`.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from anytime.compiler.model import CompileModel
from anytime.profiles.profile import Array


class Evaluates(Protocol):
    """What the allocators need of an evaluator: batched expected quality (an `Evaluator`, or
    one restricted to some positions of the allocation, see `reallocate`)."""

    @property
    def model(self) -> CompileModel: ...

    @property
    def n_modules(self) -> int: ...

    def expected(self, quality: ArrayLike, allocation: ArrayLike) -> Array: ...


class Allocator(Protocol):
    """A time allocator, as the compiler runs it."""

    name: str

    def memory_needed(self, evaluator: Evaluates, units: np.ndarray) -> int:
        """The bytes the search holds at the least (with its smallest chunks) for these
        totals, so that a table that cannot fit the cap is refused before it starts."""
        ...

    def allocate(
        self, evaluator: Evaluates, quality: Array, units: np.ndarray, dt: float
    ) -> tuple[np.ndarray, Array]:
        """Allocations `(C, n)` in units, and their expected output qualities `(C,)`."""
        ...


class AllocatorClass(Protocol):
    """An allocator's class: made with the memory cap its search keeps within."""

    def __call__(self, memory: int = ...) -> Allocator: ...


def nothing_to_allocate(
    evaluator: Evaluates, quality: Array, units: np.ndarray
) -> tuple[np.ndarray, Array]:
    """A program without anytime modules: no time to split, its quality whatever T is."""
    allocation = np.zeros((len(units), 0), dtype=np.int64)
    return allocation, evaluator.expected(quality, allocation)
