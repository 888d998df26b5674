"""The process's environment made safe before a command runs: caches, umask, threads, encoding, dates.

Where numba and matplotlib keep their caches when neither the install nor HOME is writable:

numba compiles the per-pixel loops once and caches them beside the source (``__pycache__``)
or in the user's cache folder; with neither writable (a read-only install, a service
account whose HOME is read-only) it raises at import, a traceback before any command runs.
matplotlib then prints a warning about its config folder. Both read an environment variable
when they load: this module sets it, to a folder of this user's under the system's
temporary folder, before either loads, and only where the usual places cannot be written.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from pathlib import Path

from workbench.errors import WorkbenchError
from workbench.text import ASCII_ERRORS


def _can_create(path: Path) -> bool:
    """Whether ``path`` is, or could be made, a writable folder (its first existing ancestor is a writable folder)."""
    for p in (path, *path.parents):
        if p.exists():
            return p.is_dir() and os.access(p, os.W_OK | os.X_OK)
    return False


def cache_dir(environ) -> Path:
    """The workbench's own cache folder: ``$XDG_CACHE_HOME/workbench`` (``~/.cache/workbench``).

    Where that cannot be made (a read-only or file HOME), a folder of this user's under the
    system's temporary folder. Third-party caches (matplotlib's fonts, Mitsuba's kernels)
    live under it, never in HOME directly.

    Parameters
    ----------
    environ : dict
        The environment (``os.environ``).

    Returns
    -------
    Path
        The folder (not created here).
    """
    home = Path(environ.get("HOME") or "~").expanduser()
    xdg = Path(environ.get("XDG_CACHE_HOME") or home / ".cache") / "workbench"
    if xdg.is_absolute() and _can_create(xdg):
        return xdg
    uid = os.getuid() if hasattr(os, "getuid") else 0
    return Path(tempfile.gettempdir()) / f"workbench-cache-{uid}"


def cache_environment(environ: dict, package_dir: Path) -> dict[str, str]:
    """The variables to set so that numba and matplotlib find a writable cache of the workbench's.

    matplotlib's folder is always the workbench's (:func:`cache_dir`): a user's
    ``matplotlibrc`` would otherwise change the bytes of every figure, and its font cache is
    then not written into HOME. numba keeps its first choice, beside the installed source,
    where that is writable.

    Parameters
    ----------
    environ : dict
        The environment (``os.environ``).
    package_dir : Path
        The installed ``workbench`` package (numba's first choice, beside the source).

    Returns
    -------
    dict of str to str
        ``MPLCONFIGDIR`` unless set, and ``NUMBA_CACHE_DIR`` where the usual places cannot be written.
    """
    home = Path(environ.get("HOME") or "~").expanduser()
    xdg_cache = Path(environ.get("XDG_CACHE_HOME") or home / ".cache")
    ours = cache_dir(environ)
    out = {}
    if "NUMBA_CACHE_DIR" not in environ:
        in_tree = any(_can_create(d / "__pycache__") for d in (package_dir, package_dir / "validate"))
        if not in_tree and not _can_create(xdg_cache / "numba"):
            out["NUMBA_CACHE_DIR"] = str(ours / "numba")
    if "MPLCONFIGDIR" not in environ:
        out["MPLCONFIGDIR"] = str(ours / "matplotlib")
    return out


def use_writable_caches() -> None:
    """Set :func:`cache_environment`'s variables in this process (before numba or matplotlib loads)."""
    for key, value in cache_environment(dict(os.environ), Path(__file__).parent).items():
        os.environ[key] = value


def load_reportlab(environ) -> None:
    """Load ReportLab with its user settings out of reach.

    ReportLab runs ``~/.reportlab_mods`` and ``~/.reportlab_settings`` when it loads: a user's
    settings there would change the bytes of every PDF, and a HOME that is a file made the
    load fail. It is loaded once, here, with HOME at the workbench's cache.
    """
    with home_for_a_library(cache_dir(environ) / "reportlab"):
        import reportlab.rl_config  # noqa: F401


@contextlib.contextmanager
def home_for_a_library(folder: Path):
    """Run with ``HOME`` pointing at ``folder`` (made if needed), then put it back.

    Dr.Jit (Mitsuba) keeps its kernel cache in ``$HOME/.drjit`` and reads HOME once, when it
    loads; giving it the workbench's cache folder there keeps it out of the user's HOME.
    """
    before = os.environ.get("HOME")
    with contextlib.suppress(OSError):
        folder.mkdir(parents=True, exist_ok=True)
    os.environ["HOME"] = str(folder)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("HOME", None)
        else:
            os.environ["HOME"] = before


# --- the rest of the environment, checked before a command runs ---------------------------

# the latest second datetime can write (9999-12-31T23:59:59Z); later is no date a page can print
_LAST_EPOCH = 253402300799

# the thread counts numba, OpenMP and the BLAS libraries read when they load: 0 or a word
# makes numba raise at import and OpenBLAS print its own fatal line
THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def source_date_epoch(environ) -> int | None:
    """``SOURCE_DATE_EPOCH`` (reproducible builds) as whole seconds, or None when unset.

    Raises
    ------
    WorkbenchError
        The value is not ASCII digits (``"²"`` passes ``str.isdigit``), or lies beyond year 9999.
    """
    epoch = environ.get("SOURCE_DATE_EPOCH")
    if epoch is None:
        return None
    text = epoch.strip()
    if not text or not (text.isascii() and text.isdigit()) or int(text) > _LAST_EPOCH:
        raise WorkbenchError(
            f"SOURCE_DATE_EPOCH={epoch!r}: must be whole seconds since 1970-01-01 UTC up to year 9999 "
            "(reproducible builds), or unset"
        )
    return int(text)


def check_thread_counts(environ) -> None:
    """Refuse a thread count the numeric libraries cannot start with (``OMP_NUM_THREADS=0``).

    A count is a positive whole number, or for OpenMP a comma-separated list of them (nested levels).

    Raises
    ------
    WorkbenchError
        Naming the variable and its value.
    """
    for key in THREAD_VARIABLES:
        value = environ.get(key)
        if value is None:
            continue
        parts = value.strip().split(",") if key == "OMP_NUM_THREADS" else [value.strip()]
        if not all(p.strip().isascii() and p.strip().isdigit() and int(p) > 0 for p in parts):
            raise WorkbenchError(f"{key}={value!r}: must be a positive whole number of threads, or unset")


# the libraries every command loads: under an address-space limit (``ulimit -v``) below what they
# map, loading one ends the process in the loader, not in Python (OpenCV segfaulted at 600 MB;
# glibc aborted "cannot allocate memory for thread-local data" at 1 GB when a pool started a
# thread), so they are tried first in a child process under the same limit
LIBRARIES = ("numpy", "scipy.sparse", "scipy.spatial", "cv2", "numba")  # and MKL's PARDISO where installed
# the address space a command needs beyond its libraries for the least of its work, its
# compilers included: measured on the default job, flatten, pdf and suggest-views finished within
# 0.20 to 0.25 GiB beyond the libraries' 0.85; within less, numba's compiler (LLVM) ended the
# process with its own lines ("LLVM ERROR: out of memory", abort) where a region of Python would
# have said "out of memory". A limit that leaves less is refused before any work
HEADROOM_BYTES = 256 * 2**20
# glibc's mallopt parameter for the number of malloc arenas (malloc.h's M_ARENA_MAX): each thread
# otherwise gets its own, 64 MiB of address space reserved apiece on 64-bit Linux
_M_ARENA_MAX = -8


def address_space_limit() -> int | None:
    """The process's soft address-space limit (``ulimit -v``, RLIMIT_AS), bytes; None where there is none."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        infinite = resource.RLIM_INFINITY
    except (ImportError, AttributeError, OSError, ValueError):
        return None
    return None if soft == infinite or soft < 0 else int(soft)


def load_libraries() -> None:
    """Load :data:`LIBRARIES`, OpenBLAS's buffer with one product, and MKL's PARDISO with one small solve
    where pypardiso is installed.

    (MKL loads its threading layer and kernels at the first solve, and exits with its own fatal
    lines where it cannot: loaded first, before a command's data takes the address space.)
    """
    import importlib

    for name in LIBRARIES:
        importlib.import_module(name)
    import numpy as np

    # (OpenBLAS takes its working buffer at the first product, and exits with its own line
    # where it cannot: "Memory allocation still failed after 10 retries, giving up")
    np.ones((128, 128)) @ np.ones((128, 128))
    try:
        import pypardiso
    except ImportError:
        return
    import scipy.sparse as sp

    pypardiso.spsolve(sp.identity(4, format="csr"), np.ones(4))


def proc_bytes(path: str, key: str) -> int | None:
    """A ``KEY:  N kB`` line of one of Linux's ``/proc`` files, in bytes; None where the system does not say."""
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def address_space_peak() -> int:
    """The most address space this process has held, bytes (Linux's VmPeak); 0 where the system does not say."""
    return proc_bytes("/proc/self/status", "VmPeak") or 0


def _libraries_load(raise_limit: bool) -> int | None:
    """:func:`load_libraries` and HEADROOM_BYTES more in a child process; the address space it peaked
    at, bytes, or None if it failed.

    With ``raise_limit`` the child lifts its soft limit to the hard one first (what they need).
    """
    import subprocess
    import sys

    code = (
        "import resource, sys\n"
        + (
            "resource.setrlimit(resource.RLIMIT_AS, (resource.getrlimit(resource.RLIMIT_AS)[1],) * 2)\n"
            if raise_limit
            else ""
        )
        + f"sys.path.insert(0, {str(Path(__file__).resolve().parents[1])!r})\n"
        + "from workbench.environment import load_libraries\n"
        + "load_libraries()\n"
        + f"import numpy\nnumpy.empty({HEADROOM_BYTES}, numpy.uint8)\n"  # (address space, untouched)
        + "from workbench.environment import address_space_peak\n"
        + "print(address_space_peak())\n"
    )
    try:
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    if r.returncode != 0:
        return None
    try:
        return int(r.stdout.split()[-1])
    except (ValueError, IndexError):
        return 0


def fit_the_address_space(environ) -> None:
    """Under an address-space limit, take less of it and refuse, in one line, a limit the libraries cannot load in.

    One thread for the numeric libraries where the user set none (OpenBLAS reserves buffers per
    thread: 0.72 GB of address space after the imports with one, 0.94 GB with two), one for
    OpenCV's pool, and one malloc arena; then :data:`LIBRARIES` are loaded in a child process under
    the same limit, and where they load there, here.

    Raises
    ------
    WorkbenchError
        The libraries cannot load within the limit: the limit, and what they need where that can be measured.
    """
    limit = address_space_limit()
    if limit is None:
        return
    for key in THREAD_VARIABLES:
        environ.setdefault(key, "1")
    with contextlib.suppress(OSError, AttributeError):
        import ctypes

        ctypes.CDLL(None).mallopt(_M_ARENA_MAX, 1)
    if _libraries_load(raise_limit=False) is not None:
        # (and in this process, now, as the child did: a library that maps itself later, with a
        # command's data in the address space, fails where no line of ours can say so)
        load_libraries()
        import cv2

        cv2.setNumThreads(1)  # (its pool's threads, each a stack and an arena: "Can't spawn new thread")
        return
    need = _libraries_load(raise_limit=True)
    what = f": they take {(need - HEADROOM_BYTES) / 2**30:.2f} GiB of it here" if need else ""
    raise WorkbenchError(
        f"the address-space limit (ulimit -v) of {limit / 2**20:,.0f} MiB is too small for the libraries every "
        f"command loads (NumPy, SciPy, OpenCV, numba) and {HEADROOM_BYTES / 2**30:.2f} GiB of work{what}; "
        "raise it (ulimit -v unlimited)"
    )


def check_current_folder() -> None:
    """Refuse to start in a current folder that no longer exists (removed under the shell).

    Every relative path, and the default output names, are read from it.
    """
    try:
        os.getcwd()
    except OSError as exc:
        raise WorkbenchError(
            f"the current folder cannot be read ({exc.strerror or exc}); change to an existing folder"
        ) from None


def keep_owner_permissions() -> None:
    """Clear the owner's bits from the umask, keeping the group's and others'.

    With ``umask 777`` every folder the command makes is closed to its owner too, so its own
    temporary folder cannot be written; an output its owner cannot read is never what was meant.
    """
    old = os.umask(0o077)
    os.umask(old & 0o077)


def speak_the_terminals_language(*streams) -> None:
    """Make the streams spell what their encoding cannot show in ASCII instead of raising.

    Under ``LANG=C`` or ``PYTHONIOENCODING=latin-1`` printing ``mm²`` or ``✓`` raised
    ``UnicodeEncodeError``. A stream that can encode everything is left as it is.
    """
    for stream in streams:
        if stream is not None and hasattr(stream, "reconfigure"):
            with contextlib.suppress(ValueError, OSError):
                stream.reconfigure(errors=ASCII_ERRORS)


def print_result(text: str) -> None:
    """Write a command's result ``text`` to standard output, flushed, before its files are written.

    A reader that closed the pipe (``| head``) took what it wanted: no error. A full disk or a
    closed terminal is one line (:class:`WorkbenchError`), raised before any file is written, and
    what stays in the buffer goes to /dev/null (flushed again at exit, it would fail again: a
    second line).
    """
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:
        pass
    except OSError as exc:
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        raise WorkbenchError(f"standard output: {exc.strerror or exc}; nothing written") from None
