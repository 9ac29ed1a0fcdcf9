"""Saving a compiled program and loading it back, with its table, without compiling again.

The file is a profile file (`anytime-profile/1`): the compiled profile, with `modules` and
`allocation` (its time-allocation table), so that anything that reads profiles reads it. It
adds one mapping, `compiled`, that a reader of profiles skips: the program's schema text (and
that of every schema it calls), the fields of the compile result (its notes both as the
sentences people read and, under `codes`, as codes with their fields), a fingerprint of each
module's profile it was compiled against, and, nested the same way, the compiled schemas it
calls and the compiled branches of its ifs.

Loading resolves the program against the library again (the modules' code comes from there)
and takes every table from the file; a module whose profile has changed since is an error,
since the table was optimal for the old one. A file saved before the codes has only the
sentences: its obstacle to dp is the one found again (where it reads the same), and any other
sentence is kept as it was written (`Code.TEXT`).

Everything loaded is checked with the rules `anytime plot` reads a compiled file by, each
error a `CompileError` whose `where` is the file and whose message names the field (and the
first bad cell): tables of the program's shape, of numbers (not ragged), allocations finite
and >= 0, baselines and dependence bounds qualities in [0, 1], standard errors finite and
>= 0, the resolution a finite number > 0 whose lattice up to the largest total has at most
`MAX_LATTICE` points, the allocators among the known ones. A tampered file is refused, never run.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import yaml

from anytime.compiler.allocators import ALLOCATORS, dp_obstacle
from anytime.compiler.loops import loop_profiles
from anytime.compiler.model import CompileError, CompileModel, IfNode, LoopNode, ModuleNode
from anytime.compiler.outcomes import Note, text
from anytime.compiler.resolve import build_model
from anytime.compiler.result import CompiledProgram
from anytime.dsl import format_program, parse_schemas
from anytime.dsl.program import Program, SchemaFile
from anytime.errors import AnytimeError
from anytime.library import AnytimeLibrary
from anytime.profiles.io import (
    profile_from_dict,
    profile_to_dict,
    read_profile_file,
    save_profile,
)
from anytime.profiles.io.document import format_number
from anytime.profiles.profile import ConditionalPerformanceProfile

#: The most points of the time lattice (the multiples of a file's resolution up to its largest
#: total) a loaded file may imply: its loops' profiles are computed on it again. The command
#: line compiles on at most 20,000.
MAX_LATTICE = 1_000_000

#: The compile result's fields that are plain data, as the file carries them.
_FIELDS = (
    "allocator",
    "requested",
    "dp_obstacle",
    "kept_smaller",
    "warnings",
    "resolution",
    "exhaustive_gap",
)


def save_compiled(compiled: CompiledProgram, path: str | os.PathLike[str]) -> None:
    """Write `compiled` to `path`, atomically (OSError if it cannot)."""
    document = _document(compiled)
    document["schema"] = _schema_text(compiled)
    save_profile(
        compiled.profile,
        path,
        extra={
            "modules": compiled.modules,
            "allocation": compiled.allocation,
            "compiled": document,
        },
    )


def load_compiled(path: str | os.PathLike[str], library: AnytimeLibrary) -> CompiledProgram:
    """Read a compiled program written by `save_compiled`, its modules from `library`.

    Raises:
        ProfileError: the file is not a readable profile file.
        CompileError: it has no compiled program, or one that does not fit the library (a
            module missing or changed since), or its tables do not fit its program.
    """
    filename = os.fspath(path)
    profile, data = read_profile_file(path)  # the file read once, by the fast loader
    document = data.get("compiled")
    if not isinstance(document, Mapping) or not isinstance(document.get("schema"), str):
        raise CompileError(
            "compiled: missing (a profile, not a compiled program: expected a file written "
            "by `anytime compile -o` or save_compiled)",
            where=filename,
        )
    try:
        schemas = parse_schemas(document["schema"], f"{filename} (compiled.schema)")
    except AnytimeError as error:
        raise CompileError(f"compiled.schema: {error}", where=filename) from None
    top = document.get("name")
    if not isinstance(top, str) or top not in schemas:
        raise CompileError(
            f"compiled.name: expected one of {list(schemas.names)}, got {top!r}", where=filename
        )
    loader = _Loader(filename, library, schemas)
    tables = {"allocation": data.get("allocation"), "modules": data.get("modules")}
    return loader.program(schemas[top], profile, {**document, **tables}, "compiled", top=True)


def _document(compiled: CompiledProgram) -> dict[str, Any]:
    """The compile result's fields, nested callees and branches, for the file."""
    document: dict[str, Any] = {"name": compiled.name}
    for field in _FIELDS:
        value = getattr(compiled, field)
        if isinstance(value, Note):
            value = value.message
        elif isinstance(value, tuple):
            value = [v.message if isinstance(v, Note) else v for v in value]
        document[field] = value
    obstacle = compiled.dp_obstacle
    document["codes"] = {
        "dp_obstacle": None if obstacle is None else obstacle.to_dict(),
        "warnings": [warning.to_dict() for warning in compiled.warnings],
    }
    document["baselines"] = {k: _plain(v) for k, v in compiled.baselines.items()}
    if compiled.standard_error is not None:
        document["standard_error"] = _plain(compiled.standard_error)
    if compiled.dependence is not None:
        document["dependence"] = _plain(compiled.dependence)
    document["profiles"] = {
        node.name: fingerprint(node.profile)
        for node in _modules_of(compiled.model.anytime_nodes)
        if isinstance(node, ModuleNode) and node.callee is None
    }
    nested = {}
    for node in compiled.model.anytime_nodes:
        if isinstance(node, ModuleNode) and node.callee is not None:
            nested[node.name] = _nested(node.callee)
    if nested:
        document["callees"] = nested
    branches = {
        plan.compiled.name: _nested(plan.compiled)
        for node in compiled.model.anytime_nodes
        if isinstance(node, IfNode)
        for plan in node.branches
    }
    if branches:
        document["branches"] = branches
    return document


