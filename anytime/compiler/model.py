"""What the compiler needs of a program: its calls, their profiles, and where qualities flow.

A `CompileModel` resolves every node of a program's dataflow graph against the anytime library,
one class per kind of node: a `ModuleNode` (an interruptible or contract module, or a compiled
schema) gets a share of the time and is described by its conditional performance profile; an
`ElementaryNode` takes no time and combines its inputs' qualities (min by default); a `TestNode`
is a best-of's precondition, a `ChoiceNode` the best-of itself, an `IfNode` a conditional, a
`LoopNode` a map or a repeat (its time split among its calls at run time). For
each quality-carrying input of a node, a `Slot` says where its quality comes from: another node,
a quality-carrying program input, or a constant (a literal argument has quality 1).
"""

from __future__ import annotations

import builtins
import inspect
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal

import attrs
import numpy as np
from attrs import frozen
from numpy.typing import ArrayLike

from anytime.dsl.graph import DataflowGraph, InputRef, NodeRef, Source
from anytime.dsl.normalize import count
from anytime.dsl.program import (
    BestOf,
    Call,
    If,
    Map,
    Program,
    Repeat,
    SchemaCall,
    Step,
    Var,
    variables,
    walk,
)
from anytime.dsl.program import Literal as LiteralArg
from anytime.dsl.source import Source as SourceText
from anytime.errors import AnytimeError, Diagnostic, SchemaError
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.profiles.profile import (
    Array,
    ConditionalPerformanceProfile,
    default_bins,
    new_profile,
    point_mass,
)
from anytime.text import suggest


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
    run, and its quality is not their maximum (see the evaluator)."""

    index: int
    slots: tuple[Slot, ...]
    values: tuple[Source, ...]
    preconditions: tuple[int | None, ...]
    within: Within | None = None
    name: str = "best-of"
    estimated: tuple[bool, ...] = ()


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


def _estimated(node: CompileNode | None) -> bool:
    """Whether the runtime judges a node's result by its profile's prediction (its module does
    not report its true quality), not by the quality the result says."""
    if not isinstance(node, ModuleNode) or node.entry is None or node.entry.module is None:
        return False
    return node.entry.module.reports != "true"


def is_deterministic(profile: ConditionalPerformanceProfile) -> bool:
    """True when each cell is a point mass at the cell's mean (a tabulated quality curve)."""
    return profile.mean is not None and bool(
        np.array_equal(profile.probability, point_mass(profile.mean, profile.bins))
    )


