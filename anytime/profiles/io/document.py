"""The YAML document of a file of the profile family (profiles, dynamic profiles, traces):
reading it safely, where a field's value is, how a value is named in a message, and writing it.

Files are read by a safe loader only, libyaml's (`yaml.CSafeLoader`) where PyYAML has it, else
the pure one: a tag that would construct a Python object is refused, never run. A file the fast
loader refuses is read again by the pure one, so a message is the same with either. What a
document may expand to (aliases, nesting, integers) and duplicate keys are checked first
(`anytime.profiles.yaml_limits`). Writing uses repr precision for floats (integral values as
integers), one row of a table per line.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from typing import Any, cast

import numpy as np
import yaml

from anytime.errors import ProfileError
from anytime.files import write_atomic
from anytime.profiles.profile import Array
from anytime.profiles.yaml_limits import YAMLLimitError, check_document

#: libyaml's loader where PyYAML was built with it (ten times faster), else the pure one; both
#: construct plain data only (the safe constructor).
FAST_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: A file describing more cells than this is refused before its tables are read: YAML aliases
#: can make a small file stand for an enormous table.
MAX_CELLS = 10_000_000

#: Numbers YAML 1.1 reads as strings: an exponent without a dot, or without a sign.
EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")
_TAG = re.compile(r"could not determine a constructor for the tag '([^']*)'")


def parse_yaml(text: str, filename: str) -> object:
    """The document, read by the fast loader; a document it refuses is read again by the pure
    one, whose messages (and marks) are the ones the format documents. What the document may
    expand to (aliases, nesting, integers) and duplicate keys are checked before either loads."""
    try:
        check_document(text, FAST_LOADER)
    except YAMLLimitError as exc:
        raise ProfileError(f"{filename}:{exc.line}:{exc.column}: {exc}") from None
    try:
        return yaml.load(text, Loader=FAST_LOADER)  # a safe loader: plain data only
    except yaml.YAMLError:
        pass
    try:
        return yaml.safe_load(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{filename}:{mark.line + 1}:{mark.column + 1}" if mark else filename
        tag = _TAG.match(exc.problem or "")
        if isinstance(exc, yaml.constructor.ConstructorError) and tag:
            name = tag.group(1).replace("tag:yaml.org,2002:", "!!")
            field = field_at(text, mark.index) if mark else "top level"
            what = "a tag that would construct a Python object" if "python/" in name else "a tag"
            raise ProfileError(
                f"{where}: {field}: refused YAML tag {name!r} (expected plain data: numbers,"
                f" strings, lists and mappings, got {what})"
            ) from None
        problem = ", ".join(part for part in (exc.context, exc.problem) if part)
        raise ProfileError(f"{where}: not YAML: {problem}") from None
    except yaml.reader.ReaderError as exc:  # a character YAML does not allow
        line = text.count("\n", 0, exc.position) + 1
        column = exc.position - text.rfind("\n", 0, exc.position)
        raise ProfileError(
            f"{filename}:{line}:{column}: not YAML: unacceptable character"
            f" #x{exc.character:04x}: {exc.reason}"
        ) from None
    except yaml.YAMLError as exc:  # not raised by the loaders today; kept as a safety net
        raise ProfileError(f"{filename}: not YAML: {exc}") from None


def field_at(text: str, index: int) -> str:
    """The top-level field whose value holds character `index` (composing builds no objects)."""
    root = yaml.compose(text, Loader=yaml.SafeLoader)  # the marks of the pure loader's message
    if isinstance(root, yaml.MappingNode):
        for key, value in root.value:
            if value.start_mark.index <= index <= value.end_mark.index:
                return str(key.value)
    return "top level"


def value_mark(text: str, field: str) -> yaml.Mark | None:
    """Where the value of the top-level `field` starts (composing builds no objects)."""
    try:
        root = yaml.compose(text, Loader=FAST_LOADER)
    except yaml.YAMLError:  # cannot happen for text that loaded; kept as a safety net
        return None
    if isinstance(root, yaml.MappingNode):
        for key, value in root.value:
            if isinstance(key, yaml.ScalarNode) and key.value == field:
                return cast(yaml.Mark, value.start_mark)
    return None


def is_count(n: object) -> bool:
    return isinstance(n, int) and not isinstance(n, bool) and n >= 0


def count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def format_number(x: float) -> str:
    """A number as YAML would show it: `.nan`, `-.inf`, integers without `.0`."""
    if np.isnan(x):
        return ".nan"
    if np.isinf(x):
        return ".inf" if x > 0 else "-.inf"
    if x.is_integer() and abs(x) < 2**53:
        return str(int(x))
    return repr(x)


def describe(value: object) -> str:
    """What a parsed YAML value is, for a message."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return format_number(value)
    if isinstance(value, int | str):
        return repr(value)
    if isinstance(value, list):
        return f"a list of {len(value)}" if value else "an empty list"
    if isinstance(value, Mapping):
        return "a mapping"
    return f"{value} (a {type(value).__name__})"


# --- writing ---------------------------------------------------------------------------------


def write_document(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Write the mapping `data` to `path` as YAML, atomically, in the order of its keys."""
    text = yaml.dump(
        dict(data),
        Dumper=Dumper,
        sort_keys=False,
        default_flow_style=False,
        allow_unicode=True,
        width=1_000_000,  # one row of a table per line, however many bins
    )
    write_atomic(path, text)


def plain(array: Array) -> Any:
    """Nested lists of Python numbers; floats keep full precision, integral ones print as ints."""

    def number(x: Any) -> Any:
        if isinstance(x, list):
            return [number(item) for item in x]
        return int(x) if x.is_integer() and abs(x) < 2**53 else x

    return number(array.tolist())


class Dumper(yaml.SafeDumper):
    """The safe dumper, indenting lists under their key and writing the innermost ones inline."""

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        super().increase_indent(flow, False)


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.SequenceNode:
    inline = not any(isinstance(item, list) for item in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=inline)


Dumper.add_representer(list, _represent_list)
