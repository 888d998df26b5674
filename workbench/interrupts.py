"""Ctrl-C and SIGTERM: taken from the command's first moment, raised where the command is, held during renames.

Its own module, with nothing heavier than :mod:`signal` and :mod:`threading` to import: the
``workbench`` process takes the signals before the rest of the command line loads. Python's own
start comes before any of this: the launcher (:mod:`workbench.launcher`) starts Python with both
signals blocked, so that one sent then waits for the handler here.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading

# (typing's TYPE_CHECKING without importing typing: 10 ms of the start, before the signals are taken)
TYPE_CHECKING = False
if TYPE_CHECKING:
    from collections.abc import Iterator
    from pathlib import Path


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, raised where the command was; ``signum`` says which."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signum)
        self.signum = signum


class _Signals:
    """What the handler needs across calls: signals are the process's, so is this record.

    ``held``: depth of :func:`_held` sections (a signal then waits until the last ends; start-up
    counts as one, see :func:`take_signals_early`);
    ``pending``: the last signal, until it is raised where the command stops (it arrived while
    held, or Python swallowed its raise: see :func:`_handler`); ``written``: outputs completed so far
    by the running command, so that an interrupt after them is not reported as "nothing
    written"; ``came``: a signal came during the running command (whether or not it was raised).
    """

    def __init__(self) -> None:
        self.held = 0
        self.pending: int | None = None
        self.came = False
        self.written: list[Path] = []
        self.installed = False
        # the handlers before :func:`take_signals_early`, restored when the command ends
        self.original: dict = {}


_SIGNALS = _Signals()


# while a module is being imported, a signal is sent again after this long (seconds), until it
# comes outside the import
REDELIVER_S = 0.05


def _handler(signum, frame) -> None:
    # recorded before it is raised: Python runs a handler between any two bytecodes, also inside
    # a weakref callback of the garbage collector, which prints what it raises ("Exception ignored
    # in ...") and goes on: design then finished and exited 0 after a Ctrl-C (5 of 13 tries in
    # the issue). What is recorded is raised again at the next safe point (:func:`deliver_pending`).
    _SIGNALS.pending = signum
    _SIGNALS.came = True
    if _SIGNALS.held:
        return
    if _importing(frame):
        # an extension module's initialisation is C code that may catch what the handler raises
        # and print it as a traceback before failing in its own words (a Ctrl-C 0.6 s into
        # design, once in a suite's run: "Traceback ... in _handler ... Interrupted: 2" above the
        # command's own line): the signal is sent again shortly, until it comes outside the import
        again = threading.Timer(REDELIVER_S, _send_again, (signum,))
        again.daemon = True  # (nothing to wait for at exit)
        again.start()
        return
    raise Interrupted(signum)


def _importing(frame) -> bool:
    """Whether the frame the signal came in is inside the import machinery (a module being imported)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _send_again(signum: int) -> None:
    """The signal once more, to this process (the handler raises it if it now comes outside an import)."""
    import os

    if _SIGNALS.pending == signum:  # (not already raised at a safe point meanwhile)
        os.kill(os.getpid(), signum)


def deliver_pending() -> None:
    """Raise the signal that came while held, or whose raise was swallowed; nothing when none is waiting.

    Called where a command may stop: before and after the renames of a write (:func:`_held`)
    and when the command is done. Nothing is raised while held, or while the signal's own
    ``KeyboardInterrupt`` is already on its way up (in a ``finally`` it passes through).
    """
    if _SIGNALS.held or _SIGNALS.pending is None or isinstance(sys.exc_info()[1], KeyboardInterrupt):
        return
    signum, _SIGNALS.pending = _SIGNALS.pending, None
    raise Interrupted(signum)


def ignore_swallowed_interrupts(unraisable) -> None:
    """``sys.unraisablehook``: an interrupt raised where Python cannot raise it is kept for later, not printed.

    Any other such exception is printed as Python prints it, unless an interrupt came before it.
    """
    if isinstance(unraisable.exc_value, KeyboardInterrupt):
        return  # recorded by the handler; :func:`deliver_pending` raises it
    if _SIGNALS.came:
        # what an interrupt left half made fails in its finaliser (llvmlite's ObjectRef.__del__,
        # after a Ctrl-C inside its constructor: "AttributeError: ... '_as_parameter_'"): a
        # consequence of the interrupt the command has already reported, not news
        return
    sys.__unraisablehook__(unraisable)


