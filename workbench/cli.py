"""The ``workbench`` command line."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings

from workbench import __version__
from workbench.atomic import signals_handled
from workbench.environment import use_writable_caches
from workbench.errors import UsageError, WorkbenchError

# in the order of `workbench --help`
COMMANDS = ("flatten", "design", "suggest-views", "pdf", "board", "render", "validate", "calibrate")


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line and exit 2, as argparse does, without the usage block
        raise UsageError(message)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The argument parser; with ``only``, just that command's (its modules load OpenCV,
    numba, matplotlib...: a command imports only what it uses, which saves about 0.5 s)."""
    parser = _Parser(
        prog="workbench",
        description="Pre-distorted prints for decorated plastic parts, and their photo validation.",
    )
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in (only,) if only else COMMANDS:
        importlib.import_module(f"workbench.commands.{name.replace('-', '_')}").add_parser(sub)
    return parser


def _run_quietly(args) -> int:
    """Run a command with library warnings kept off stderr.

    Every result is checked where it matters (finite maps, plausible profiles): a numpy
    overflow or a deprecation notice printed before the one-line error, or among the
    progress lines, only hides what the command itself says.
    """
    import numpy as np

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        return args.run(args)


OUTPUT_OPTIONS = ("--out", "-o", "--output")


def _refuse_empty_outputs(argv: list[str]) -> None:
    """An output option given an empty name is a usage error (it read as "not given": ``--out ""``
    wrote the default ``design-JOB/`` into the current folder)."""
    for k, a in enumerate(argv):
        name, eq, value = a.partition("=")
        if name in OUTPUT_OPTIONS and (value if eq else (argv[k + 1] if k + 1 < len(argv) else None)) == "":
            raise UsageError(f"{name}: an empty name; give the output's name, or leave {name} out for the default")


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    0 on success, 1 for bad input or a failed run (a file, key or value at fault, a
    calibration that drifted), 2 for a malformed command line (an unknown, missing or
    out-of-range option), 130 when interrupted (Ctrl-C, SIGTERM) before the output was complete (0
    after). Every error is one line on stderr,
    ``workbench COMMAND: error: WHAT: why``, and a failed run writes nothing.
    """
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch is not None and not epoch.strip().isdigit():
        # read by ReportLab when it loads, and by every PDF's date line: say so before either fails
        print(
            f"workbench: error: SOURCE_DATE_EPOCH={epoch!r}: must be whole seconds since 1970-01-01 UTC "
            "(reproducible builds), or unset",
            file=sys.stderr,
        )
        return 1
    use_writable_caches()  # before a command's modules load numba and matplotlib
    args_in = sys.argv[1:] if argv is None else argv
    first = next((a for a in args_in if not a.startswith("-")), None)
    parser = build_parser(first if first in COMMANDS else None)
    # name the subcommand in usage errors too, which argparse reports before `args` exists
    prog = f"workbench {first}" if first in COMMANDS else "workbench"
    with signals_handled() as written:
        try:
            _refuse_empty_outputs(args_in)
            args = parser.parse_args(argv)
            if args.command is None:
                parser.print_help()
                return 2
            prog = f"workbench {args.command}"
            return _run_quietly(args)
        except WorkbenchError as exc:
            print(f"{prog}: error: {exc}", file=sys.stderr)
            return exc.exit_status
        except MemoryError:
            # the pre-checks (design's print, render's photo) refuse what cannot fit; this is what they missed
            print(f"{prog}: error: out of memory; nothing written (lower the resolution or the size)", file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            # Ctrl-C or SIGTERM: a write undoes itself (no temporary left) unless its renames
            # were done, and then the output is complete: that is what the user needs to know
            if written:
                done = ", ".join(map(str, written))
                print(f"{prog}: interrupted after writing {done}, which is complete", file=sys.stderr)
                return 0
            print(f"{prog}: interrupted; nothing written", file=sys.stderr)
            return 130
