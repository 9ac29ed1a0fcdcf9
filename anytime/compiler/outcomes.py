"""Compile outcomes as codes, and the one table of the sentences people read.

As scipy.optimize's results carry a `status` and a `message`, a compile result keeps what it
found as `Note`s: a `Code` and the fields its sentence needs (the module, the input, the
numbers). `MESSAGES` renders each the one way every report says it (`anytime compile`, its
JSON, a saved program); tests and programs compare codes and fields, not sentences.

The codes, by what they say:

- which allocator filled the table and why (one per compile result): `DP_EXACT`,
  `HILL_CLIMBING`, `MULTI_START`, `EXHAUSTIVE`, `PROPORTIONAL`; `AUTO_FALLBACK` (auto chose
  another allocator because dp would not be exact, its `obstacle` a nested note) and
  `DP_FALLBACK` (dp was asked for where it is not exact: hill-climbing ran);
- why dp would not be exact (`CompiledProgram.dp_obstacle`): `DAG`, `IF_MIXTURE`,
  `UNKNOWN_MONOTONICITY`, `CALLEE_READS_RESULT`, `STOCHASTIC`, `NOT_INPUT_MONOTONE`;
- what the table's expectations approximate: `SAMPLED`, and how far a dependence between a
  best-of's alternatives could move them: `DEPENDENCE`;
- where the table leaves time unused: `KEPT_SMALLER`;
- what the table cannot vouch for (`CompiledProgram.warnings`): `OUTSIDE_INPUT_GRID`;
- a module's margin in an explanation (`anytime.compiler.explain`): `AT_CEILING`,
  `ZERO_MARGINAL`, `MORE_TIME_LOWERS`;
- `TEXT`: a sentence read from a file saved before the codes, kept as it was written.
"""

from __future__ import annotations

import string
from collections.abc import Mapping
from enum import StrEnum
from typing import Any

from attrs import frozen


class Code(StrEnum):
    """What a compile result says, one code per kind of sentence (see `MESSAGES`)."""

    DP_EXACT = "dp-exact"
    HILL_CLIMBING = "hill-climbing"
    MULTI_START = "multi-start"
    EXHAUSTIVE = "exhaustive"
    PROPORTIONAL = "proportional"
    AUTO_FALLBACK = "auto-fallback"
    DP_FALLBACK = "dp-fallback"
    DAG = "dag"
    IF_MIXTURE = "if-mixture"
    UNKNOWN_MONOTONICITY = "unknown-monotonicity"
    CALLEE_READS_RESULT = "callee-reads-result"
    STOCHASTIC = "stochastic"
    NOT_INPUT_MONOTONE = "not-input-monotone"
    SAMPLED = "sampled"
    DEPENDENCE = "dependence"
    KEPT_SMALLER = "kept-smaller"
    OUTSIDE_INPUT_GRID = "outside-input-grid"
    AT_CEILING = "at-ceiling"
    ZERO_MARGINAL = "zero-marginal"
    MORE_TIME_LOWERS = "more-time-lowers"
    TEXT = "text"