def _least(q: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """The minimum along axis 0; 1 for no inputs (the modules' default combination)."""
    return np.min(q, axis=0) if len(q) else np.ones(q.shape[1:])


def _most(q: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    most: np.ndarray[Any, Any] = np.max(q, axis=0)
    return most


@frozen
class _Pointwise:
    """Any other combination, applied to one combination of input qualities at a time (a
    class, not a closure, so that a compiled program pickles with it)."""

    combine: Callable[[Sequence[float]], float]

    def __call__(self, q: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        flat = q.reshape(len(q), -1)
        out = np.array([self.combine(list(column)) for column in flat.T], dtype=np.float64)
        return out.reshape(q.shape[1:])


_COMBINATIONS: dict[Callable[..., Any], Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]]] = {
    builtins.min: _least,
    builtins.max: _most,
}


def _vector_combine(
    combine: Callable[[Sequence[float]], float],
) -> tuple[Callable[[np.ndarray[Any, Any]], np.ndarray[Any, Any]], bool]:
    """An array version of an elementary function's quality combination, and whether it is
    known to be monotone (min and max are; any other function is applied point by point)."""
    name = getattr(combine, "__name__", "")
    if combine in _COMBINATIONS:
        return _COMBINATIONS[combine], True
    if name == "_min_quality":  # the modules' default: min, with 1.0 for no inputs
        return _least, True
    return _Pointwise(combine), False


def _call_mismatch(entry: LibraryEntry, n_args: int, keywords: Sequence[str]) -> str | None:
    """Why a call does not fit the module's function (its positional arity, then its keyword
    parameters, as Python would bind them), or None; a call that compiled but could not run
    failed with a TypeError at run time."""
    if entry.arity is not None and n_args != entry.arity:
        return f"function '{entry.name}' takes {count(entry.arity)}, got {n_args}"
    module = entry.module
    if module is None:
        return None
    try:
        signature = inspect.signature(module.function)
    except (TypeError, ValueError):  # a builtin or an object without a readable signature
        return None
    context = () if module.kind == "elementary" else (None,)
    try:
        signature.bind(*context, *[None] * n_args, **dict.fromkeys(keywords))
    except TypeError as error:
        return f"function '{entry.name}': {error}"
    return None


#: Makes a loop's profiles: (the call, the most calls, the loop's name) -> one per count 0..most.
LoopCompiler = Callable[[ModuleNode, int, str], tuple[ConditionalPerformanceProfile, ...]]


def build_model(
    program: Program,
    library: AnytimeLibrary,
    source: SourceText | None = None,
    compile_branch: Callable[[Program], Any] | None = None,
    callees: Mapping[str, Any] | None = None,
    compile_loop: LoopCompiler | None = None,
) -> CompileModel:
    """Resolve `program` against `library` (and its schema calls against `callees`, the
    compiled schemas of its file, by name); errors are placed in `source`, the program's file.

    A best-of becomes a node whose quality is the maximum of its alternatives' (they run side
    by side, sharing the time); an if becomes one node that gets time, whose branches are
    compiled as programs of their own by `compile_branch` (the calls inside them are not
    nodes of this model), its profile the mixture of theirs; a map or a repeat becomes one node
    that gets time, its profile for each count made by `compile_loop`.

    Raises:
        SchemaError: a call to an unknown function, to a module without a profile, or whose
            quality-carrying arguments cannot be told apart; each names its place.
        CompileError: profiles in different time units.
    """
    source = source if source is not None else SourceText("<schema>", "")
    resolver = _Resolver(program, library, source, compile_branch, callees or {}, compile_loop)
    return resolver.model()


class _Resolver:
    """Resolves each node of a program's dataflow graph, one method per kind of step."""

    def __init__(
        self,
        program: Program,
        library: AnytimeLibrary,
        source: SourceText,
        compile_branch: Callable[[Program], Any] | None,
        callees: Mapping[str, Any],
        compile_loop: LoopCompiler | None = None,
    ) -> None:
        self.program, self.library, self.source = program, library, source
        self.compile_branch, self.callees = compile_branch, callees
        self.compile_loop = compile_loop
        self.graph = program.graph
        self.diagnostics: list[Diagnostic] = []
        self.quality_inputs: dict[str, int] = {}
        self.time_index = 0
        self.within: dict[str, Within | None] = {}
        self.in_if: set[str] = set()
        self.tests: set[str] = set()
        self.built: dict[int, CompileNode] = {}
        self.place(program.steps, None, inside_if=False)

    def place(self, steps: Sequence[Step], within: Within | None, inside_if: bool) -> None:
        """Record where each step sits: the alternative it is inside, whether it is inside an
        if's branch (compiled with the branch), whether it is a precondition."""
        for step in steps:
            self.within[step.target] = within
            if inside_if:
                self.in_if.add(step.target)
            match step:
                case BestOf(target=target, alternatives=alternatives):
                    choice = self.graph.index_of(target)
                    for i, alternative in enumerate(alternatives):
                        test = alternative.precondition
                        if test is not None:
                            self.tests.add(test.target)
                            self.place((test,), Within(choice, i), inside_if)
                        self.place(alternative.steps, Within(choice, i), inside_if)
                case If(then=then, else_=other):
                    self.place((*then.steps, *other.steps), within, inside_if=True)
                case _:
                    pass

    def complain(self, index: int, message: str) -> None:
        step = self.graph.nodes[index].step
        span = step.function_span if step is not None else None
        self.diagnostics.append(self.source.diagnostic(message, span))

    def slot(self, source: Source) -> Slot:
        if isinstance(source, NodeRef):
            return Slot("node", source.index)
        if isinstance(source, InputRef):
            index = self.quality_inputs.setdefault(source.name, len(self.quality_inputs))
            return Slot("input", index)
        return Slot("constant", value=1.0)

    def timed(self) -> int:
        self.time_index += 1
        return self.time_index - 1

    def model(self) -> CompileModel:
        graph, program = self.graph, self.program
        nodes: list[CompileNode] = []
        for index, node in enumerate(graph.nodes):
            if node.variable in self.in_if:
                continue
            built: CompileNode | str
            match node.step:
                case Call() as call:
                    built = self.call(index, call)
                case SchemaCall() as call:
                    built = self.schema_call(index, call)
                case BestOf() as choice:
                    built = self.best_of(index, choice)
                case If() as conditional:
                    built = self.conditional(index, conditional)
                case Map() | Repeat() as loop:
                    built = self.loop(index, loop)
                case _:
                    raise AssertionError(node)
            if isinstance(built, str):
                self.complain(index, built)
            else:
                nodes.append(built)
                self.built[index] = built
        if self.diagnostics:
            raise SchemaError(self.diagnostics)
        profiles = [n for n in nodes if isinstance(n, Timed)]
        units = {n.profile.time_unit for n in profiles}
        if len(units) > 1:
            detail = ", ".join(f"{n.name}: {n.profile.time_unit}" for n in profiles)
            raise CompileError(
                f"schema '{program.name}': its modules' profiles are in different time units "
                f"({detail}); measure them with one clock",
                where=self.source.filename,
            )
        # Program inputs only count when some quality slot reads them (or when one is the
        # output); number them in the program's input order.
        quality_inputs = self.quality_inputs
        if isinstance(graph.output, InputRef):
            quality_inputs.setdefault(graph.output.name, len(quality_inputs))
        order = [name for name in program.inputs if name in quality_inputs]
        renumber = {quality_inputs[name]: i for i, name in enumerate(order)}
        nodes = [_renumbered(n, renumber) for n in nodes]
        if isinstance(graph.output, InputRef):
            output = Slot("input", order.index(graph.output.name))
        else:
            output = Slot("node", graph.output.index)
        return CompileModel(
            program=program,
            graph=graph,
            nodes=tuple(nodes),
            quality_inputs=tuple(order),
            output=output,
            time_unit=units.pop() if units else "ticks",
        )

    def call(self, index: int, call: Call) -> CompileNode | str:
        node = self.graph.nodes[index]
        built = self.resolve_call(index, call.target, call.function, node.args, node.keywords)
        return built if isinstance(built, str) else built[0]

    def resolve_call(
        self,
        index: int,
        target: str,
        function: str,
        args: Sequence[Source],
        keywords: Sequence[tuple[str, Source]],
    ) -> tuple[CompileNode, list[Source]] | str:
        """The node of a call of `function` with these arguments, and the arguments that carry
        its inputs' qualities (in its profile-axis order), or why it cannot be compiled."""
        entry = self.library.get(function)
        if entry is None:
            return f"unknown function '{function}'{suggest(function, self.library.names())}"
        mismatch = _call_mismatch(entry, len(args), [name for name, _ in keywords])
        if mismatch is not None:
            return mismatch
        sources = _quality_sources(args, entry, node_variables(self.graph, args))
        if isinstance(sources, str):
            return sources
        slots = tuple(self.slot(s) for s in sources)
        within = self.within[target]
        if target in self.tests:
            if entry.kind != "elementary":
                article = "an" if entry.kind == "interruptible" else "a"
                return (
                    f"the precondition '{entry.name}' must be an elementary function (it takes "
                    f"no time), but it is {article} {entry.kind} module"
                )
            assert within is not None
            return TestNode(index, entry.name, slots, entry, within), sources
        if entry.kind == "elementary":
            assert entry.module is not None
            combine, monotone = _vector_combine(entry.module.combine)
            elementary = ElementaryNode(index, entry.name, slots, combine, monotone, entry, within)
            return elementary, sources
        try:
            profile = entry.profile
        except AnytimeError as error:
            return f"the profile of '{entry.name}' cannot be read: {error}"
        if profile is None:
            return (
                f"module '{entry.name}' has no performance profile ({entry.origin}): "
                "the compiler cannot allocate time to it"
            )
        module = entry.module
        built = ModuleNode(
            index,
            entry.name,
            slots,
            profile,
            is_deterministic(profile),
            self.timed(),
            entry,
            within=within,
            step=float(entry.step or 0.0),
            accepts_missing=module is not None and module.accepts_missing,
        )
        return built, sources

    def loop(self, index: int, step: Map | Repeat) -> CompileNode | str:
        """A map's or a repeat's call resolved as a module call (its time the loop's), and the
        loop's profile for every count up to its most."""
        word: Literal["map", "repeat"] = "map" if isinstance(step, Map) else "repeat"
        args = self.graph.nodes[index].args  # a map's collection first: it fills the item
        built = self.resolve_call(index, step.target, step.function, args, ())
        if isinstance(built, str):
            return built
        call, sources = built
        if not isinstance(call, ModuleNode):
            return (
                f"{word} applies an anytime module, but '{step.function}' is an elementary "
                "function (it takes no time): call it on the results instead"
            )
        if self.compile_loop is None:
            return f"a {word} can only be compiled by compile_program"
        # Identity, not equality: the item is the call's first argument, not an equal one.
        items = tuple(i for i, s in enumerate(sources) if isinstance(step, Map) and s is args[0])
        most = step.max_items if isinstance(step, Map) else step.count
        name = f"{word} {step.function}"
        profiles = self.compile_loop(call, most, f"{self.program.name}/{step.target}")
        return LoopNode(
            index, name, word, call.slots, call, items, profiles, most, call.time_index, call.within
        )

    def schema_call(self, index: int, call: SchemaCall) -> CompileNode | str:
        callee = self.callees.get(call.schema)
        if callee is None:  # a schema compiled elsewhere, registered as a module
            return self.call(index, Call(call.target, call.schema, call.args))
        node = self.graph.nodes[index]
        inputs = callee.model.program.inputs
        sources = [node.args[inputs.index(name)] for name in callee.model.quality_inputs]
        profile = callee.profile
        return ModuleNode(
            index,
            call.schema,
            tuple(self.slot(s) for s in sources),
            profile,
            is_deterministic(profile),
            self.timed(),
            callee=callee,
            within=self.within[call.target],
        )

    def best_of(self, index: int, choice: BestOf) -> CompileNode:
        graph = self.graph
        values = tuple(graph.source(a.value) for a in choice.alternatives)
        tests = tuple(
            None if a.precondition is None else graph.index_of(a.precondition.target)
            for a in choice.alternatives
        )
        slots = tuple(self.slot(s) for s in values)
        estimated = tuple(
            isinstance(s, NodeRef) and _estimated(self.built.get(s.index)) for s in values
        )
        return ChoiceNode(
            index, slots, values, tests, self.within[choice.target], estimated=estimated
        )

    def conditional(self, index: int, step: If) -> CompileNode | str:
        graph = self.graph
        built = _if_branches(self.program, graph, step, self.library, self.compile_branch)
        if isinstance(built, str):
            return built
        plans, names = built
        index_of = {n.variable: i for i, n in enumerate(graph.nodes)}
        reads: list[Source] = [
            InputRef(v) if v not in index_of else NodeRef(index_of[v]) for v in names
        ]
        mixture = _mixture(plans, names, f"{self.program.name}/{step.target}")
        return IfNode(
            index,
            tuple(self.slot(s) for s in reads),
            mixture,
            self.timed(),
            plans,
            graph.source(step.condition),
            self.within[step.target],
        )


def node_variables(graph: DataflowGraph, args: Sequence[Source]) -> list[str | None]:
    """The variable name each argument was written as (None for literals)."""
    return [None if isinstance(a, LiteralArg) else graph.variable(a) for a in args]


def _quality_sources(
    args: Sequence[Source], entry: LibraryEntry, variables: Sequence[str | None]
) -> list[Source] | str:
    """The arguments that carry the quality of each of the entry's inputs, in its axis order
    (or a message saying why they cannot be told)."""
    if entry.parameters:
        positions = [entry.parameters.index(name) for name in entry.inputs]
        if any(p >= len(args) for p in positions):
            return (
                f"'{entry.name}' takes its quality-carrying inputs ({', '.join(entry.inputs)}) "
                f"at positions the call does not reach (it passes {len(args)} arguments)"
            )
        return [args[p] for p in positions]
    # Known by its profile alone: match input names to argument names, else the arguments
    # computed by other calls, in order.
    if all(name in variables for name in entry.inputs):
        return [args[variables.index(name)] for name in entry.inputs]
    computed: list[Source] = [a for a in args if isinstance(a, NodeRef)]
    if len(computed) == len(entry.inputs):
        return computed
    return (
        f"cannot tell which arguments of '{entry.name}' carry the quality of its inputs "
        f"({', '.join(entry.inputs)}): it is known only by its profile; name the arguments "
        "like its inputs"
    )


def _renumbered(node: CompileNode, renumber: Mapping[int, int]) -> CompileNode:
    slots = tuple(Slot("input", renumber[s.index]) if s.kind == "input" else s for s in node.slots)
    return attrs.evolve(node, slots=slots)


def branch_program(program: Program, choice: If, branch: int) -> Program | str:
    """One branch of an `if` as a program of its own: its inputs are the variables it reads
    from outside (program inputs or earlier results), in order of first use."""
    part = (choice.then, choice.else_)[branch]
    word = ("then", "else")[branch]
    if not isinstance(part.value, Var):
        return f"the {word} branch of 'if' is a constant: give a variable or a call"
    steps = tuple(walk(part.steps))
    produced = {s.target for s in steps}
    reads = [v for s in steps for v in variables(s) if v not in produced]
    if part.value.name not in produced:
        reads.append(part.value.name)
    return Program(
        name=f"{program.name}/{choice.target}/{word}",
        inputs=tuple(dict.fromkeys(reads)),
        steps=part.steps,
        output=part.value.name,
    )


def _if_branches(
    program: Program,
    graph: DataflowGraph,
    step: If,
    library: AnytimeLibrary,
    compile_branch: Callable[[Program], Any] | None,
) -> tuple[tuple[BranchPlan, ...], list[str]] | str:
    """The branches of an if, compiled, and the names of the quality inputs they read."""
    p = step.p
    if p is None:
        condition = graph.source(step.condition)
        function = graph.nodes[condition.index].function if isinstance(condition, NodeRef) else None
        entry = library.get(function) if function is not None else None
        declared = getattr(entry.module, "probability", None) if entry and entry.module else None
        if declared is None:
            what = f"'{function}' declares" if function else "the condition is not a call and"
            return (
                f"the probability of the condition of 'if' is unknown: {what} no probability; "
                "give it as (if CONDITION THEN ELSE :p P)"
            )
        p = float(declared)
    if compile_branch is None:
        return "an 'if' can only be compiled by compile_program"
    compiled = []
    for branch in (0, 1):
        sub = branch_program(program, step, branch)
        if isinstance(sub, str):
            return sub
        compiled.append(compile_branch(sub))
    names = list(dict.fromkeys(n for c in compiled for n in c.model.quality_inputs))
    plans = tuple(
        BranchPlan(prob, c, tuple(names.index(n) for n in c.model.quality_inputs))
        for prob, c in zip((p, 1.0 - p), compiled, strict=True)
    )
    return plans, names


def _mixture(
    plans: Sequence[BranchPlan], names: Sequence[str], module: str
) -> ConditionalPerformanceProfile:
    """The if's profile: the branches' compiled profiles mixed with their probabilities, on the
    union of their input axes (a branch that does not read an input is constant along it)."""
    profiles = [plan.compiled.profile for plan in plans]
    grids = [np.asarray(g) for p in profiles for g in p.input_grids]
    q_grid = grids[0] if grids else np.zeros(0)
    time = profiles[0].time
    bins = profiles[0].bins
    same = all(np.array_equal(p.bins, bins) for p in profiles)
    if not same:
        bins = default_bins()
    m = len(names)
    shape = (len(q_grid),) * m + (len(time),)
    mean = np.zeros(shape)
    probability = np.zeros(shape + (len(bins) - 1,))
    for plan, profile in zip(plans, profiles, strict=True):
        order = np.argsort(plan.axes)
        expand = [a for a in range(m) if a not in plan.axes]
        cells = profile.mean_table
        cells = np.moveaxis(cells, list(range(len(order))), list(np.argsort(order)))
        probs = profile.probability
        if not same:  # each old bin's mass to the new bin holding its midpoint
            k = np.clip(np.searchsorted(bins, profile.values, side="right") - 1, 0, len(bins) - 2)
            probs = np.einsum("...k,kj->...j", probs, np.eye(len(bins) - 1)[k])
        probs = np.moveaxis(probs, list(range(len(order))), list(np.argsort(order)))
        mean = mean + plan.probability * np.expand_dims(cells, tuple(expand))
        probability = probability + plan.probability * np.expand_dims(probs, tuple(expand))
    return new_profile(
        input_grids=[q_grid] * m,
        time=time,
        bins=bins,
        probability=probability,
        mean=np.clip(mean, 0.0, 1.0),
        inputs=names,
        module=module,
        kind="contract",
        time_unit=profiles[0].time_unit,
    )
