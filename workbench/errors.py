"""Errors the command line reports as one line, without a traceback."""


class WorkbenchError(Exception):
    """Bad input or an impossible request: reported as one line, exit status 1."""

    exit_status = 1


class UsageError(WorkbenchError):
    """A malformed command line: exit status 2, as argparse uses."""

    exit_status = 2
