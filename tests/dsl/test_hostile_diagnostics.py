"""A schema with thousands of errors on one enormous line prints a bounded report: the first
`MAX_REPORTED` diagnostics, each quoting at most `EXCERPT` characters of its line around the
column, then "... and N more errors"; and the checks gather "did you mean" names for only the
first `MAX_HINTS` errors, so building the messages is linear in the errors."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from anytime.dsl import parse_schemas
from anytime.errors import EXCERPT, MAX_REPORTED, Diagnostic, SchemaError

#: The module (`anytime.dsl.normalize` as an attribute is the function of that name).
normalize_module = importlib.import_module("anytime.dsl.normalize")

#: The `cli` fixture (tests/conftest.py): runs `anytime` in-process, (exit code, stdout, stderr).
Cli = Callable[..., tuple[int, str, str]]


def _undefined(n: int) -> str:
    """One line: a call of `n` undefined names (the issue's 55 KB file has 4,000)."""
    return "(defschema s (x) (f " + " ".join(f"u{i}" for i in range(n)) + "))\n"


def _errors(text: str, known: object = None) -> SchemaError:
    with pytest.raises(SchemaError) as caught:
        parse_schemas(text, "s.any", known)  # type: ignore[arg-type]
    return caught.value


def test_the_report_is_the_first_twenty_then_a_count() -> None:
    error = _errors(_undefined(4000))
    assert len(error.diagnostics) == 4000  # every one is kept for a caller that wants them
    lines = str(error).split("\n")
    assert (MAX_REPORTED, len(lines)) == (20, 20 * 3 + 1)
    assert lines[-1] == "... and 3,980 more errors"
    assert lines[-4:-1] == [
        "s.any:1:87: error: undefined variable 'u19'; did you mean 'u9'?",
        "  ... u11 u12 u13 u14 u15 u16 u17 u18 u19 u20 u21 u22 u23 u24 u25 u26 u27 u28 u29 u30"
        " u31 u32 u33 u34 u35...",
        "                                      ^~~",
    ]


def test_one_more_error_is_counted_in_the_singular() -> None:
    assert str(_errors(_undefined(21))).endswith("\n... and 1 more error")
    assert "more error" not in str(_errors(_undefined(20)))


def test_the_report_does_not_grow_with_the_errors_or_the_line() -> None:
    """16,000 undefined names on a 100 KB line (the issue's 229 KB file printed 5.4 GB before
    a MemoryError): the report is a few kilobytes, as for 4,000."""
    small, large = str(_errors(_undefined(4000))), str(_errors(_undefined(16000)))
    assert len(large) < 6_000
    assert len(large) - len(small) < 400  # longer names and a longer count, nothing more
    assert large.endswith("\n... and 15,980 more errors")


def test_a_diagnostic_far_into_a_long_line_quotes_a_window_around_it() -> None:
    error = _errors(_undefined(16000))
    assert error.diagnostics[5000].format() == (
        "s.any:1:28911: error: undefined variable 'u5000'\n"
        "  ...94 u4995 u4996 u4997 u4998 u4999 u5000 u5001 u5002 u5003 u5004 u5005 u5006 u5007"
        " u5008 u5009 u5010 u...\n"
        "                                      ^~~~~"
    )
    assert error.diagnostics[-1].format() == (
        "s.any:1:100904: error: undefined variable 'u15999'\n"
        "  ... u15986 u15987 u15988 u15989 u15990 u15991 u15992 u15993 u15994 u15995 u15996"
        " u15997 u15998 u15999))\n"
        "                                                                                    "
        "             ^~~~~~"
    )


@given(
    line=st.text(alphabet="ab \t()", max_size=400),
    place=st.floats(min_value=0, max_value=1),
    width=st.integers(min_value=1, max_value=500),
)
def test_the_excerpt_is_bounded_and_its_caret_under_the_same_character(
    line: str, place: float, width: int
) -> None:
    column = 1 + int(place * len(line))  # on the line, or just past its end
    text = Diagnostic("f.any", 1, column, "m", line, width).format()
    parts = text.split("\n")
    if len(parts) == 1:  # nothing visible to quote
        assert not line[max(0, column - 1 - EXCERPT) : column - 1 + EXCERPT].strip()
        return
    _, quoted, caret = parts
    assert len(quoted) <= 2 + EXCERPT + 6 and len(caret) <= 2 + EXCERPT + 3 + width
    at = caret.index("^")
    full = line.expandtabs(1)
    if column <= len(full.rstrip()):
        assert quoted[at] == full[column - 1]
    if len(line) <= EXCERPT:  # a short line is quoted whole, as before
        assert quoted == "  " + full.rstrip()


class _Known(dict[str, int]):
    """The library's names, counting how often they are listed."""

    listed = 0

    def __iter__(self) -> Iterator[str]:
        type(self).listed += 1
        return super().__iter__()


def test_did_you_mean_names_are_gathered_for_the_first_errors_only(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """2,000 schemas each calling an unknown function: the names known (the library's and the
    2,000 schemas) are gathered for 20 hints, not for each of the 2,000 errors (quadratic)."""
    gathered: list[int] = []
    real = normalize_module.suggest

    def counting(name: str, known: Iterable[str]) -> str:
        names = list(known)
        gathered.append(len(names))
        return real(name, names)

    monkeypatch.setattr(normalize_module, "suggest", counting)
    monkeypatch.setattr(_Known, "listed", 0)
    text = "\n".join(f"(defschema s{i} (x) (g{i} x))" for i in range(2000))
    error = _errors(text, _Known(f=1))
    assert len(error.diagnostics) == 2000
    assert gathered == [2001] * normalize_module.MAX_HINTS == [2001] * 20
    assert _Known.listed == 20
    assert error.diagnostics[0].message == (
        "unknown function 'g0' (known: f, s0, s1, s10, s100, s1000, s1001, s1002, s1003, s1004,"
        " s1005, s1006, ...)"
    )
    assert error.diagnostics[20].message == "unknown function 'g20'"


def test_parse_prints_the_bounded_report_and_exits_1(tmp_path: Path, cli: Cli) -> None:
    path = tmp_path / "huge.any"
    path.write_text(_undefined(16000))
    code, out, err = cli("parse", str(path))
    assert (code, out) == (1, "")
    assert err.startswith(f"{path}:1:21: error: undefined variable 'u0'\n")
    assert err.endswith("\n... and 15,980 more errors\n")
    assert len(err.splitlines()) == 61 and "Traceback" not in err
