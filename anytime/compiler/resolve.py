"""Resolving a program against the library: `build_model` makes a `CompileModel`, one node per
step of the program's dataflow graph, or says, placed in the schema's source, why a call
cannot be compiled."""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal

import attrs

from anytime.compiler.branches import if_branches, mixture
from anytime.compiler.combinations import vector_combine
from anytime.compiler.model import (
    ChoiceNode,
    CompileError,
    CompileModel,
    CompileNode,
    ElementaryNode,
    IfNode,
    LoopNode,
    ModuleNode,
    Slot,
    TestNode,
    Timed,
    Within,
    is_deterministic,
)
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
)
from anytime.dsl.program import Literal as LiteralArg
from anytime.dsl.source import Source as SourceText
from anytime.errors import AnytimeError, Diagnostic, SchemaError
from anytime.library import AnytimeLibrary, LibraryEntry
from anytime.profiles.profile import ConditionalPerformanceProfile
from anytime.text import suggest


def _estimated(node: CompileNode | None) -> bool:
    """Whether the runtime judges a node's result by its profile's prediction (its module does
    not report its true quality), not by the quality the result says."""
    if not isinstance(node, ModuleNode) or node.entry is None or node.entry.module is None:
        return False
    return node.entry.module.reports != "true"


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
            combine, monotone = vector_combine(entry.module.combine)
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
            index,
            slots,
            values,
            tests,
            self.within[choice.target],
            estimated=estimated,
            dependence=choice.dependence,
        )

    def conditional(self, index: int, step: If) -> CompileNode | str:
        graph = self.graph
        built = if_branches(self.program, graph, step, self.library, self.compile_branch)
        if isinstance(built, str):
            return built
        plans, names = built
        index_of = {n.variable: i for i, n in enumerate(graph.nodes)}
        reads: list[Source] = [
            InputRef(v) if v not in index_of else NodeRef(index_of[v]) for v in names
        ]
        profile = mixture(plans, names, f"{self.program.name}/{step.target}")
        return IfNode(
            index,
            tuple(self.slot(s) for s in reads),
            profile,
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
