"""Issue 41: an output is a file of its own: never a link written through, never a device or a pipe renamed over."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from workbench import atomic
from workbench.cli import main
from workbench.errors import WorkbenchError


def one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


def test_an_output_beside_the_one_named_that_is_a_link_is_refused_and_its_target_kept(tmp_path, capsys, monkeypatch):
    # `ln -s job.toml b.json; workbench board charuco -o b.pdf`: the board's definition would
    # have replaced the job file through the link (the job is no input of `board`)
    monkeypatch.chdir(tmp_path)
    job = tmp_path / "job.toml"
    job.write_text("[print]\ndpi = 300\n")
    (tmp_path / "b.json").symlink_to(job)
    assert main(["board", "charuco", "-o", "b.pdf", "-q"]) == 1
    line = one_line(capsys)
    assert "b.json: is a symbolic link" in line and "job.toml" in line
    assert job.read_text() == "[print]\ndpi = 300\n" and (tmp_path / "b.json").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.json", "job.toml"]


def test_an_output_that_is_a_named_pipe_is_refused_and_stays_a_pipe(tmp_path, capsys):
    pipe = tmp_path / "out.pdf"
    os.mkfifo(pipe)
    assert main(["board", "charuco", "-o", str(pipe), "-q"]) == 1
    assert "out.pdf: is a named pipe, not a file" in one_line(capsys)
    assert stat.S_ISFIFO(os.lstat(pipe).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.pdf"]


@pytest.mark.parametrize("device", ["/dev/null", "/dev/zero"])
def test_a_device_is_no_output(device):
    # (checked without writing: were the check missing, nothing is renamed over the device here)
    if not Path(device).exists():
        pytest.skip(f"{device} is not on this machine")
    with pytest.raises(WorkbenchError, match=f"{device}: is a character device, not a file"):
        atomic.check_outputs(Path(device))


@pytest.mark.parametrize(
    "argv",
    [
        ["design", "JOB", "--out", ""],
        ["design", "JOB", "--out="],
        ["board", "charuco", "-o", ""],
    ],
    ids=["out-empty", "out-equals-empty", "o-empty"],
)
def test_an_empty_output_name_is_a_usage_error_and_writes_nothing(tmp_path, capsys, monkeypatch, argv):
    # `--out ""` read as "not given": design wrote its default design-JOB/ into the current folder
    monkeypatch.chdir(tmp_path)
    job = Path(__file__).resolve().parents[1] / "fixtures" / "default" / "job.toml"
    assert main([str(job) if a == "JOB" else a for a in argv]) == 2
    assert "an empty name" in one_line(capsys)
    assert list(tmp_path.iterdir()) == []
