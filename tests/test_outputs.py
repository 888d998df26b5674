"""Ordinary mistakes with outputs and the environment: one line, exit 1, nothing written, no traceback."""

from __future__ import annotations

import pytest
from conftest import ROOT

from workbench.atomic import write_files
from workbench.cli import main
from workbench.errors import WorkbenchError

DEFAULT = ROOT / "fixtures" / "default"


def test_an_output_path_that_is_a_directory_is_one_line(tmp_path, capsys):
    d = tmp_path / "existing"
    d.mkdir()
    (d / "keep.txt").write_text("mine")
    assert main(["board", "fixture", str(DEFAULT / "job.toml"), "-o", str(d)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{d}: is a directory" in err[0]
    assert (d / "keep.txt").read_text() == "mine"


def test_a_set_of_files_with_a_directory_among_them_writes_none(tmp_path):
    # found before anything is written: the first file does not appear either
    d = tmp_path / "existing"
    d.mkdir()
    with pytest.raises(WorkbenchError, match="is a directory"):
        write_files({tmp_path / "a.txt": b"a", d: b"b"})
    assert not (tmp_path / "a.txt").exists()


def test_a_malformed_source_date_epoch_is_one_line(monkeypatch, capsys, tmp_path):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "abc")
    out = tmp_path / "f.pdf"
    assert main(["board", "fixture", str(DEFAULT / "job.toml"), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "SOURCE_DATE_EPOCH='abc'" in err[0]
    assert not out.exists()
