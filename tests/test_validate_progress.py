"""validate's progress lines: one per photo and stage on a terminal, none with -q or into a pipe."""

from __future__ import annotations

import os
import pty
import sys
import threading

import pytest
from conftest import ROOT

from workbench.cli import main
from workbench.validate.photo import STAGES


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    d = tmp_path_factory.mktemp("progress")
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d / "design"), "-q"]) == 0
    p = d / "small.jpg"
    args = ["render", str(d / "design"), "--orbit=10,55,330", "--size", "640x480", "-o", str(p), "-q"]
    assert main(args) == 0
    return d / "design", p


def run_on_a_terminal(args, monkeypatch) -> str:
    """validate with stderr on a pseudo-terminal; what the terminal received."""
    master, slave = pty.openpty()
    received = []
    reader = threading.Thread(target=lambda: received.extend(iter(lambda: _read(master), b"")), daemon=True)
    reader.start()
    with os.fdopen(slave, "w") as tty:
        monkeypatch.setattr(sys, "stderr", tty)
        assert main(args) == 0
        tty.flush()
    reader.join(timeout=10)
    os.close(master)
    return b"".join(received).decode(errors="replace").replace("\r\n", "\n")


def _read(fd: int) -> bytes:
    try:
        return os.read(fd, 65536)
    except OSError:  # the terminal's other end closed: all is read
        return b""


def validate_args(photo, out, *extra):
    design, p = photo
    return ["validate", str(design), str(p), "--camera", str(p.with_suffix(".json")), "--out", str(out), "--jobs", "1",
            *extra]  # fmt: skip


def test_a_terminal_gets_a_line_per_stage(photo, tmp_path, monkeypatch):
    seen = run_on_a_terminal(validate_args(photo, tmp_path / "a"), monkeypatch)
    for k, stage in enumerate(STAGES):
        assert f"small.jpg: {stage} done ({k + 1}/{len(STAGES)}," in seen, seen
    assert "the part: its 1 photo(s) together" in seen and "the QA report: " in seen


def test_quiet_or_a_pipe_gets_no_progress(photo, tmp_path, monkeypatch, capsys):
    assert run_on_a_terminal(validate_args(photo, tmp_path / "q", "-q"), monkeypatch) == ""
    monkeypatch.undo()
    assert main(validate_args(photo, tmp_path / "p")) == 0
    err = capsys.readouterr().err
    assert "small.jpg: " in err and " done (" not in err  # the result's lines, not the progress
