"""Random programs for the compiler tests: chains and trees of anytime modules with random
input-monotone profiles, and the libraries that hold them.

A program is drawn as a tree of n anytime modules `m1..mn`, numbered in post-order (children
left to right, then the parent), which is also the order of the dataflow graph's nodes and of
the compiler's allocation vector. A leaf reads a program input (`x`, sometimes `y`), and its
profile is either conditioned on that input's quality or not. An inner module reads one or two
subtrees, sometimes with a program input, a literal (quality 1) or the minimum / maximum of
program inputs (a call that takes no time) as its second input, or the minimum / maximum of two
subtrees through an elementary function (`lo` = min, `hi` = max).

Every profile is non-decreasing in each input quality, so local compilation is exact for the
deterministic ones (`tabulate`, a point mass at the curve), and a stochastic one's CDFs are
non-increasing in input quality and in time (mixtures of point masses at the curve and below it
and of a uniform spread up to it), so it is input-monotone in the stochastic-dominance sense.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
from attrs import frozen
from hypothesis import strategies as st

from anytime.library import AnytimeLibrary, RegistrySource
from anytime.modules import Context, Registry, Result, elementary, interruptible
from anytime.profiles import ConditionalPerformanceProfile, default_bins, new_profile, tabulate
from anytime.profiles.profile import point_mass

#: The compile grid all random programs use: totals 0..40 on a lattice of 5.
TIME = np.arange(0, 41, 5, dtype=np.float64)
#: The program input-quality grid.
QUALITY = [0.0, 0.5, 1.0]

Array = np.ndarray[Any, Any]


@frozen
class Curve:
    """`f(t, q_1..q_m) = scale * sum_i w_i * g_i(q) ** a_i * (1 - exp(-c_i t))`, where `g_i` is
    the identity (m = 1), or min, product or mean of two inputs (m = 2): non-decreasing in every
    input quality and in time, with values in [0, 1]."""

    n_inputs: int
    weights: tuple[float, ...]
    powers: tuple[float, ...]
    rates: tuple[float, ...]
    combos: tuple[str, ...]
    scale: float

    def __call__(self, t: Any, *q: Any) -> Array:
        t = np.asarray(t, dtype=np.float64)
        total = np.zeros(np.broadcast_shapes(t.shape, *(np.shape(x) for x in q)))
        for w, a, c, combo in zip(self.weights, self.powers, self.rates, self.combos, strict=True):
            if self.n_inputs == 0:
                g: Any = 1.0
            elif self.n_inputs == 1:
                g = q[0]
            elif combo == "min":
                g = np.minimum(q[0], q[1])
            elif combo == "product":
                g = np.asarray(q[0]) * np.asarray(q[1])
            else:
                g = (np.asarray(q[0]) + np.asarray(q[1])) / 2
            total = total + w * np.power(g, a) * -np.expm1(-c * t)
        return np.clip(self.scale * total, 0.0, 1.0)


@st.composite
def curves(draw: st.DrawFn, n_inputs: int) -> Curve:
    k = draw(st.integers(1, 3))
    raw = [draw(st.floats(0.1, 1.0)) for _ in range(k)]
    weights = tuple(w / sum(raw) for w in raw)
    return Curve(
        n_inputs=n_inputs,
        weights=weights,
        powers=tuple(draw(st.floats(0.3, 3.0)) for _ in range(k)),
        rates=tuple(draw(st.floats(0.01, 0.5)) for _ in range(k)),
        combos=tuple(draw(st.sampled_from(["min", "product", "mean"])) for _ in range(k)),
        scale=draw(st.floats(0.5, 1.0)),
    )


@st.composite
def quality_grids(draw: st.DrawFn) -> list[float]:
    """An increasing grid of 3 to 5 qualities (not always reaching 0 or 1: outside, clamped)."""
    inner = draw(
        st.lists(st.integers(1, 19).map(lambda i: i / 20), min_size=1, max_size=3, unique=True)
    )
    low = draw(st.sampled_from([0.0, 0.0, 0.05]))
    high = draw(st.sampled_from([1.0, 1.0, 0.95]))
    return sorted({low, high, *inner})


#: Profile time grids: the compile lattice, a coarser one, and one off the lattice (interpolated).
PROFILE_TIMES = [list(TIME), [0.0, 10.0, 20.0, 40.0], [0.0, 3.0, 12.0, 27.0, 50.0]]


@frozen
class ModuleSpec:
    """One anytime module of a random program: its name, its quality-carrying inputs (the
    profile's axes, in order) and its profile."""

    name: str
    inputs: tuple[str, ...]
    arity: int  # positional parameters (some may carry no quality)
    curve: Curve
    profile: ConditionalPerformanceProfile
    stochastic: bool


@frozen
class RandomProgram:
    """A random program: its schema text, its modules in post-order, and its shape."""

    text: str
    modules: tuple[ModuleSpec, ...]
    shape: str  # "chain", "tree" or "dag"
    quality_inputs: tuple[str, ...]  # program inputs whose quality conditions the output

    @property
    def n(self) -> int:
        return len(self.modules)

    def library(self) -> AnytimeLibrary:
        return library_of(self.modules)


def stochastic_table(
    curve_values: Array, bins: Array, weights: Sequence[float], low: float
) -> Array:
    """A mixture of a point mass at the curve, one at `low` times it, and a uniform spread over
    the bins up to the curve's: each component's CDF is non-increasing in the curve value, so
    the profile is input- and time-monotone in the stochastic-dominance sense."""
    k = np.clip(np.searchsorted(bins, curve_values, side="right") - 1, 0, len(bins) - 2)
    spread = (np.arange(len(bins) - 1) <= k[..., None]) / (k[..., None] + 1.0)
    w = np.asarray(weights) / np.sum(weights)
    table = (
        w[0] * point_mass(curve_values, bins)
        + w[1] * point_mass(low * curve_values, bins)
        + w[2] * spread
    )
    return table / table.sum(axis=-1, keepdims=True)


@st.composite
def module_specs(
    draw: st.DrawFn, name: str, inputs: tuple[str, ...], arity: int, stochastic: bool
) -> ModuleSpec:
    curve = draw(curves(len(inputs)))
    time = draw(st.sampled_from(PROFILE_TIMES))
    grids = [draw(quality_grids()) for _ in inputs]
    if not stochastic:
        profile = tabulate(curve, time, input_grids=grids, inputs=inputs, module=name)
    else:
        bins = default_bins()
        mesh = np.meshgrid(*[np.asarray(g) for g in grids], np.asarray(time), indexing="ij")
        values = np.broadcast_to(curve(mesh[-1], *mesh[:-1]), mesh[-1].shape)
        weights = [draw(st.floats(0.05, 1.0)) for _ in range(3)]
        low = draw(st.floats(0.2, 0.9))
        profile = new_profile(
            input_grids=grids,
            time=time,
            bins=bins,
            probability=stochastic_table(values, bins, weights, low),
            inputs=inputs,
            module=name,
        )
    return ModuleSpec(name, inputs, arity, curve, profile, stochastic)


@st.composite
def tree_programs(
    draw: st.DrawFn, min_modules: int = 2, max_modules: int = 4, stochastic: bool = False
) -> RandomProgram:
    """A chain or tree of 2..4 modules. With `stochastic`, a random non-empty subset of the
    modules has a stochastic profile (the rest stay deterministic)."""
    n = draw(st.integers(min_modules, max_modules))
    random_set = draw(st.sets(st.integers(1, n), min_size=1)) if stochastic else set()
    specs: list[ModuleSpec] = []
    used_inputs: set[str] = set()

    def new_module(inputs: tuple[str, ...], arity: int) -> str:
        name = f"m{len(specs) + 1}"
        specs.append(draw(module_specs(name, inputs, arity, len(specs) + 1 in random_set)))
        return name

    def build(k: int) -> str:
        """An expression calling k anytime modules."""
        if k == 1:
            program_input = draw(st.sampled_from(["x", "x", "y"]))
            used_inputs.add(program_input)
            conditioned = draw(st.booleans())
            name = new_module(("a",) if conditioned else (), 1)
            return f"({name} {program_input})"
        children = draw(st.integers(1, 2)) if k >= 3 else 1
        if children == 1:
            child = build(k - 1)
            extra = draw(st.sampled_from(["none", "none", "x", "literal", "elementary"]))
            if extra == "none":
                return f"({new_module(('a',), 1)} {child})"
            if extra == "x":
                used_inputs.add("x")
                second = "x"
            elif extra == "literal":
                second = "3"
            else:  # a call that takes no time: the min or max of program inputs and a literal
                other = draw(st.sampled_from(["y", "3"]))
                used_inputs.update({"x"} | ({"y"} if other == "y" else set()))
                second = f"({draw(st.sampled_from(['lo', 'hi']))} x {other})"
            name = new_module(("a", "b"), 2)
            return f"({name} {child} {second})"
        left_size = draw(st.integers(1, k - 2))
        left = build(left_size)
        right = build(k - 1 - left_size)
        how = draw(st.sampled_from(["module", "lo", "hi"]))
        if how == "module":
            return f"({new_module(('a', 'b'), 2)} {left} {right})"
        return f"({new_module(('a',), 1)} ({how} {left} {right}))"

    # Sometimes the output itself is an elementary combination of two subtrees.
    if n >= 2 and draw(st.integers(0, 4)) == 0:
        left_size = draw(st.integers(1, n - 1))
        body = f"({draw(st.sampled_from(['lo', 'hi']))} {build(left_size)} {build(n - left_size)})"
    else:
        body = build(n)
    params = sorted(used_inputs)
    text = f"(defschema p ({' '.join(params)})\n  {body})\n"
    quality = tuple(
        name for name in params if _reads_quality(specs, body, name)
    )  # checked against the compiler's own finding in the tests
    shape = "chain" if _is_chain(body) else "tree"
    return RandomProgram(text, tuple(specs), shape, quality)


def _reads_quality(specs: Sequence[ModuleSpec], body: str, name: str) -> bool:
    """Whether some call passes program input `name` in a quality-carrying position (a leaf
    conditioned on it, or an inner module's second input)."""
    by_name = {s.name: s for s in specs}
    for token in _calls(body):
        function, args = token
        spec = by_name.get(function)
        if spec is None:  # `lo` and `hi`: every argument carries quality
            if name in args:
                return True
            continue
        for position, arg in enumerate(args):
            carries = position < len(spec.inputs) if spec.arity == 2 else bool(spec.inputs)
            if arg == name and carries:
                return True
    return False


def _calls(body: str) -> Iterator[tuple[str, list[str]]]:
    """(function, top-level argument texts) of every call in an expression."""
    depth, starts = 0, []
    for i, ch in enumerate(body):
        if ch == "(":
            starts.append(i)
            depth += 1
        elif ch == ")":
            start = starts.pop()
            depth -= 1
            yield _split_call(body[start + 1 : i])


def _split_call(inner: str) -> tuple[str, list[str]]:
    parts, depth, current = [], 0, ""
    for ch in inner:
        if ch == " " and depth == 0:
            if current:
                parts.append(current)
            current = ""
            continue
        depth += ch == "("
        depth -= ch == ")"
        current += ch
    if current:
        parts.append(current)
    return parts[0], parts[1:]


def _is_chain(body: str) -> bool:
    """Every call has at most one computed argument."""
    return all(sum(a.startswith("(") for a in args) <= 1 for _, args in _calls(body))


# --- libraries -------------------------------------------------------------------------------


def _one(ctx: Context, a: Any) -> Iterator[Result]:
    yield Result(None, 0.0)


def _two(ctx: Context, a: Any, b: Any) -> Iterator[Result]:
    yield Result(None, 0.0)


def _pair(a: Any, b: Any) -> Any:
    return (a, b)


def library_of(
    specs: Sequence[ModuleSpec], extra: Callable[[Registry], None] | None = None
) -> AnytimeLibrary:
    """A library of a fresh registry holding the modules, plus `lo` (min) and `hi` (max)."""
    registry = Registry()
    for spec in specs:
        function = _one if spec.arity == 1 else _two
        interruptible(spec.name, inputs=spec.inputs, profile=spec.profile, registry=registry)(
            function
        )
    elementary("lo", combine=min, registry=registry)(_pair)
    elementary("hi", combine=max, registry=registry)(_pair)
    if extra is not None:
        extra(registry)
    return AnytimeLibrary([RegistrySource(registry)])


#: DAG programs (a result used twice), by number of anytime modules: (text, arities/inputs).
DAG_TEMPLATES: dict[str, tuple[str, tuple[tuple[tuple[str, ...], int], ...]]] = {
    "both-inputs-shared": (
        "(defschema p (x) (setf s (m1 x)) (m2 s s))",
        ((("a",), 1), (("a", "b"), 2)),
    ),
    "shared-and-refined": (
        "(defschema p (x) (setf s (m1 x)) (m3 (m2 s) s))",
        ((("a",), 1), (("a",), 1), (("a", "b"), 2)),
    ),
    "diamond": (
        "(defschema p (x) (setf s (m1 x)) (m4 (m2 s) (m3 s)))",
        ((("a",), 1), (("a",), 1), (("a",), 1), (("a", "b"), 2)),
    ),
    "shared-through-min": (
        "(defschema p (x) (setf s (m1 x)) (m3 (lo (m2 s) s)))",
        ((("a",), 1), (("a",), 1), (("a",), 1)),
    ),
}


@st.composite
def dag_programs(draw: st.DrawFn) -> RandomProgram:
    template = draw(st.sampled_from(sorted(DAG_TEMPLATES)))
    text, shapes = DAG_TEMPLATES[template]
    specs = tuple(
        draw(module_specs(f"m{i + 1}", inputs, arity, False))
        for i, (inputs, arity) in enumerate(shapes)
    )
    return RandomProgram(text, specs, "dag", ("x",))
