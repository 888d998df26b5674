"""The ``workbench`` command line."""

from __future__ import annotations

import argparse
import sys

from workbench import __version__
from workbench.commands import board as board_cmd
from workbench.commands import calibrate as calibrate_cmd
from workbench.commands import design as design_cmd
from workbench.commands import flatten as flatten_cmd
from workbench.commands import pdf as pdf_cmd
from workbench.commands import render as render_cmd
from workbench.commands import validate as validate_cmd
from workbench.errors import UsageError, WorkbenchError


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line and exit 2, as argparse does, without the usage block
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="workbench",
        description="Pre-distorted prints for decorated plastic parts, and their photo validation.",
    )
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    flatten_cmd.add_parser(sub)
    design_cmd.add_parser(sub)
    pdf_cmd.add_parser(sub)
    board_cmd.add_parser(sub)
    render_cmd.add_parser(sub)
    validate_cmd.add_parser(sub)
    calibrate_cmd.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0, 1 for bad input, 2 for bad usage)."""
    parser = build_parser()
    prog = "workbench"
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 2
        prog = f"workbench {args.command}"
        return args.run(args)
    except WorkbenchError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return exc.exit_status
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; nothing written", file=sys.stderr)
        return 130
