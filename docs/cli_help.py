"""Write the `--help` texts of every `anytime` command into docs/cli.md, so that its option lists
follow the command line (`make docs`; tests/test_docs.py fails when the page is out of date).

Each block of the page between `<!-- anytime ARGS --help -->` and `<!-- end -->` is replaced by
what `anytime ARGS --help` prints at a width of 100 columns, with the installed plugins loaded.

    .venv/bin/python docs/cli_help.py [--check]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import sys
from pathlib import Path

PAGE = Path(__file__).resolve().parent / "cli.md"

#: `<!-- anytime compile --help -->` ... `<!-- end -->`
BLOCK = re.compile(r"(<!-- anytime(?P<args>(?: [^>]*?)?) --help -->\n)(.*?)(<!-- end -->)", re.S)

#: argparse lays out help differently from one Python version to another; the page is written
#: with this one (the project's oldest, which CI runs).
PYTHON = (3, 11)
WIDTH = "100"


def help_text(args: list[str]) -> str:
    """What `anytime ARGS --help` prints."""
    from anytime.cli import build_parser

    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            build_parser().parse_args([*args, "--help"])
    finally:
        if saved is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = saved
    return out.getvalue()


def render(page: str) -> str:
    """The page with every help block rewritten."""

    def block(match: re.Match[str]) -> str:
        args = match["args"].split()
        command = " ".join(["anytime", *args, "--help"])
        return f"{match[1]}\n```text\n$ {command}\n{help_text(args)}```\n\n{match[4]}"

    return BLOCK.sub(block, page)


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only say whether it is current")
    args = parser.parse_args()
    if sys.version_info[:2] != PYTHON:
        print(f"write the page with Python {PYTHON[0]}.{PYTHON[1]}", file=sys.stderr)
        return 2
    old = PAGE.read_text(encoding="utf-8")
    new = render(old)
    if args.check:
        print("docs/cli.md is up to date" if new == old else "docs/cli.md is out of date")
        return 0 if new == old else 1
    PAGE.write_text(new, encoding="utf-8")
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
