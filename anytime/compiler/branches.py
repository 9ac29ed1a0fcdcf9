"""An if's branches: each compiled as a program of its own, and the if's profile, the mixture
of the branches' compiled profiles."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from anytime.compiler.model import BranchPlan
from anytime.dsl.graph import DataflowGraph, NodeRef
from anytime.dsl.program import If, Program, Var, variables, walk
from anytime.library import AnytimeLibrary
from anytime.profiles.profile import ConditionalPerformanceProfile, default_bins, new_profile


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


def if_branches(
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


def mixture(
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
