"""Progress lines for a person at a terminal: one per photo and stage, on stderr, never into a pipe or a log."""

from __future__ import annotations

import sys

_SHOWN = {"on": False}  # set once by the command, before any worker is forked (a fork keeps it)


def wanted(quiet: bool, stream=None) -> bool:
    """Whether progress is shown: not with ``-q``, and only when ``stream`` (default: stderr) is a terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return not quiet and stream.isatty()
    except (AttributeError, ValueError):  # (a replaced or closed stream)
        return False


def show(on: bool) -> None:
    """Progress lines on (True) or off, for this process and the workers it forks afterwards."""
    _SHOWN["on"] = bool(on)


def shown() -> bool:
    """Whether progress lines are on in this process."""
    return _SHOWN["on"]


def say(line: str) -> None:
    """One progress line on stderr when progress is on (one write, so lines of parallel workers do not mix)."""
    if _SHOWN["on"]:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()
