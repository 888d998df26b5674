"""Bad input to workbench design: one clear line naming the file and key, exit 1, nothing written."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from conftest import ROOT

from workbench.cli import main
from workbench.job import load_job

TWO_VIEWS = ROOT / "fixtures" / "two-views"


@pytest.fixture
def job_dir(tmp_path):
    d = tmp_path / "job"
    shutil.copytree(TWO_VIEWS, d)
    return d


def run(capsys, job_dir, text=None):
    job = job_dir / "job.toml"
    if text is not None:
        job.write_text(text)
    out = job_dir / "out"
    status = main(["design", str(job), "--out", str(out), "-q"])
    err = capsys.readouterr().err.strip()
    assert not out.exists(), "a failed run must write nothing"
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    return status, err


def edit(job_dir, old, new):
    text = (job_dir / "job.toml").read_text()
    assert old in text
    return text.replace(old, new, 1)


def test_unknown_key_names_key_and_file(capsys, job_dir):
    status, err = run(capsys, job_dir, edit(job_dir, "dpi = 300", "dpi = 300\ncolour = 3"))
    assert status == 1
    assert f"{job_dir / 'job.toml'}: print: unknown key 'colour'" in err


def test_unknown_key_in_a_view(capsys, job_dir):
    status, err = run(capsys, job_dir, edit(job_dir, 'name = "right"', 'name = "right"\nzoom = 2'))
    assert status == 1 and "views[1]: unknown key 'zoom'" in err


def test_missing_image(capsys, job_dir):
    (job_dir / "right.png").unlink()
    status, err = run(capsys, job_dir)
    assert status == 1 and "views[1].image: file 'right.png' not found" in err


def test_corrupt_image(capsys, job_dir):
    (job_dir / "left.png").write_bytes(b"\x89PNG\r\n\x1a\n this is not a png")
    status, err = run(capsys, job_dir)
    assert status == 1 and "views[0].image: cannot read image" in err and "left.png" in err


def test_view_that_sees_nothing(capsys, job_dir):
    # looking at the roof from below: only back faces
    text = edit(job_dir, "position = [230, 30, 140]", "position = [30, 20, -240]")
    status, err = run(capsys, job_dir, text)
    assert status == 1
    assert "views[1] ('right') sees nothing of the object to decorate: it sees no front face" in err


def test_camera_among_the_object(capsys, job_dir):
    text = edit(job_dir, "position = [-230, -30, 140]", "position = [0, 0, 20]")
    status, err = run(capsys, job_dir, text)
    assert status == 1
    assert "views[0] ('left'): the camera at [0.0, 0.0, 20.0] mm has part of the object level with or behind it" in err


def test_print_too_large_is_refused_before_allocating(capsys, job_dir):
    status, err = run(capsys, job_dir, edit(job_dir, "dpi = 300", "dpi = 200000"))
    assert status == 1
    assert "[print].dpi: a " in err and "GiB; this machine has" in err and "lower [print].dpi" in err


def test_mesh_that_is_not_a_disc(capsys, job_dir):
    import trimesh

    from workbench.mesh.io import format_obj

    ico = trimesh.creation.icosphere(subdivisions=2, radius=30)
    (job_dir / "part.obj").write_bytes(format_obj(ico.vertices, ico.faces))
    # a closed mesh is cut to what the views see by default (tests/test_closed_parts.py); asked
    # to print the whole of it, design refuses it as before
    status, err = run(capsys, job_dir, edit(job_dir, 'mesh = "part.obj"', 'mesh = "part.obj"\nsurface = "whole"'))
    assert status == 1 and "mesh is closed (no boundary)" in err


@pytest.mark.parametrize(
    ("old", "new", "fragment"),
    [
        ("fov_deg = 40", "fov_deg = 0", "views[0].fov_deg: must be a number between 0 and 180, got 0"),
        ("fov_deg = 40", 'fov_deg = "wide"', "views[0].fov_deg: must be a number, got 'wide'"),
        ("dpi = 300", "dpi = -5", "print.dpi: must be a number above 0, got -5"),
        ('mesh = "part.obj"', 'mesh = "nope.obj"', "object.mesh: file 'nope.obj' not found"),
        ("[print]", '[print]\nbackground = "red"', 'print.background: must be "#rrggbb" or [r, g, b]'),
        ('name = "right"', 'name = "left"', "views[1].name: view name 'left' is used twice"),
        ("[[views]]", "[[viewz]]", "job: unknown key 'viewz'"),
        ("fov_deg = 40", "fov_deg = 40\nfx = 100", "views[0]: give the camera as"),
        ("dpi = 300", 'dpi = 300\nscale = "huge"', "print.scale: 'huge': use isometric, area, no-shrink"),
        ("[object]", 'name = "  "\n[object]', "job.name: must name the job"),
        ("[object]", "name = 3\n[object]", "job.name: must be a string, got 3"),
    ],
)
def test_job_file_errors_name_the_key(capsys, job_dir, old, new, fragment):
    status, err = run(capsys, job_dir, edit(job_dir, old, new))
    assert status == 1
    assert fragment in err, err


def test_not_toml(capsys, job_dir):
    status, err = run(capsys, job_dir, "[object\nmesh = ")
    assert status == 1 and "not valid TOML" in err


def test_intrinsics_camera_equals_look_at_camera(job_dir):
    # the same camera given both ways gives the same print, bit for bit
    import cv2

    from workbench.design import design

    job = load_job(job_dir / "job.toml")
    cam = job.views[0].make_camera(1000, 750)
    rvec = cv2.Rodrigues(cam.R)[0].ravel()
    text = (job_dir / "job.toml").read_text()
    block = text[text.index("[[views]]") : text.index("[[views]]", text.index("[[views]]") + 1)]
    new_block = (
        '[[views]]\nname = "left"\nimage = "left.png"\n'
        + "".join(
            f"{k} = {float(v)!r}\n"
            for k, v in zip(("fx", "fy", "cx", "cy"), cam.K[[0, 1, 0, 1], [0, 1, 2, 2]], strict=True)
        )
        + f"rotation = [{', '.join(repr(float(x)) for x in rvec)}]\n"
        f"translation = [{', '.join(repr(float(x)) for x in cam.t)}]\n\n"
    )
    (job_dir / "k.toml").write_text(text.replace(block, new_block))
    a = design(load_job(job_dir / "job.toml"))
    b = design(load_job(job_dir / "k.toml"))
    np.testing.assert_allclose(b.cameras[0].R, a.cameras[0].R, atol=1e-12)
    assert (a.rgb != b.rgb).mean() < 1e-4  # Rodrigues round trip: a few pixels may round differently


def test_the_jobs_name_key_names_it_whatever_its_folder(job_dir):
    # a job.toml in a folder: named after its folder, unless it names itself
    assert load_job(job_dir / "job.toml").name == "job"
    (job_dir / "job.toml").write_text(edit(job_dir, "[object]", 'name = "cow flank"\n[object]'))
    assert load_job(job_dir / "job.toml").name == "cow flank"
