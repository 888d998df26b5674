"""All-or-nothing writing of a command's output files, and the names they may take.

One mechanism serves every command:

- outputs are checked before any work (:func:`check_outputs`, :func:`check_output_dir`) and
  again at the write: no output is a directory, a name too long for the file system, two
  outputs of one name, one of the command's inputs (paths resolved, symlinks followed), a
  link into the system's devices (``/dev/stdout``), or a device, a named pipe or a socket (the
  rename would replace the node); any other output that is a symbolic link is replaced as a
  link (never written through to what it points to);
- files are written to temporary names, flushed, then renamed into place; a failure or an
  interrupt (Ctrl-C, SIGTERM) before the renames leaves every target as it was and no
  temporary behind; the renames themselves run with those signals held, so that an interrupt
  there ends after the output is complete and is reported as such (:func:`workbench.interrupts.signals_handled`);
- an output folder holds exactly what its last run wrote: a hidden list of them,
  ``.workbench-files``, tells the next run which files are its own (a stale one is removed)
  and which are not (a user's file, another command's folder: kept).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import stat
import sys
from collections.abc import Iterable
from pathlib import Path

from workbench.errors import WorkbenchError
from workbench.interrupts import _SIGNALS, _held

# what a file name made from a user's name (a view, a photo) may hold: no separator, no "..", no blank
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]")

MANIFEST = ".workbench-files"
# the longest name a file system takes (Linux, macOS, Windows: 255 bytes), less what the
# temporary and backup names add to it (".", ".tmp-", a process id)
NAME_MAX = 255
_TEMP_EXTRA = 24


def safe_name(name: str) -> str:
    """``name`` as a file name that stays in its folder.

    Characters other than ASCII letters, digits, ``.``, ``_`` and ``-`` become ``_``, and a
    leading dot (a hidden file, or ``..``) becomes ``_``.
    """
    name = _UNSAFE.sub("_", name) or "_"
    return "_" + name[1:] if name.startswith(".") else name


# --- checks before any work -------------------------------------------------------------------


def _check_name_lengths(path: Path, what: str = "") -> None:
    parts = Path(path).parts
    for k, part in enumerate(parts):
        n = len(os.fsencode(part))
        room = NAME_MAX - (_TEMP_EXTRA if k == len(parts) - 1 else 0)
        if n > room:
            raise WorkbenchError(
                f"{what or path}: the name {part[:24]}... is {n} bytes; a file name takes at most {room}"
            )


def _check_parents(directory: Path) -> None:
    """Refuse a folder for outputs that is a file or lies under one."""
    for d in (directory, *directory.parents):
        if d.exists() and not d.is_dir():
            raise WorkbenchError(f"{d}: is a file; give a directory for the output")
        if d.exists():
            return


def _resolved(path: Path) -> Path:
    """``path`` made absolute, ``.`` and ``..`` and every symlink along it followed."""
    return Path(os.path.realpath(os.path.abspath(path)))


def _input_files(inputs: Iterable[Path]) -> tuple[dict[Path, Path], dict[Path, Path]]:
    """Resolved input files and input folders, each to the path as given."""
    files, folders = {}, {}
    for p in inputs:
        if p is None:
            continue
        r = _resolved(Path(p))
        try:
            is_dir = r.is_dir()
        except OSError:  # a name too long to look up (its own command says so): no folder
            is_dir = False
        (folders if is_dir else files)[r] = Path(p)
    return files, folders


def check_outputs(*paths: Path, inputs: Iterable[Path] = ()) -> None:
    """Refuse, before any work, output files that cannot or must not be written.

    Parameters
    ----------
    *paths : Path
        Files a command is about to write.
    inputs : iterable of Path
        Files the command reads (folders among them are for :func:`check_output_dir`):
        no output may be one of them.

    Raises
    ------
    WorkbenchError
        Naming the first path that is a directory, whose name is too long, that two outputs
        share (``board -o b.json``: the PDF and its definition), that is an input, a symbolic
        link into /dev, /proc or /sys, or a device, a named pipe or a socket.
    """
    in_files, _ = _input_files(inputs)
    seen: dict[Path, Path] = {}
    for path in paths:
        path = Path(path)
        _check_name_lengths(path)
        if path.is_dir():
            raise WorkbenchError(f"{path}: is a directory; give a file name for this output")
        _check_parents(path.parent)
        if path.name == MANIFEST:
            raise WorkbenchError(f"{path}: is the name of an output folder's list of its files; give another name")
        r = _resolved(path)
        if r in seen:
            raise WorkbenchError(f"{path}: two outputs of this command would share this name; give another name")
        seen[r] = path
        given = in_files.get(r)
        if given is not None:
            also = "" if given == path else f" ({given})"
            raise WorkbenchError(f"{path}: is an input of this command{also}; write the output elsewhere")
        # an output is a file of its own: a link is replaced as a link (written through, it replaced
        # what it points to: a user's job file behind a board's definition), but never one of the
        # system's (`-o /dev/stdout` is a link to /proc/self/fd/1: replaced, /dev/stdout became a
        # PDF); renamed over a device or a pipe it would replace the node itself (`-o /dev/null`
        # made /dev/null a regular file)
        if path.is_symlink():
            if _in_system(path) or _in_system(r):
                raise WorkbenchError(
                    f"{path}: is a link into the system's devices (to {os.readlink(path)}), not a file; give a file "
                    "name for this output"
                )
            continue  # replaced as a link: what it points to is not touched
        if (kind := _special_kind(path)) is not None:
            raise WorkbenchError(f"{path}: is {kind}, not a file; give a file name for this output")


# the pseudo file systems of devices, processes and the kernel: no output is renamed over a link there
_SYSTEM_ROOTS = (Path("/dev"), Path("/proc"), Path("/sys"))


def _in_system(path: Path) -> bool:
    """Whether ``path`` (made absolute, its folder's links followed) lies under /dev, /proc or /sys."""
    p = _output_path(path)
    return any(p == root or root in p.parents for root in _SYSTEM_ROOTS)


def _output_path(path: Path) -> Path:
    """Where an output is written: ``path`` absolute, its folder's links followed, not a link it is itself.

    A link named as an output is replaced by the file (rename does not follow it), so that
    what it pointed to stays as it was; a folder that is a link is followed.
    """
    path = Path(os.path.abspath(path))
    return _resolved(path.parent) / path.name


def _special_kind(path: Path) -> str | None:
    """What an existing path that is neither a regular file nor a folder is (a device, a pipe, a socket), else None."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    kinds = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe"))
    kinds += ((stat.S_ISSOCK, "a socket"),)
    return next((name for test, name in kinds if test(mode)), "not a regular file")


def check_output_dir(directory: Path, inputs: Iterable[Path] = ()) -> None:
    """Refuse, before any work, an output folder that cannot or must not be written.

    A file, a folder under a file, a name too long, an input folder itself (``validate
    --out DESIGN``), or a folder whose earlier run wrote (so that this run would replace
    or remove) one of the inputs.
    """
    directory = Path(directory)
    _check_name_lengths(directory)
    _check_parents(directory)
    in_files, in_folders = _input_files(inputs)
    r = _resolved(directory)
    if r in in_folders:
        also = "" if in_folders[r] == directory else f" ({in_folders[r]})"
        raise WorkbenchError(f"{directory}: is an input folder of this command{also}; write the output elsewhere")
    for name in folder_manifest(r):
        if (r / name) in in_files:
            raise WorkbenchError(
                f"{directory}: its earlier output {name} is an input of this command; write the output elsewhere"
            )


# --- writing ----------------------------------------------------------------------------------


def _oserror(path: Path, exc: OSError) -> WorkbenchError:
    return WorkbenchError(f"{path}: cannot write: {exc.strerror or exc}")


def _write_file(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


def _link_or_copy(src: Path, dst: Path) -> None:
    dst.unlink(missing_ok=True)
    try:
        os.link(src, dst)
    except OSError:  # a file system without hard links
        shutil.copy2(src, dst)


def _rmtree(path: Path) -> None:
    """Remove ``path`` even where an earlier output made its folders read-only."""

    def retry(func, p, _exc):
        try:
            os.chmod(os.path.dirname(p), stat.S_IRWXU)
            if os.path.isdir(p):
                os.chmod(p, stat.S_IRWXU)
            func(p)
        except OSError:
            pass

    if not path.exists():
        return
    if sys.version_info >= (3, 12):
        shutil.rmtree(path, onexc=retry)
    else:  # pragma: no cover
        shutil.rmtree(path, onerror=retry)


def write_files(files: dict[Path, bytes], inputs: Iterable[Path] = ()) -> None:
    """Write several files so that either all appear complete or none changes.

    Each file is written to a temporary name beside its target and flushed; only when
    every one is written are they renamed into place (rename is atomic on POSIX), with
    Ctrl-C and SIGTERM held. The targets that existed are kept as hard-linked backups until
    the last rename, so that a rename failing half-way puts the earlier ones back. A
    target that is a symlink is replaced as a link (one into /dev, /proc or /sys is refused, as
    are a device, a pipe and a socket). For a set of files that
    makes up an output folder of its own, :func:`write_folder` writes the folder instead.

    Parameters
    ----------
    files : dict of Path to bytes
        Target path and content of each file. Parent directories are created.
    inputs : iterable of Path
        The command's inputs, which no target may be.

    Raises
    ------
    WorkbenchError
        A file cannot be written, or must not (see :func:`check_outputs`); names it.
    """
    # a target that is a directory would fail only at the rename, after others were
    # replaced: refuse it before anything is written
    check_outputs(*files, inputs=inputs)
    temps: list[tuple[Path, Path, Path]] = []
    backups: dict[Path, Path | None] = {}
    try:
        for given, data in files.items():
            path = _output_path(Path(given))
            tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
            temps.append((tmp, path, Path(given)))
            try:
                _write_file(tmp, data)
            except OSError as exc:
                raise _oserror(Path(given), exc) from None
        with _held():
            for tmp, path, given in temps:
                try:
                    backups[path] = _backup(path)
                    os.replace(tmp, path)
                except OSError as exc:
                    _restore(backups)
                    raise _oserror(given, exc) from None
            temps.clear()
            _SIGNALS.written.extend(Path(p) for p in files)
    finally:
        with _held():
            for p in [t for t, _, _ in temps] + [b for b in backups.values() if b is not None]:
                with contextlib.suppress(OSError):
                    p.unlink(missing_ok=True)


def _backup(path: Path) -> Path | None:
    """A hard link to the existing ``path`` (None when there is none), to restore it; a link's copy for a link."""
    backup = path.with_name(f".{path.name}.old-{os.getpid()}")
    if path.is_symlink():
        backup.unlink(missing_ok=True)
        os.symlink(os.readlink(path), backup)
        return backup
    if not path.exists():
        return None
    _link_or_copy(path, backup)
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


def folder_manifest(directory: Path) -> list[str]:
    """The files the last run wrote into ``directory`` (relative, POSIX), from its ``.workbench-files``."""
    try:
        text = (directory / MANIFEST).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return []
    names = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        p = Path(line)
        # only names inside the folder: a tampered list must not reach outside it
        if p.parts and not p.is_absolute() and ".." not in p.parts and p.parts[0] != MANIFEST:
            names.append(p.as_posix())
    return names


def _manifest_bytes(names: Iterable[str]) -> bytes:
    head = "# written by workbench: the next run into this folder replaces these and removes those it does not write\n"
    return (head + "".join(f"{n}\n" for n in sorted(names))).encode()


def write_folder(directory: Path, files: dict[Path, bytes], inputs: Iterable[Path] = ()) -> None:
    """Write a command's output folder all or nothing; afterwards it holds what this run wrote.

    A new folder is written as a temporary sibling ``.NAME.tmp-PID`` and renamed into
    place. An existing one (``.``, a symlink to a folder: followed) is updated in place:
    the new files are written into ``DIR/.workbench.tmp-PID/``, then, with Ctrl-C and
    SIGTERM held, each is renamed over its target (the old one kept as a hard link until
    the end) and the files the earlier run wrote that this one does not (its
    ``.workbench-files``) are removed. Everything else in the folder (a user's file,
    another command's output such as ``validation/`` in a design folder) is left alone. A
    failure at any step leaves the folder as it was and no temporary behind.

    Parameters
    ----------
    directory : Path
        The output folder (created when missing).
    files : dict of Path to bytes
        Each file's path, inside ``directory``, and content.
    inputs : iterable of Path
        The command's inputs: none may be replaced or removed.

    Raises
    ------
    WorkbenchError
        A path outside the folder, a folder that is a file, an input at stake, or a file
        that cannot be written.
    """
    given = Path(directory)
    check_output_dir(given, inputs)
    check_outputs(*files, inputs=inputs)
    rel: dict[str, bytes] = {}
    for path, data in files.items():
        try:
            name = Path(path).relative_to(given)
        except ValueError:
            raise WorkbenchError(f"{path}: outside the output folder {given}") from None
        if not name.parts or ".." in name.parts or name.as_posix() == MANIFEST:
            raise WorkbenchError(f"{path}: not a file name inside the output folder {given}")
        rel[name.as_posix()] = data
    directory = _resolved(given)
    in_files, _ = _input_files(inputs)
    old = folder_manifest(directory) if directory.is_dir() else []
    # a stale file is removed only where it really is inside the folder (not through a symlink out of it)
    stale = [
        n for n in old if n not in rel and (directory / n).is_file() and directory in _resolved(directory / n).parents
    ]
    for n in stale:
        if directory / n in in_files:
            raise WorkbenchError(f"{given / n}: is an input of this command; write the output elsewhere")
    rel[MANIFEST] = _manifest_bytes(n for n in rel)
    if directory.is_dir():
        _update_folder(directory, given, rel, stale)
    else:
        _new_folder(directory, given, rel)


def _write_all(root: Path, given: Path, rel: dict[str, bytes]) -> None:
    """Every file of ``rel`` under ``root``; an error names the file as the user gave it (under ``given``)."""
    for name, data in rel.items():
        try:
            _write_file(root / name, data)
        except OSError as exc:
            raise _oserror(given / name, exc) from None


def _new_folder(directory: Path, given: Path, rel: dict[str, bytes]) -> None:
    try:
        directory.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _oserror(given, exc) from None
    tmp = directory.with_name(f".{directory.name}.tmp-{os.getpid()}")
    try:
        _rmtree(tmp)
        _write_all(tmp, given, rel)
        with _held():
            try:
                os.rename(tmp, directory)
            except OSError as exc:
                raise _oserror(given, exc) from None
            _SIGNALS.written.append(given)
    finally:
        with _held():
            _rmtree(tmp)


def _update_folder(directory: Path, given: Path, rel: dict[str, bytes], stale: list[str]) -> None:
    stage = directory / f".workbench.tmp-{os.getpid()}"
    new, old = stage / "new", stage / "old"
    # (target, its backup or None) for every change made, in order, to undo them
    done: list[tuple[Path, Path | None]] = []
    try:
        with _held():
            _rmtree(stage)
        _write_all(new, given, rel)
        with _held():
            try:
                old.mkdir(parents=True)
                for k, name in enumerate([*rel, *stale]):
                    target = directory / name
                    backup = old / str(k)
                    if target.exists():
                        _link_or_copy(target, backup)
                    else:
                        backup = None
                    if name in rel:
                        target.parent.mkdir(parents=True, exist_ok=True)
                        done.append((target, backup))
                        os.replace(new / name, target)
                    else:
                        done.append((target, backup))
                        target.unlink()
            except OSError as exc:
                for target, backup in reversed(done):
                    try:
                        if backup is None:
                            target.unlink(missing_ok=True)
                        else:
                            os.replace(backup, target)
                    except OSError:
                        pass
                raise _oserror(given, exc) from None
            _SIGNALS.written.append(given)
            for name in stale:  # folders that held only stale files go with them
                for parent in (directory / name).parents:
                    if parent == directory:
                        break
                    with contextlib.suppress(OSError):
                        parent.rmdir()
    finally:
        with _held():
            _rmtree(stage)
