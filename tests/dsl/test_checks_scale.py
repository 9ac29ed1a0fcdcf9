"""The DSL's checks on large files: linear (or n log n) in the file's size, and what they
report still exact. (No timing assertions: files that took minutes are built and checked.)"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from anytime.dsl import parse_schemas
from anytime.dsl.normalize import MAX_HINTS
from anytime.errors import SchemaError


def _errors(text: str) -> list[str]:
    with pytest.raises(SchemaError) as raised:
        parse_schemas(text, "t.any")
    return [d.message for d in raised.value.diagnostics]


def _reaches(calls: dict[int, set[int]], start: int) -> bool:
    seen, todo = set(), list(calls[start])
    while todo:
        here = todo.pop()
        if here == start:
            return True
        if here not in seen:
            seen.add(here)
            todo.extend(calls[here])
    return False


@settings(max_examples=60, deadline=None)
@given(
    st.integers(1, 7).flatmap(
        lambda n: st.lists(st.sets(st.integers(0, n - 1), max_size=3), min_size=n, max_size=n)
    )
)
def test_a_schema_is_reported_recursive_only_on_a_cycle(callees: list[set[int]]) -> None:
    """Every reported schema calls itself (the chain shown is a real call path back to it), and
    at least one schema of every cycle is reported."""
    calls = dict(enumerate(callees))
    text = "".join(
        f"(defschema s{i} (x) "
        + "".join(f"(s{c} " for c in sorted(cs))
        + "x"
        + ")" * len(cs)
        + ")\n"
        for i, cs in calls.items()
    )
    recursive = {i for i in calls if _reaches(calls, i)}
    try:
        parse_schemas(text, "t.any")
        messages: list[str] = []
    except SchemaError as error:
        messages = [d.message for d in error.diagnostics]
    reported = set()
    for message in messages:
        name = int(message.split("'")[1][1:])
        reported.add(name)
        if "through other schemas" in message:
            chain = [int(s[1:]) for s in message.split(": ")[1].split(" -> ")]
            assert chain[0] == chain[-1] == name
            assert all(b in calls[a] for a, b in zip(chain, chain[1:], strict=False))
        else:
            assert message == f"schema 's{name}' calls itself" and name in calls[name]
    assert reported <= recursive
    assert bool(reported) == bool(recursive)


def test_a_long_chain_back_to_its_start_is_one_error() -> None:
    n = 3000
    text = "".join(f"(defschema s{i} (x) (s{(i + 1) % n} x))\n" for i in range(n))
    (message,) = _errors(text)
    assert message.startswith("schema 's0' calls itself through other schemas: s0 -> s1 -> ")
    assert message.endswith(f"-> s{n - 1} -> s0")


def test_thousands_of_undefined_variables_each_reported_the_first_hinted() -> None:
    n = 2000
    body = "".join(f"  (setf y{i} (f v{i}))\n" for i in range(n))
    messages = _errors(f"(defschema p (x)\n{body}  y0)\n")
    assert len(messages) == n
    assert [m.split(";")[0] for m in messages] == [f"undefined variable 'v{i}'" for i in range(n)]
    hinted = [m for m in messages if "did you mean" in m]
    assert 0 < len(hinted) <= MAX_HINTS


def test_twenty_thousand_keywords_and_one_twice() -> None:
    keywords = " ".join(f":k{i} 1" for i in range(20000))
    assert len(parse_schemas(f"(defschema p (x) (f x {keywords}))\n", "t.any")) == 1
    assert _errors(f"(defschema p (x) (f x {keywords} :k7 2))\n") == ["keyword :k7 is given twice"]
