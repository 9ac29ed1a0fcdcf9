"""What a YAML document may expand to, checked on its event stream before it is loaded.

A few hundred bytes of YAML can stand for gigabytes: an alias repeats a whole subtree, so ten
levels of ten aliases each are ten billion nodes ("billion laughs"); a thousand nested brackets
exhaust the loader's recursion; a 5,000-digit integer stops Python's `int`. The document's event
stream (the parser's output, produced without recursion and without building any value) tells
all of this in one pass: `check_document` counts the nodes the document stands for with every
alias expanded, the deepest nesting, and the digits of each integer, and finds a mapping's
duplicate keys (which the loaders accept silently, the last one winning). Any of these is a
`YAMLLimitError` with the line and column of the place.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

from anytime.errors import AnytimeError

__all__ = ["MAX_DEPTH", "MAX_INTEGER_DIGITS", "MAX_NODES", "YAMLLimitError", "check_document"]

#: The most nodes a document may stand for, aliases expanded (a profile's cells are nodes: the
#: largest table a file may describe is 10,000,000 cells, in its companion beyond 100,000).
MAX_NODES = 20_000_000
#: The deepest nesting of lists and mappings (profiles nest three or four levels).
MAX_DEPTH = 64
#: The longest integer literal (Python refuses to convert more than 4,300 digits).
MAX_INTEGER_DIGITS = 1000

_INTEGER = re.compile(r"[-+]?[0-9][0-9_]*$")


class YAMLLimitError(AnytimeError, ValueError):
    """A document over a limit, or with a duplicate key; `line` and `column` count from 1."""

    def __init__(self, message: str, mark: Any) -> None:
        super().__init__(message)
        self.line = mark.line + 1
        self.column = mark.column + 1


class _Collection:
    """A list or mapping being read: where its nodes start in the count, and a mapping's keys."""

    __slots__ = ("anchor", "first", "keys", "mapping", "want_key")

    def __init__(self, anchor: str | None, mapping: bool, first: int) -> None:
        self.anchor = anchor
        self.mapping = mapping
        self.first = first  # the document's node count when it started (itself included)
        self.keys: set[str] = set()
        self.want_key = mapping  # in a mapping, keys and values alternate


def check_document(text: str, loader: Any) -> None:
    """Raise `YAMLLimitError` when the document `text` is over a limit or has a duplicate key;
    YAML syntax errors are left to the loader, whose messages name them."""
    sizes: dict[str, int] = {}  # the nodes each anchored node stands for
    stack: list[_Collection] = []
    nodes = 0  # the nodes read so far, every alias counted as the node it repeats

    def child(key: str | None, mark: Any) -> None:
        """A node of the innermost collection is complete: check a mapping's keys."""
        if not stack or not stack[-1].mapping:
            return
        parent = stack[-1]
        if parent.want_key and key is not None:
            if key in parent.keys:
                raise YAMLLimitError(f"duplicate key {key!r} in a mapping", mark)
            parent.keys.add(key)
        parent.want_key = not parent.want_key

    try:
        for event in yaml.parse(text, Loader=loader):
            if isinstance(event, yaml.MappingStartEvent | yaml.SequenceStartEvent):
                if len(stack) >= MAX_DEPTH:
                    raise YAMLLimitError(
                        f"nested more than {MAX_DEPTH} lists and mappings deep", event.start_mark
                    )
                nodes += 1
                mapping = isinstance(event, yaml.MappingStartEvent)
                stack.append(_Collection(event.anchor, mapping, nodes))
                continue
            if isinstance(event, yaml.MappingEndEvent | yaml.SequenceEndEvent):
                done = stack.pop()
                if done.anchor is not None:
                    sizes[done.anchor] = nodes - done.first + 1
                child(None, event.start_mark)
                continue
            if isinstance(event, yaml.ScalarEvent):
                value = event.value
                if not event.style and _INTEGER.match(value):  # plain, not quoted
                    digits = sum(c.isdigit() for c in value)
                    if digits > MAX_INTEGER_DIGITS:
                        raise YAMLLimitError(
                            f"an integer of {digits:,} digits (at most {MAX_INTEGER_DIGITS:,})",
                            event.start_mark,
                        )
                nodes += 1
                if event.anchor is not None:
                    sizes[event.anchor] = 1
                child(value, event.start_mark)
            elif isinstance(event, yaml.AliasEvent):
                # an alias of an unknown anchor is the loader's error; counted as one node
                nodes += sizes.get(event.anchor or "", 1)
                child(None, event.start_mark)
            else:
                continue
            if nodes > MAX_NODES:
                raise YAMLLimitError(
                    f"the document stands for more than {MAX_NODES:,} values (with its aliases"
                    " expanded)",
                    event.start_mark,
                )
    except yaml.YAMLError:
        # not YAML, or past libyaml's own nesting limit: the pure parser (no recursion either)
        # reads as far as it can, then the loader says where and why
        if loader is not yaml.SafeLoader:
            check_document(text, yaml.SafeLoader)
