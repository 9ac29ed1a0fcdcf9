"""What the compiler needs of a program: its calls, their profiles, and where qualities flow.

A `CompileModel` resolves every node of a program's dataflow graph against the anytime library,
one class per kind of node: a `ModuleNode` (an interruptible or contract module, or a compiled
schema) gets a share of the time and is described by its conditional performance profile; an
`ElementaryNode` takes no time and combines its inputs' qualities (min by default); a `TestNode`
is a best-of's precondition, a `ChoiceNode` the best-of itself, an `IfNode` a conditional, a
`LoopNode` a map or a repeat (its time split among its calls at run time). For
each quality-carrying input of a node, a `Slot` says where its quality comes from: another node,
a quality-carrying program input, or a constant (a literal argument has quality 1).

`anytime.compiler.resolve` builds the model (`build_model`); `combinations` holds the array
versions of elementary functions' quality combinations, `branches` an if's branches.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import attrs
import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.dsl.graph import DataflowGraph, Source
from anytime.dsl.program import Program
from anytime.errors import AnytimeError
from anytime.library import LibraryEntry
from anytime.profiles.profile import Array, ConditionalPerformanceProfile, point_mass


class CompileError(AnytimeError, ValueError):
    """A program cannot be compiled as asked (grids, units); the message says what to change."""


@frozen
class Slot:
    """Where one quality-carrying input of a node gets its quality."""

    kind: Literal["node", "input", "constant"]
    index: int = 0  # node index, or index among the program's quality-carrying inputs
    value: float = 1.0  # for a constant


@frozen
class Within:
    """Where a node sits: inside alternative `alternative` (0-based) of the best-of node
    `choice` (through nested choices, the innermost)."""

    choice: int
    alternative: int


@frozen(eq=False)
class BranchPlan:
    """One branch of an `if`, compiled as a program of its own.

    Attributes:
        probability: the probability that this branch runs.
        compiled: the branch compiled on the time lattice (a `CompiledProgram`).
        axes: for each quality-carrying input of the branch, its position in the if node's slots.
    """

    probability: float
    compiled: Any
    axes: tuple[int, ...]

    @property
    def deterministic(self) -> bool:
        return is_deterministic(self.compiled.profile)


@frozen(eq=False)
class ModuleNode:
    """A call that gets time: an interruptible or contract module, or a compiled schema.

    Attributes:
        index: the node's index in the dataflow graph (topological).
        name: the module or schema called.
        slots: the sources of its quality-carrying inputs, in profile-axis order.
        profile: its conditional performance profile.
        deterministic: every cell of the profile is a point mass at its mean quality.
        time_index: its position in an allocation vector.
        entry: the library entry (None for a schema call).
        callee: for a schema call, the callee compiled (a `CompiledProgram`).
        within: the alternative it is inside, if any.
        step: the module's step, reserved out of its share (see `run_time`): declared, or
            measured by the profile builder (0 when unknown, and for a called schema, whose
            own modules reserve theirs).
        accepts_missing: the module is called even when an input has no result.
    """

    index: int
    name: str
    slots: tuple[Slot, ...]
    profile: ConditionalPerformanceProfile
    deterministic: bool
    time_index: int
    entry: LibraryEntry | None = None
    callee: Any = None
    within: Within | None = None
    step: float = 0.0
    accepts_missing: bool = False

    def run_time(self, share: ArrayLike) -> Array:
        """The time the module runs with, given its share of the total: the share less its
        step (the most it may use past its deadline before it answers), so that it answers
        within its share; a result it registers after that time does not count, as in the
        profile, which says what it has by then. For a measured profile, that time is rounded
        down to the profile's time grid (up to its last time): between the times it was
        measured at, nothing is known of what a module has, and a module whose results come
        in steps is not what a straight line between them says."""
        run = np.maximum(np.asarray(share, dtype=np.float64) - self.step, 0.0)
        grid = self.profile.time
        if self.profile.samples is None or len(grid) < 2:
            return run
        slack = 1e-9 * max(1.0, float(grid[-1]))
        below = grid[np.clip(np.searchsorted(grid, run + slack, side="right") - 1, 0, None)]
        return np.where(run >= grid[-1], run, np.minimum(below, run))

    def starts(self, share: ArrayLike) -> Array:
        """Whether the module is started with this share: not when the share is less than its
        step (it could not be sure to answer within it)."""
        slack = 1e-9 * max(1.0, self.step)
        return np.asarray(np.asarray(share, dtype=np.float64) >= self.step - slack)


@frozen(eq=False)
class ElementaryNode:
    """A call of an elementary function: it takes no time and combines its inputs' qualities
    (`combine`, on arrays along axis 0; `monotone`: known to be non-decreasing in each)."""

    index: int
    name: str
    slots: tuple[Slot, ...]
    combine: Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]]
    monotone: bool
    entry: LibraryEntry | None = None
    within: Within | None = None


@frozen(eq=False)
class TestNode:
    """The precondition of a best-of alternative: an elementary call whose value decides
    whether the alternative is applicable; its quality flows nowhere. `within` is its
    alternative."""

    index: int
    name: str
    slots: tuple[Slot, ...]
    entry: LibraryEntry
    within: Within


@frozen(eq=False)
class ChoiceNode:
    """A best-of: its quality is the best of its alternatives' (`slots`, one per alternative,
    `values` where each comes from); `preconditions` gives each alternative's test node
    (None: always applicable). `estimated` marks the alternatives whose result comes from a
    module that does not report its true quality: the runtime judges those by what their
    profile predicts, not by their quality, so the best-of cannot pick the best of them run by
    run, and its quality is not their maximum (see the evaluator). `dependence`: the schema's
    `:dependence`, the probability that one draw decides every alternative's quality."""

    index: int
    slots: tuple[Slot, ...]
    values: tuple[Source, ...]
    preconditions: tuple[int | None, ...]
    within: Within | None = None
    name: str = "best-of"
    estimated: tuple[bool, ...] = ()
    dependence: float = 0.0


