"""The source of a schema file: its name and text, from which every diagnostic about it is made.

A `Source` travels with the parsed file (`SourceFile.source`, `SchemaFile.source`), so that an
error found after parsing (by the checker, the compiler, the command line) shows the source line
and a caret without reading the file again.
"""

from __future__ import annotations

from attrs import field, frozen

from anytime.errors import Diagnostic


@frozen
class Span:
    """A place in the source: 1-based line and column where it starts and one past its end."""

    line: int
    column: int
    end_line: int
    end_column: int


@frozen
class Source:
    """A file name (as it was given) and the file's text."""

    filename: str
    text: str = field(repr=False)
    #: The text's lines as the parser counts them: split at "\n" only, not `str.splitlines`.
    lines: tuple[str, ...] = field(init=False, repr=False, eq=False)

    @lines.default
    def _split(self) -> tuple[str, ...]:
        return tuple(self.text.split("\n"))

    def line(self, number: int) -> str:
        """The text of 1-based line `number` (empty past the end)."""
        return self.lines[number - 1] if 0 < number <= len(self.lines) else ""

    def position(self, offset: int) -> tuple[int, int]:
        """The 1-based (line, column) of a character offset into the text."""
        line = self.text.count("\n", 0, offset) + 1
        return line, offset - (self.text.rfind("\n", 0, offset) + 1) + 1

    def diagnostic(
        self,
        message: str,
        span: Span | None = None,
        *,
        line: int = 1,
        column: int = 1,
        width: int = 1,
    ) -> Diagnostic:
        """A diagnostic at `span` (its caret as wide as the span when it is on one line), or,
        without a span, at `line` and `column` with a caret `width` characters wide."""
        if span is not None:
            line, column = span.line, span.column
            width = span.end_column - span.column if span.end_line == span.line else 1
        return Diagnostic(self.filename, line, column, message, self.line(line), width)

    def at_offset(self, offset: int, message: str) -> Diagnostic:
        """A diagnostic at a character offset into the text (a one-character caret)."""
        line, column = self.position(offset)
        return self.diagnostic(message, line=line, column=column)
