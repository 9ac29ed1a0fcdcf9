"""Elementary functions' quality combinations as array functions, for the evaluator: min and
max vectorised (and known to be monotone), any other combination applied point by point."""

from __future__ import annotations

import builtins
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from attrs import frozen


def least(q: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """The minimum along axis 0; 1 for no inputs (the modules' default combination)."""
    return np.min(q, axis=0) if len(q) else np.ones(q.shape[1:])


def most(q: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """The maximum along axis 0."""
    most: np.ndarray[Any, Any] = np.max(q, axis=0)
    return most


@frozen
class Pointwise:
    """Any other combination, applied to one combination of input qualities at a time (a
    class, not a closure, so that a compiled program pickles with it)."""

    combine: Callable[[Sequence[float]], float]

    def __call__(self, q: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        flat = q.reshape(len(q), -1)
        out = np.array([self.combine(list(column)) for column in flat.T], dtype=np.float64)
        return out.reshape(q.shape[1:])


COMBINATIONS: dict[Callable[..., Any], Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]]] = {
    builtins.min: least,
    builtins.max: most,
}


def vector_combine(
    combine: Callable[[Sequence[float]], float],
) -> tuple[Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]], bool]:
    """An array version of an elementary function's quality combination, and whether it is
    known to be monotone (min and max are; any other function is applied point by point)."""
    name = getattr(combine, "__name__", "")
    if combine in COMBINATIONS:
        return COMBINATIONS[combine], True
    if name == "_min_quality":  # the modules' default: min, with 1.0 for no inputs
        return least, True
    return Pointwise(combine), False