@frozen(eq=False)
class IfNode:
    """An if: one node that gets time, which goes to the branch its condition selects; its
    profile is the mixture of the branches' compiled profiles."""

    index: int
    slots: tuple[Slot, ...]
    profile: ConditionalPerformanceProfile
    time_index: int
    branches: tuple[BranchPlan, ...]
    condition: Source
    within: Within | None = None
    name: str = "if"


@frozen(eq=False)
class LoopNode:
    """A map or a repeat: one node that gets time, which the runtime splits among its calls
    (`anytime.compiler.loops`); its quality is the mean of theirs.

    Attributes:
        name: "map F" or "repeat F".
        kind: "map" or "repeat".
        slots: the sources of the call's quality-carrying inputs (a map's collection stands
            for each item), in the call's profile-axis order.
        call: the module called, as a node of its own (not in the model: its time is the
            loop's), with the same slots.
        item_axes: the axes of the call's profile that the item fills (none for a repeat).
        profiles: the loop's compiled profile for each count 0, 1, ..., the most compiled for
            (a map's `:max`, a repeat's count).
        count: the count the program's table is planned for (the most compiled for); a run
            that finds a map's collection of another size re-plans with that count's profile
            (`with_count`; a count above the most uses the most's profile).
    """

    index: int
    name: str
    kind: Literal["map", "repeat"]
    slots: tuple[Slot, ...]
    call: ModuleNode
    item_axes: tuple[int, ...]
    profiles: tuple[ConditionalPerformanceProfile, ...]
    count: int
    time_index: int
    within: Within | None = None
    accepts_missing: bool = False  # no collection (or argument), no loop

    @property
    def profile(self) -> ConditionalPerformanceProfile:
        return self.profiles[min(self.count, len(self.profiles) - 1)]

    @property
    def deterministic(self) -> bool:
        return self.call.deterministic

    @property
    def most(self) -> int:
        return len(self.profiles) - 1

    def run_time(self, share: ArrayLike) -> Array:
        """The loop runs with its whole share (each call keeps its own step back)."""
        return np.maximum(np.asarray(share, dtype=np.float64), 0.0)

    def starts(self, share: ArrayLike) -> Array:
        return np.ones(np.shape(share), dtype=bool)


CompileNode = ModuleNode | ElementaryNode | TestNode | ChoiceNode | IfNode | LoopNode

#: The kinds of node that get a share of the time.
Timed = ModuleNode | IfNode | LoopNode


def reserved_step(node: CompileNode) -> float:
    """The part of a node's share it reserves for its last step (see `ModuleNode.run_time`):
    a module's step; none for an if or a loop, whose own calls reserve theirs."""
    return node.step if isinstance(node, ModuleNode) else 0.0


@frozen(eq=False)
class CompileModel:
    """A program resolved against a library, ready for evaluating allocations."""

    program: Program
    graph: DataflowGraph
    nodes: tuple[CompileNode, ...]
    quality_inputs: tuple[str, ...]  # program inputs whose quality conditions the output
    output: Slot
    time_unit: str

    @property
    def anytime_nodes(self) -> tuple[ModuleNode | IfNode | LoopNode, ...]:
        """The nodes that get time, in allocation-vector order."""
        return tuple(n for n in self.nodes if isinstance(n, Timed))

    @property
    def module_names(self) -> tuple[str, ...]:
        return tuple(n.name for n in self.anytime_nodes)

    def node(self, index: int) -> CompileNode:
        """The node with this graph index."""
        return next(n for n in self.nodes if n.index == index)

    def with_count(self, index: int, count: int) -> CompileModel:
        """The model with the loop at graph index `index` planned for `count` calls."""
        nodes = tuple(
            attrs.evolve(n, count=count) if n.index == index and isinstance(n, LoopNode) else n
            for n in self.nodes
        )
        return attrs.evolve(self, nodes=nodes)

    def alternative_modules(self, choice: int, alternative: int) -> tuple[int, ...]:
        """The allocation-vector positions of the nodes that get time inside one alternative
        of a best-of (through nested choices too)."""
        return tuple(
            n.time_index for n in self.anytime_nodes if self.inside(n, Within(choice, alternative))
        )

    def inside(self, node: CompileNode, within: Within) -> bool:
        tag = node.within
        while tag is not None:
            if tag == within:
                return True
            tag = self.node(tag.choice).within
        return False


def is_deterministic(profile: ConditionalPerformanceProfile) -> bool:
    """True when each cell is a point mass at the cell's mean (a tabulated quality curve)."""
    return profile.mean is not None and bool(
        np.array_equal(profile.probability, point_mass(profile.mean, profile.bins))
    )
