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


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["board", "charuco", "--square-mm", "0"], "--square-mm 0: must be positive, at most 1000 mm"),
        (["pdf", "{design}", "--paper", "1000000000x1000000000"], "1000000000: must be positive, at most 5000 mm"),
        (["render", "{design}", "--orbit", "10,55,330", "--light", "0,0,0"], "a direction cannot be zero"),
        (["render", "{design}", "--orbit", "10,55,330", "-o", "{tmp}/p.bmp"], "photos are written as .png or .jpg"),
        (["render", "{design}"], "workbench render: error: one of the arguments"),
    ],
    ids=["board-square-0", "pdf-paper-huge", "render-light-0", "render-bmp", "usage-names-the-command"],
)
def test_absurd_options_are_usage_errors(tmp_path, capsys, argv, fragment):
    # a design directory is needed by pdf and render; one small design serves them all
    design_dir = tmp_path / "design"
    if "{design}" in argv:
        job = tmp_path / "job.toml"
        for name in ("part.obj", "logo.png", "front.png"):
            (tmp_path / name).write_bytes((DEFAULT / name).read_bytes())
        job.write_text((DEFAULT / "job.toml").read_text().replace("dpi = 300", "dpi = 50"))
        assert main(["design", str(job), "--out", str(design_dir), "-q"]) == 0
    args = [a.replace("{design}", str(design_dir)).replace("{tmp}", str(tmp_path)) for a in argv]
    out = tmp_path / "out.pdf"
    if "-o" not in args:
        args += ["-o", str(out)]
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