#: The sentence of each code, a format string of the note's fields (`{share:percent}`: a
#: probability as a percentage, see `percent`).
MESSAGES: dict[Code, str] = {
    Code.DP_EXACT: "dp: local compilation, exact for this tree of monotone modules",
    Code.HILL_CLIMBING: "hill-climbing as in the papers (may stop at a local maximum)",
    Code.MULTI_START: (
        "multi-start: hill-climbing from the papers' start, the proportional split, the"
        " best points of a coarse lattice and the neighbouring totals' allocations (no"
        " worse than hill-climbing; may miss the optimum)"
    ),
    Code.EXHAUSTIVE: "exhaustive: every allocation on the time lattice",
    Code.PROPORTIONAL: (
        "proportional: Romanenko's rule, T_i = T * T_i* / sum T_j*, with T_i* the least "
        "time at which module i's expected quality rises (a baseline, not optimal)"
    ),
    Code.AUTO_FALLBACK: "{allocator}, because dp would not be exact: {obstacle}",
    Code.DP_FALLBACK: "dp was asked for but {obstacle}: fell back to hill-climbing",
    Code.DAG: (
        "the program is a DAG (a result is used twice), and local compilation is exact "
        "only for chains and trees"
    ),
    Code.IF_MIXTURE: "an if's output is a mixture of its branches, not a function of its time",
    Code.UNKNOWN_MONOTONICITY: (
        "the quality combination of '{function}' is not known to be monotone (only min and max are)"
    ),
    Code.CALLEE_READS_RESULT: (
        "the called schema '{schema}' reads a result computed in the program, "
        "whose quality falls between its table's grid points, where the schema "
        "runs the allocation its table gives there, not the optimum dp would assume"
    ),
    Code.STOCHASTIC: (
        "module '{module}' has a stochastic profile; local compilation is exact "
        "only when every module's quality is a function of its input qualities and time"
    ),
    Code.NOT_INPUT_MONOTONE: (
        "module '{module}' is not input-monotone: a better quality of input "
        "{input} lowers its output somewhere"
    ),
    Code.SAMPLED: (
        "the shared results' joint outcomes were sampled ({draws} draws) at"
        " {sampled} of {cells} cells of the table: their expected"
        " quality has a standard error of up to {error:.2g}"
    ),
    Code.DEPENDENCE: (
        "a best-of's alternatives are taken as independent given their inputs' qualities,"
        " or as dependent as its :dependence says; if they depend on each other otherwise"
        " (a problem hard for one is hard for all), the expected quality is up to"
        " {below:.3f} lower or {above:.3f} higher than the table's (the bounds over every"
        " dependence: dependence)"
    ),
    Code.KEPT_SMALLER: (
        "at {totals} of the table's totals a smaller total does better:"
        " there the program uses that allocation and leaves the rest of the time unused,"
        " so its quality never falls as the total grows"
    ),
    Code.OUTSIDE_INPUT_GRID: (
        "module '{module}': input '{input}' receives qualities {low:.3g} to"
        " {high:.3g}, but its profile was measured on {measured_low:g} to {measured_high:g};"
        " outside that range (up to {share:percent} of its inputs at some total)"
        " the profile is clamped to its nearest end, and the table may count on it:"
        " measure '{module}' on input qualities that cover {low:.3g} to"
        " {high:.3g} (its Measurement's input_grids), or compile with --strict to"
        " refuse such a table"
    ),
    Code.AT_CEILING: "at its profile's ceiling: more time gains nothing",
    Code.ZERO_MARGINAL: "zero marginal: one more unit gains nothing",
    Code.MORE_TIME_LOWERS: "more time lowers the expected quality",
    Code.TEXT: "{text}",
}


def percent(p: float) -> str:
    """A probability as a percentage with two significant digits (at least 0.01%)."""
    return f"{max(p, 1e-4) * 100:.2g}%" if p < 0.995 else "100%"


class _Formatter(string.Formatter):
    """`str.format` with one more format spec, `percent`."""

    def format_field(self, value: Any, format_spec: str) -> Any:
        if format_spec == "percent":
            return percent(float(value))
        return super().format_field(value, format_spec)


_FORMATTER = _Formatter()


@frozen
class Note:
    """One outcome of a compilation: its code and the fields its message is made of (plain
    numbers and strings, or a nested `Note`), sorted by name."""

    code: Code
    fields: tuple[tuple[str, Any], ...] = ()

    @classmethod
    def of(cls, code: Code, **fields: Any) -> Note:
        return cls(Code(code), tuple(sorted(fields.items())))

    def __getitem__(self, name: str) -> Any:
        return dict(self.fields)[name]

    @property
    def message(self) -> str:
        """The sentence people read: `MESSAGES[code]` with the fields filled in."""
        return _FORMATTER.format(MESSAGES[self.code], **dict(self.fields))

    def __str__(self) -> str:
        return self.message

    def __format__(self, format_spec: str) -> str:
        return format(self.message, format_spec)

    def to_dict(self) -> dict[str, Any]:
        """The note as plain data (a nested note as its own mapping), for a file."""
        data: dict[str, Any] = {"code": self.code.value}
        for name, value in self.fields:
            data[name] = value.to_dict() if isinstance(value, Note) else value
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Note:
        """The note `to_dict` wrote (ValueError: an unknown code, KeyError: none)."""
        fields = {
            str(name): cls.from_dict(value) if isinstance(value, Mapping) else value
            for name, value in data.items()
            if name != "code"
        }
        return cls.of(Code(data["code"]), **fields)


def text(sentence: str) -> Note:
    """A sentence without a code (read from a file saved before the codes)."""
    return Note.of(Code.TEXT, text=sentence)
