"""Measuring a module where the program puts it: on the inputs its upstream modules produce.

A conditional profile says what a module does with an input of each quality, and it is measured
on inputs that its problem set makes for each quality. Where one quality number does not carry
everything the module's result depends on (an estimate's quality says how far off it is, not
on which side; a clustering's, not whether its demand was a prior), the inputs a program feeds
the module at a quality are not the ones the problem set made, and the compiled promise is off
by the difference (`anytime verify` measures by how much).

`measure_upstream` measures the module on what its program feeds it instead. First, in the
calling process, `PROBES` program runs (`probe_pools`): each draws a problem from the schema's
program-level problem set and one of the compiled table's totals, and runs the program up to
the module's call (`anytime.runtime.run_until`, the compiled allocation for that problem and
total). An input lands in the cell of the module's input grid of its qualities' nearest grid
points, and is accepted there when the quality of each quality-carrying argument is within
`TOLERANCE` of the way from the cell's to the next grid point; a cell's pool is the inputs
accepted in it (where none was, every input that landed in it), and its acceptance rate the
accepted ones per program run. The cells the probes land in are the ones the program reaches.

Each trial of the profile builder asks for an input of a cell and chooses it with its own
random stream (so the same seed gives the same profile on any number of workers): from the
cell's pool, uniformly. Where the pool is thin (fewer accepted inputs than the cell has
trials) and the cell is not rare (the probes accepted an input in it at least once in
`FRESH_DRAWS` runs), a trial draws a fresh one instead with probability 1 - pool / trials:
up to 3 / rate program runs (at most `MAX_DRAWS`), the pool's if none is accepted. A rarer
cell spends no program runs on its trials: they take from its pool. A cell with no accepted
input is measured on the module's own problem set where it declares one (an input of the
cell's own quality), else on the inputs that landed in it (so that a program whose inputs
take a few qualities only still measures the cells around them). A cell the program does not
reach is measured on the module's own problem set, as before, where it declares one, else
keeps its current profile's measurement (the program never asks for it). An argument's
quality is its true quality where the problem set scores intermediate results
(`score_step(instance, module, value)`), else the quality the result reports. The module's
result is scored by the problem set: by `score` where the module's call is the program's
output, else by `score_step`.

Reused inputs are not independent samples. t trials choosing among a pool of n inputs, which
is itself a sample of the program's, measure a cell's expected quality with the variance of
n t / (n + t - 1) independent trials (between n / 2 and n for t >= n; about t for n >> t), and
the measured profile says so: a pooled cell's `samples` is that effective count (a lower
bound where some trials drew fresh inputs), so its standard error, the compiled table's
(`CompiledProgram.standard_error`) and `anytime verify`'s allowance are what the pool can
tell, not what the trial count suggests. A module whose result depends on its own random
stream (not only its input) gets more from its trials than that; the count is for the
worst case, a module that does the same on the same input. A cell whose pool is small is
measured coarsely, and measuring with more trials does not help it: more probes would
(`measure_upstream(probes=...)`, `anytime profile --upstream --probes N`).

The allocations depend on the profile and the profile on the allocations, so the measurement
is iterated: compile, measure on the compiled program's inputs, compile again with the new
profile, until the compiled table's expectations move by at most `tolerance` (a fixed point;
a second round usually changes little).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import attrs
import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.compiler.compile import DEFAULT_INPUT_QUALITY, CompiledProgram, compile_file
from anytime.compiler.compile import default_time_grid as default_totals
from anytime.compiler.model import ModuleNode
from anytime.dsl.graph import NodeRef
from anytime.dsl.program import SchemaFile
from anytime.errors import AnytimeError
from anytime.library import AnytimeLibrary
from anytime.measure.builder import build_profile
from anytime.modules import AnytimeModule, Result
from anytime.problems import Instance, ProblemSet, ProgramProblems
from anytime.profiles.profile import Array, ConditionalPerformanceProfile
from anytime.runtime.modes import SOFT, RunMode
from anytime.runtime.program import run_until
from anytime.vocabulary import PROFILE_KINDS

__all__ = [
    "FRESH_DRAWS",
    "MAX_DRAWS",
    "PROBES",
    "TOLERANCE",
    "Pool",
    "Pools",
    "Round",
    "UpstreamError",
    "UpstreamMeasurement",
    "measure_upstream",
    "probe_pools",
]

#: An input is kept for a cell when each of its qualities is within this share of the way
#: from the cell's to the nearest other grid point (0.025 on a grid of step 0.1).
TOLERANCE = 0.25
#: The most program runs a trial draws for a fresh input of its cell.
MAX_DRAWS = 200
#: Program runs drawn first, in the parent, whose inputs are the cells' pools.
PROBES = 1000
#: A trial draws fresh inputs (where its cell's pool is thin) only in a cell where the probes
#: found one in at most this many program runs on average; in a rarer cell it takes from the
#: pool.
FRESH_DRAWS = 20


class UpstreamError(AnytimeError, ValueError):
    """A module cannot be measured on its program's inputs; the message says why."""


