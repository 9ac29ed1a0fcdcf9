"""One exception tree for the whole framework.

Every error the framework raises on bad input derives from `AnytimeError` and from the builtin it
resembles, so callers can catch either. Errors about a place in a source file carry
`Diagnostic`s that print as `FILE:LINE:COL: error: MESSAGE`, the source line (at most `EXCERPT`
characters of it, around the place) and a caret; a schema error prints its first `MAX_REPORTED`
and counts the rest. No other message carries a prefix saying it is an error: the command line
adds one, in one place (`anytime.cli.describe`, used by `main`).

This module imports nothing of the framework (every layer imports it).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import TypeVar

from attrs import frozen

_E = TypeVar("_E", bound=BaseException)


class AnytimeError(Exception):
    """Root of every error anytime-compose raises on bad input.

    Attributes:
        where: the file (or `FILE:LINE`) the error is about when the message does not name it,
            or None; the command line puts it before the message (`anytime.cli.describe`).
    """

    where: str | None = None

    def __init__(self, *args: object, where: str | None = None) -> None:
        super().__init__(*args)
        if where is not None:
            self.where = where


#: The most diagnostics a schema error prints; the rest are counted ("... and 3,912 more
#: errors"). A file can hold thousands of errors, and each prints its line.
MAX_REPORTED = 20

#: The most characters of its source line a diagnostic quotes: a window around its column
#: (a one-line file of 200 KB would otherwise be printed whole under every error).
EXCERPT = 100
_VISIBLE = re.compile(r"\S")


@frozen
class Diagnostic:
    """One message about one place in a source file (line and column are 1-based)."""

    filename: str
    line: int
    column: int
    message: str
    source_line: str = ""
    width: int = 1  # how many characters the caret underlines

    def format(self) -> str:
        """The message, then at most `EXCERPT` characters of the source line around the column
        (cut ends shown as "...") and a caret under the place."""
        head = f"{self.filename}:{self.line}:{self.column}: error: {self.message}"
        text = self.source_line
        start = max(0, min(self.column - 1 - EXCERPT // 3, len(text) - EXCERPT))
        piece = text[start : start + EXCERPT].expandtabs(1).rstrip()  # a tab is one column
        if not piece.strip():
            return head
        before = "..." if start > 0 else ""
        after = "..." if _VISIBLE.search(text, start + EXCERPT) else ""
        line, column = before + piece, self.column - start + len(before)
        width = max(1, min(self.width, len(line) - column + 1))
        caret = " " * (column - 1) + "^" + "~" * (width - 1)
        return f"{head}\n  {line}{after}\n  {caret}"


class SchemaError(AnytimeError):
    """A schema file is wrong; `diagnostics` lists every error found, in source order (the
    message shows the first `MAX_REPORTED` of them and counts the rest)."""

    filename: str | None  # as on SyntaxError, which a subclass also derives from

    def __init__(self, diagnostics: Sequence[Diagnostic]) -> None:
        if not diagnostics:
            raise ValueError("SchemaError needs at least one diagnostic")
        self.diagnostics = tuple(diagnostics)
        first = self.diagnostics[0]
        self.filename = first.filename
        self.line = first.line
        self.column = first.column
        self.message = first.message
        super().__init__(first.message)

    def __str__(self) -> str:
        """The first `MAX_REPORTED` diagnostics, then how many more there are."""
        text = "\n".join(d.format() for d in self.diagnostics[:MAX_REPORTED])
        more = len(self.diagnostics) - MAX_REPORTED
        if more > 0:
            text += f"\n... and {more:,} more error{'s' if more > 1 else ''}"
        return text


class SchemaSyntaxError(SchemaError, SyntaxError):
    """The text of a schema file does not follow the grammar."""

    def __init__(self, diagnostics: Sequence[Diagnostic]) -> None:
        super().__init__(diagnostics)
        # The attributes Python's own tooling reads from a SyntaxError.
        first = self.diagnostics[0]
        self.msg = first.message
        self.lineno = first.line
        self.offset = first.column
        self.text = first.source_line

    def __str__(self) -> str:
        return SchemaError.__str__(self)


class ProfileError(AnytimeError, ValueError):
    """A performance profile (in memory or in a file) is malformed; the message names the field."""


class InputError(AnytimeError):
    """Bad input found by a command (or a plugin) itself. The message says what is wrong, without
    a prefix: the command line adds one (`anytime.cli.describe`), naming the file when `where`
    is given."""


class UsageError(InputError):
    """Options that do not go together, found after parsing (argparse cannot check them):
    exit status 2, and the prefix names the command, like argparse's own usage errors."""


def first_in_chain(error: BaseException, kind: type[_E]) -> _E | None:
    """The first exception of `kind` in `error`'s chain: `error` itself, then what it was
    raised from or while handling, and so on; None when there is none."""
    seen: set[int] = set()
    link: BaseException | None = error
    while link is not None and id(link) not in seen:
        if isinstance(link, kind):
            return link
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return None


def interrupt_behind(error: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C (or SIGTERM) an error stands for, if it was raised because of one, else None.
    A signal is handled at the next call into Python code, and compiled code that calls back
    into Python there turns the interrupt into a `SystemError` ("... returned a result with an
    exception set") whose cause is the interrupt: numba does, boxing every array a compiled
    function returns (it unpickles the array class), so a Ctrl-C during a numba module's call
    surfaces so far more often than as itself."""
    return first_in_chain(error, KeyboardInterrupt)
