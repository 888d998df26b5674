"""Every command under every hostile environment (issue 41): the convention holds, nothing outside the outputs changes.

Each case runs the real command in its own process (``python -m workbench``), as a user's shell
would, under one environment class: a terminal that speaks only ASCII or Latin-1, an absurd
``SOURCE_DATE_EPOCH`` or thread count, ``umask 777``, a current folder removed under the shell,
standard output on a full disk, a HOME that cannot be written or must not be, file names that
are not UTF-8, SIGTERM or SIGINT (Ctrl-C) at a random moment, an address-space limit
(``ulimit -v``) drawn from below what the libraries need to what the work needs. What is
asserted, for every case: no traceback and no "internal error" (those are bugs), exit status 0,
1, 2 or 130, a failure is one line and writes nothing, and no file is created or changed outside
the declared output and the workbench's own cache. A fast subset runs by default (each class
once, on commands in turn); ``make bench`` runs
every class on every command.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT
from test_fuzz import command_inputs, default_output, make_base, output_flag

COMMANDS = ("flatten", "design", "suggest-views", "pdf", "board", "render", "validate", "calibrate")
STORE_COMMANDS = ("lot", "store export", "trend")  # the store's readers (their seeds after the first eight's)
CLASSES = (
    "ascii-terminal",
    "latin-1-terminal",
    "source-date-epoch",
    "thread-count",
    "umask-777",
    "current-folder-removed",
    "stdout-full",
    "home-a-file",
    "home-watched",
    "names-not-utf-8",
    "sigterm",
    "sigint",
    "address-space-limit",
)
# cases per command in `make bench` for the classes that draw a value (a moment, a variable's value)
DRAWS = {"sigterm": 10, "sigint": 10, "source-date-epoch": 5, "thread-count": 4, "address-space-limit": 6}
# `ulimit -v` drawn over this range, GiB: below what the libraries map when they load (about 0.85
# here), through what a command's data takes, to enough for the base job
ADDRESS_SPACE_GIB = (0.4, 2.5)
SIGNAL_DELAYS_S = (0.05, 4.0)  # after Python's own start (about 40 ms here), to the end of the slowest case


def case_params() -> list:
    """(class, command, draw): each class once by default (commands in turn), and each store reader under
    two classes; in `make bench` every command under every class, DRAWS[class] times where the class draws
    a value."""
    out = []
    for k, cls in enumerate(CLASSES):
        fast = (COMMANDS[k % len(COMMANDS)], STORE_COMMANDS[k % len(STORE_COMMANDS)] if k < 6 else None)
        for command in COMMANDS + STORE_COMMANDS:
            for draw in range(DRAWS.get(cls, 1)):
                marks = () if (command in fast and draw == 0) else (pytest.mark.slow,)
                out.append(pytest.param(cls, command, draw, id=f"{cls}-{command}-{draw}", marks=marks))
    return out


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return make_base(tmp_path_factory.mktemp("env-base"))


def snapshot(root: Path) -> dict:
    """Every file and folder under ``root``, by path, with its content's hash (None for a folder)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(os.fsencode(root)):
        for d in dirnames:
            out[os.path.join(dirpath, d)] = None
        for f in filenames:
            p = os.path.join(dirpath, f)
            with open(p, "rb") as fh:
                out[p] = hashlib.sha256(fh.read()).hexdigest()
    return out


def argv_for(command: str, root: Path, base: Path) -> tuple[list, Path]:
    """The command's argv (with its output under ``root / "out"``) and that output."""
    if command == "suggest-views":
        job = root / "job"
        job.mkdir()
        for name in ("part.obj", "top.png", "job.toml"):
            shutil.copy(base / name, job / name)
        out = root / "out" / "suggest.toml"
        return ["suggest-views", job / "job.toml", "-o", out], out
    argv, _ = command_inputs(command, root, base)
    out = default_output(command, root / "out")
    return [*argv, output_flag(command), out], out


