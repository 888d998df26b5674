"""All-or-nothing writing of a command's output files."""

from __future__ import annotations

import os
from pathlib import Path

from workbench.errors import WorkbenchError


def check_outputs(*paths: Path) -> None:
    """Refuse, before any work, output paths that name an existing directory.

    Parameters
    ----------
    *paths : Path
        Files a command is about to write.

    Raises
    ------
    WorkbenchError
        Naming the first path that is a directory.
    """
    for path in paths:
        if Path(path).is_dir():
            raise WorkbenchError(f"{path}: is a directory; give a file name for this output")


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
    # a target that is a directory would fail only at the rename, after others were
    # replaced: refuse it before anything is written
    check_outputs(*files)
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
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise WorkbenchError(f"{path}: cannot write: {exc.strerror or exc}") from None
        temps.clear()
    finally:
        for tmp, _ in temps:
            tmp.unlink(missing_ok=True)
