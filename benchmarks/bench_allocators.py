"""Allocators on random programs of every shape (scratch, being written)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from bench_compiler import one_input, random_parents, random_profile, two_inputs

from anytime.dsl import Program, parse_schemas
from anytime.library import AnytimeLibrary
from anytime.modules import Context, Registry, Result, elementary, interruptible


def three_inputs(ctx: Context, a: Result, b: Result, c: Result) -> Iterator[Result]:
    while not ctx.expired:
        ctx.tick(1)
        yield Result(None, min(a.quality, b.quality, c.quality))


BODIES = {1: one_input, 2: two_inputs, 3: three_inputs}


def _condition(x: Result) -> bool:
    return True


def random_general(
    rng: np.random.Generator,
    n: int,
    shape: str,
    shared: int,
    choice: str,
    horizon: float,
    stochastic: bool,
) -> tuple[Program, AnytimeLibrary]:
    """A random program of `n` nodes that get time (modules, or an if of two): a chain or a
    binary tree (`shape`), `shared` of whose results are read once more by a later module (a
    DAG), with `choice` "best-of" (a module reads the best of two of its inputs), "if" (a leaf is
    an if of two modules) or "none". Leaves read the program's one input `x`."""
    parents = random_parents(rng, n, shape)
    reads: list[list[str]] = [[f"r{j}" for j in range(n) if parents[j] == i] for i in range(n)]
    for _ in range(shared):
        options = [
            (i, j)
            for i in range(n - 1)
            for j in range(i + 1, n)
            if j != parents[i] and f"r{i}" not in reads[j] and len(reads[j]) < 2
        ]
        if not options:  # every later module reads two results already
            break
        i, j = options[int(rng.integers(len(options)))]
        reads[j].append(f"r{i}")
    registry = Registry()
    steps = []
    best_of = choice == "best-of" and any(len(r) >= 2 for r in reads)
    leaves = [i for i in range(n) if not reads[i]]
    branch = int(rng.choice(leaves)) if choice == "if" else -1
    for i in range(n):
        args = reads[i] or ["x"]
        if best_of and len(args) >= 2:
            steps.append(f"  (setf b{i} (best-of {args[0]} {args[1]}))")
            args = [f"b{i}", *args[2:]]
            best_of = False
        names = ("a", "b", "c")[: len(args)]
        for name in (f"m{i}", f"m{i}e") if i == branch else (f"m{i}",):
            profile = random_profile(rng, name, names, horizon, stochastic)
            body = BODIES[len(args)]
            interruptible(name, inputs=list(names), profile=profile, registry=registry)(body)
        call = f"(m{i} {' '.join(args)})"
        if i == branch:
            call = f"(if (ok? x) {call} (m{i}e {' '.join(args)}) :p 0.4)"
        steps.append(f"  (setf r{i} {call})")
    elementary("ok?", registry=registry)(_condition)
    text = f"(defschema random (x)\n{chr(10).join(steps)}\n  r{n - 1})\n"
    library = AnytimeLibrary.default(registry=registry, plugins=False)
    return parse_schemas(text, known_functions=library.known_functions())["random"], library
