"""Where numba and matplotlib keep their caches when neither the install nor HOME is writable.

numba compiles the per-pixel loops once and caches them beside the source (``__pycache__``)
or in the user's cache folder; with neither writable (a read-only install, a service
account whose HOME is read-only) it raises at import, a traceback before any command runs.
matplotlib then prints a warning about its config folder. Both read an environment variable
when they load: this module sets it, to a folder of this user's under the system's
temporary folder, before either loads, and only where the usual places cannot be written.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def _can_create(path: Path) -> bool:
    """Whether ``path`` is, or could be made, a writable folder (its first existing ancestor is a writable folder)."""
    for p in (path, *path.parents):
        if p.exists():
            return p.is_dir() and os.access(p, os.W_OK | os.X_OK)
    return False


def cache_environment(environ: dict, package_dir: Path) -> dict[str, str]:
    """The variables to set so that numba and matplotlib find a writable cache.

    Parameters
    ----------
    environ : dict
        The environment (``os.environ``).
    package_dir : Path
        The installed ``workbench`` package (numba's first choice, beside the source).

    Returns
    -------
    dict of str to str
        ``NUMBA_CACHE_DIR`` and ``MPLCONFIGDIR`` where they are needed; empty when the usual places do.
    """
    home = Path(environ.get("HOME") or "~").expanduser()
    xdg_cache = Path(environ.get("XDG_CACHE_HOME") or home / ".cache")
    xdg_config = Path(environ.get("XDG_CONFIG_HOME") or home / ".config")
    uid = os.getuid() if hasattr(os, "getuid") else 0
    fallback = Path(tempfile.gettempdir()) / f"workbench-cache-{uid}"
    out = {}
    if "NUMBA_CACHE_DIR" not in environ:
        in_tree = any(_can_create(d / "__pycache__") for d in (package_dir, package_dir / "validate"))
        if not in_tree and not _can_create(xdg_cache / "numba"):
            out["NUMBA_CACHE_DIR"] = str(fallback / "numba")
    if "MPLCONFIGDIR" not in environ and not _can_create(xdg_config / "matplotlib"):
        out["MPLCONFIGDIR"] = str(fallback / "matplotlib")
    return out


def use_writable_caches() -> None:
    """Set :func:`cache_environment`'s variables in this process (before numba or matplotlib loads)."""
    for key, value in cache_environment(dict(os.environ), Path(__file__).parent).items():
        os.environ[key] = value
