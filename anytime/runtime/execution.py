"""One run of a compiled program (`Execution`): the calls in topological order on one clock,
each through `run` with its share of the total (see `anytime.runtime.program`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from attrs import frozen

from anytime.compiler.allocators import reallocate
from anytime.compiler.allocators.reallocate import Replanner, replanner
from anytime.compiler.compile import CompiledProgram
from anytime.compiler.evaluate import NO_RESULT
from anytime.compiler.loops import run_time_split
from anytime.compiler.model import (
    ChoiceNode,
    CompileNode,
    ElementaryNode,
    IfNode,
    LoopNode,
    ModuleNode,
    TestNode,
    Within,
)
from anytime.dsl.graph import InputRef, NodeRef, Source
from anytime.dsl.program import Literal
from anytime.modules import MISSING, AnytimeModule, Result
from anytime.profiles.profile import Array
from anytime.runtime.executor import RunRecord, Status, run
from anytime.runtime.modes import Budget, RunMode
from anytime.runtime.observe import Observer
from anytime.runtime.values import (
    ExecutionError,
    bind_inputs,
    decision_quality,
    is_collection,
    judged_inputs,
    news,
    no_result,
    passed,
    plain,
    quality_of,
    resplit,
    truth,
    wrapped,
)


@frozen
class ProgramRecord:
    """What a program run gives back.

    Attributes:
        result: the output's best result (None when the output module registered none).
        status: "failed" if any call failed or crashed, "no-result" without an output result,
            "contract-expired" if the run used more than its total, else "completed".
        records: one run record per call of the program, in execution order, then those of
            the calls inside the schemas it called and the branches its ifs ran.
        allocations: the time each module was given, in allocation-vector order.
        time_used: time on the run's clock from start to the answer.
    """

    result: Result | None
    status: Status
    records: tuple[RunRecord, ...]
    allocations: tuple[float, ...]
    time_used: float

    @property
    def quality(self) -> float:
        return self.result.quality if self.result is not None else 0.0


class Execution:
    """One run of a compiled program: the state its calls share."""

    def __init__(
        self,
        compiled: CompiledProgram,
        inputs: Sequence[Any] | Mapping[str, Any],
        budget: Budget,
        adaptive: bool,
        mode: RunMode,
        observers: Mapping[str, Observer],
    ) -> None:
        self.compiled, self.model = compiled, compiled.model
        self.adaptive, self.mode, self.observers = adaptive, mode, observers
        self.total, self.clock, self.stop = budget.allocation, budget.clock, budget.stop
        program = self.model.program
        self.values = bind_inputs(program.name, program.inputs, inputs)
        self.qualities = [quality_of(self.values[name]) for name in self.model.quality_inputs]
        self.start = self.clock.now()
        self.allocation = np.array(compiled.allocation_at(self.qualities, self.total), dtype=float)
        self.results: dict[int, Result] = {}
        self.records: dict[int, RunRecord] = {}
        self.inner: list[RunRecord] = []  # the calls of called schemas and of ifs' branches
        self.judged: dict[int, float] = {}  # the qualities decisions go by
        self.applicable: dict[int, list[bool]] = {}  # each best-of's, once decided
        self.informed = False  # whether a call has shown what the plan did not know yet
        # The last node with time of its own: what finishes after it leaves nothing to re-plan.
        self.last_timed = max((n.index for n in self.model.anytime_nodes), default=-1)
        self.planner: Replanner | None = None  # the model's, once asked

    def call(
        self, module: AnytimeModule, args: Sequence[Any], kwargs: Mapping[str, Any], share: float
    ) -> RunRecord:
        """A module's call with `share` of the time, in the program's mode."""
        budget = Budget(share, self.clock, self.stop)
        observer = self.observers.get(module.name)
        return run(module, args, kwargs, budget=budget, mode=self.mode, observer=observer)

    def run(self, until: int | None = None) -> ProgramRecord:
        """Run the program's calls in order (up to, not including, node `until` when given)."""
        self.count_input_collections()
        for node in self.model.nodes:
            if node.index == until:
                break
            if not self.active(node):
                continue
            record = self.step(node)
            self.records[node.index] = record
            if record.result is not None:
                self.results[node.index] = record.result
                self.judged[node.index] = self.judge(node, record)
            else:
                self.judged[node.index] = NO_RESULT
            if self.adaptive and not self.informed:
                self.informed = self.informative(node, record)
        output = self.model.graph.output
        if isinstance(output, NodeRef):
            last = self.records.get(output.index)
            final = last.result if last is not None else None
        else:
            final = wrapped(self.values[output.name])
        used = self.clock.now() - self.start
        every = [*self.records.values(), *self.inner]
        if any(r.status in (Status.FAILED, Status.CRASHED) for r in every):
            status = Status.FAILED
        elif final is None:
            status = Status.NO_RESULT
        elif used > self.total + 1e-9:
            status = Status.CONTRACT_EXPIRED
        else:
            status = Status.COMPLETED
        return ProgramRecord(
            result=final,
            status=status,
            records=tuple(every),
            allocations=tuple(float(a) for a in self.allocation),
            time_used=used,
        )

    # --- one handler per kind of node ------------------------------------------------------

    def step(self, node: CompileNode) -> RunRecord:
        match node:
            case ChoiceNode():
                return self.best_of(node)
            case IfNode():
                return self.conditional(node)
            case LoopNode():
                return self.loop(node)
        skipped = self.not_run(node)
        if skipped is not None:
            return no_result(node.name, skipped)
        match node:
            case ElementaryNode() | TestNode():
                module, args, kwargs = self.arguments(node)
                return run(module, args, kwargs, budget=Budget(clock=self.clock))
            case ModuleNode(callee=None):
                module, args, kwargs = self.arguments(node)
                share = self.budget(node)
                allocation = float(node.run_time(share))
                if not node.starts(share):
                    return no_result(
                        node.name,
                        f"not run: its share ({share:g}) is less than its step ({node.step:g}):"
                        " it could not be sure to answer within it",
                    )
                if self.certainly_nothing(node, allocation):
                    return no_result(
                        node.name,
                        f"not run: with {allocation:g} of its share of {share:g} (its step "
                        f"{node.step:g} kept back) its profile gives it no result",
                    )
                return self.call(module, args, kwargs, allocation)
            case ModuleNode(callee=callee):
                _, args, _ = self.arguments(node, callee.model.program.inputs)
                return self.subprogram(callee, args, self.budget(node), node.name)
        raise AssertionError(node)

    def best_of(self, node: ChoiceNode) -> RunRecord:
        """The best applicable alternative's result (by the judged qualities, the first on
        ties); none applicable, or none with a result, is a no-result, not an exception."""
        applicable = self.decided(node)
        chosen = [s for s, ok in zip(node.values, applicable, strict=True) if ok]
        present = [s for s in chosen if self.value(s) is not MISSING]
        if not present:
            why = (
                f"all {len(node.values)} preconditions are false"
                if not chosen
                else "none of the applicable ones has a result"
            )
            variable = self.model.graph.nodes[node.index].variable
            return no_result(
                "best-of",
                f"schema '{self.model.program.name}': no alternative of best-of '{variable}' "
                f"is applicable ({why})",
            )
        candidates = [wrapped(self.value(s)) for s in present]
        scores = [
            self.judged.get(s.index, r.quality) if isinstance(s, NodeRef) else r.quality
            for s, r in zip(present, candidates, strict=True)
        ]
        best = candidates[max(range(len(candidates)), key=lambda i: (scores[i], -i))]
        return RunRecord("best-of", Status.COMPLETED, best, 0.0, 0.0, registered=1)

    def conditional(self, node: IfNode) -> RunRecord:
        """The branch the condition selects, run with the if's time."""
        condition = node.condition
        if isinstance(condition, NodeRef) and condition.index not in self.results:
            variable = self.model.graph.nodes[condition.index].variable
            return no_result("if", f"not run: its condition '{variable}' has no value")
        plan = node.branches[0 if truth(self.value(condition)) else 1]
        index_of = {n.variable: i for i, n in enumerate(self.model.graph.nodes)}
        inputs = {
            name: self.values[name]
            if name not in index_of
            else self.results.get(index_of[name], MISSING)
            for name in plan.compiled.model.program.inputs
        }
        given = self.budget(node)
        return self.subprogram(plan.compiled, inputs, given, f"if -> {plan.compiled.name}")

    def loop(self, node: LoopNode) -> RunRecord:
        """A map's or a repeat's calls, one after another, each with its share of the loop's
        time; the result is the list of their results (`MISSING` for a call without one),
        its quality their mean (1 for no calls)."""
        skipped = self.not_run(node)
        if skipped is not None:
            return no_result(node.name, skipped)
        module = node.call.entry.module if node.call.entry is not None else None
        if module is None:
            raise ExecutionError(
                f"schema '{self.model.program.name}': '{node.call.name}' is known only by its "
                "profile (no code to run)"
            )
        calls, qualities = self.loop_calls(node, module)
        if len(calls) != node.count:
            self.model = self.model.with_count(node.index, len(calls))
            self.replan()
        share = self.budget(node)
        shares = run_time_split(node.call, qualities, share, self.compiled.resolution)
        start = self.clock.now()
        records = []
        for i, args in enumerate(calls):
            left = share - (self.clock.now() - start) - float(shares[i + 1 :].sum())
            given = min(float(shares[i]), max(0.0, left))
            if not node.call.starts(given):
                records.append(
                    no_result(
                        module.name,
                        f"not run: its share ({given:g}) is less "
                        f"than its step ({node.call.step:g})",
                    )
                )
                continue
            allocation = float(node.call.run_time(given))
            if self.certainly_nothing(node.call, allocation, qualities[i]):
                records.append(
                    no_result(
                        module.name,
                        f"not run: with {allocation:g} of its share of {given:g} its profile"
                        " gives it no result",
                    )
                )
                continue
            records.append(self.call(module, args, {}, allocation))
        self.inner.extend(records)
        quality = float(np.mean([r.quality for r in records])) if records else 1.0
        value = [r.result.value if r.result is not None else MISSING for r in records]
        failed = any(r.status in (Status.FAILED, Status.CRASHED) for r in records)
        return RunRecord(
            node.name,
            Status.FAILED if failed else Status.COMPLETED,
            Result(value, quality),
            self.clock.now() - start,
            share,
            registered=1,
        )

    def count_input_collections(self) -> None:
        """The maps over program inputs know their counts from the start: where one is not the
        count planned for, the whole time is re-planned with that count's profile."""
        planned = self.model
        for node in planned.nodes:
            if not isinstance(node, LoopNode) or node.kind != "map":
                continue
            source = planned.graph.nodes[node.index].args[0]
            if isinstance(source, InputRef):
                items = plain(self.values[source.name])
                if is_collection(items) and len(items) != node.count:
                    self.model = self.model.with_count(node.index, len(items))
        if self.model is not planned:
            self.replan()

    def loop_calls(self, node: LoopNode, module: AnytimeModule) -> tuple[list[list[Any]], Array]:
        """Each call's arguments and the qualities of its quality-carrying inputs (c, m): a
        map's item first, at its own quality (a `Result`'s, else the collection's); a repeat's
        calls all alike."""
        sources = self.model.graph.nodes[node.index].args
        carrying = {module.parameters.index(name) for name in module.inputs}
        judged = judged_inputs(node.call, self.judged, self.qualities)
        rest = [self.argument(s, i in carrying) for i, s in enumerate(sources)]
        if node.kind == "repeat":
            n = node.most
            return [list(rest) for _ in range(n)], np.tile(judged, (n, 1)).reshape(n, -1)
        collection = self.value(sources[0])
        items = plain(collection)
        if not is_collection(items):
            variable = self.model.graph.nodes[node.index].variable
            raise ExecutionError(
                f"schema '{self.model.program.name}': the collection of map '{variable}' must "
                f"be a sequence (a list or a tuple), got {type(items).__name__}"
            )
        outer = quality_of(collection)
        calls, qualities = [], []
        for item in items:
            if 0 in carrying:  # a plain item has the collection's quality
                item = item if isinstance(item, Result) else Result(item, outer)
            calls.append([passed(item, 0 in carrying), *rest[1:]])
            quality = list(judged)
            for axis in node.item_axes:
                quality[axis] = item.quality if isinstance(item, Result) else outer
            qualities.append(quality)
        return calls, np.asarray(qualities, dtype=np.float64).reshape(len(calls), len(judged))

    def subprogram(
        self,
        compiled: CompiledProgram,
        inputs: Sequence[Any] | Mapping[str, Any],
        given: float,
        name: str,
    ) -> RunRecord:
        """A called schema or an if's branch, run on this run's clock: one record for the
        call, its own calls' records kept after it."""
        sub = Execution(
            compiled,
            inputs,
            Budget(given, self.clock, self.stop),
            self.adaptive,
            self.mode,
            self.observers,
        ).run()
        self.inner.extend(sub.records)
        return RunRecord(
            module=name,
            status=sub.status,
            result=sub.result,
            time_used=sub.time_used,
            allocation=given,
            registered=int(sub.result is not None),
        )

    # --- time --------------------------------------------------------------------------------

    def certainly_nothing(
        self, node: ModuleNode, allocation: float, inputs: Array | None = None
    ) -> bool:
        """Whether the module's profile says it has no result with this allocation, at the
        qualities `inputs` (default: those its inputs were judged to have): then it is not
        started (it could only use time, past its share when that is less than its step)."""
        judged = judged_inputs(node, self.judged, self.qualities) if inputs is None else inputs
        q = np.asarray(judged, dtype=np.float64).reshape(1, -1)
        return bool(node.profile.no_result(q, np.asarray([allocation]))[0] >= 1.0 - 1e-12)

    def budget(self, node: ModuleNode | IfNode | LoopNode) -> float:
        """The time a node gets: its planned share (re-planned first in adaptive mode), less
        whatever earlier calls used past theirs (a module may overshoot by its last step), so
        that the calls still to run keep their planned time and the program its contract."""
        if self.adaptive and self.informed:
            self.adapt()
        spent = self.clock.now() - self.start
        later = sum(
            float(self.allocation[n.time_index])
            for n in self.model.anytime_nodes
            if n.index > node.index and not self.ruled_out(n)
        )
        planned = float(self.allocation[node.time_index])
        left = self.total - spent - later
        given = planned if left >= planned - 1e-9 * max(1.0, abs(self.total)) else max(0.0, left)
        self.allocation[node.time_index] = given  # what it was given, as recorded
        return given

    def informative(self, node: CompileNode, record: RunRecord) -> bool:
        """Whether a finished call is news to the plan (`values.news`); what finishes after
        the last call with time of its own leaves nothing to re-plan."""
        if node.index >= self.last_timed or not isinstance(node, ModuleNode | LoopNode | IfNode):
            return False
        share = float(self.allocation[node.time_index])
        return news(node, record, share, self.compiled.resolution, self.judged, self.qualities)

    def adapt(self) -> None:
        """Adaptive mode, after a call that was news: the split of the time left that the
        compiler finds best given the qualities judged so far, where it is expected to beat the
        split planned (the model's `Replanner`, which remembers its answers). A search not
        remembered is made only where it is worth its time (`worth`)."""
        self.informed = False
        observed = dict(self.judged)
        nodes = self.model.anytime_nodes
        if self.applicable:  # only a best-of's decision rules nodes out
            for other in nodes:
                if other.index not in observed and self.ruled_out(other):
                    observed[other.index] = 0.0
        free = [n.time_index for n in nodes if n.index not in observed]
        before = self.clock.now()
        left = max(0.0, self.total - (before - self.start))
        if len(free) == 1 and left < self.allocation[free[0]] + self.compiled.resolution - 1e-9:
            return  # one call left, and not a lattice unit more for it: nothing to re-split
        planner = self.planner
        if planner is None or planner.model is not self.model:
            planner = self.planner = replanner(self.model, self.compiled.resolution)
        args = (self.qualities, self.allocation, free, left, observed)
        new = planner.plan(*args, search=False)
        if new is None:  # not remembered
            kind = type(self.clock).__name__
            spent, gained, searches = planner.costs.get(kind, (0.0, 0.0, 0))
            if searches and not self.worth(spent / searches, gained / searches, left):
                return
            new = planner.plan(*args)
            assert new is not None
            used = self.clock.now() - before
            planner.costs[kind] = (spent + used, gained + planner.gain, searches + 1)
        self.allocation = new

    def worth(self, cost: float, gain: float, left: float) -> bool:
        """Whether a search is worth making that is expected (by the means of the program's
        searches on this kind of clock) to take `cost` of the run's clock and to gain `gain` in
        expected quality: the time it takes is lost to the calls still to run, and what that
        time is worth is read off the compiled profile at the time left (the gain of its last
        `cost`). On the work clock a search takes no time, and is always made."""
        if cost <= 0.0:
            return True
        if cost >= left:
            return False
        q = np.tile(np.asarray(self.qualities, dtype=np.float64), (2, 1))
        value = self.compiled.profile.expected(q, np.array([left, left - cost]))
        return gain > float(value[0] - value[1])

    def replan(self) -> None:
        """Where a map's count is not the one planned for: the best split of the time left
        among the nodes still to run, given the qualities judged so far (the alternatives ruled
        out count as quality 0)."""
        observed = dict(self.judged)
        for other in self.model.anytime_nodes:
            if other.index not in observed and self.ruled_out(other):
                observed[other.index] = 0.0
        free = [n.time_index for n in self.model.anytime_nodes if n.index not in observed]
        left = max(0.0, self.total - (self.clock.now() - self.start))
        self.allocation = reallocate(
            self.model,
            self.compiled.resolution,
            self.qualities,
            self.allocation,
            free,
            left,
            observed,
        )

    # --- choices -----------------------------------------------------------------------------

    def active(self, node: CompileNode) -> bool:
        """Whether `node` runs: every alternative it is inside is applicable (a precondition
        runs when its best-of does)."""
        tag = node.within
        if tag is None:
            return True
        choice = self.model.node(tag.choice)
        if not self.active(choice):
            return False
        if isinstance(node, TestNode):
            return True
        assert isinstance(choice, ChoiceNode)
        return self.decided(choice)[tag.alternative]

    def decided(self, choice: ChoiceNode) -> list[bool]:
        """The applicable alternatives of a best-of (its preconditions have run); the first
        time, the compiled time of its alternatives is re-split among the applicable ones."""
        if choice.index not in self.applicable:
            # A precondition that has no value (its input had no result) rules its out.
            found = [
                p is None or (p in self.results and bool(self.results[p].value))
                for p in choice.preconditions
            ]
            self.applicable[choice.index] = found
            if not all(found):
                self.allocation = resplit(
                    self.compiled, choice, found, self.allocation, self.qualities
                )
        return self.applicable[choice.index]

    def ruled_out(self, node: CompileNode) -> bool:
        """Whether `node` is known not to run: it is inside an alternative found inapplicable
        (looks only at choices already decided)."""
        tag: Within | None = node.within
        if tag is None:
            return False
        if self.ruled_out(self.model.node(tag.choice)):
            return True
        decided = self.applicable.get(tag.choice)
        return decided is not None and not decided[tag.alternative]

    # --- arguments and qualities -------------------------------------------------------------

    def value(self, source: Source) -> Any:
        """What an argument stands for: a literal's value, an input's value, or a call's
        Result (`MISSING` for a call that has none)."""
        if isinstance(source, Literal):
            return source.value
        if isinstance(source, InputRef):
            return self.values[source.name]
        return self.results.get(source.index, MISSING)

    def not_run(self, node: ModuleNode | ElementaryNode | TestNode | LoopNode) -> str | None:
        """Why a call is not made (an input has no result and its module does not accept
        that), or None when it runs."""
        graph = self.model.graph
        call = graph.nodes[node.index]
        missing = []
        for source in [*call.args, *(s for _, s in call.keywords)]:
            if isinstance(source, NodeRef) and source.index not in self.results:
                missing.append(f"from '{graph.nodes[source.index].function}'")
            elif isinstance(source, InputRef) and self.values[source.name] is MISSING:
                missing.append(f"'{source.name}'")
        entry = node.call.entry if isinstance(node, LoopNode) else node.entry
        module = entry.module if entry is not None else None
        if not missing or (module is not None and module.accepts_missing):
            return None
        plural = "s" if len(missing) > 1 else ""
        names = ", ".join(missing)
        return f"not run: its input{plural} {names} {'have' if plural else 'has'} no result"

    def arguments(
        self, node: ModuleNode | ElementaryNode | TestNode, carrying: Sequence[str] = ()
    ) -> tuple[AnytimeModule, list[Any], dict[str, Any]]:
        """The module a node calls and its arguments: `Result`s where the module takes
        quality-carrying inputs (for a called schema: its parameters `carrying`), else plain
        values."""
        module = node.entry.module if node.entry is not None else None
        call = self.model.graph.nodes[node.index]
        if isinstance(node, ModuleNode) and node.callee is not None:
            quality = set(node.callee.model.quality_inputs)
            positions = {i for i, name in enumerate(carrying) if name in quality}
        elif module is None:
            raise ExecutionError(
                f"schema '{self.model.program.name}': '{node.name}' is known only by its "
                "profile (no code to run)"
            )
        else:
            positions = {module.parameters.index(name) for name in module.inputs}

        args = [self.argument(source, i in positions) for i, source in enumerate(call.args)]
        kwargs = {name: self.argument(source, False) for name, source in call.keywords}
        return module, args, kwargs  # type: ignore[return-value]

    def argument(self, source: Source, carries_quality: bool) -> Any:
        """What a call is passed for an argument (see `arguments`)."""
        return passed(self.value(source), carries_quality)

    def judge(self, node: CompileNode, record: RunRecord) -> float:
        """The quality decisions go by for a node's answer: a best-of's is its chosen
        alternative's, a call's its `decision_quality`."""
        result = record.result
        assert result is not None
        if isinstance(node, ChoiceNode):
            chosen = (
                self.judged[i] for i, r in self.results.items() if r is result and i in self.judged
            )
            return next(chosen, result.quality)
        return decision_quality(node, result, record.time_used, self.judged, self.qualities)
