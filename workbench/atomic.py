"""All-or-nothing writing of a command's output files, and the names they may take."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

from workbench.errors import WorkbenchError

# what a file name made from a user's name (a view, a photo) may hold: no separator, no "..", no blank
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]")


def safe_name(name: str) -> str:
    """``name`` as a file name that stays in its folder.

    Characters other than ASCII letters, digits, ``.``, ``_`` and ``-`` become ``_``, and a
    leading dot (a hidden file, or ``..``) becomes ``_``.
    """
    name = _UNSAFE.sub("_", name) or "_"
    return "_" + name[1:] if name.startswith(".") else name


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


def check_output_dir(directory: Path) -> None:
    """Refuse, before any work, an output folder that is an existing file or lies under one."""
    directory = Path(directory)
    for d in (directory, *directory.parents):
        if d.exists() and not d.is_dir():
            raise WorkbenchError(f"{d}: is a file; give a directory for the output")
        if d.exists():
            return


def _write_temp(path: Path, data: bytes) -> Path:
    """``data`` in a flushed temporary file beside ``path``; returns the temporary's path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    return tmp


def _oserror(path: Path, exc: OSError) -> WorkbenchError:
    return WorkbenchError(f"{path}: cannot write: {exc.strerror or exc}")


def write_files(files: dict[Path, bytes]) -> None:
    """Write several files so that either all appear complete or none changes.

    Each file is written to a temporary name beside its target and flushed; only when
    every one is written are they renamed into place (rename is atomic on POSIX). The
    targets that existed are kept as hard-linked backups until the last rename, so that a
    rename failing half-way puts the earlier ones back. For a set of files that makes up
    an output folder of its own, :func:`write_folder` swaps the whole folder instead.

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
    backups: dict[Path, Path | None] = {}
    try:
        for path, data in files.items():
            path = Path(path)
            try:
                temps.append((_write_temp(path, data), path))
            except OSError as exc:
                raise _oserror(path, exc) from None
        for tmp, path in temps:
            try:
                backups[path] = _backup(path)
                os.replace(tmp, path)
            except OSError as exc:
                _restore(backups)
                raise _oserror(path, exc) from None
        temps.clear()
    finally:
        for tmp, _ in temps:
            tmp.unlink(missing_ok=True)
        for backup in backups.values():
            if backup is not None:
                backup.unlink(missing_ok=True)


def _backup(path: Path) -> Path | None:
    """A hard link to the existing ``path`` (None when there is none), to restore it."""
    if not path.exists():
        return None
    backup = path.with_name(f".{path.name}.old-{os.getpid()}")
    backup.unlink(missing_ok=True)
    try:
        os.link(path, backup)
    except OSError:  # a file system without hard links
        shutil.copy2(path, backup)
    return backup


def _restore(backups: dict[Path, Path | None]) -> None:
    """Put back every target replaced so far (and remove those that did not exist)."""
    for path, backup in backups.items():
        try:
            if backup is None:
                path.unlink(missing_ok=True)
            else:
                os.replace(backup, path)
        except OSError:
            pass


def write_folder(directory: Path, files: dict[Path, bytes]) -> None:
    """Write a command's output folder all or nothing: a temporary sibling folder, then a swap.

    The files are written into ``.NAME.tmp-PID`` beside ``directory``; entries of an
    existing ``directory`` that this set does not replace (another command's output kept
    there, such as ``validation/`` in a design folder) are moved across; then the old
    folder is renamed aside, the new one into its place, and the old one removed. A
    failure at any step before the swap leaves ``directory`` as it was and removes the
    temporary folder.

    Parameters
    ----------
    directory : Path
        The output folder (created when missing).
    files : dict of Path to bytes
        Each file's path, inside ``directory``, and content.

    Raises
    ------
    WorkbenchError
        A path outside the folder, a folder that is a file, or a file that cannot be written.
    """
    directory = Path(directory)
    check_output_dir(directory)
    check_outputs(*files)
    rel = {}
    for path, data in files.items():
        try:
            rel[Path(path).relative_to(directory)] = data
        except ValueError:
            raise WorkbenchError(f"{path}: outside the output folder {directory}") from None
    directory.parent.mkdir(parents=True, exist_ok=True)
    tmp = directory.with_name(f".{directory.name}.tmp-{os.getpid()}")
    old = directory.with_name(f".{directory.name}.old-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    moved: list[str] = []
    try:
        tmp.mkdir()
        for name, data in rel.items():
            try:
                _write_file(tmp / name, data)
            except OSError as exc:
                raise _oserror(directory / name, exc) from None
        if directory.exists():
            tops = {n.parts[0] for n in rel}
            for entry in sorted(os.listdir(directory)):
                if entry not in tops:
                    os.rename(directory / entry, tmp / entry)
                    moved.append(entry)
            os.rename(directory, old)
        os.rename(tmp, directory)
    except (OSError, WorkbenchError) as exc:
        if old.exists() and not directory.exists():
            os.rename(old, directory)
        for entry in moved:  # give the old folder back what it lent the new one
            try:
                os.rename(tmp / entry, directory / entry)
            except OSError:
                pass
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, WorkbenchError):
            raise
        raise _oserror(directory, exc) from None
    shutil.rmtree(old, ignore_errors=True)


def _write_file(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
