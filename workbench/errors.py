"""Errors the command line reports as one line, without a traceback."""


class WorkbenchError(Exception):
    """Bad input or an impossible request: reported as one line, exit status 1."""

    exit_status = 1


class UsageError(WorkbenchError):
    """A malformed command line: exit status 2, as argparse uses."""

    exit_status = 2


def exhausted(exc: BaseException) -> bool:
    """Whether ``exc`` says the machine ran out of memory: no fault of the input, never to be caught as one.

    ``MemoryError``; OpenCV's ``cv2.error`` "Insufficient memory" (its allocator, in C++); an
    ``OSError`` with ENOMEM; a thread that cannot start. A handler that takes any exception for
    the input's fault (a parser, a backend with a fallback) lets these through, so that the
    command says "out of memory".
    """
    import errno

    return (
        isinstance(exc, MemoryError)
        or "Insufficient memory" in str(exc)
        or (isinstance(exc, OSError) and exc.errno == errno.ENOMEM)
        # (a thread's stack and arena not given: Python's "can't start new thread")
        or (isinstance(exc, RuntimeError) and "can't start new thread" in str(exc))
    )
