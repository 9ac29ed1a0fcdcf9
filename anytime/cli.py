"""The `anytime` command.

Exit codes: 0 success, 1 bad input (a message naming the file and place, never a traceback),
2 usage errors (argparse's own).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence

from anytime import __version__
from anytime.dsl import format_programs, graph_to_dot, load_schemas, program_to_json
from anytime.errors import AnytimeError

EXIT_OK, EXIT_INPUT, EXIT_USAGE = 0, 1, 2


class InputError(AnytimeError):
    """Bad input found by the command itself; the message is printed as it is."""


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    run: Callable[[argparse.Namespace], int] = args.run
    try:
        return run(args)
    except AnytimeError as error:
        print(error, file=sys.stderr)
        return EXIT_INPUT
    except BrokenPipeError:  # the reader went away, e.g. `anytime parse f | head -1`
        return EXIT_OK
    except OSError as error:
        print(f"anytime: error: cannot read '{error.filename}': {error.strerror}", file=sys.stderr)
        return EXIT_INPUT


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="anytime",
        description="Compose anytime algorithms: write program schemas, compile them into "
        "contract algorithms with optimal time allocation, run them under a monitor.",
    )
    parser.add_argument("--version", action="version", version=f"anytime {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    parse = commands.add_parser(
        "parse",
        help="check a schema file and print its straight-line form or dataflow graph",
        description="Check a schema file and print each schema in straight-line form "
        "(DSL text that parses back to the same program), as JSON, or as a Graphviz graph.",
    )
    parse.add_argument("file", metavar="FILE", help="a schema file (.any)")
    parse.add_argument("--schema", metavar="NAME", help="only this schema (default: all)")
    output = parse.add_mutually_exclusive_group()
    output.add_argument("--json", action="store_true", help="print JSON")
    output.add_argument("--dot", action="store_true", help="print the dataflow graph as DOT")
    parse.set_defaults(run=run_parse)
    return parser


def run_parse(args: argparse.Namespace) -> int:
    schemas = load_schemas(args.file)
    programs = schemas.programs
    if args.schema is not None:
        if args.schema not in schemas:
            known = ", ".join(schemas.names)
            raise InputError(
                f"{args.file}: error: no schema named '{args.schema}' (the file defines: {known})"
            )
        programs = (schemas[args.schema],)
    if args.json:
        print(json.dumps({"schemas": [program_to_json(p) for p in programs]}, indent=2))
    elif args.dot:
        print(graph_to_dot(p.graph for p in programs), end="")
    else:
        print(format_programs(programs), end="")
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
