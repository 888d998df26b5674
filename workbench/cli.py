"""The ``workbench`` command line."""

from __future__ import annotations

import os
import sys

from workbench.interrupts import (
    deliver_pending,
    ignore_swallowed_interrupts,
    interrupt_came,
    release_early_signals,
    signals_handled,
    take_signals_early,
)


def _is_the_command() -> bool:
    """Whether this process is the ``workbench`` command (its script, or ``python -m workbench``)."""
    main_module = sys.modules.get("__main__")
    spec = getattr(main_module, "__spec__", None)
    if spec is not None:
        return spec.name == "workbench.__main__"
    return os.path.basename(sys.argv[0] if sys.argv else "") == "workbench"  # (no pathlib yet: 19 ms)


# the command's own process takes Ctrl-C and SIGTERM from its first moment, before the rest of
# this module's imports (under load they took over 50 ms, and a Ctrl-C then was a traceback); a
# program that imports this module (a test, a notebook) keeps its own handlers
if _is_the_command():
    take_signals_early()
    sys.unraisablehook = ignore_swallowed_interrupts

import argparse  # noqa: E402
import contextlib  # noqa: E402
import importlib  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

from workbench import __version__  # noqa: E402
from workbench.environment import (  # noqa: E402
    cache_dir,
    check_current_folder,
    check_thread_counts,
    fit_the_address_space,
    keep_owner_permissions,
    load_reportlab,
    source_date_epoch,
    speak_the_terminals_language,
    use_writable_caches,
)
from workbench.errors import UsageError, WorkbenchError, exhausted  # noqa: E402
from workbench.text import one_line  # noqa: E402

# exit status of an internal error (a bug), as sysexits.h's EX_SOFTWARE
INTERNAL_ERROR = 70

# in the order of `workbench --help`
COMMANDS = (
    "flatten",
    "design",
    "suggest-views",
    "pdf",
    "board",
    "render",
    "validate",
    "lot",
    "trend",
    "store",
    "calibrate",
)


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


def _crash_report(prog: str, exc: BaseException) -> str:
    """Write the traceback of an unexpected error to the workbench's cache; its path, or why not."""
    import datetime
    import traceback

    folder = cache_dir(os.environ) / "crashes"
    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%dT%H%M%SZ")
    path = folder / f"{prog.replace(' ', '-')}-{stamp}-{os.getpid()}.txt"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        text = f"{prog} {__version__}\nargv: {sys.argv!r}\n\n" + "".join(traceback.format_exception(exc))
        path.write_text(text, encoding="utf-8", errors="backslashreplace")
    except OSError as why:
        return f"(its traceback could not be saved: {why.strerror or why})"
    return str(path)


def _finish_output(status: int, prog: str) -> int:
    """Flush standard output; a full disk or a closed pipe is one line, not "Exception ignored"."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        pass  # the reader took what it wanted (``| head``): nothing to say, as for ``cat``
    except OSError as exc:
        print(f"{prog}: error: standard output: {exc.strerror or exc}", file=sys.stderr)
        status = status or 1
    else:
        return status
    # what stays in the buffer would be written, and fail again, when Python exits
    with contextlib.suppress(OSError, ValueError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return status


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    0 on success, 1 for bad input or a failed run (a file, key or value at fault, a
    calibration that drifted), 2 for a malformed command line (an unknown, missing or
    out-of-range option), 70 for an internal error (a bug: the traceback is saved to a file
    named in the line), 130 when interrupted (Ctrl-C, SIGTERM) before the output was complete
    (0 after). Every error is one line on stderr, ``workbench COMMAND: error: WHAT: why``, and a
    failed run writes nothing.
    """
    args_in = sys.argv[1:] if argv is None else argv
    first = next((a for a in args_in if not a.startswith("-")), None)
    # name the subcommand in usage errors too, which argparse reports before `args` exists
    prog = f"workbench {first}" if first in COMMANDS else "workbench"
    speak_the_terminals_language(sys.stdout, sys.stderr)
    with signals_handled() as written:
        try:
            status = _main(argv, args_in, first)
        except WorkbenchError as exc:
            if interrupt_came():  # (what an interrupt broke, reported as the input's fault by a caller)
                status = _interrupted(prog, written)
            else:
                print(f"{prog}: error: {one_line(str(exc))}", file=sys.stderr)
                status = exc.exit_status
        except KeyboardInterrupt:
            status = _interrupted(prog, written)
        except SystemExit as exc:
            # argparse's --help and --version: their text is on stdout, which may still fail to flush
            status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except Exception as exc:
            # (a library's import the interrupt broke, tried again, fails in its own words)
            if _wraps_an_interrupt(exc) or interrupt_came():
                status = _interrupted(prog, written)
            elif (why := _resources_exhausted(exc)) is not None:
                print(f"{prog}: error: {why}; nothing written", file=sys.stderr)
                status = 1
            else:
                status = _internal_error(prog, exc)
    return _finish_output(status, prog)