def run_case(cls: str, command: str, draw: int, root: Path, base: Path, home: Path) -> tuple[int, str, Path]:
    """Run ``command`` under environment class ``cls`` (its ``draw``-th value); exit status, stderr, output."""
    rng = np.random.default_rng([CLASSES.index(cls), (COMMANDS + STORE_COMMANDS).index(command), draw])
    if cls == "names-not-utf-8":
        root = Path(os.fsdecode(os.fsencode(root) + b"/Teil \xfc"))
        root.mkdir()
    argv, out = argv_for(command, root, base)
    if cls == "home-watched" and command == "render":
        # Dr.Jit writes its kernel cache into HOME when it loads
        k = argv.index("--supersample")
        argv[k : k + 2] = ["--renderer", "mitsuba", "--spp", "1"]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("LC_", "PYTHONIO"))}
    env.update({"HOME": str(home), "PYTHONPATH": str(ROOT)})
    env.pop("XDG_CACHE_HOME", None)
    env.pop("MPLCONFIGDIR", None)
    cwd, stdout, preexec, delay = str(root), subprocess.DEVNULL, None, None
    if cls == "ascii-terminal":
        env.update(LANG="C", LC_ALL="C", PYTHONIOENCODING="ascii")
    elif cls == "latin-1-terminal":
        env.update(PYTHONIOENCODING="latin-1")
    elif cls == "source-date-epoch":
        env["SOURCE_DATE_EPOCH"] = str(rng.choice(["253402300800", "99999999999999999999", "²", "-1", "1e9"]))
    elif cls == "thread-count":
        key = str(rng.choice(["OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS"]))
        env[key] = str(rng.choice(["0", "-2", "two", ""]))
    elif cls == "umask-777":
        preexec = lambda: os.umask(0o777)  # noqa: E731
    elif cls == "current-folder-removed":
        gone = root / "gone"
        gone.mkdir()
        cwd = str(gone)
        preexec = lambda: os.rmdir(gone)  # noqa: E731  (after the fork, in the child's own current folder)
    elif cls == "stdout-full":
        if not Path("/dev/full").exists():
            pytest.skip("/dev/full is not on this machine")
        stdout = open("/dev/full", "w")  # noqa: SIM115
    elif cls == "home-a-file":
        env["HOME"] = str(root / "home-is-a-file")
        Path(env["HOME"]).write_text("")
    elif cls in ("sigterm", "sigint"):
        delay = float(rng.uniform(*SIGNAL_DELAYS_S))
    elif cls == "address-space-limit":
        import resource

        limit = int(rng.uniform(*ADDRESS_SPACE_GIB) * 2**30)
        preexec = lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit))  # noqa: E731
    if cls == "sigint":  # as a terminal's Ctrl-C reaches it (a test runner may start children ignoring it)
        preexec = lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)  # noqa: E731
    cmd = [sys.executable, "-m", "workbench", *map(str, argv)]
    with subprocess.Popen(cmd, cwd=cwd, env=env, stdout=stdout, stderr=subprocess.PIPE, preexec_fn=preexec) as p:
        if delay is not None:
            time.sleep(delay)
            p.send_signal(signal.SIGINT if cls == "sigint" else signal.SIGTERM)
        err = p.stderr.read().decode("utf-8", "replace")
        status = p.wait()
    if stdout is not subprocess.DEVNULL:
        stdout.close()
    return status, err, out


@pytest.mark.parametrize(("cls", "command", "draw"), case_params())
def test_every_command_under_every_environment(cls, command, draw, tmp_path, base):
    root, home = tmp_path / "work", tmp_path / "home"
    root.mkdir()
    home.mkdir()
    before_base = snapshot(base)
    status, err, out = run_case(cls, command, draw, root, base, home)
    lines = err.strip().splitlines()
    assert "Traceback" not in err and "internal error" not in err and "Exception ignored" not in err, err
    assert status in (0, 1, 2, 130), (status, err)
    assert snapshot(base) == before_base, "an input outside the case changed"
    leftovers = [p for p in root.rglob("*") if ".tmp-" in p.name or ".old-" in p.name]
    assert not leftovers, leftovers
    # HOME holds nothing but the workbench's own cache folder
    made = sorted(str(p.relative_to(home)) for p in home.rglob("*"))
    assert all(m == ".cache" or m.startswith(".cache/workbench") for m in made), made
    if cls in ("source-date-epoch", "thread-count", "current-folder-removed"):
        named = {"source-date-epoch": "SOURCE_DATE_EPOCH", "current-folder-removed": "current folder"}
        assert status == 1 and len(lines) == 1 and named.get(cls, "_THREADS") in lines[0], err
        assert not out.exists()
        return
    if cls == "address-space-limit" and status != 0:
        # what did not fit says so in one line of its own (never a loader's crash or a library's fatal line)
        said = ("address-space limit (ulimit -v)", "out of memory", "a library could not be loaded")
        assert status == 1 and len(lines) == 1 and any(w in lines[0] for w in said), (status, err)
        assert not out.exists()
        return
    if cls == "stdout-full" and command in ("lot", "trend"):  # their result is on standard output: it cannot be
        assert status == 1 and len(lines) == 1 and "standard output: No space left on device" in lines[0], err
        assert not out.exists(), "the output was written beside a result that could not be"
        return
    if cls in ("sigterm", "sigint"):
        if status == 130:
            assert lines and lines[-1].endswith("interrupted; nothing written"), err
            assert not out.exists(), "an interrupted run left its output"
        else:
            assert status == 0 and (out.exists()), err
        return
    assert status == 0, err
    assert out.exists(), err
    if cls == "umask-777":  # the mode bits, not os.access: root may read anything
        for p in [out, *out.rglob("*")] if out.is_dir() else [out]:
            need = 0o700 if p.is_dir() else 0o600
            assert p.stat().st_mode & need == need, f"{p}: {oct(p.stat().st_mode)}: its owner cannot read it"