def _nested(compiled: CompiledProgram) -> dict[str, Any]:
    return {
        "profile": profile_to_dict(compiled.profile),
        "modules": list(compiled.modules),
        "allocation": _plain(compiled.allocation),
        **_document(compiled),
    }


def _schema_text(compiled: CompiledProgram) -> str:
    """The program and every schema it calls (callees first), as DSL text that parses back to
    the same programs."""
    programs: dict[str, Program] = {}

    def visit(program: CompiledProgram) -> None:
        for node in program.model.anytime_nodes:
            if isinstance(node, ModuleNode) and node.callee is not None:
                visit(node.callee)
        programs.setdefault(program.name, program.model.program)

    visit(compiled)
    return "\n\n".join(format_program(p) for p in programs.values()) + "\n"


def stored_curves(
    filename: str, profile: ConditionalPerformanceProfile, data: Mapping[str, Any]
) -> tuple[dict[str, np.ndarray], np.ndarray | None]:
    """The baselines and the best-ofs' dependence bounds a compiled program's file holds
    (`save_compiled`; `data` the file's mapping, `profile` its profile), checked as
    `load_compiled` checks them but without the library: what `anytime plot` draws with the
    program's curve. A file without a compiled program (a profile) has neither: ({}, None).

    Raises:
        CompileError: a table of the wrong shape, or not of qualities in [0, 1].
    """
    document = data.get("compiled")
    if not isinstance(document, Mapping):
        return {}, None
    fields, cells = _Fields(filename), profile.probability.shape[:-1]
    return (
        fields.baselines(document, "compiled", cells),
        fields.dependence(document, "compiled", cells),
    )


