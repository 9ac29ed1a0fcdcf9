"""What a compilation is asked for, checked: the time grid and its resolution, the grid of
input qualities, the memory cap, and their defaults (a callee's grid, a schema's totals)."""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import ArrayLike

from anytime.compiler.model import CompileError
from anytime.dsl.program import Call, SchemaCall, SchemaFile
from anytime.library import AnytimeLibrary
from anytime.profiles.profile import Array

#: The default grid of program input qualities: 0, 0.1, ..., 1.
DEFAULT_INPUT_QUALITY = tuple(float(q) for q in np.round(np.linspace(0, 1, 11), 12))

_UNITS = {"b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9, "tb": 10**12}
_UNITS |= {"kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}


def memory_bytes(memory: int | str) -> int:
    """A memory cap in bytes: a number of bytes, or a size such as "512MB", "1.5GB", "2GiB"
    (kB, MB, GB, TB: powers of 1000; KiB, MiB, GiB, TiB: of 1024)."""
    if isinstance(memory, str):
        match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([a-zA-Z]*)\s*", memory)
        unit = match.group(2).lower() if match else ""
        if match is None or (unit and unit not in _UNITS):
            raise CompileError(
                f"memory: expected a size such as 512MB, 1GB or 2GiB, got '{memory}'"
            )
        size = float(match.group(1)) * _UNITS[unit or "b"]
    else:
        size = memory
    if not size >= 1:
        raise CompileError(f"memory: expected at least one byte, got {memory!r}")
    return int(size)


def callee_grid(input_quality: ArrayLike) -> Array:
    """The input-quality grid a called schema or an if's branch is compiled on: the program's
    grid and the default one together, so that every quality a result computed in the program
    can reach it with, 0 to 1, lies within the grid (the callee runs the allocation its table
    gives at the quality that reaches it, never a clamped one)."""
    merged = np.union1d(np.asarray(input_quality, dtype=np.float64), DEFAULT_INPUT_QUALITY)
    keep = np.concatenate([[True], np.diff(merged) > 1e-9])
    grid: Array = merged[keep]
    return grid


def check_time_grid(grid: ArrayLike, filename: str) -> Array:
    """The totals to fill a table for: at least one, each >= 0, increasing."""
    time = np.asarray(grid, dtype=np.float64)
    if time.ndim != 1 or len(time) == 0:
        raise CompileError(
            "time grid: expected at least one total time, got none",
            where=filename,
        )
    if not np.all(np.isfinite(time)) or np.any(time < 0):
        raise CompileError(
            f"time grid: expected times >= 0, got {time[~(time >= 0)][0]:g}",
            where=filename,
        )
    if np.any(np.diff(time) <= 0):
        raise CompileError("time grid: expected increasing times", where=filename)
    return time


def check_resolution(time: Array, resolution: float | None, filename: str) -> float:
    """The lattice unit allocations are multiples of (default: the grid's least step), of
    which every total must be a multiple."""
    if resolution is None:
        steps = np.diff(time)
        resolution = float(steps.min()) if len(steps) else float(time[0]) or 1.0
    if not resolution > 0:
        raise CompileError(
            f"time resolution: expected a number > 0, got {resolution:g}",
            where=filename,
        )
    off = np.abs(time / resolution - np.rint(time / resolution)) > 1e-9
    if np.any(off):
        raise CompileError(
            f"time grid: every total must be a multiple of the resolution "
            f"{resolution:g} "
            f"(allocations are whole multiples of it), got {time[off][0]:g}",
            where=filename,
        )
    return float(resolution)


def check_quality_grid(grid: ArrayLike, filename: str) -> Array:
    """The grid of program input qualities: at least one, each in [0, 1], increasing."""
    q = np.asarray(grid, dtype=np.float64)
    if q.ndim != 1 or len(q) == 0:
        raise CompileError(
            "input quality: expected at least one quality, got none",
            where=filename,
        )
    if not np.all((q >= 0) & (q <= 1)):
        bad = q[~((q >= 0) & (q <= 1))][0]
        raise CompileError(
            f"input quality: expected qualities in [0, 1], got {bad:g}",
            where=filename,
        )
    if np.any(np.diff(q) <= 0):
        raise CompileError("input quality: expected increasing qualities", where=filename)
    return q


def default_time_grid(
    schemas: SchemaFile, library: AnytimeLibrary, schema: str | None = None
) -> list[float]:
    """0 to the sum of the longest profiled times of the modules the schemas call (beyond it no
    module has anything more to give), in about 20 round steps."""
    programs = [schemas[schema]] if schema is not None else list(schemas.programs)
    seen: set[str] = set()
    total = 0.0
    while programs:
        program = programs.pop()
        for call in program.walk():
            if isinstance(call, SchemaCall):
                if call.schema not in seen:
                    seen.add(call.schema)
                    programs.append(schemas[call.schema])
                continue
            if not isinstance(call, Call):
                continue
            entry = library.get(call.function)
            profile = entry.profile if entry is not None and entry.kind != "elementary" else None
            if profile is not None:
                total += float(profile.time[-1])
    if total <= 0:
        return [0.0]
    raw = total / 20
    magnitude = 10 ** np.floor(np.log10(raw))
    step = float(min(m * magnitude for m in (1, 2, 5, 10) if m * magnitude >= raw))
    count = int(np.ceil(total / step - 1e-9))
    return [i * step for i in range(count + 1)]
