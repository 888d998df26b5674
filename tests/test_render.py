"""workbench render: exact geometry, imperfections that do what they say, truth files, bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from closed_loop import render_decorated, tile_misregistration
from conftest import ROOT

from workbench.camera import Camera, load_camera
from workbench.cli import main
from workbench.design_dir import Design
from workbench.export import texture_uv
from workbench.printing.boards import CharucoSpec
from workbench.render.imperfections import Imperfections
from workbench.render.photo import Scene, render_linear, render_photo

LENS = (-0.15, 0.06, 0.0008, -0.0004, 0.01)


@pytest.fixture(scope="module")
def default_design(tmp_path_factory):
    d = tmp_path_factory.mktemp("design") / "default"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d), "-q"]) == 0
    return Design(d)


@pytest.mark.parametrize("lens", [(0.0,) * 5, LENS], ids=["no-distortion", "distortion"])
def test_every_pixel_lands_where_the_camera_model_puts_it(lens):
    # a plane whose texture holds its own texel coordinates: bilinear sampling of a
    # linear function is exact, so each rendered pixel says which point of the plane
    # it shows; the truth is the pixel's (distorted) ray meeting the plane
    tw, th = 2000, 1500
    ii, jj = np.mgrid[0:th, 0:tw].astype(np.float32)
    tex = np.stack([jj, ii, np.zeros_like(ii)], axis=-1)
    V = np.array([[-100, 75, 0], [100, 75, 0], [100, -75, 0], [-100, -75, 0]], float)
    uv = np.array([[-0.5, -0.5], [tw - 0.5, -0.5], [tw - 0.5, th - 0.5], [-0.5, th - 0.5]])
    scene = Scene(
        V, np.array([[0, 3, 2], [0, 2, 1]]), uv, np.tile([0, 0, 1.0], (4, 1)), np.zeros(2, np.int8), [tex, tex], 2
    )
    cam = Camera.look_at([40, -150, 250], [0, 0, 0], [0, 0, 1], 55, 800, 600)
    img = render_linear(scene, cam, Imperfections(distortion=lens), supersample=2)
    jj2, ii2 = np.meshgrid(np.arange(800.0), np.arange(600.0))
    pts = np.stack([jj2.ravel(), ii2.ravel()], 1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    und = cv2.undistortPoints(pts, cam.K, np.asarray(lens), None, None, None, crit).reshape(-1, 2)
    d = np.column_stack([und, np.ones(len(und))]) @ cam.R
    X = cam.center + (-cam.center[2] / d[:, 2])[:, None] * d
    tx, ty = (X[:, 0] + 100) * 10 - 0.5, (75 - X[:, 1]) * 10 - 0.5
    texels_per_px = np.abs(np.gradient(tx.reshape(600, 800), axis=1)).ravel()
    err_px = np.hypot(img[..., 0].ravel() - tx, img[..., 1].ravel() - ty) / texels_per_px
    inside = (tx > 20) & (tx < tw - 21) & (ty > 20) & (ty < th - 21)
    assert inside.sum() > 150_000
    assert np.median(err_px[inside]) < 0.001 and err_px[inside].max() < 0.01


@pytest.mark.parametrize("lens", [(0.0,) * 5, LENS], ids=["no-distortion", "distortion"])
def test_board_corners_land_where_projectpoints_puts_them(default_design, lens):
    fx = default_design.fixture
    imp = Imperfections(distortion=lens)
    cam = Camera.look_at([60, -260, 300], [0, 0, 0], [0, 0, 1], 50, 1600, 1200)
    img = cv2.cvtColor(render_photo(default_design.scene(imp), cam, imp, supersample=4), cv2.COLOR_RGB2GRAY)
    spec = CharucoSpec(tuple(fx["squares"]), fx["square_mm"], fx["marker_mm"], fx["dictionary"])
    rvec = cv2.Rodrigues(cam.R)[0]
    # ChArUco (chessboard) corners, sub-pixel refined by the detector
    cc, ids, mc, mids = cv2.aruco.CharucoDetector(spec.opencv()).detectBoard(img)
    ids = ids.ravel()
    proj, _ = cv2.projectPoints(np.asarray(fx["charuco_corners"]["mesh_mm"])[ids], rvec, cam.t, cam.K, np.asarray(lens))
    err = np.linalg.norm(cc.reshape(-1, 2) - proj.reshape(-1, 2), axis=1)
    assert len(ids) >= 25 and np.median(err) <= 0.05
    # marker corners, refined the AprilTag way: about 0.1 px, in the pixel-corner
    # convention (+0.5 px in x and y against OpenCV's pixel centres; DESIGN.md)
    dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, fx["dictionary"]))
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
    corners, mids, _ = cv2.aruco.ArucoDetector(dic, params).detectMarkers(img)
    mesh = np.asarray(fx["markers"]["corners_mesh_mm"])
    index = {int(i): k for k, i in enumerate(fx["markers"]["ids"])}
    got = np.concatenate([c.reshape(4, 2) for c in corners]) - 0.5
    want, _ = cv2.projectPoints(
        np.concatenate([mesh[index[int(i)]] for i in mids.ravel()]), rvec, cam.t, cam.K, np.asarray(lens)
    )
    merr = np.linalg.norm(got - want.reshape(-1, 2), axis=1)
    assert len(merr) >= 100 and np.median(merr) <= 0.12


def test_a_designed_view_renders_its_image(default_design):
    # closed loop with design, through the workbench's own renderer this time
    d = default_design
    names = [v["name"] for v in d.info["views"]]
    ref_v = cv2.cvtColor(cv2.imread(str(ROOT / "fixtures" / "default" / "logo.png")), cv2.COLOR_BGR2RGB)
    cam = d.view_camera("logo")
    imp = Imperfections()
    img = render_photo(d.scene(imp, fixture=False), cam, imp)
    # the logo view owns all the part it sees (it comes first): compare where a ray hits
    p = d.info["print"]
    rows, cols = d.rgb.shape[:2]
    vt = texture_uv(d.flat, cols * 25.4 / p["dpi"], rows * 25.4 / p["dpi"], p["height_mm"])
    _, px = render_decorated(d.V, d.F, vt, d.rgb, cam)
    hit = np.isfinite(px[..., 0])
    mask = cv2.erode(hit.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    mis = np.linalg.norm(tile_misregistration(ref_v, img, mask), axis=1)
    assert names[0] == "logo" and len(mis) >= 100
    assert np.median(mis) <= 0.1 and np.percentile(mis, 95) <= 0.3


def test_film_offset_moves_the_print_on_the_surface_by_that_much(tmp_path):
    # the half cylinder's flat sheet, seen from straight above: print mm are surface mm
    # there (developable, isometric), and one mm is f / z pixels in the photo
    d = tmp_path / "hc"
    assert main(["design", str(ROOT / "fixtures" / "half-cylinder" / "job.toml"), "--out", str(d), "-q"]) == 0
    des = Design(d)
    cam = Camera.look_at([-42, 0, 300], [-42, 0, 0], [0, 1, 0], 10, 800, 800)
    base = render_photo(des.scene(Imperfections(), fixture=False), cam, Imperfections())
    moved_imp = Imperfections(film_offset_mm=(1.0, -0.5))
    moved = render_photo(des.scene(moved_imp, fixture=False), cam, moved_imp)
    shifts = tile_misregistration(base, moved, np.ones(base.shape[:2], bool), tile=96)
    px_per_mm = cam.K[0, 0] / 300.0
    # print x is mesh +x (image right), print y is mesh -y (image down)
    med = np.median(shifts, axis=0) / px_per_mm
    assert len(shifts) >= 20
    assert med[0] == pytest.approx(1.0, abs=0.02) and med[1] == pytest.approx(-0.5, abs=0.02)


def test_cli_truth_file_is_a_camera_profile_and_output_is_reproducible(tmp_path, default_design):
    args = [
        "render",
        str(default_design.dir),
        "--orbit",
        "20,40,400",
        "--size",
        "640x480",
        "--realistic",
        "--film-offset-mm",
        "0.8,0",
        "--distortion=" + ",".join(map(str, LENS)),
        "--seed",
        "7",
        "-q",
    ]
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    assert main([*args, "-o", str(a)]) == 0 and main([*args, "-o", str(b)]) == 0
    assert a.read_bytes() == b.read_bytes()
    t = json.loads(a.with_suffix(".json").read_text())
    assert t["imperfections"]["film_offset_mm"] == [0.8, 0.0] and t["imperfections"]["noise"] == 3.0
    assert t["dist"] == list(LENS) and t["image_size"] == [640, 480]
    cam = load_camera(a.with_suffix(".json"))
    np.testing.assert_allclose(cam.center, t["camera_center_mm"])
    # and it can be rendered from again: the same geometry, no noise
    c = tmp_path / "c.png"
    assert main(["render", str(default_design.dir), "--camera", str(a.with_suffix(".json")), "-o", str(c), "-q"]) == 0
    assert json.loads(c.with_suffix(".json").read_text())["dist"] == list(LENS)


def test_previews(tmp_path, default_design):
    out = tmp_path / "prev"
    assert main(["render", str(default_design.dir), "--previews", "-o", str(out), "-q"]) == 0
    assert {p.name for p in out.iterdir()} >= {"logo.png", "front.png", "generic.png", "contact_sheet.png"}
    # each designed view's preview is that view's camera, and shows that view's image where the part is
    logo = cv2.cvtColor(cv2.imread(str(out / "logo.png")), cv2.COLOR_BGR2RGB)
    cam = default_design.view_camera("logo")
    assert logo.shape[:2] == (cam.height, cam.width)
    ref = default_design.view_image(0)
    assert np.median(np.abs(logo.astype(int) - ref.astype(int))) <= 2
    sheet = cv2.imread(str(out / "contact_sheet.png"))
    assert sheet.shape[0] == 336  # one row of 300 px tiles with their labels


@pytest.mark.parametrize(
    ("args", "fragment", "status"),
    [
        (["--orbit", "0,30"], "--orbit '0,30': give 3 comma-separated numbers", 2),
        (["--view", "nope"], "no view named 'nope'", 1),
        (["--camera", "BADCAM"], "K: must be a 3x3 array of finite numbers", 1),
        (["--camera", "AWAY"], "the camera sees nothing of the object", 1),
        (["--camera", "missing.json"], "no such camera file", 1),
        (["--orbit", "0,30,400", "--blur-px", "-1"], "--blur-px -1: must be between 0 and 50", 2),
    ],
)
def test_bad_input(tmp_path, capsys, default_design, args, fragment, status):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"K": [1, 2, 3], "R": np.eye(3).tolist(), "t": [0, 0, 0], "image_size": [64, 48]}))
    away = tmp_path / "away.json"
    cam = Camera.look_at([0, 0, 300], [0, 0, 600], [0, 1, 0], 40, 64, 48)  # looking up, away from the part
    away.write_text(json.dumps(cam.to_dict()))
    args = [str(bad) if a == "BADCAM" else str(away) if a == "AWAY" else a for a in args]
    out = tmp_path / "p.png"
    assert main(["render", str(default_design.dir), *args, "-o", str(out), "-q"]) == status
    err = capsys.readouterr().err.strip()
    assert fragment in err and len(err.splitlines()) == 1 and not out.exists()


def test_missing_design_dir(tmp_path, capsys):
    assert main(["render", str(tmp_path / "nope"), "--orbit", "0,30,300", "-o", str(tmp_path / "p.png"), "-q"]) == 1
    assert "no such design directory" in capsys.readouterr().err