def fingerprint(profile: ConditionalPerformanceProfile) -> str:
    """A short digest of a profile's contents, to tell a changed profile."""
    text = yaml.safe_dump(profile_to_dict(profile), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _plain(array: Any) -> Any:
    return np.asarray(array, dtype=np.float64).tolist()


class _Fields:
    """The checks of a compiled program's plain fields, each error naming the file and the field:
    what reading its tables needs, without the library."""

    def __init__(self, filename: str) -> None:
        self.filename = filename

    def fail(self, field: str, problem: str) -> CompileError:
        return CompileError(f"{field}: {problem}", where=self.filename)

    def numbers(self, field: str, value: Any) -> np.ndarray:
        """`value` as a table of numbers (any shape): a ragged or non-numeric one is an error."""
        try:
            array = np.asarray(value)
        except ValueError:  # ragged
            array = None
        if array is None or array.dtype.kind not in "iuf" or array.ndim == 0:
            got = "nothing" if value is None else "a ragged or non-numeric table"
            raise self.fail(field, f"expected a table of numbers, got {got}")
        return array.astype(np.float64)

    def check(self, field: str, table: np.ndarray, bad: Callable[[Any], Any], what: str) -> None:
        """An error naming the first cell of `table` where `bad` holds (vectorised)."""
        wrong = np.asarray(bad(table))
        if np.any(wrong):
            index = tuple(int(i) for i in np.argwhere(wrong)[0])
            where = field + "".join(f"[{i}]" for i in index)
            raise self.fail(where, f"expected {what}, got {format_number(float(table[index]))}")

    def baselines(
        self, document: Mapping[str, Any], field: str, cells: tuple[int, ...]
    ) -> dict[str, np.ndarray]:
        """The baselines' expected qualities, each shaped like the table's cells, in [0, 1]."""
        value = document.get("baselines", {})
        if not isinstance(value, Mapping):
            raise self.fail(f"{field}.baselines", f"expected a mapping, got {value!r}")
        baselines = {}
        for key, table in value.items():
            where = f"{field}.baselines.{key}"
            array = self.numbers(where, table)
            if array.shape != cells:
                raise self.fail(
                    where,
                    f"expected shape {list(cells)} (input grids, time), got {list(array.shape)}",
                )
            self.check(where, array, _bad_quality, "a quality in [0, 1]")
            baselines[str(key)] = array
        return baselines

    def dependence(
        self, document: Mapping[str, Any], field: str, cells: tuple[int, ...]
    ) -> np.ndarray | None:
        """The expected qualities over the dependences of the best-ofs' alternatives (None:
        no best-of), the least then the most, each shaped like the table's cells, in [0, 1]."""
        value = document.get("dependence")
        if value is None:
            return None
        where = f"{field}.dependence"
        bounds = self.numbers(where, value)
        if bounds.shape != (2, *cells):
            raise self.fail(
                where,
                f"expected shape {[2, *cells]} (least and most, input grids, time), got"
                f" {list(bounds.shape)}",
            )
        self.check(where, bounds, _bad_quality, "a quality in [0, 1]")
        return bounds


class _Loader(_Fields):
    """Rebuilds a compiled program and, through it, the ones it calls and its branches."""

    def __init__(self, filename: str, library: AnytimeLibrary, schemas: SchemaFile) -> None:
        super().__init__(filename)
        self.library, self.schemas = library, schemas

    def program(
        self,
        program: Program,
        profile: ConditionalPerformanceProfile,
        document: Mapping[str, Any],
        field: str,
        *,
        top: bool = False,
    ) -> CompiledProgram:
        """The compiled `program` from its `document` (whose fields are under `field`; the top
        program's `modules` and `allocation` are the file's own top-level fields)."""
        table_field = "" if top else f"{field}."
        cells = profile.probability.shape[:-1]
        allocation = self.numbers(f"{table_field}allocation", document.get("allocation"))
        values = {name: document.get(name) for name in _FIELDS}
        dt = self.resolution(values["resolution"], field, float(profile.time[-1]))
        allocator, requested = self.allocators(values, field)
        callees_doc = _mapping(document.get("callees", {}))
        callees = {
            name: self.nested(self.schemas[name], callees_doc.get(name), f"{field}.callees.{name}")
            for name in program.callees()
        }
        branches_doc = _mapping(document.get("branches", {}))

        def branch(sub: Program) -> CompiledProgram:
            return self.nested(sub, branches_doc.get(sub.name), f"{field}.branches.{sub.name}")

        def loop(call: ModuleNode, most: int, name: str) -> tuple[Any, ...]:
            # a loop's profiles are computed again from its call's (checked below)
            lattice = np.arange(int(np.rint(profile.time[-1] / dt)) + 1, dtype=np.float64) * dt
            return loop_profiles(call, most, lattice, name)

        model = build_model(program, self.library, self.schemas.source, branch, callees, loop)
        modules = document.get("modules")
        if not isinstance(modules, list) or modules != list(model.module_names):
            raise self.fail(
                f"{table_field}modules",
                f"expected {list(model.module_names)} (the program's), got "
                f"{document.get('modules')!r}",
            )
        expected = (*cells, len(model.module_names))
        if allocation.shape != expected:
            raise self.fail(
                f"{table_field}allocation",
                f"expected a table of shape {list(expected)} (input grids, time, one per"
                f" module), got {list(allocation.shape)}",
            )
        self.check(f"{table_field}allocation", allocation, _bad_time, "a finite time >= 0")
        printed = _mapping(document.get("profiles", {}))
        for node in _modules_of(model.anytime_nodes):
            if isinstance(node, ModuleNode) and node.callee is None:
                if printed.get(node.name) != fingerprint(node.profile):
                    raise self.fail(
                        f"{field}.profiles.{node.name}",
                        f"module '{node.name}' has a profile other than the one the program "
                        "was compiled against: compile it again",
                    )
        obstacle, warnings = self.notes(document, field, model)
        return CompiledProgram(
            name=program.name,
            model=model,
            profile=profile,
            allocation=allocation,
            allocator=allocator,
            baselines=self.baselines(document, field, cells),
            exhaustive_gap=self.gap(values["exhaustive_gap"], field),
            resolution=dt,
            requested=requested,
            dp_obstacle=obstacle,
            standard_error=self.standard_error(document, field, profile),
            kept_smaller=self.kept_smaller(values["kept_smaller"], field),
            warnings=warnings,
            dependence=self.dependence(document, field, cells),
        )

    # --- the checks of the plain fields ------------------------------------------------------

    def resolution(self, value: Any, field: str, largest: float) -> float:
        """The allocations' time step: a finite number > 0 (1 in a file without one) whose
        lattice up to the largest total has at most `MAX_LATTICE` points."""
        if value is None:
            return 1.0
        expected = "a finite number > 0 (the allocations' time step)"
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(f"{field}.resolution", f"expected {expected}, got {value!r}")
        dt = float(value)
        if not np.isfinite(dt) or dt <= 0:
            raise self.fail(f"{field}.resolution", f"expected {expected}, got {format_number(dt)}")
        points = largest / dt + 1
        if points > MAX_LATTICE:
            raise self.fail(
                f"{field}.resolution",
                f"expected at most {MAX_LATTICE:,} multiples of it up to the largest total"
                f" {format_number(largest)}, got {format_number(dt)} ({points:.3g} points)",
            )
        return dt

    def allocators(self, values: Mapping[str, Any], field: str) -> tuple[str, str]:
        """The allocator that ran (one of `ALLOCATORS`) and the one asked for ("auto" in a
        file without one)."""
        allocator, requested = values["allocator"], values["requested"] or "auto"
        names = list(ALLOCATORS)
        if allocator not in names:
            raise self.fail(f"{field}.allocator", f"expected one of {names}, got {allocator!r}")
        if requested not in ("auto", *names):
            raise self.fail(
                f"{field}.requested", f"expected one of {['auto', *names]}, got {requested!r}"
            )
        return str(allocator), str(requested)

    def gap(self, value: Any, field: str) -> float | None:
        """The gap to the exhaustive optimum: a finite number, or None (not computed)."""
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
            raise self.fail(
                f"{field}.exhaustive_gap", f"expected a finite number or null, got {value!r}"
            )
        return float(value)

    def kept_smaller(self, value: Any, field: str) -> tuple[float, ...]:
        """The totals where a smaller split was kept: finite numbers >= 0."""
        if value is None or value == []:
            return ()
        array = self.numbers(f"{field}.kept_smaller", value)
        if array.ndim != 1:
            raise self.fail(f"{field}.kept_smaller", "expected a list of totals")
        self.check(f"{field}.kept_smaller", array, _bad_time, "a finite total >= 0")
        return tuple(float(t) for t in array)

    def notes(
        self, document: Mapping[str, Any], field: str, model: CompileModel
    ) -> tuple[Note | None, tuple[Note, ...]]:
        """The obstacle to dp and the warnings, from their codes, or from the sentences of a
        file saved before the codes."""
        codes = document.get("codes")
        if isinstance(codes, Mapping):
            try:
                obstacle = codes.get("dp_obstacle")
                return (
                    None if obstacle is None else Note.from_dict(obstacle),
                    tuple(Note.from_dict(w) for w in codes.get("warnings") or ()),
                )
            except (KeyError, ValueError, TypeError, AttributeError) as error:
                problem = f"not a compile result's codes ({error})"
                raise self.fail(f"{field}.codes", problem) from None
        sentence = document.get("dp_obstacle")
        found = dp_obstacle(model)
        if sentence is None or (found is not None and found.message == sentence):
            obstacle = None if sentence is None else found
        else:
            obstacle = text(str(sentence))
        return obstacle, tuple(text(str(w)) for w in document.get("warnings") or ())

    def standard_error(
        self, document: Mapping[str, Any], field: str, profile: ConditionalPerformanceProfile
    ) -> np.ndarray | None:
        """The table's standard errors (None: every cell exact), shaped like its cells,
        finite and >= 0."""
        value = document.get("standard_error")
        if value is None:
            return None
        where = f"{field}.standard_error"
        error = self.numbers(where, value)
        cells = profile.probability.shape[:-1]
        if error.shape != cells:
            raise self.fail(
                where, f"expected shape {list(cells)} (input grids, time), got {list(error.shape)}"
            )
        self.check(where, error, _bad_time, "a finite number >= 0")
        return error

    def nested(self, program: Program, document: Any, field: str) -> CompiledProgram:
        if not isinstance(document, Mapping):
            raise self.fail(field, "missing (the file holds no table for it)")
        prefix = f"{self.filename}: {field}"
        try:
            profile = profile_from_dict(document.get("profile"), prefix)
        except AnytimeError as error:  # its message names the file: said once, by `where`
            problem = str(error).removeprefix(f"{prefix}: ")
            raise self.fail(f"{field}.profile", problem) from None
        return self.program(program, profile, document, field)


def _bad_time(table: np.ndarray) -> Any:
    return ~np.isfinite(table) | (table < 0)


def _bad_quality(table: np.ndarray) -> Any:
    # an expected quality is a sum of products: 1 may come out a rounding error above it
    return ~np.isfinite(table) | (table < 0) | (table > 1 + 1e-9)


def _modules_of(nodes: Any) -> list[Any]:
    """The nodes that get time, a loop's call in the loop's place (its profile is the call's)."""
    return [node.call if isinstance(node, LoopNode) else node for node in nodes]


def _mapping(value: Any) -> Mapping[str, Any]:
    return value if isinstance(value, Mapping) else {}
