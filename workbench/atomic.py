"""All-or-nothing writing of a command's output files."""

from __future__ import annotations

import os
from pathlib import Path

from workbench.errors import WorkbenchError


def write_files(files: dict[Path, bytes]) -> None:
    """Write several files so that either all appear complete or none changes.

    Each file is written to a temporary name beside its target and flushed; only
    when every one is written are they renamed into place (rename is atomic on
    POSIX). On failure the temporaries are removed and the targets are untouched.

    Parameters
    ----------
    files : dict of Path to bytes
        Target path and content of each file. Parent directories are created.

    Raises
    ------
    WorkbenchError
        A file cannot be written; names it.
    """
    temps: list[tuple[Path, Path]] = []
    try:
        for path, data in files.items():
            path = Path(path)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
                with open(tmp, "wb") as fh:
                    temps.append((tmp, path))
                    fh.write(data)
                    fh.flush()
                    os.fsync(fh.fileno())
            except OSError as exc:
                raise WorkbenchError(f"{path}: cannot write: {exc.strerror or exc}") from None
        for tmp, path in temps:
            os.replace(tmp, path)
        temps.clear()
    finally:
        for tmp, _ in temps:
            tmp.unlink(missing_ok=True)
