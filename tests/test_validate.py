"""workbench validate on synthetic photos whose truth is known."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest
from conftest import ROOT

from workbench.camera import Camera
from workbench.cli import main
from workbench.design_dir import Design
from workbench.export import png_bytes
from workbench.render.imperfections import Imperfections
from workbench.render.photo import render_photo

SIZE = (2000, 1500)
PHOTO_AT = (10.0, 55.0, 330.0)  # orbit: azimuth, elevation (deg), distance (mm)


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    d = tmp_path_factory.mktemp("v") / "design"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d), "-q"]) == 0
    return Design(d)


def photo(design, path, orbit=PHOTO_AT, realistic=True, extra=(), size=SIZE):
    args = [
        "render",
        str(design.dir),
        "--orbit=" + ",".join(map(str, orbit)),
        "--size",
        f"{size[0]}x{size[1]}",
        "-o",
        str(path),
        "-q",
        *extra,
    ]
    if realistic:
        args.append("--realistic")
    assert main(args) == 0
    return path


def validate(design, photos, out, *extra):
    profile = photos[0].with_suffix(".json")
    status = main(
        ["validate", str(design.dir), *map(str, photos), "--camera", str(profile), "--out", str(out), "-q", *extra]
    )
    return status, json.loads((out / "validation.json").read_text()) if (out / "validation.json").exists() else None


def test_perfect_decoration_passes_and_the_pose_is_exact(design, tmp_path):
    p = photo(design, tmp_path / "perfect.png")
    status, report = validate(design, [p], tmp_path / "out", "--tolerance-mm", "0.2")
    assert status == 0
    e = report["photos"][0]
    assert e["verdict"] == "PASS", e["reason"]
    assert e["misregistration_mm"]["p95"] <= 0.05 and e["coverage"] >= 0.99 and e["ssim"] >= 0.9
    truth = json.loads(p.with_suffix(".json").read_text())
    R, Rt = np.asarray(e["pose"]["R"]), np.asarray(truth["R"])
    angle = np.degrees(np.arccos(np.clip((np.trace(R.T @ Rt) - 1) / 2, -1, 1)))
    assert angle <= 0.02
    assert np.linalg.norm(np.asarray(e["pose"]["camera_center_mm"]) - np.asarray(truth["camera_center_mm"])) <= 0.1
    assert e["reprojection_rms_px"] <= 0.3 and e["corners_used"] >= 20
    assert (tmp_path / "out" / "qa_report.pdf").read_bytes().startswith(b"%PDF")


@pytest.mark.parametrize(
    ("flags", "offset", "rotation", "scale"),
    [
        (["--film-offset-mm", "0.1,0"], (0.1, 0.0), 0.0, 0.0),
        (["--film-offset-mm=-0.5,0.8"], (-0.5, 0.8), 0.0, 0.0),
        (["--film-offset-mm", "2,-1"], (2.0, -1.0), 0.0, 0.0),
        (["--film-rotation-deg", "0.3"], (0.0, 0.0), 0.3, 0.0),
        (["--film-scale-pct", "0.4"], (0.0, 0.0), 0.0, 0.4),
    ],
)
def test_injected_film_errors_are_recovered(design, tmp_path, flags, offset, rotation, scale):
    p = photo(design, tmp_path / "p.png", extra=flags)
    _, report = validate(design, [p], tmp_path / "out")
    e = report["photos"][0]
    # the injected quantity within the bounds (0.05 mm, 0.05°, 0.05 %); what was
    # not injected may leak a little (seen: 0.056° of rotation for a 2.2 mm offset, from
    # tiles the front view sees at a grazing angle), bounded at twice that
    tol = {
        "offset": 0.05 if any(offset) else 0.1,
        "rotation": 0.05 if rotation else 0.1,
        "scale": 0.05 if scale else 0.1,
    }
    assert e["film_offset_mm"][0] == pytest.approx(offset[0], abs=tol["offset"])
    assert e["film_offset_mm"][1] == pytest.approx(offset[1], abs=tol["offset"])
    assert e["film_rotation_deg"] == pytest.approx(rotation, abs=tol["rotation"])
    assert e["film_scale_pct"] == pytest.approx(scale, abs=tol["scale"])


# (26 s; make bench)
@pytest.mark.slow
def test_photos_away_from_the_viewpoint_score_the_same(design, tmp_path):
    scores = []
    for k, orbit in enumerate([(0.0, 55.0, 330.0), (15.0, 55.0, 330.0), (-15.0, 45.0, 360.0)]):
        p = photo(design, tmp_path / f"p{k}.png", orbit=orbit, extra=["--film-offset-mm", "0.6,0"])
        _, report = validate(design, [p], tmp_path / f"out{k}", "--view", "front")
        scores.append(report["photos"][0])
    med = [s["misregistration_mm"]["median"] for s in scores]
    assert max(med) - min(med) <= 0.05 and all(abs(m - 0.6) <= 0.05 for m in med)
    assert all(abs(s["film_offset_mm"][0] - 0.6) <= 0.05 for s in scores)


def test_a_perfect_small_photo_passes(design, tmp_path):
    # 640 x 480 with its exact profile: the photo resolves the print at about 2 px per mm; what it
    # cannot resolve is unresolved, not defects (it once failed with four defects over 4 mm²)
    p = photo(design, tmp_path / "small.jpg", size=(640, 480))
    status, report = validate(design, [p], tmp_path / "out", "--tolerance-mm", "0.2")
    e = report["photos"][0]
    assert status == 0 and e["verdict"] == "PASS", (e["reason"], e["defects"])
    assert not [d for d in e["defects"] if d["area_mm2"] > 4.0]
    assert e["dense"]["detection_limit"]["min_area_mm2"] > 1.0  # it says it sees less than a larger photo


def test_wrong_print_fails(design, tmp_path):
    wrong = tmp_path / "wrong"
    shutil.copytree(design.dir, wrong)
    # the part decorated with another job's print (the deformed grid's), same size
    other = cv2.imread(str(ROOT / "fixtures" / "deformed-grid" / "top.png"))
    rgb = cv2.resize(other, (design.rgb.shape[1], design.rgb.shape[0]))
    (wrong / "print.png").write_bytes(png_bytes(cv2.cvtColor(rgb, cv2.COLOR_BGR2RGB)))
    p = photo(Design(wrong), tmp_path / "wrong.png")
    status, report = validate(design, [p], tmp_path / "out")
    e = report["photos"][0]
    assert status == 0 and e["verdict"] == "FAIL" and "does not match the design" in e["reason"]


def test_bad_photos_are_invalid_and_do_not_stop_the_others(design, tmp_path):
    good = photo(design, tmp_path / "good.png", realistic=False)
    no_markers = photo(design, tmp_path / "nomarkers.png", extra=["--no-fixture"])
    unreadable = tmp_path / "broken.png"
    unreadable.write_bytes(b"not an image")
    # the part 40 mm off its place on the fixture: markers show where it should hide them
    moved = tmp_path / "moved.png"
    imp = Imperfections()
    shifted = Design(design.dir)
    shifted.V = shifted.V + [45.0, 0.0, 0.0]
    truth = json.loads(good.with_suffix(".json").read_text())
    cam = Camera(np.asarray(truth["K"]), np.asarray(truth["R"]), np.asarray(truth["t"]), *truth["image_size"])
    moved.write_bytes(png_bytes(render_photo(shifted.scene(imp), cam, imp)))
    status, report = validate(design, [good, no_markers, unreadable, moved], tmp_path / "out")
    assert status == 0
    verdicts = {e["photo"].rsplit("/", 1)[-1]: e for e in report["photos"]}
    assert verdicts["good.png"]["verdict"] == "PASS"
    assert (
        verdicts["nomarkers.png"]["verdict"] == "INVALID"
        and "no fixture markers" in verdicts["nomarkers.png"]["reason"]
    )
    assert verdicts["broken.png"]["verdict"] == "INVALID" and "unreadable image" in verdicts["broken.png"]["reason"]
    assert verdicts["moved.png"]["verdict"] == "INVALID"
    assert "the object is not where the fixture says" in verdicts["moved.png"]["reason"]


def test_markers_of_another_board_are_invalid(design, tmp_path):
    other = tmp_path / "other"
    shutil.copytree(design.dir, other)
    fx = json.loads((other / "fixture.json").read_text())
    from workbench.printing.boards import CharucoSpec, definition

    spec = CharucoSpec(tuple(fx["squares"]), fx["square_mm"], fx["marker_mm"], fx["dictionary"], first_id=100)
    (other / "fixture.json").write_text(json.dumps(definition(spec, "fixture", origin_mm=fx["origin_mm"])))
    p = photo(Design(other), tmp_path / "p.png")
    _, report = validate(design, [p], tmp_path / "out")
    e = report["photos"][0]
    assert e["verdict"] == "INVALID" and "another board" in e["reason"]


def test_missing_camera_profile(design, tmp_path, capsys):
    p = photo(design, tmp_path / "p.png", realistic=False, size=(640, 480))
    status = main(["validate", str(design.dir), str(p), "--camera", str(tmp_path / "none.json"), "-q"])
    assert status == 1 and "no such camera profile" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("offset_mm", [0.1, 0.5, 2.0])
def test_full_size_realistic_photos(design, tmp_path, offset_mm):
    # the conditions: 4000 x 3000, blur 1 px, noise 3, JPEG 90, shading on
    p = photo(design, tmp_path / "p.jpg", size=(4000, 3000), extra=["--film-offset-mm", f"{offset_mm},0"])
    _, report = validate(design, [p], tmp_path / "out")
    e = report["photos"][0]
    truth = json.loads(p.with_suffix(".json").read_text())
    R, Rt = np.asarray(e["pose"]["R"]), np.asarray(truth["R"])
    assert np.degrees(np.arccos(np.clip((np.trace(R.T @ Rt) - 1) / 2, -1, 1))) <= 0.02
    assert np.linalg.norm(np.asarray(e["pose"]["camera_center_mm"]) - np.asarray(truth["camera_center_mm"])) <= 0.1
    assert e["film_offset_mm"][0] == pytest.approx(offset_mm, abs=0.05)
    assert abs(e["film_offset_mm"][1]) <= 0.05


def test_the_first_page_gives_a_long_reason_in_full(tmp_path):
    # a FAIL whose reason is longer than a line: the first page wraps it, it is not cut off
    import pypdf
    from test_qa_report import report_of

    from workbench.validate.report import qa_report

    reason = (
        "misregistration p95 0.412 mm > tolerance 0.2 mm by more than 3 x its uncertainty 0.014 mm; "
        "2 defects > 4 mm² (largest: missing, 54.9 mm² at (78.5, 57.1) mm on the print)"
    )
    photo = {"photo": "a.jpg", "verdict": "FAIL", "reason": reason, "view": "front", "defects": []}
    report = report_of([photo], {"verdict": "FAIL", "defects": []})
    (tmp_path / "r.pdf").write_bytes(qa_report(report, {}))
    first = pypdf.PdfReader(tmp_path / "r.pdf").pages[0].extract_text()
    assert len(reason) > 110 and " ".join(first.split()).count(" ".join(f"a.jpg: {reason}".split())) == 1, first


@pytest.mark.parametrize("name", ["inferno", "viridis"])
def test_the_pictures_colour_tables_are_matplotlibs(name):
    # validate's pictures are drawn with OpenCV from written-out tables (no matplotlib import in a
    # photo); they must be matplotlib's own, as its pictures used them (a colour picture's pixels
    # the same), not OpenCV's copies, which round where matplotlib truncates
    import matplotlib

    from workbench.validate.pictures import colour_table

    expected = (matplotlib.colormaps[name](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)
    assert np.array_equal(colour_table(name), expected)


def test_a_photo_that_shows_one_grey_over_the_view_has_no_similarity_and_no_crash():
    """A view the photo shows as one grey (black where a warp fell off the photo) has no exposure to
    fit: the similarity is None (not a crash, which cost a perfect 12 Mpx photo its verdict)."""
    from workbench.validate.score import ViewSurface, score

    H, W = 120, 160
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    X = np.stack([jj * 0.5, ii * 0.5, np.zeros_like(jj)], axis=-1)
    surface = ViewSurface(X, X[..., :2].copy(), np.ones((H, W), bool), np.zeros((H, W), np.int64))
    design = np.dstack([np.uint8(60 + jj)] * 3).astype(np.uint8)
    for grey in (0, 128):
        got = score(design, np.full((H, W, 3), grey, np.uint8), np.ones((H, W), bool), surface, (80.0, 60.0))
        assert got.ssim is None and len(got.centres) == 0
