"""Free outline: the conformal map with boundary scale factors 0 (the film keeps the rim's lengths)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import ROOT, cylinder_patch, mercator_patch
from test_conformal_maps import check_subdivision
from test_design import FIXTURES, view_check

from workbench.cli import main
from workbench.conformal.flatten import FlattenOptions, ScaleMode, flatten
from workbench.conformal.layout import signed_areas
from workbench.design import design
from workbench.export import texture_uv
from workbench.job import load_job
from workbench.mesh.io import read_mesh
from workbench.mesh.topology import boundary_loops

SHARED = ROOT.parent / "shared" / "meshes"


def rigid_error(uv, exact):
    zu, ze = uv[:, 0] + 1j * uv[:, 1], exact[:, 0] + 1j * exact[:, 1]
    rot = np.exp(1j * np.angle(np.sum((ze - ze.mean()) * np.conj(zu - zu.mean()))))
    return float(np.abs(rot * (zu - zu.mean()) - (ze - ze.mean())).max())


@pytest.mark.parametrize("scale", ["isometric", "rim"])
def test_developable_part_prints_its_true_unrolled_outline(scale):
    # the half cylinder of the paper's experiment: rigid fit only, no scale fit
    V, F, exact = cylinder_patch(60)
    r = flatten(V, F, FlattenOptions(outline="free", scale=ScaleMode.parse(scale)))
    assert rigid_error(r.uv, exact) <= 0.01
    assert r.flipped_faces == 0 and (signed_areas(r.uv, r.F) > 0).all()
    assert r.width_mm * r.height_mm == pytest.approx(80 * 60, rel=1e-3)  # the outline is the rectangle itself


def test_curved_part_keeps_its_rim_length():
    V, F, _ = mercator_patch(60)
    r = flatten(V, F, FlattenOptions(outline="free", scale=ScaleMode("rim")))
    loop = boundary_loops(F)[0]
    rim_3d = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1).sum()
    rim_flat = np.linalg.norm(r.uv[np.roll(loop, -1)] - r.uv[loop], axis=1).sum()
    assert rim_flat == pytest.approx(rim_3d, rel=1e-3)
    # and each boundary edge keeps its own length (boundary scale factors 0)
    e3 = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1)
    ef = np.linalg.norm(r.uv[np.roll(loop, -1)] - r.uv[loop], axis=1)
    np.testing.assert_allclose(ef, e3, rtol=1e-6)
    # a sphere cap is not developable: the free outline is conformal, its interior angles 2π
    assert r.newton.residual_rad <= 1e-9


@pytest.mark.skipif(not SHARED.is_dir(), reason="the shared meshes are not beside this checkout")
def test_face_mask_free_outline_has_no_fold():
    # the scanned face (24 x 34 x 26 cm) flattens onto its free outline without a fold.
    # It is nearly closed (a 68 cm rim around 1,850 cm² of surface, five times the area
    # of a disc with that rim), so one film squeezes its middle: at isometric scale the
    # outline has 9.5 times the surface's area. That needs several films (issue 12).
    V, F = read_mesh(SHARED / "face.obj", "cm")
    r = flatten(V, F, FlattenOptions(outline="free"))
    check_subdivision(r, V, F)


def test_design_with_a_free_outline_keeps_every_view_exact():
    job = load_job(FIXTURES / "default" / "job.toml")
    job = dataclasses.replace(job, print=dataclasses.replace(job.print, outline="free", dpi=600.0))
    r = design(job)
    assert r.flat.corner_rule == "free outline" and len(r.flat.corners) == 0
    rows, cols = r.grid.shape
    vt = texture_uv(r.flat.uv, cols / r.grid.px_per_mm, rows / r.grid.px_per_mm, r.flat.height_mm)
    for v in range(len(job.views)):
        mis, coverage = view_check(job, r, vt, v)
        assert np.median(mis) <= 0.1 and np.percentile(mis, 95) <= 0.3 and coverage >= 0.99


def test_corners_with_a_free_outline_are_a_usage_error(capsys, tmp_path):
    part = FIXTURES / "default" / "part.obj"
    assert main(["flatten", str(part), "--outline", "free", "--corners", "0,1,2,3", "--out", str(tmp_path / "o")]) == 2
    assert "free outline has no corners" in capsys.readouterr().err


def face_mask_job(tmp_path, outline="rectangle", views=("front",), dpi=20):
    """The bundled face mask job with some of its views, another outline and dpi, in tmp_path."""
    import shutil

    src = FIXTURES / "face-mask"
    for name in ("part.obj", *(f"{v}.png" for v in views)):
        shutil.copy(src / name, tmp_path / name)
    text = (src / "job.toml").read_text()
    head, *tables = text.split("[[views]]")
    head = head.replace('outline = "free"', f'outline = "{outline}"').replace("dpi = 100", f"dpi = {dpi}")
    kept = [t for t in tables if any(f'name = "{v}"' in t for v in views)]
    job = tmp_path / "job.toml"
    job.write_text("[[views]]".join([head, *kept]))
    return job


def test_a_print_that_does_not_fit_warns_and_strict_refuses(tmp_path, capsys):
    # the scanned face with its front view on a rectangle: a print ten times its
    # developed area, almost all background, and a film stretch far outside [0.8, 1.3];
    # and the front view's largest region leaves a third of what it sees (issue 36)
    import json

    job = face_mask_job(tmp_path)
    assert main(["design", str(job), "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    info = json.loads((tmp_path / "o" / "design.json").read_text())
    assert len(info["warnings"]) == 4
    for fragment in (
        "the film stretch leaves [0.8, 1.3]",
        "background is 99",
        "times the part's developed area",
        "view 'front' (views[0]) keeps its largest connected region and drops 33.7 %",
    ):
        assert sum(fragment in w for w in info["warnings"]) == 1, fragment
        assert sum(line.startswith("warning: ") and fragment in line for line in err.splitlines()) == 1
    # --strict: the same warnings are one error line, exit 1, nothing written
    out = tmp_path / "strict"
    assert main(["design", str(job), "--out", str(out), "--strict", "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not fit the part (--strict)" in err[0]
    assert not out.exists()


def test_face_mask_fixture_free_outline_fits_where_the_rectangle_does_not(tmp_path):
    # the bundled face mask (three views): its free outline holds the surface's area
    # (the default scale of a free outline), 0.5 to 1.5 times it, without a background
    # warning; print.png is transparent outside the outline, which holds the film's
    # area to 1 %; the same job on a rectangle is 10 times the developed area
    import json

    import cv2

    job = face_mask_job(tmp_path, "free", ("front", "left", "right"), dpi=40)
    assert main(["design", str(job), "--out", str(tmp_path / "free"), "-q"]) == 0
    info = json.loads((tmp_path / "free" / "design.json").read_text())
    surface = info["mesh"]["surface_area_mm2"]
    assert 0.5 <= info["print"]["film_area_mm2"] / surface <= 1.5
    assert info["scale_mode"] == "area" and info["print"]["outline"] == "free"
    assert not any("background" in w for w in info["warnings"])
    rgba = cv2.imread(str(tmp_path / "free" / "print.png"), cv2.IMREAD_UNCHANGED)
    assert rgba.shape[2] == 4 and set(np.unique(rgba[:, :, 3])) == {0, 255}
    film_mm2 = (rgba[:, :, 3] == 255).sum() * (25.4 / 40) ** 2
    assert film_mm2 == pytest.approx(info["print"]["film_area_mm2"], rel=0.01)
    (tmp_path / "r").mkdir()
    rect = face_mask_job(tmp_path / "r", "rectangle", ("front",), 40)
    assert main(["design", str(rect), "--out", str(tmp_path / "rect"), "-q"]) == 0
    info = json.loads((tmp_path / "rect" / "design.json").read_text())
    assert info["print"]["film_area_mm2"] / surface > 10
    assert cv2.imread(str(tmp_path / "rect" / "print.png"), cv2.IMREAD_UNCHANGED).shape[2] == 3


def test_bundled_jobs_fit_their_parts():
    # no fit warning on the default lid (stretch 0.97 to 1.09 of a 1.10 film, no background)
    job = load_job(FIXTURES / "default" / "job.toml")
    from workbench.design import fit_warnings

    assert fit_warnings(design(job), job.object.material.max_stretch) == []


def test_cut_line_follows_the_free_outline_in_the_pdf(tmp_path):
    # the cut line is the film's outline in the spot colour CutContour, at true scale:
    # measured in a 600 dpi raster of the PDF (the difference with --no-cut), every
    # stroked pixel lies within 0.1 mm of the outline flat.obj gives, and the whole
    # outline is stroked
    import json

    import pypdfium2 as pdfium

    from workbench.mesh.topology import boundary_loops
    from workbench.printing.pdf import layout_sheet

    d = tmp_path / "free"
    jt = tmp_path / "job.toml"
    text = (FIXTURES / "default" / "job.toml").read_text()
    text = text.replace('scale = "isometric"', 'scale = "isometric"\noutline = "free"')
    text = text.replace("dpi = 300", "dpi = 100")
    for name in ("part.obj", "logo.png", "front.png"):
        (tmp_path / name).write_bytes((FIXTURES / "default" / name).read_bytes())
    jt.write_text(text)
    assert main(["design", str(jt), "--out", str(d), "-q"]) == 0
    info = json.loads((d / "design.json").read_text())
    info_w, info_h = info["print"]["width_mm"], info["print"]["height_mm"]
    pages = {}
    for flag in ([], ["--no-cut"]):
        pdf = tmp_path / f"p{len(flag)}.pdf"
        assert main(["pdf", str(d), "-o", str(pdf), "--paper", "A4", "-q", *flag]) == 0
        pages[len(flag)] = np.asarray(pdfium.PdfDocument(str(pdf))[0].render(scale=600 / 72).to_pil(), dtype=int)
        if not flag:
            assert b"/CutContour" in pdf.read_bytes()
    changed = np.argwhere(np.abs(pages[0] - pages[1]).sum(axis=2) > 60)
    px_per_mm = 600 / 25.4
    sheet = layout_sheet(info_w, info_h, 3.0, 10.0, "A4")
    x0, y0 = sheet.trim[0], sheet.trim[1]
    V, F = read_mesh(d / "flat.obj")
    P = V[boundary_loops(F)[0], :2]
    # outline in raster mm: x from the page's left, y down from its top
    Q = np.stack([x0 + P[:, 0], sheet.page_h - (y0 + P[:, 1])], axis=1)
    pix = (changed[:, ::-1] + 0.5) / px_per_mm
    A, B = Q, np.roll(Q, -1, axis=0)
    AB = B - A
    t = np.clip(((pix[:, None, :] - A[None]) * AB[None]).sum(2) / (AB * AB).sum(1)[None], 0, 1)
    d_seg = np.linalg.norm(pix[:, None, :] - (A[None] + t[..., None] * AB[None]), axis=2).min(axis=1)
    assert len(pix) > 1000 and d_seg.max() <= 0.1
    # every outline vertex is stroked
    near = np.array([np.linalg.norm(pix - q, axis=1).min() for q in Q])
    assert near.max() <= 0.1


def test_bleed_follows_a_free_outline_and_the_cut_line_has_its_own_layer():
    # an elliptical film (60 x 40 mm) of one ink colour at 300 dpi: in a 600 dpi raster
    # of the PDF, the ink covers the ellipse grown by the 3 mm bleed, to 0.15 mm, and
    # nothing beyond; the cut line is on an optional content group named CutContour
    import io

    import pypdf
    import pypdfium2 as pdfium

    from workbench.printing.pdf import layout_sheet, print_pdf

    dpi, w_mm, h_mm, bleed = 300.0, 60.0, 40.0, 3.0
    rows, cols = round(h_mm * dpi / 25.4), round(w_mm * dpi / 25.4)
    w_mm, h_mm = cols * 25.4 / dpi, rows * 25.4 / dpi
    yy, xx = (np.mgrid[:rows, :cols] + 0.5) * 25.4 / dpi
    a, b = w_mm / 2, h_mm / 2
    film = ((xx - a) / a) ** 2 + ((yy - b) / b) ** 2 <= 1
    rgb = np.zeros((rows, cols, 3), np.uint8)
    rgb[:] = (20, 60, 200)
    rgb[~film] = 255  # what lies outside the outline must not show
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    outline = np.stack([a + a * np.cos(t), b + b * np.sin(t)], axis=1)
    pdf, sheet = print_pdf(rgb, dpi, w_mm, h_mm, "ellipse", "0" * 64, "A4", bleed, outline_mm=outline, film=film)
    bare, _ = print_pdf(rgb, dpi, w_mm, h_mm, "ellipse", "0" * 64, "A4", bleed, outline_mm=outline, film=film, cut=0)
    px_per_mm = 600 / 25.4
    img = np.asarray(pdfium.PdfDocument(bare)[0].render(scale=600 / 72).to_pil(), dtype=int)
    blue = (img[:, :, 2] > 150) & (img[:, :, 0] < 120)
    sheet = layout_sheet(w_mm, h_mm, bleed, 10.0, "A4")
    cx = sheet.trim[0] + a
    cy = sheet.page_h - (sheet.trim[1] + b)
    # the texture's neighbourhood only (the marks are black, not blue)
    i0, j0 = int((cy - b - 8) * px_per_mm), int((cx - a - 8) * px_per_mm)
    i1, j1 = int((cy + b + 8) * px_per_mm), int((cx + a + 8) * px_per_mm)
    assert blue.sum() == blue[i0:i1, j0:j1].sum()
    blue = blue[i0:i1:2, j0:j1:2]  # every other pixel is plenty
    yy, xx = (np.mgrid[i0:i1:2, j0:j1:2] + 0.5) / px_per_mm
    # signed distance beyond the ellipse: to a dense polygon of it, negative inside
    from scipy.spatial import cKDTree

    s = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    dist, _ = cKDTree(np.stack([cx + a * np.cos(s), cy + b * np.sin(s)], axis=1)).query(
        np.stack([xx.ravel(), yy.ravel()], axis=1), distance_upper_bound=8.0
    )
    inside = ((xx - cx) / a) ** 2 + ((yy - cy) / b) ** 2 <= 1
    beyond = np.where(inside, -1.0, 1.0) * np.minimum(dist, 8.0).reshape(xx.shape)
    beyond[inside & (dist.reshape(xx.shape) >= 8.0)] = -8.0
    assert blue[np.abs(beyond - 1.5) < 1.4].mean() > 0.999  # film and bleed: inked
    assert (beyond[blue] <= bleed + 0.15).all()  # nothing beyond the bleed
    assert blue[(beyond > bleed + 0.15) & (beyond < bleed + 3)].sum() == 0
    reader = pypdf.PdfReader(io.BytesIO(pdf))
    assert reader.pdf_header == "%PDF-1.6"  # PDF/X-4
    ocgs = [o.get_object()["/Name"] for o in reader.trailer["/Root"]["/OCProperties"]["/OCGs"]]
    assert ocgs == ["CutContour"]
    page = reader.pages[0]
    layer = page["/Resources"]["/Properties"]
    name = next(k for k, v in layer.items() if v.get_object()["/Name"] == "CutContour")
    content = page.get_contents().get_data()
    start = content.index(f"{name} BDC".encode())
    assert b"/CutContour CS" in content[start : content.index(b"EMC", start)]
    assert "/OCProperties" not in pypdf.PdfReader(io.BytesIO(bare)).trailer["/Root"]


def default_design_with_free_outline(tmp_path, dpi: int):
    """The default job with outline = "free" at ``dpi``, designed into tmp_path/d."""
    job = tmp_path / "job.toml"
    for name in ("part.obj", "logo.png", "front.png"):
        (tmp_path / name).write_bytes((FIXTURES / "default" / name).read_bytes())
    text = (FIXTURES / "default" / "job.toml").read_text().replace('scale = "isometric"', 'outline = "free"')
    job.write_text(text.replace("dpi = 300", f"dpi = {dpi}"))
    d = tmp_path / "d"
    assert main(["design", str(job), "--out", str(d), "-q"]) == 0
    return d


def test_render_and_validate_work_unchanged_on_a_free_outline(tmp_path):
    # the default job on a free outline (RGBA print.png): a perfect photo passes at
    # p95 below 0.05 mm, a film moved 0.8 mm in x is measured to 0.03 mm and fails
    import json

    d = default_design_with_free_outline(tmp_path, 200)
    photos = []
    for k, offset in enumerate(([], ["--film-offset-mm", "0.8,0"])):
        photos.append(tmp_path / f"p{k}.jpg")
        args = ["render", str(d), "--orbit", "10,55,330", "--size", "2000x1500", "-o", str(photos[-1]), "-q"]
        assert main(args + offset) == 0
    args = ["validate", str(d), *map(str, photos), "--camera", str(tmp_path / "p0.json"), "--out", str(tmp_path / "v")]
    assert main([*args, "-q"]) == 0
    perfect, moved = json.loads((tmp_path / "v" / "validation.json").read_text())["photos"]
    assert perfect["verdict"] == "PASS" and perfect["misregistration_mm"]["p95"] < 0.05
    assert moved["verdict"] == "FAIL" and abs(moved["film_offset_mm"][0] - 0.8) < 0.03
    assert abs(moved["film_offset_mm"][1]) < 0.03


def helical_ramp(turns: float, nr: int = 12, nphi: int = 220) -> tuple[np.ndarray, np.ndarray]:
    """A ramp r in [40, 80] mm winding ``turns`` times, rising 10 mm per turn: nearly flat,
    so its free outline is nearly the annular sector of ``turns`` full turns."""
    r = np.linspace(40, 80, nr)
    phi = np.linspace(0, 2 * np.pi * turns, nphi)
    R, PHI = np.meshgrid(r, phi)
    V = np.stack([(R * np.cos(PHI)).ravel(), (R * np.sin(PHI)).ravel(), (10 / (2 * np.pi) * PHI).ravel()], axis=1)
    idx = np.arange(nr * nphi).reshape(nphi, nr)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return V, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_a_free_outline_that_overlaps_itself_is_refused_naming_where(tmp_path, capsys):
    # 1.2 turns: the outline crosses itself where the ramp passes over its start; the
    # refusal names two rim vertices a turn apart (same angle, heights 10 mm apart).
    # 0.8 turns: no overlap, and the outline is simple.
    from workbench.conformal.layout import polygon_self_intersections
    from workbench.mesh.io import format_obj

    V, F = helical_ramp(0.8)
    r = flatten(V, F, FlattenOptions(outline="free"))
    loop = boundary_loops(r.F)[0]
    assert len(polygon_self_intersections(r.uv[loop])) == 0
    V, F = helical_ramp(1.2)
    path = tmp_path / "ramp.obj"
    path.write_bytes(format_obj(V, F))
    out = tmp_path / "flat"
    assert main(["flatten", str(path), "--outline", "free", "--out", str(out), "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ramp.obj" in err[0] and "the free outline overlaps itself" in err[0], err
    import re

    i, j = (int(v) for v in re.findall(r"rim at vertex (\d+)", err[0]))
    assert abs(abs(V[i, 2] - V[j, 2]) - 10.0) < 1.0
    assert np.linalg.norm(V[i, :2] - V[j, :2]) < 10.0
    assert not out.exists()


def test_polygon_self_intersections_finds_every_crossing():
    from workbench.conformal.layout import polygon_self_intersections

    t = np.linspace(0, 2 * np.pi, 5000, endpoint=False)
    assert len(polygon_self_intersections(np.stack([np.cos(t), np.sin(t)], 1))) == 0
    # a figure eight crosses itself once, at the origin: two edges (or four, at a vertex)
    eight = np.stack([np.sin(t), np.sin(t) * np.cos(t)], 1)
    pairs = polygon_self_intersections(eight + [1e-7, 0])
    assert 1 <= len(pairs) <= 4
    assert np.abs(eight[pairs.ravel()]).max() < 0.01
    bow = np.array([[0, 0], [1, 1], [1, 0], [0, 1]], float)
    assert polygon_self_intersections(bow).tolist() == [[0, 2]]


def test_renders_see_the_films_bleed_not_the_transparent_pixels(tmp_path):
    # a texture lookup at a film's cut samples pixels on both sides of it: the film as
    # printed carries a bleed there (see workbench pdf), so the render's texture repeats
    # the nearest film pixel out to 2 mm; the design's own print (validate's reference) is
    # left as it is
    import cv2

    from workbench.design_dir import Design
    from workbench.render.imperfections import Imperfections

    design = Design(default_design_with_free_outline(tmp_path, 100))
    film = design.alpha > 0
    texture = design.scene(Imperfections(), fixture=False).textures[0]
    np.testing.assert_array_equal(texture[film], design.rgb[film])
    dist, labels = cv2.distanceTransformWithLabels(
        (~film).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE, labelType=cv2.DIST_LABEL_PIXEL
    )
    ring = ~film & (dist <= 2.0 * 100 / 25.4)
    nearest = np.flatnonzero(film.ravel())[labels[ring] - 1]
    assert ring.sum() > 100
    np.testing.assert_array_equal(texture[ring], design.rgb.reshape(-1, 3)[nearest])
    beyond = ~film & (dist > 2.0 * 100 / 25.4)
    np.testing.assert_array_equal(texture[beyond], design.rgb[beyond])
