"""Compilation: a program schema plus the library's profiles -> a contract algorithm.

`compile_program` fills the papers' table: for every program input quality and every total time
T on the grid, the allocation of T among the anytime modules that maximises expected output
quality, the output-quality distribution it gives and its expectation. The result, a
`CompiledProgram`, is a contract algorithm with an ordinary conditional performance profile, so
schemas compose hierarchically (`compile_file` compiles callees first). A `CompiledProgram` is
data; the runtime runs it (`anytime.runtime.run_program`, `program_module`).
Every compilation also reports the baselines of the papers' Figures 8/10 (equal
split, MIN and MAX for the first module) and, where that search is small, the gap to the
exhaustive optimum. The search runs within a memory cap (`memory=`): allocations are evaluated
in chunks, and a table whose search cannot fit is refused before it starts.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from anytime.compiler.allocators import ALLOCATORS, DEFAULT_MEMORY, Exhaustive, dp_obstacle
from anytime.compiler.allocators.lattice import equal_split
from anytime.compiler.allocators.memory import (
    check_memory,
    chunk_rows,
    expected_in_chunks,
    row_bytes,
)
from anytime.compiler.dist import Dist, binned_profile
from anytime.compiler.evaluate import Evaluator
from anytime.compiler.grids import (
    DEFAULT_INPUT_QUALITY,
    callee_grid,
    check_quality_grid,
    check_resolution,
    check_time_grid,
    default_time_grid,
    memory_bytes,
)
from anytime.compiler.loops import loop_profiles
from anytime.compiler.model import (
    ChoiceNode,
    CompileError,
    CompileModel,
    CompileNode,
    IfNode,
    ModuleNode,
    Timed,
)
from anytime.compiler.outcomes import Code, Note
from anytime.compiler.resolve import build_model
from anytime.compiler.result import CompiledProgram
from anytime.dsl.program import Program, SchemaFile
from anytime.dsl.source import Source
from anytime.library import AnytimeLibrary
from anytime.profiles.profile import (
    Array,
    ConditionalPerformanceProfile,
    default_bins,
)
from anytime.vocabulary import first_useful_time

__all__ = [
    "ALLOCATORS",
    "ALLOCATOR_NAMES",
    "AUTO_EXHAUSTIVE_PER_CELL",
    "DEFAULT_INPUT_QUALITY",
    "REFERENCE_WORK",
    "CompiledProgram",
    "callee_grid",
    "compile_file",
    "compile_program",
    "default_time_grid",
    "evaluate_in_chunks",
    "memory_bytes",
]

#: The names an allocator may be asked for by: "auto" chooses (see `_choose`).
ALLOCATOR_NAMES = ("auto", *ALLOCATORS)

#: "auto" runs the exhaustive search (exact) where it evaluates at most this many allocations
#: per cell of the table, about what the multi-start search evaluates itself.
AUTO_EXHAUSTIVE_PER_CELL = 1_000
#: The exhaustive reference behind `exhaustive_gap` is run where its allocations times the
#: bytes of evaluating one (`row_bytes`, a measure of the work) stay below this: a few seconds.
REFERENCE_WORK = 2 * 10**9


def _rows(
    m: int, q_grid: Array, units: NDArray[np.int64]
) -> tuple[tuple[int, ...], Array, NDArray[np.int64]]:
    """The table's cell shape, and one row per cell: the input qualities (rows, m) and the
    total in lattice units (rows,)."""
    if m:
        q_cells = np.stack(np.meshgrid(*([q_grid] * m), indexing="ij"), axis=-1).reshape(-1, m)
    else:
        q_cells = np.zeros((1, 0))
    cell_shape = (len(q_grid),) * m + (len(units),)
    return cell_shape, np.repeat(q_cells, len(units), axis=0), np.tile(units, len(q_cells))


def _gap(
    evaluator: Evaluator,
    q_rows: Array,
    u_rows: NDArray[np.int64],
    dt: float,
    cap: int,
    output: Dist,
) -> float | None:
    """How far below the exhaustive optimum the table is at its worst cell, where the
    exhaustive search is affordable as a reference (None where it is not)."""
    model = evaluator.model
    reference = Exhaustive(cap)
    if not (
        Exhaustive.computable(u_rows, len(model.anytime_nodes))
        and Exhaustive.rows(u_rows, len(model.anytime_nodes)) * row_bytes(model) <= REFERENCE_WORK
        and reference.memory_needed(evaluator, u_rows) <= cap
    ):
        return None
    _, optimum = reference.allocate(evaluator, q_rows, u_rows, dt)
    return float(np.max(optimum - output.expected()))


def compile_program(
    program: Program,
    library: AnytimeLibrary,
    time_grid: ArrayLike,
    input_quality: ArrayLike = DEFAULT_INPUT_QUALITY,
    *,
    allocator: str = "auto",
    resolution: float | None = None,
    source: Source | None = None,
    callees: Mapping[str, CompiledProgram] | None = None,
    memory: int | str = DEFAULT_MEMORY,
    strict: bool = False,
) -> CompiledProgram:
    """Compile one program; the schemas it calls must be compiled already (`callees`, by
    name), or be modules of the library. Errors are placed in `source`, the program's file
    (`SchemaFile.source`).

    Args:
        time_grid: the totals T to fill the table for (increasing, >= 0).
        input_quality: the grid of qualities for every quality-carrying program input.
        allocator: "auto", "dp", "hill-climbing", "exhaustive", "proportional" or
            "multi-start" (see `_choose` for what "auto" picks).
        resolution: the time unit allocations are multiples of (default: the grid's step);
            every T must be a multiple of it.
        memory: the most memory the search may hold at once, in bytes or as a size ("1GB");
            it evaluates in chunks within it, and a table whose search cannot fit is refused
            before it starts (a CompileError with the estimate).
        strict: refuse (a CompileError) a table that feeds a module input qualities outside
            the grid its profile was measured on, instead of warning.
    """
    filename = source.filename if source is not None else "<schema>"
    cap = memory_bytes(memory)
    time = check_time_grid(time_grid, filename)
    dt = check_resolution(time, resolution, filename)
    units = np.rint(time / dt).astype(np.int64)
    q_grid = check_quality_grid(input_quality, filename)
    lattice = np.arange(int(units.max()) + 1) * dt

    def compile_branch(branch: Program) -> CompiledProgram:
        """A branch of an if, on every lattice time up to the largest total."""
        return compile_program(
            branch,
            library,
            lattice,
            callee_grid(q_grid),
            allocator=allocator,
            resolution=dt,
            source=source,
            callees=callees,
            memory=cap,
            strict=strict,
        )

    def compile_loop(
        call: ModuleNode, most: int, name: str
    ) -> tuple[ConditionalPerformanceProfile, ...]:
        """A loop's profiles, on every lattice time up to the largest total."""
        return loop_profiles(call, most, np.asarray(lattice, dtype=np.float64), name)

    model = build_model(program, library, source, compile_branch, callees, compile_loop)
    cell_shape, q_rows, u_rows = _rows(len(model.quality_inputs), q_grid, units)

    evaluator = Evaluator(model)
    n = len(model.anytime_nodes)
    exhaustive_rows = Exhaustive.rows(u_rows, n)
    cheap = exhaustive_rows <= AUTO_EXHAUSTIVE_PER_CELL * len(u_rows)
    chosen = _choose(model, allocator, cheap)
    search = ALLOCATORS[chosen](cap)
    # The search, and the evaluation of the whole table after it.
    needed = search.memory_needed(evaluator, u_rows) + row_bytes(model)
    try:
        check_memory(chosen, needed, cap)
    except CompileError as error:
        raise CompileError(f"schema '{program.name}': {error}", where=filename) from None
    allocation, _ = search.allocate(evaluator, q_rows, u_rows, dt)
    seen: dict[int, list[Dist]] = {}
    output = evaluate_in_chunks(evaluator, q_rows, allocation * dt, cap, seen)
    warnings = outside_input_grids(model, seen)
    if strict and warnings:
        said = "; ".join(warning.message for warning in warnings)
        raise CompileError(f"schema '{program.name}' (--strict): {said}", where=filename)
    allocation, output, kept = _never_worse_with_more_time(allocation, output, len(time))
    baselines = {
        name: expected_in_chunks(evaluator, q_rows, split * dt, cap).reshape(cell_shape)
        for name, split in _baselines(model, u_rows, dt).items()
    }
    gap = 0.0 if chosen == "exhaustive" else _gap(evaluator, q_rows, u_rows, dt, cap, output)
    dependence = None
    if has_best_of(model):
        dependence = np.stack(
            [
                expected_in_chunks(Evaluator(model, bound), q_rows, allocation * dt, cap)
                for bound in ("least", "most")
            ]
        ).reshape(2, *cell_shape)
    profile = _compiled_profile(model, output, q_grid, time, cell_shape)
    return CompiledProgram(
        name=program.name,
        model=model,
        profile=profile,
        allocation=(allocation * dt).reshape(*cell_shape, n),
        allocator=chosen,
        requested=allocator,
        dp_obstacle=dp_obstacle(model),
        standard_error=None if output.error is None else output.error.reshape(cell_shape),
        kept_smaller=tuple(float(t) for t in time[kept]),
        baselines=baselines,
        exhaustive_gap=gap,
        resolution=dt,
        warnings=warnings,
        dependence=dependence,
    )


def has_best_of(model: CompileModel) -> bool:
    """Whether the program has a best-of of several alternatives judged by their quality,
    itself or in a schema it calls or a branch of its ifs (those whose results a dependence
    between the alternatives moves: `CompiledProgram.dependence`)."""
    return bool(_best_ofs(model)) or any(_holds_best_of(node) for node in model.nodes)


def declared_dependence(model: CompileModel) -> float | None:
    """The `:dependence` of the program's best-of where it has exactly one judged by quality,
    of its own (none in a schema it calls or in an if's branch): then its promise is linear in
    it, `(1 - D) * independent + D * least`. None otherwise."""
    choices = _best_ofs(model)
    if len(choices) != 1 or any(_holds_best_of(node) for node in model.nodes):
        return None
    return choices[0].dependence


def _best_ofs(model: CompileModel) -> list[ChoiceNode]:
    """The program's own best-ofs of several alternatives judged by their quality."""
    return [
        node
        for node in model.nodes
        if isinstance(node, ChoiceNode) and len(node.slots) > 1 and not any(node.estimated)
    ]


def _holds_best_of(node: CompileNode) -> bool:
    """Whether a call's schema or an if's branch has such a best-of."""
    if isinstance(node, ModuleNode) and node.callee is not None:
        return node.callee.dependence is not None
    if isinstance(node, IfNode):
        return any(plan.compiled.dependence is not None for plan in node.branches)
    return False


def evaluate_in_chunks(
    evaluator: Evaluator,
    quality: Array,
    allocation: Array,
    memory: int,
    seen: dict[int, list[Dist]] | None = None,
) -> Dist:
    """`evaluator.evaluate` of rows `quality (R, m)`, `allocation (R, n)`, a chunk of rows at a
    time within `memory` bytes (a DAG's shared results multiply the rows it works on), with
    `seen` filled for all of them."""
    step = chunk_rows(evaluator.model, memory)
    parts: list[Dist] = []
    inputs: dict[int, list[list[Dist]]] = {}
    for first in range(0, max(len(allocation), 1), step):
        rows = slice(first, first + step)
        part_seen: dict[int, list[Dist]] = {}
        parts.append(evaluator.evaluate(quality[rows], allocation[rows], seen=part_seen))
        for index, dists in part_seen.items():
            inputs.setdefault(index, []).append(dists)
    if seen is not None:
        for index, chunks in inputs.items():
            seen[index] = [Dist.concatenate(list(column)) for column in zip(*chunks, strict=True)]
    return Dist.concatenate(parts)


def outside_input_grids(model: CompileModel, seen: Mapping[int, list[Dist]]) -> tuple[Note, ...]:
    """A warning (`OUTSIDE_INPUT_GRID`) for every module input that the compiled allocations
    feed qualities outside the input grid its profile was measured on (where the profile is
    only clamped)."""
    warnings: list[Note] = []
    for node in model.anytime_nodes:
        profile = node.profile
        if node.index not in seen:
            continue
        names = profile.inputs or tuple(f"input {i + 1}" for i in range(profile.n_inputs))
        for name, grid, dist in zip(names, profile.input_grids, seen[node.index], strict=False):
            present = (dist.probs > 1e-9) & (dist.values >= 0)  # not no result
            if not present.any():
                continue
            reached = dist.values[present]
            low, high = float(reached.min()), float(reached.max())
            outside = present & ((dist.values < grid[0] - 1e-9) | (dist.values > grid[-1] + 1e-9))
            if not outside.any():
                continue
            # The worst cell: how often an input falls outside, given its share of the time.
            share = float(np.where(outside, dist.probs, 0.0).sum(axis=1).max())
            warnings.append(
                Note.of(
                    Code.OUTSIDE_INPUT_GRID,
                    module=node.name,
                    input=name,
                    low=low,
                    high=high,
                    measured_low=float(grid[0]),
                    measured_high=float(grid[-1]),
                    share=share,
                )
            )
    return tuple(warnings)


def compile_file(
    schemas: SchemaFile,
    library: AnytimeLibrary,
    time_grid: ArrayLike,
    input_quality: ArrayLike = DEFAULT_INPUT_QUALITY,
    *,
    schema: str | None = None,
    allocator: str = "auto",
    resolution: float | None = None,
    memory: int | str = DEFAULT_MEMORY,
    strict: bool = False,
) -> list[CompiledProgram]:
    """Compile the schemas of a file bottom-up (callees first), so that a call of a schema
    uses the callee's compiled profile (and, at run time, runs the callee's program).

    Only `schema` and the schemas it calls are compiled when it is given. A callee is compiled
    on every multiple of the resolution up to the largest total and on `callee_grid`'s input
    qualities, so that its callers can give it any share of their time on the lattice and any
    quality (a schema both asked for and called is compiled once for each role where the two
    grids differ). Returns the compiled programs, callees first. Errors
    are placed in the file's own source (`schemas.source`). `memory` caps each compilation's
    search and `strict` refuses clamped tables (see `compile_program`).
    """
    wanted = [schemas[schema]] if schema is not None else list(schemas.programs)
    called: set[str] = set()
    stack = [callee for p in wanted for callee in p.callees()]
    while stack:
        name = stack.pop()
        if name not in called:
            called.add(name)
            stack.extend(schemas[name].callees())
    top = {p.name for p in wanted}
    time = check_time_grid(time_grid, schemas.filename)
    dt = check_resolution(time, resolution, schemas.filename)
    lattice = np.arange(int(np.rint(time[-1] / dt)) + 1) * dt
    grids = {
        "top": (time, np.asarray(input_quality, dtype=np.float64)),
        "callee": (lattice, callee_grid(input_quality)),
    }
    same = all(np.array_equal(a, b) for a, b in zip(grids["top"], grids["callee"], strict=True))
    callees: dict[str, CompiledProgram] = {}  # as their callers see them
    compiled: dict[str, CompiledProgram] = {}  # as asked for
    for program in schemas.dependency_order():
        roles = [r for r, names in (("callee", called), ("top", top)) if program.name in names]
        for role in roles:
            if role == "top" and "callee" in roles and same:
                compiled[program.name] = callees[program.name]
                continue
            totals, qualities = grids[role]
            result = compile_program(
                program,
                library,
                totals,
                qualities,
                allocator=allocator,
                resolution=dt,
                source=schemas.source,
                callees=callees,
                memory=memory,
                strict=strict,
            )
            (callees if role == "callee" else compiled)[program.name] = result
    order = [p.name for p in schemas.dependency_order()]
    return [
        *(callees[name] for name in order if name in callees and name not in top),
        *(compiled[name] for name in order if name in compiled),
    ]


def _choose(model: CompileModel, allocator: str, cheap: bool = False) -> str:
    """The allocator to run for `allocator` ("auto": dp where it is exact, else exhaustive
    where it is cheap, else multi-start; dp asked for where it is not exact: hill-climbing)."""
    if allocator not in ALLOCATOR_NAMES:
        raise CompileError(
            f"unknown allocator '{allocator}' (expected one of {', '.join(ALLOCATOR_NAMES)})"
        )
    obstacle = dp_obstacle(model)
    if allocator == "auto":
        if obstacle is None:
            return "dp"
        # The exact search where it costs no more than the multi-start's own evaluations.
        return "exhaustive" if cheap else "multi-start"
    if allocator == "dp" and obstacle is not None:
        return "hill-climbing"
    return allocator


def _baselines(model: CompileModel, units: np.ndarray, dt: float) -> dict[str, np.ndarray]:
    """Equal split; MIN and MAX: the first module gets its minimum / maximum useful time (the
    first time its best-input expected quality is above 0 / reaches its maximum), capped by
    T, and the rest is shared equally by the others (the papers' Figures 8 and 10)."""
    nodes = model.anytime_nodes
    n = len(nodes)
    equal = equal_split(units, n) if n else np.zeros((len(units), 0), dtype=np.int64)
    if n == 0:
        return {"equal": equal, "min": equal, "max": equal}
    profile = nodes[0].profile
    assert profile is not None
    best_input = np.ones((len(profile.time), profile.n_inputs))
    curve = profile.expected(best_input, profile.time)
    useful_min = first_useful_time(profile.time, curve)
    useful_max = profile.time[np.argmax(curve >= curve.max() - 1e-12)]
    if isinstance(nodes[0], ModuleNode):  # its share holds its step too
        useful_min, useful_max = useful_min + nodes[0].step, useful_max + nodes[0].step
    result = {"equal": equal}
    for name, useful in (("min", useful_min), ("max", useful_max)):
        first = np.minimum(np.ceil(useful / dt - 1e-9).astype(np.int64), units)
        split = np.zeros((len(units), n), dtype=np.int64)
        split[:, 0] = first if n > 1 else units
        if n > 1:
            split[:, 1:] = equal_split(units - split[:, 0], n - 1)
        result[name] = split
    return result


def _never_worse_with_more_time(
    allocation: np.ndarray, output: Dist, n_times: int
) -> tuple[np.ndarray, Dist, np.ndarray]:
    """A contract program may finish early: at a total T where some smaller total of the grid
    gives a higher expected quality (modules whose profiles fall with time can make it so),
    use the best smaller total's allocation and leave the rest unused. Rows are (input
    quality cell, time) in time-fastest order. Returns the allocation, the output and which
    totals of the grid changed (for some input quality)."""
    expected = output.expected().reshape(-1, n_times)
    best_so_far = np.maximum.accumulate(expected, axis=1)
    steps = np.arange(n_times)
    # The index of the best total up to each one; a total keeps its own allocation unless a
    # smaller one is better by more than rounding.
    own = expected >= best_so_far - 1e-12
    best = np.maximum.accumulate(np.where(own, steps, 0), axis=1)
    changed = np.any(best != steps, axis=0)
    if not changed.any():
        return allocation, output, changed
    rows = (np.arange(expected.shape[0])[:, None] * n_times + best).reshape(-1)
    return allocation[rows], output.rows(rows), changed


def _compiled_profile(
    model: CompileModel, output: Dist, q_grid: Array, time: Array, cell_shape: tuple[int, ...]
) -> ConditionalPerformanceProfile:
    """The output distributions binned (on the output module's bins, or ten equal bins) into
    the program's profile (see `binned_profile`)."""
    bins = default_bins()
    if model.output.kind == "node":
        node = model.node(model.output.index)
        if isinstance(node, Timed):
            bins = node.profile.bins
    return binned_profile(
        output,
        bins,
        input_grids=[q_grid] * len(model.quality_inputs),
        time=time,
        cell_shape=cell_shape,
        inputs=model.quality_inputs,
        module=model.program.name,
        time_unit=model.time_unit,
    )