def _interrupted(prog: str, written: list[Path]) -> int:
    """Ctrl-C or SIGTERM, said in one line: the exit status.

    A write undoes itself (no temporary left) unless its renames were done, and then the output
    is complete: that is what the user needs to know.
    """
    if written:
        done = ", ".join(map(str, written))
        print(f"{prog}: interrupted after writing {done}, which is complete", file=sys.stderr)
        return 0
    print(f"{prog}: interrupted; nothing written", file=sys.stderr)
    return 130


def _wraps_an_interrupt(exc: BaseException) -> bool:
    """Whether an interrupt is the cause of ``exc``: Python wraps what a class's creation raises.

    (SIGTERM while numba loaded came out as "RuntimeError: Error calling __set_name__ on
    'cached_property' instance", its cause the interrupt.)
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, KeyboardInterrupt):
            return True
        exc = exc.__cause__ or exc.__context__
    return False


def _resources_exhausted(exc: BaseException) -> str | None:
    """What the machine ran out of, where a library says so in its own exception; None for anything else.

    Memory (:func:`workbench.errors.exhausted`: what the pre-checks of design's print and render's
    photo did not foresee, or OpenCV's allocator in C++), or a library that cannot load: under a
    memory limit its shared objects fail to map (an ``ImportError`` of a module not ours;
    llvmlite's ``OSError``: "Could not find/load shared object file", ctypes': "failed to map
    segment"). No bug of ours, the machine's limit; an ``ImportError`` of our own module is one.
    """
    text = str(exc)
    if exhausted(exc):
        return "out of memory (lower the resolution or the size)"
    library = isinstance(exc, ImportError) and not (exc.name or "").startswith("workbench")
    if library or (isinstance(exc, OSError) and ("shared object" in text or "failed to map segment" in text)):
        return f"a library could not be loaded ({one_line(text)})"
    return None


def _internal_error(prog: str, exc: BaseException) -> int:
    """A bug: one line that says so and where its traceback is, never the traceback itself."""
    report = _crash_report(prog, exc)
    print(
        f"{prog}: internal error: {type(exc).__name__}: {one_line(str(exc))}; nothing written; "
        f"please report it with {report}",
        file=sys.stderr,
    )
    return INTERNAL_ERROR


def _main(argv: list[str] | None, args_in: list[str], first: str | None) -> int:
    """:func:`main` inside its error handling: the environment checked, the command run."""
    release_early_signals()  # a Ctrl-C while Python started is raised here, and reported
    check_current_folder()
    keep_owner_permissions()
    check_thread_counts(os.environ)
    source_date_epoch(os.environ)  # read by ReportLab when it loads, and by every PDF's date line
    use_writable_caches()  # before a command's modules load numba and matplotlib
    fit_the_address_space(os.environ)  # (it loads numba: after its cache is set) before a command's modules
    load_reportlab(os.environ)
    parser = build_parser(first if first in COMMANDS else None)
    _refuse_empty_outputs(args_in)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    status = _run_quietly(args)
    deliver_pending()  # a Ctrl-C whose raise Python swallowed (in a weakref callback) is reported here
    return status
