"""workbench design: closed loop against an independent renderer, physical scale, files."""

from __future__ import annotations

import dataclasses
import json

import cv2
import numpy as np
import pytest
from closed_loop import view_check
from conftest import ROOT

from workbench.cli import main
from workbench.design import design
from workbench.export import png_dpi, texture_uv
from workbench.job import load_job
from workbench.mesh.io import read_mesh

FIXTURES = ROOT / "fixtures"


def designed(name: str, dpi: float = 600.0):
    job = load_job(FIXTURES / name / "job.toml")
    job = dataclasses.replace(job, print=dataclasses.replace(job.print, dpi=dpi))
    r = design(job)
    rows, cols = r.grid.shape
    vt = texture_uv(r.flat.uv, cols / r.grid.px_per_mm, rows / r.grid.px_per_mm, r.flat.height_mm)
    return job, r, vt


@pytest.mark.parametrize(
    ("name", "min_tiles"),
    [("half-cylinder", 15), ("deformed-grid", 100), ("two-views", 15), ("default", 8)],
)
def test_every_view_sees_its_image(name, min_tiles):
    job, r, vt = designed(name)
    for v in range(len(job.views)):
        mis, coverage = view_check(job, r, vt, v)
        assert len(mis) >= min_tiles, (job.views[v].name, len(mis))
        assert np.median(mis) <= 0.1, (job.views[v].name, np.median(mis))
        assert np.percentile(mis, 95) <= 0.3, (job.views[v].name, np.percentile(mis, 95))
        assert coverage >= 0.99, (job.views[v].name, coverage)


def test_the_measure_sees_an_injected_shift():
    # the closed loop can fail: move the texture by 8 print pixels and it reports it,
    # scaled to view pixels (about 0.2 view px per print px at 600 dpi here)
    job, r, vt = designed("half-cylinder")
    rows, cols = r.grid.shape
    mis, _ = view_check(job, r, vt, 0, shift_vt=(8.0 / cols, 0.0))
    scale = r.view_px_per_print_px[0]
    # `scale` is the view's median over all its faces, not at these tiles: 10 %
    assert np.median(mis) == pytest.approx(8.0 * scale, rel=0.1)
    assert np.median(mis) > 1.0


def test_developable_job_prints_at_true_size(tmp_path):
    out = tmp_path / "d"
    assert main(["design", str(FIXTURES / "half-cylinder" / "job.toml"), "--out", str(out), "-q"]) == 0
    info = json.loads((out / "design.json").read_text())
    # the sheet: 2 x 40 mm flat + a half circle of radius 20 mm, by 80 mm
    assert info["print"]["width_mm"] == pytest.approx(80 + 20 * np.pi, abs=0.01)
    assert info["print"]["height_mm"] == pytest.approx(80.0, abs=0.01)
    data = (out / "print.png").read_bytes()
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    dpi = png_dpi(data)
    assert dpi == pytest.approx(300, abs=0.01)
    px_per_mm = 300 / 25.4
    # whole pixels covering the rectangle, less than one pixel beyond it
    assert img.shape[1] == info["print"]["width_px"] == int(np.ceil(info["print"]["width_mm"] * px_per_mm))
    assert img.shape[0] == info["print"]["height_px"] == int(np.ceil(info["print"]["height_mm"] * px_per_mm))
    assert 0 <= img.shape[1] / px_per_mm - info["print"]["width_mm"] < 1 / px_per_mm


def test_outputs_and_conventions(tmp_path):
    out = tmp_path / "d"
    assert main(["design", str(FIXTURES / "two-views" / "job.toml"), "--out", str(out), "-q"]) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {
        "print.png",
        "owner.png",
        "view-left.png",
        "view-right.png",
        "fixture.json",
        "decorated.obj",
        "decorated.mtl",
        "decorated.glb",
        "flat.obj",
        "design.json",
        "views.png",
        "stretch.png",
        ".workbench-files",  # what this run wrote: the next one removes what it does not write again
    }
    V, F = read_mesh(FIXTURES / "two-views" / "part.obj")
    V2, F2 = read_mesh(out / "decorated.obj")
    np.testing.assert_allclose(V2, V, atol=1e-9)  # input vertex order kept
    np.testing.assert_array_equal(F2, F)
    info = json.loads((out / "design.json").read_text())
    assert [v["name"] for v in info["views"]] == ["left", "right"]
    shares = [v["print_share"] for v in info["views"]]
    assert all(s > 0.3 for s in shares) and sum(shares) + info["print"]["background_share"] == pytest.approx(1.0)
    assert info["job"]["sha256"] and info["material"]["max_stretch"] == 1.005
    import trimesh

    glb = trimesh.load(out / "decorated.glb", force="mesh", process=False)
    assert len(glb.vertices) == len(V) and glb.visual.uv.shape == (len(V), 2)


def test_same_job_same_bytes(tmp_path):
    job = FIXTURES / "default" / "job.toml"
    for d in ("a", "b"):
        assert main(["design", str(job), "--out", str(tmp_path / d), "-q"]) == 0
    for name in ("print.png", "decorated.obj", "decorated.glb", "flat.obj", "views.png", "stretch.png"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    a = json.loads((tmp_path / "a" / "design.json").read_text())
    b = json.loads((tmp_path / "b" / "design.json").read_text())
    a.pop("timings_s"), b.pop("timings_s")
    assert a == b


@pytest.mark.parametrize("name", ["default", "two-views"])
def test_closed_loop_holds_through_the_common_subdivision(monkeypatch, name):
    # Forced Ptolemy flips: the print is synthesised through the common subdivision of
    # input and flat triangulation, decorated.obj carries it; every view must still
    # see its image to the same figures as without flips.
    import functools

    from workbench.conformal.flatten import FlattenOptions
    from workbench.conformal.layout import signed_areas

    monkeypatch.setattr("workbench.design.FlattenOptions", functools.partial(FlattenOptions, flips=True))
    job, r, vt = designed(name)
    V_in, _ = read_mesh(job.object.mesh, job.object.units)
    assert r.flat.intrinsic_flips > 0 and len(r.V) > len(V_in)
    np.testing.assert_array_equal(r.V[: len(V_in)], V_in)
    assert (signed_areas(vt, r.F) > 0).all()  # no fold in the texture coordinates either
    for v in range(len(job.views)):
        mis, coverage = view_check(job, r, vt, v)
        assert np.median(mis) <= 0.1, (job.views[v].name, np.median(mis))
        assert np.percentile(mis, 95) <= 0.3, (job.views[v].name, np.percentile(mis, 95))
        assert coverage >= 0.99, (job.views[v].name, coverage)


def test_job_corners_auto_is_never_worse_than_the_default():
    # corners = "auto": the search includes the automatic corners, so the chosen map has
    # at most their area distortion
    from workbench.conformal.flatten import area_distortion

    job = load_job(FIXTURES / "two-views" / "job.toml")
    plain = design(job)
    auto = design(dataclasses.replace(job, object=dataclasses.replace(job.object, corners="auto")))
    assert auto.flat.corner_rule == "auto" and auto.flat.flipped_faces == 0
    assert area_distortion(auto.flat) <= area_distortion(plain.flat) + 1e-12
