"""`Source`: the file name and text a parsed file carries, and the diagnostics made from it."""

from __future__ import annotations

from pathlib import Path

import pytest

from anytime.dsl import load_schemas, parse_schemas
from anytime.dsl.parser import parse_syntax
from anytime.dsl.program import SchemaFile
from anytime.dsl.source import Source, Span
from anytime.errors import Diagnostic, SchemaError

TEXT = "(defschema p (x)\n  (find-path x))\n"


def test_a_diagnostic_from_a_span_has_the_line_and_a_caret_as_wide_as_the_span() -> None:
    source = Source("p.any", TEXT)
    diagnostic = source.diagnostic("unknown function 'find-path'", Span(2, 4, 2, 13))
    assert diagnostic == Diagnostic(
        "p.any", 2, 4, "unknown function 'find-path'", "  (find-path x))", 9
    )
    assert diagnostic.format() == (
        "p.any:2:4: error: unknown function 'find-path'\n    (find-path x))\n     ^~~~~~~~~"
    )


def test_a_span_over_several_lines_gets_a_one_character_caret() -> None:
    diagnostic = Source("p.any", TEXT).diagnostic("m", Span(1, 1, 2, 16))
    assert (diagnostic.line, diagnostic.column, diagnostic.width) == (1, 1, 1)
    assert diagnostic.source_line == "(defschema p (x)"


def test_a_diagnostic_from_a_line_and_column_or_an_offset() -> None:
    source = Source("p.any", TEXT)
    assert source.diagnostic("m", line=2, column=3, width=2) == Diagnostic(
        "p.any", 2, 3, "m", "  (find-path x))", 2
    )
    offset = TEXT.index("x))")
    assert source.position(offset) == (2, 14)
    assert source.at_offset(offset, "m") == Diagnostic("p.any", 2, 14, "m", "  (find-path x))")
    assert source.at_offset(len(TEXT), "m") == Diagnostic("p.any", 3, 1, "m", "")


def test_lines_are_counted_as_the_parser_counts_them() -> None:
    source = Source("f.any", "a\rb\nc")  # a lone CR is not a line break for the parser
    assert source.lines == ("a\rb", "c")
    assert (source.line(1), source.line(2), source.line(0), source.line(3)) == ("a\rb", "c", "", "")


def test_the_parsed_file_carries_its_source() -> None:
    parsed = parse_syntax(TEXT, "p.any")
    assert parsed.source == Source("p.any", TEXT)
    assert (parsed.filename, parsed.text) == ("p.any", TEXT)
    schemas = parse_schemas(TEXT, "p.any")
    assert schemas.source == Source("p.any", TEXT)
    assert schemas.filename == "p.any"


def test_a_loaded_file_carries_the_text_it_was_read_as(tmp_path: Path) -> None:
    path = tmp_path / "p.any"
    path.write_bytes(b"\xef\xbb\xbf" + TEXT.encode())  # the byte-order mark is not text
    schemas = load_schemas(path)
    assert schemas.source == Source(str(path), TEXT)


def test_a_schema_file_made_by_hand_has_a_source_without_text() -> None:
    schemas = SchemaFile("made.any", ())
    assert schemas.source == Source("made.any", "")
    assert schemas.source.diagnostic("m", line=1, column=1).format() == "made.any:1:1: error: m"


def test_the_checker_makes_its_diagnostics_from_the_source() -> None:
    with pytest.raises(SchemaError) as raised:
        parse_schemas("(defschema p (domain)\n  (f domian))", "p.any")
    assert str(raised.value) == (
        "p.any:2:6: error: undefined variable 'domian'; did you mean 'domain'?\n"
        "    (f domian))\n"
        "       ^~~~~~"
    )
