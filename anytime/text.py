"""'Did you mean' text: the closest known name to a misspelt one, in the words every message
uses. A low layer: it imports nothing of the framework, and every layer may import it (the DSL,
the library, the profile files, the profile builder, the command line)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

#: How alike a name must be to a known one to be suggested (difflib's ratio, 0 to 1).
CUTOFF = 0.6

#: How many known names a listing shows before it ends with "...".
LISTED = 12


def closest(name: str, known: Iterable[str], *, cutoff: float = CUTOFF) -> str | None:
    """The known name most like `name`, or None when none is alike enough."""
    close = difflib.get_close_matches(name, sorted(set(known)), n=1, cutoff=cutoff)
    return close[0] if close else None


def did_you_mean(name: str, known: Iterable[str], *, separator: str = "; ") -> str:
    """`"; did you mean 'NAME'?"` naming the closest known name, or "" when none is close."""
    close = closest(name, known)
    return f"{separator}did you mean '{close}'?" if close is not None else ""


def suggest(name: str, known: Iterable[str]) -> str:
    """A 'did you mean' hint naming the closest known name, or else a listing of the known
    ones: `"; did you mean 'x'?"`, `" (known: a, b, c)"`, or "" when nothing is known."""
    names = sorted(set(known))
    hint = did_you_mean(name, names)
    if hint or not names:
        return hint
    shown = ", ".join(names[:LISTED]) + (", ..." if len(names) > LISTED else "")
    return f" (known: {shown})"