@frozen
class _FromProgram:
    """A trial's reference: the program problem its input came from."""

    problem: Instance


@frozen
class _StandIn:
    """A trial's reference for a cell the program does not reach, without a problem set of the
    module's own: its result is replaced by the current profile's cell."""

    problem: Instance


@frozen
class _Own:
    """A trial's reference: the module's own problem set's (its cell was not reached)."""

    reference: Any


#: A drawn program problem, the call's arguments, and their qualities.
_Drawn = tuple[Instance, list[Any], tuple[float, ...]]


@frozen
class Pool:
    """What the probes found in one cell of the module's input grid: `inputs`, the ones within
    `TOLERANCE` of it (`accepted` of them), or where none was, every input that landed in it;
    `rate`, the accepted ones per program run of the probes."""

    inputs: tuple[_Drawn, ...]
    accepted: int
    rate: float


@frozen
class Pools:
    """The probes' inputs, cell by cell (the cells the program reaches), how many program runs
    they took, and the first call they met (a stand-in for the cells the program does not
    reach; None: it never called the module)."""

    cells: Mapping[tuple[float, ...], Pool]
    runs: int
    stand_in: _Drawn | None


class UpstreamProblems:
    """A module's problem set made of what a compiled program feeds it (see the module's
    docstring): `pools` are the probes' inputs in the cells the program reaches, which a trial
    takes from (drawing fresh ones where a cell's pool is thin, fewer than `trials`, and the
    cell is not rare); `fallback`, where the module has a problem set of its own, makes the
    others."""

    def __init__(
        self,
        compiled: CompiledProgram,
        node: ModuleNode,
        problems: ProgramProblems,
        grids: Sequence[ArrayLike],
        fallback: ProblemSet | None,
        pools: Pools | None = None,
        trials: int = 1,
    ) -> None:
        self.compiled, self.node, self.problems = compiled, node, problems
        self.grids = [np.asarray(g, dtype=np.float64) for g in grids]
        self.fallback = fallback
        self.pools = pools if pools is not None else Pools({}, 0, None)
        self.trials = trials
        module = _module(node)
        self.name = module.name
        self.positions = [module.parameters.index(name) for name in module.inputs]
        self.sources = _producers(compiled, node)
        self.is_output = _output(compiled) == node.index

    @property
    def reached(self) -> frozenset[tuple[float, ...]]:
        """The cells the probes' inputs landed in."""
        return frozenset(self.pools.cells)

    def draw(self, rng: np.random.Generator) -> _Drawn | None:
        """One program problem and total, run up to the module's call: the problem, the call's
        arguments and the qualities of its quality-carrying ones (None: the call is not
        made)."""
        totals = self.compiled.profile.time
        problem = self.problems.problems.instance(rng)
        total = float(totals[int(rng.integers(len(totals)))])
        call = run_until(self.compiled, problem.args, total, self.node.index)
        if call is None or not bool(self.node.starts(call.share)) or call.share <= 0:
            return None
        qualities = tuple(self._quality(problem, call.args[p], s) for p, s in self.sources)
        return problem, list(call.args), qualities

    def _cell(self, qualities: tuple[float, ...]) -> tuple[float, ...]:
        """The cell of the input grid qualities land in: each axis's nearest grid point."""
        return tuple(_nearest(g, q) for g, q in zip(self.grids, qualities, strict=True))

    def _accepts(self, qualities: tuple[float, ...], cell: tuple[float, ...]) -> bool:
        """Whether an input of these qualities is kept for `cell`: each within `TOLERANCE` of
        the way to the cell's nearest other grid point (any input, for a module without
        quality-carrying inputs)."""
        return all(
            abs(q - c) <= _width(g, c) for g, q, c in zip(self.grids, qualities, cell, strict=True)
        )

    def instance(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        cell = tuple(float(q) for q in input_qualities)
        pool = self.pools.cells.get(cell)
        if pool is None:  # the program does not reach the cell
            if self.fallback is not None:
                return self._own(rng, input_qualities)
            if self.pools.stand_in is None:
                raise UpstreamError(
                    f"'{self.name}': schema '{self.compiled.name}' did not call it in"
                    f" {self.pools.runs} runs of its problems"
                )
            problem, args, _ = _copied(self.pools.stand_in)  # its result is not kept
            return Instance(self._given(args, cell), _StandIn(problem))
        thin = pool.accepted < self.trials
        if thin and pool.rate * FRESH_DRAWS >= 1 and rng.random() >= pool.accepted / self.trials:
            drawn = self._fresh(rng, cell, min(MAX_DRAWS, math.ceil(3 / pool.rate)))
            if drawn is not None:
                problem, args, _ = drawn
                return Instance(self._given(args, cell), _FromProgram(problem))
        if pool.accepted == 0 and self.fallback is not None:  # its own quality beats a far one
            return self._own(rng, input_qualities)
        problem, args, _ = _copied(pool.inputs[int(rng.integers(len(pool.inputs)))])
        return Instance(self._given(args, cell), _FromProgram(problem))

    def _fresh(
        self, rng: np.random.Generator, cell: tuple[float, ...], draws: int
    ) -> _Drawn | None:
        """The first of up to `draws` program runs whose input is kept for `cell`, or None."""
        for _ in range(draws):
            drawn = self.draw(rng)
            if drawn is not None and self._cell(drawn[2]) == cell and self._accepts(drawn[2], cell):
                return drawn
        return None

    def _own(self, rng: np.random.Generator, input_qualities: tuple[float, ...]) -> Instance:
        assert self.fallback is not None
        own = self.fallback.instance(rng, input_qualities)
        return Instance(own.args, _Own(own.reference))

    def score(self, instance: Instance, value: Any) -> float:
        reference = instance.reference
        if isinstance(reference, _Own):
            assert self.fallback is not None
            return float(self.fallback.score(Instance(instance.args, reference.reference), value))
        problem = reference.problem
        if self.is_output and self.problems.scored:
            return float(self.problems.problems.score(problem, value))  # type: ignore[attr-defined]
        return float(self.problems.problems.score_step(problem, self.name, value))  # type: ignore[attr-defined]

    def _given(self, args: list[Any], cell: tuple[float, ...]) -> tuple[Any, ...]:
        """The call's arguments, each quality-carrying one with the cell's quality (as the
        builder asks)."""
        given = list(args)
        for position, quality in zip(self.positions, cell, strict=True):
            value = (
                given[position].value if isinstance(given[position], Result) else given[position]
            )
            given[position] = Result(value, quality)
        return tuple(given)

    def _quality(self, problem: Instance, argument: Any, source: str | None) -> float:
        """An argument's true quality where the problem set scores it, else its reported one."""
        value = argument.value if isinstance(argument, Result) else argument
        score_step = getattr(self.problems.problems, "score_step", None)
        if source is not None and callable(score_step):
            return float(score_step(problem, source, value))
        return float(argument.quality) if isinstance(argument, Result) else 1.0

    def effective_samples(self) -> Array:
        """The effective sample count of each cell of the input grid (see the module's
        docstring): `trials` where the trials are independent (a cell measured on the module's
        own problem set), n t / (n + t - 1) for a pool of n inputs and t trials (a lower bound
        where some trials drew fresh inputs)."""
        t = self.trials
        mesh = np.meshgrid(*self.grids, indexing="ij")
        points = np.stack([m.reshape(-1) for m in mesh], axis=-1) if mesh else np.zeros((1, 0))
        sizes = np.array(
            [
                _pooled(self.pools.cells.get(tuple(float(q) for q in p)), self.fallback)
                for p in points
            ],
            dtype=np.float64,
        )
        pooled = sizes * t / np.maximum(sizes + t - 1, 1)
        effective = np.where(sizes > 0, np.floor(pooled * 100) / 100, float(t))
        return effective.reshape(tuple(len(g) for g in self.grids))


def _pooled(pool: Pool | None, fallback: ProblemSet | None) -> int:
    """How many inputs a cell's trials take from: its pool's, 0 where they are independent
    (not reached, or nothing accepted and the module's own problem set makes them)."""
    if pool is None or (pool.accepted == 0 and fallback is not None):
        return 0
    return len(pool.inputs)


def _copied(drawn: _Drawn) -> _Drawn:
    """A copy of a pooled input, so that a module that changes its arguments changes no other
    trial's (trials in one process share the pool)."""
    return copy.deepcopy(drawn)


def probe_pools(upstream: UpstreamProblems, seed: int, probes: int = PROBES) -> Pools:
    """`probes` runs of the program's problems (from `seed`), their inputs pooled by the cell
    of the module's input grid they land in (see `Pool`)."""
    rng = np.random.default_rng([seed, 1])
    landed: dict[tuple[float, ...], list[_Drawn]] = {}
    accepted: dict[tuple[float, ...], list[_Drawn]] = {}
    first = None
    for _ in range(probes):
        drawn = upstream.draw(rng)
        if drawn is None:
            continue
        first = drawn if first is None else first
        cell = upstream._cell(drawn[2])
        landed.setdefault(cell, []).append(drawn)
        if upstream._accepts(drawn[2], cell):
            accepted.setdefault(cell, []).append(drawn)
    cells = {}
    for cell, inputs in landed.items():
        kept = accepted.get(cell, [])
        cells[cell] = Pool(tuple(kept or inputs), len(kept), len(kept) / probes)
    return Pools(cells, probes, first)


def reached_cells(
    upstream: UpstreamProblems, seed: int, probes: int = PROBES
) -> frozenset[tuple[float, ...]]:
    """The cells of the module's input grid that `probes` runs of the program's problems feed
    it inputs in."""
    return frozenset(probe_pools(upstream, seed, probes).cells)


def _keep_unreached(
    built: ConditionalPerformanceProfile,
    current: ConditionalPerformanceProfile,
    reached: frozenset[tuple[float, ...]],
) -> ConditionalPerformanceProfile:
    """`built` with the cells the program does not reach taken from `current` (same grid): its
    distribution, expected quality, bin means (its representatives where it has none) and
    probability of no result (0 where it has none)."""
    mesh = np.meshgrid(*built.input_grids, indexing="ij")
    points = np.stack([m.reshape(-1) for m in mesh], axis=-1) if mesh else np.zeros((1, 0))
    keep = np.array([tuple(float(q) for q in p) not in reached for p in points])
    keep = keep.reshape(built.cell_shape[:-1])[..., None]  # (inputs..., 1): every time
    cells = np.meshgrid(*built.input_grids, built.time, indexing="ij")
    q = np.stack(cells[:-1], axis=-1) if built.n_inputs else np.zeros((*cells[-1].shape, 0))
    old = {
        "probability": current.probability,
        "mean": current.mean_table,
        "bin_mean": current.representatives(q, cells[-1]),
        "no_result_table": (
            current.no_result_table
            if current.no_result_table is not None
            else np.zeros(current.cell_shape)
        ),
        "samples": current.samples,
        "std": current.std,
    }
    changes: dict[str, Any] = {}
    for name, previous in old.items():
        new = getattr(built, name)
        if new is None or previous is None:
            continue
        mask = keep.reshape(keep.shape + (1,) * (new.ndim - keep.ndim))
        changes[name] = np.where(mask, previous, new)
    return attrs.evolve(built, **changes)


@frozen
class Round:
    """One round of the fixed point: the profile measured on the compiled program's inputs,
    how far the compiled expectations moved with it (the largest change over the table's
    cells), how many cells of the module's input grid the program reached, and the
    measurement's own noise: 3 times the largest standard error of the profile's expected
    quality in a cell (a change well within it says more trials are needed, not more
    rounds), and whether that cell's trials took their inputs from a pool smaller than their
    number (then more probes are, not more trials: they would reuse the same inputs)."""

    profile: ConditionalPerformanceProfile
    change: float
    reached: int
    cells: int
    noise: float = 0.0
    pooled: bool = False


@frozen
class UpstreamMeasurement:
    """The rounds of `measure_upstream`; the last one's profile is the result."""

    module: str
    schema: str
    rounds: tuple[Round, ...]
    tolerance: float

    @property
    def profile(self) -> ConditionalPerformanceProfile:
        return self.rounds[-1].profile

    @property
    def converged(self) -> bool:
        """The last round moved the compiled expectations by at most the tolerance."""
        return self.rounds[-1].change <= self.tolerance


def measure_upstream(
    name: str,
    schemas: SchemaFile,
    schema: str,
    library: AnytimeLibrary,
    *,
    trials: int = 100,
    seed: int = 0,
    workers: int = 1,
    rounds: int = 3,
    tolerance: float = 0.005,
    time_grid: ArrayLike | None = None,
    resolution: float | None = None,
    input_quality: ArrayLike = DEFAULT_INPUT_QUALITY,
    allocator: str = "auto",
    progress: bool | None = None,
    on_round: Callable[[int, Round], None] | None = None,
    problems: ProgramProblems | None = None,
    mode: RunMode = SOFT,
    probes: int = PROBES,
) -> UpstreamMeasurement:
    """Measure module `name` on the inputs schema `schema` feeds it, compiled against
    `library` (see the module's docstring), for up to `rounds` rounds, until the compiled
    expectations move by at most `tolerance`. The grid (times, input qualities, bins) is the
    module's declared measurement's, else its current profile's; the program's problems are
    `problems` (default: the ones a plugin declares for the schema), whose time grid and
    resolution, when declared, are the compilation's (else `time_grid`, `resolution`).
    `on_round(k, round)` is told of each round as it ends. The trials run as `mode` says (see
    `build_profile`; by default in the worker itself, soft). Each round first runs the program
    `probes` times, whose inputs the trials take from (see the module's docstring).

    Raises:
        UpstreamError: the module is not called once, as a module, by the schema; or its
            result cannot be scored; or a cell cannot be measured; or `probes` is not a whole
            number >= 1.
        LibraryError: no program problem set is declared for the schema.
    """
    if not isinstance(probes, int | np.integer) or isinstance(probes, bool) or probes < 1:
        raise UpstreamError(f"probes: expected a whole number >= 1, got {probes!r}")
    if problems is None:
        problems = library.program_problems(schema)
    entry = library[name]
    module = entry.module
    if module is None or module.kind not in PROFILE_KINDS:
        raise UpstreamError(f"'{name}' is not an interruptible or contract module with code")
    try:
        measurement = library.measurement(name)
    except AnytimeError:
        measurement = None
    current = entry.profile
    if measurement is not None:
        grid = measurement.grid
        times, grids, bins = grid.time, grid.input_grids, grid.bins
        fallback: ProblemSet | None = measurement.problems
    elif current is not None:
        times, grids, bins = current.time, current.input_grids, current.bins
        fallback = None
    else:
        raise UpstreamError(f"'{name}' has neither a profile nor a declared measurement")
    totals = problems.time_grid or time_grid
    if totals is None:
        totals = default_totals(schemas, library, schema)
    step = problems.resolution or resolution

    def compiled_with(lib: AnytimeLibrary) -> CompiledProgram:
        return compile_file(
            schemas,
            lib,
            totals,
            input_quality,
            schema=schema,
            allocator=allocator,
            resolution=step,
        )[-1]

    compiled = compiled_with(library)
    node = _the_call(compiled, entry.name, schema)
    if not (node.index == _output(compiled) and problems.scored) and not callable(
        getattr(problems.problems, "score_step", None)
    ):
        raise UpstreamError(
            f"'{name}' is not the output of schema '{schema}', so its results are scored by the"
            f" schema's problem set ({problems.name}): give it a"
            " score_step(instance, module, value) method"
        )
    if fallback is None and current is not None:
        same = np.array_equal(current.time, times) and all(
            np.array_equal(a, b) for a, b in zip(current.input_grids, grids, strict=True)
        )
        assert same  # the grid is the current profile's
    done: list[Round] = []
    for index in range(rounds):
        probe = UpstreamProblems(compiled, node, problems, grids, fallback)
        pools = probe_pools(probe, seed + index, int(probes))
        upstream = UpstreamProblems(compiled, node, problems, grids, fallback, pools, trials)
        reached = upstream.reached
        build = build_profile(
            module,
            upstream,
            time=times,
            input_grids=grids,
            bins=bins,
            trials=trials,
            seed=seed + index,
            workers=workers,
            progress=progress,
            mode=mode,
        )
        effective = upstream.effective_samples()[..., None]  # (inputs..., 1): every time
        measured = build.profile
        assert measured.samples is not None
        samples = np.broadcast_to(effective, measured.samples.shape).copy()
        measured = attrs.evolve(measured, module=module.name, samples=samples)
        profile = measured
        if fallback is None and current is not None:
            profile = _keep_unreached(profile, current, reached)
        library = library.with_profile(entry.name, profile)
        current = profile
        again = compiled_with(library)
        change = float(np.max(np.abs(again.expected - compiled.expected)))
        noise, noisiest = _noise(measured)
        cells = int(np.prod(profile.cell_shape[:-1]))
        # a pool of n < t - 1 inputs: its effective count below t / 2
        pooled = bool(upstream.effective_samples().reshape(-1)[noisiest] < trials / 2)
        done.append(Round(profile, change, len(reached), cells, noise, pooled))
        if on_round is not None:
            on_round(index + 1, done[-1])
        compiled = again
        node = _the_call(compiled, entry.name, schema)
        if change <= tolerance:
            break
    return UpstreamMeasurement(module.name, schema, tuple(done), tolerance)


def _noise(profile: ConditionalPerformanceProfile) -> tuple[float, int]:
    """3 times the largest standard error of a measured profile's expected quality in a cell,
    and the flat index of that cell's input qualities."""
    if profile.std is None or profile.samples is None:
        return 0.0, 0
    se = profile.std / np.sqrt(np.maximum(profile.samples, 1))
    at = int(np.argmax(se)) if se.size else 0
    noisiest = np.unravel_index(at, se.shape)[:-1] if se.size else ()
    flat = int(np.ravel_multi_index(noisiest, se.shape[:-1])) if noisiest else 0
    return 3 * float(np.max(se, initial=0.0)), flat


def _module(node: ModuleNode) -> AnytimeModule:
    module = node.entry.module if node.entry is not None else None
    if module is None:
        raise UpstreamError(f"'{node.name}' has no code to run")
    return module


def _output(compiled: CompiledProgram) -> int:
    output = compiled.model.output
    return output.index if output.kind == "node" else -1


def _the_call(compiled: CompiledProgram, name: str, schema: str) -> ModuleNode:
    """The node that calls module `name` in the compiled schema (exactly one)."""
    calls = [
        n
        for n in compiled.model.nodes
        if isinstance(n, ModuleNode) and n.callee is None and n.name == name
    ]
    if len(calls) != 1:
        how = "does not call" if not calls else f"calls {len(calls)} times"
        raise UpstreamError(
            f"schema '{schema}' {how} module '{name}' (outside an if's branches and called"
            " schemas): measure it on its own problem set, or on a schema that calls it once"
        )
    return calls[0]


def _producers(compiled: CompiledProgram, node: ModuleNode) -> list[tuple[int, str | None]]:
    """For each quality-carrying argument of the call, its position and the module whose
    result it is (None: a program input or a constant)."""
    module = _module(node)
    call = compiled.model.graph.nodes[node.index]
    out = []
    for name in module.inputs:
        position = module.parameters.index(name)
        source = call.args[position] if position < len(call.args) else None
        producer = None
        if isinstance(source, NodeRef):
            producer = compiled.model.graph.nodes[source.index].function
        out.append((position, producer))
    return out


def _width(grid: Array, quality: float) -> float:
    """How far from grid point `quality` an input is taken as of its quality: `TOLERANCE` of
    the way to its nearest neighbour on the grid (any distance on a grid of one point)."""
    others = np.abs(grid[grid != quality] - quality)
    return float(TOLERANCE * others.min()) if len(others) else np.inf


def _nearest(grid: Array, quality: float) -> float:
    return float(grid[int(np.argmin(np.abs(grid - quality)))])