def _signals_to_take() -> tuple[int, ...]:
    """SIGTERM always; SIGINT unless the process was started with it ignored.

    A shell starts a background job (``cmd &``) and ``nohup`` starts its command with SIGINT
    ignored, so that the terminal's Ctrl-C does not reach it; taking SIGINT back would undo that.
    """
    ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    return (signal.SIGTERM,) if ignored else (signal.SIGINT, signal.SIGTERM)


def take_signals_early() -> None:
    """Hold Ctrl-C and SIGTERM from the first moment of the command's own process.

    Loading a command's modules takes about a second; a signal then must not end in a
    traceback (Python's own ``KeyboardInterrupt``) or a silent death (SIGTERM's default).
    The signal is held until :func:`release_early_signals`, which raises it where the
    command line reports it. Only for the ``workbench`` process itself: a program that
    imports the package keeps its own handlers.
    """
    if threading.current_thread() is not threading.main_thread() or _SIGNALS.original:
        return
    _SIGNALS.original = {s: signal.getsignal(s) for s in _signals_to_take()}
    _SIGNALS.held += 1
    for s in _SIGNALS.original:
        signal.signal(s, _handler)
    # the launcher (:mod:`workbench.launcher`) started Python with both blocked, so that one sent
    # during Python's own start waited: let them through now that the handler holds them (a
    # waiting one is delivered here, and raised by :func:`release_early_signals`); unblocked,
    # the children the command starts get the mask a shell would have given them
    signal.pthread_sigmask(signal.SIG_UNBLOCK, (signal.SIGINT, signal.SIGTERM))


def release_early_signals() -> None:
    """End :func:`take_signals_early`'s hold; a signal that came during start-up is raised now."""
    if _SIGNALS.original and _SIGNALS.held:
        with _held():
            _SIGNALS.held -= 1


@contextlib.contextmanager
def signals_handled() -> Iterator[list[Path]]:
    """Run a command with Ctrl-C and SIGTERM raised as :class:`Interrupted` (held during renames).

    Yields the list of outputs the command completes, for its caller to say what an
    interrupt left. Outside the main thread (where Python allows no handler) it only yields.
    Afterwards the handlers are those before the command; in the command's own process
    (:func:`take_signals_early`) the signals are ignored, as it only exits then.
    """
    _SIGNALS.written = []
    if not _SIGNALS.original:
        _SIGNALS.pending = None  # (one a process took early is still to be delivered)
        _SIGNALS.came = False
    if threading.current_thread() is not threading.main_thread() or _SIGNALS.installed:
        yield _SIGNALS.written
        return
    own_process = bool(_SIGNALS.original)
    previous = dict(_SIGNALS.original) or {s: signal.getsignal(s) for s in _signals_to_take()}
    for s in previous:
        signal.signal(s, _handler)
    _SIGNALS.installed = True
    try:
        yield _SIGNALS.written
    finally:
        # the command's own process only exits now, with the status decided: a signal in that last
        # moment (Python's shutdown) would kill it, exit -15 after "wrote ...", so it is ignored
        for s, h in previous.items():
            signal.signal(s, signal.SIG_IGN if own_process else h)
        _SIGNALS.installed = False
        _SIGNALS.pending = None
        _SIGNALS.original = {}


@contextlib.contextmanager
def _held() -> Iterator[None]:
    """Hold Ctrl-C and SIGTERM for the duration (the renames of a write, its clean-up); deliver after.

    A signal that came before and was swallowed (see :func:`_handler`) is raised first: nothing is
    renamed after an interrupt.
    """
    deliver_pending()
    _SIGNALS.held += 1
    try:
        yield
    finally:
        _SIGNALS.held -= 1
        deliver_pending()


def interrupt_came() -> bool:
    """Whether Ctrl-C or SIGTERM came during the running command, raised or not.

    A library that catches what its import raises turns an interrupt into its own error, later:
    pybind11's "type ... is already registered" on the next try, "initialization failed". Such an
    error after an interrupt is the interrupt.
    """
    return _SIGNALS.came
