"""The fixture's colour chart slot: its definition, its drawing on the fixture PDF, its render."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT

from workbench.cli import main
from workbench.printing.boards import board_to_mesh, chart_srgb, colour_chart_reference

DEFAULT = ROOT / "fixtures" / "default"


def job_copy(tmp_path, fixture_lines: str = "") -> str:
    """The default job in tmp_path with extra [fixture] lines."""
    for name in ("part.obj", "logo.png", "front.png"):
        (tmp_path / name).write_bytes((DEFAULT / name).read_bytes())
    job = tmp_path / "job.toml"
    job.write_text((DEFAULT / "job.toml").read_text() + (f"\n[fixture]\n{fixture_lines}\n" if fixture_lines else ""))
    return str(job)


def test_fixture_declares_the_chart_outside_the_footprint(tmp_path):
    import colour

    out = tmp_path / "f.pdf"
    assert main(["board", "fixture", str(DEFAULT / "job.toml"), "-o", str(out), "-q"]) == 0
    info = json.loads(out.with_suffix(".json").read_text())
    chart = info["colour_chart"]
    assert chart["kind"] == "ColorChecker Classic 24" and len(chart["patches"]) == 24
    names, lab = colour_chart_reference()
    assert [p["name"] for p in chart["patches"]] == names
    assert names[0] == "dark skin" and names[18].startswith("white 9.5")
    # colour-science's X-Rite data (xyY, D50) as CIELAB D50
    cc = colour.CCS_COLOURCHECKERS["ColorChecker24 - After November 2014"]
    want = colour.XYZ_to_Lab(colour.xyY_to_XYZ(np.array(cc.data["dark skin"])), cc.illuminant)
    np.testing.assert_allclose(chart["patches"][0]["lab_d50"], want, atol=1e-4)
    np.testing.assert_allclose([p["lab_d50"] for p in chart["patches"]], lab, atol=1e-4)
    corners = np.array([p["corners_board_mm"] for p in chart["patches"]])
    mesh = np.array([p["corners_mesh_mm"] for p in chart["patches"]])
    np.testing.assert_allclose(mesh.reshape(-1, 3), board_to_mesh(corners.reshape(-1, 2), info["origin_mm"]))
    # square patches of 0.8 x the pitch, clockwise from the top-left
    side = corners[:, 1, 0] - corners[:, 0, 0]
    np.testing.assert_allclose(side, chart["patch_mm"]) and np.testing.assert_allclose(
        corners[:, 2, 1] - corners[:, 1, 1], chart["patch_mm"]
    )
    # beyond the board's bottom edge: clear of every marker and of the part's footprint
    bh = info["squares"][1] * info["square_mm"]
    fp = np.asarray(info["footprint_board_mm"])
    assert corners[..., 1].min() > bh + 10 and corners[..., 1].min() > fp[:, 1].max()

    # drawn on the fixture PDF: the slot's frame where the definition puts it (page mm, y down)
    from test_board import PX_PER_MM, rasterise

    ink = 255 - rasterise(out).astype(int)
    x0, y0, x1, y1 = np.asarray(chart["frame_board_mm"]) + np.tile(info["page_origin_mm"], 2)
    rows = slice(int((y0 + 5) * PX_PER_MM), int((y1 - 5) * PX_PER_MM))
    for x in (x0, x1):
        col = int(round(x * PX_PER_MM))
        assert ink[rows, col - 3 : col + 4].max(axis=1).min() > 100  # the frame's side, all along
    # and each patch outlined: ink on the patch's left side, none at its centre
    for p in chart["patches"][::5]:
        c = np.asarray(p["corners_board_mm"]) + info["page_origin_mm"]
        i = int((c[0, 1] + c[2, 1]) / 2 * PX_PER_MM)
        j = int(c[0, 0] * PX_PER_MM)
        assert ink[i - 2 : i + 3, j - 3 : j + 4].max() > 100
        jc = int((c[0, 0] + c[1, 0]) / 2 * PX_PER_MM)
        assert ink[i - 100 : i - 60, jc - 10 : jc + 10].max() == 0  # above the name


def test_the_render_shows_the_chart_in_its_reference_colours(tmp_path):
    from workbench.camera import Camera
    from workbench.mesh.io import read_mesh
    from workbench.printing.boards import colour_chart_from_job, definition, fixture_from_job
    from workbench.render.imperfections import Imperfections
    from workbench.render.photo import board_scene, render_photo

    V, F = read_mesh(DEFAULT / "part.obj")
    spec, origin, _ = fixture_from_job(None, V, F, "job: fixture")
    d = definition(spec, "fixture", origin_mm=origin)
    d["colour_chart"] = colour_chart_from_job(None, spec, origin)
    centre = np.array([p["corners_mesh_mm"] for p in d["colour_chart"]["patches"]]).mean(axis=(0, 1))
    cam = Camera.look_at(centre + [0, -60, 300], centre, [0, 1, 0], 40, 800, 600)
    photo = render_photo(board_scene(d, origin), cam, Imperfections())
    want = chart_srgb([p["lab_d50"] for p in d["colour_chart"]["patches"]])
    for p, rgb in zip(d["colour_chart"]["patches"], want, strict=True):
        xy, _ = cam.project(np.asarray(p["corners_mesh_mm"]).mean(axis=0, keepdims=True))
        j, i = np.round(xy[0]).astype(int)
        np.testing.assert_array_equal(photo[i - 2 : i + 3, j - 2 : j + 3].reshape(-1, 3), np.tile(rgb, (25, 1)))
    # the frame between patches is the chart's black, not the plate's white
    c = np.asarray(d["colour_chart"]["patches"][0]["corners_mesh_mm"])
    xy, _ = cam.project(
        np.array([c[1] + [0.4 * (d["colour_chart"]["pitch_mm"] - d["colour_chart"]["patch_mm"]), -6, 0]])
    )
    j, i = np.round(xy[0]).astype(int)
    assert photo[i, j].max() < 70


def test_no_chart_and_bad_pitch(tmp_path, capsys):
    out = tmp_path / "f.pdf"
    assert main(["board", "fixture", job_copy(tmp_path, 'colour_chart = "none"'), "-o", str(out), "-q"]) == 0
    assert "colour_chart" not in json.loads(out.with_suffix(".json").read_text())
    bad = tmp_path / "bad"
    bad.mkdir()
    assert main(["board", "fixture", job_copy(bad, "colour_chart_pitch_mm = 2"), "-o", str(bad / "f.pdf"), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert "fixture.colour_chart_pitch_mm" in err and len(err.splitlines()) == 1 and not (bad / "f.pdf").exists()


@pytest.mark.parametrize("kind", ["ColorChecker Passport"])
def test_unknown_chart_kind(tmp_path, capsys, kind):
    assert (
        main(["board", "fixture", job_copy(tmp_path, f'colour_chart = "{kind}"'), "-o", str(tmp_path / "f.pdf")]) == 1
    )
    assert "colour_chart" in capsys.readouterr().err
