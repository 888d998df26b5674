"""calibrate check on real frames: misread boards left out, and the drift the check can see stated."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from workbench.calibration import board_views
from workbench.calibration_coverage import grid_rms
from workbench.calibration_power import check_power
from workbench.printing.boards import load_board

ROOT = Path(__file__).resolve().parents[1]
PROFILE = ROOT / "calib" / "cameras" / "boofcv-day-a.json"
DAY_B = ROOT / "calib" / "regression" / "boofcv-chessboard"
BOARD = ROOT / "calib" / "boards" / "chessboard-7x5-30mm.json"


def _grid(K, rvec, tvec):
    board = np.array([[(i + 1) * 30.0, (j + 1) * 30.0] for j in range(4) for i in range(6)])
    obj = np.column_stack([board, np.zeros(len(board))])
    px = cv2.projectPoints(obj, np.float64(rvec), np.float64(tvec), K, np.zeros(5))[0].reshape(-1, 2)
    return board, px


def test_grid_rms_is_zero_on_a_flat_grid_and_large_when_a_row_is_read_one_square_off():
    K = np.array([[530.0, 0, 320], [0, 530.0, 240], [0, 0, 1]])
    board, px = _grid(K, [0.9, 0.2, 0.1], [-100.0, -60.0, 400.0])  # tilted 53 degrees
    assert grid_rms(board, px) < 1e-4  # (findHomography's own precision: 4e-6 px)
    # the second row matched one square along: each of its corners is given the next one's pixels
    misread = px.copy()
    misread[6:11] = px[7:12]
    square_px = np.median(np.linalg.norm(np.diff(px[:6], axis=0), axis=1))
    assert grid_rms(board, misread) > 0.1 * square_px
    # the profile's distortion is taken out first: a distorted photo of a flat grid fits again
    dist = np.array([0.2, -0.1, 0.0, 0.0, 0.0])
    obj = np.column_stack([board, np.zeros(len(board))])
    bent = cv2.projectPoints(obj, np.float64([0.9, 0.2, 0.1]), np.float64([-100.0, -60.0, 400.0]), K, dist)[0]
    assert grid_rms(board, bent.reshape(-1, 2)) > 0.05
    assert grid_rms(board, bent.reshape(-1, 2), (K, dist)) < 1e-3


def test_misread_frames_of_a_real_video_are_left_out_with_their_reason():
    prof = json.loads(PROFILE.read_text())
    names = ["frame_081.jpg", "frame_102.jpg", "frame_120.jpg", "frame_135.jpg"]
    images = [(n, cv2.imread(str(DAY_B / n), cv2.IMREAD_GRAYSCALE)) for n in names]
    camera = (np.asarray(prof["K"]), np.asarray(prof["dist"]))
    views, per = board_views(images, load_board(BOARD), camera, prof["view_rms_limit_px"])
    by = {v["name"]: v for v in per}
    assert [v[0] for v in views] == ["frame_081.jpg", "frame_135.jpg"]
    for n in ("frame_102.jpg", "frame_120.jpg"):
        assert "flat grid" in by[n]["reason"] and "wrong squares" in by[n]["reason"]
    assert max(by[n]["grid_rms_px"] for n in ("frame_081.jpg", "frame_135.jpg")) < 0.3


def _check(profile: Path, *extra: str) -> subprocess.CompletedProcess:
    photos = sorted(str(p) for p in DAY_B.glob("*.jpg"))
    cmd = [sys.executable, "-m", "workbench", "calibrate", "check", str(profile), *photos, *extra]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)


@pytest.fixture(scope="module")
def drifted(tmp_path_factory) -> Path:
    """The day-a profile with cy moved 8 px (its board named from where it is written)."""
    prof = json.loads(PROFILE.read_text())
    prof["K"][1][2] += 8.0
    prof["board"]["file"] = str(BOARD)
    out = tmp_path_factory.mktemp("drift") / "cy8.json"
    out.write_text(json.dumps(prof))
    return out


def test_the_real_second_day_passes_the_true_profile_and_says_what_it_cannot_see():
    r = _check(PROFILE)
    assert r.returncode == 0, r.stderr
    said = (r.stdout + r.stderr).strip().splitlines()
    assert "within tolerance" in said[-1] and "cannot see a 1 % focal drift" in said[-1]
    # every misread frame was left out, none drags the re-measurement
    assert sum("matched to the wrong squares" in line for line in said) >= 15
    strict = _check(PROFILE, "--strict", "-q")
    assert strict.returncode == 1 and len(strict.stderr.strip().splitlines()) == 1
    assert "--strict" in strict.stderr and "cannot see" in strict.stderr
    # a tolerance the photos do see: no warning
    wide = _check(PROFILE, "--focal-tolerance-pct", "20", "--pp-tolerance-px", "200", "--strict", "-q")
    assert wide.returncode == 0, wide.stderr


def test_the_real_second_day_catches_the_principal_point_moved_8_px(drifted):
    r = _check(drifted, "-q")
    assert r.returncode == 1 and "drifted" in r.stderr and "cy" in r.stderr


def test_power_is_the_limit_plus_the_one_sided_quantile_in_standard_deviations():
    K0 = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    entry = {"limit": 3.0, "dof": np.inf, "sigma": 1.0, "sigma_profile": 0.5, "sigma_photos": np.sqrt(0.75)}
    r = {k: dict(entry) for k in ("fx", "fy", "cx", "cy")}
    r.update(views=20, measured=["fx", "fy", "cx", "cy"])
    p = check_power(r, K0, 1.0, 8.0)
    # (3 + 1.645) sigma = 4.645 px: 0.929 % of 500 px, and 4.645 px of the principal point
    assert p["focal_pct"] == pytest.approx(0.929, abs=1e-3) and p["pp_px"] == pytest.approx(4.645, abs=1e-3)
    assert p["short"] == [] and p["photos_needed"] is None
    # a 0.5 % tolerance: the photos' variance must fall to (2.5 / 4.645)² - 0.25 = 0.0397 px²
    p = check_power(r, K0, 0.5, 8.0)
    assert p["photos_needed"] == int(np.ceil(20 * 0.75 / ((2.5 / 4.6449) ** 2 - 0.25)))
    assert "cannot see a 0.5 % focal drift with 20 photos" in p["short"][0]
    # a tolerance inside the profile's own uncertainty: no number of photos reaches it
    assert check_power(r, K0, 0.3, 8.0)["photos_needed"] is None
    # the focal length alone re-measured: the principal point is not checked, and it says so
    fx_only = {"fx": dict(entry), "views": 4, "measured": ["fx"]}
    p = check_power(fx_only, K0, 1.0, 8.0)
    assert p["pp_px"] is None and any("principal point is not re-measured" in s for s in p["short"])


def _views_of(K, W, H, poses):
    """Board views (name, (24, 3) mm, (24, 2) px) of the 7 x 5 chessboard for (rvec, tvec) poses."""
    board = np.array([[(i + 1) * 30.0, (j + 1) * 30.0, 0.0] for j in range(4) for i in range(6)])
    views = []
    for k, (r, t) in enumerate(poses):
        px = cv2.projectPoints(board, np.float64(r), np.float64(t), K, np.zeros(5))[0].reshape(-1, 2)
        views.append((f"v{k}", board.astype(np.float32), px.astype(np.float32)))
    return views


def test_coverage_names_the_frame_corners_and_borders_no_corner_reaches_and_the_tilt_to_add():
    from workbench.calibration_coverage import photo_coverage

    W, H = 640, 480
    K = np.array([[640.0, 0, 319.5], [0, 640.0, 239.5], [0, 0, 1]])  # the nominal camera the tilts are read with
    # the board (150 x 90 mm centred on its middle, 105, 75 mm) 800 mm away in the frame's middle,
    # turned 35 degrees about the image's vertical axis, then 10 about the horizontal
    Ry = cv2.Rodrigues(np.array([0.0, np.radians(35), 0.0]))[0]
    Rx = cv2.Rodrigues(np.array([np.radians(10), 0.0, 0.0]))[0]
    poses = []
    for R in (Ry, Rx):
        t = np.array([0.0, 0.0, 800.0]) - R @ np.array([105.0, 75.0, 0.0])
        poses.append((cv2.Rodrigues(R)[0].ravel(), t))
    cov = photo_coverage(_views_of(K, W, H, poses), W, H)
    # the board's normal turned away from the camera: |tilt| as set, to the solver's precision
    assert sorted(np.abs(cov["tilt_y_deg"])) == pytest.approx([0.0, 35.0], abs=0.05)
    assert sorted(np.abs(cov["tilt_x_deg"])) == pytest.approx([0.0, 10.0], abs=0.05)
    assert set(cov["missing"]) == {
        "top-left",
        "top-right",
        "bottom-left",
        "bottom-right",
        "top",
        "bottom",
        "left",
        "right",
    }
    assert cov["next"][0] == "the board in the frame's four corners"
    assert cov["next"][1] == "the board along the frame's four borders"
    # 35 degrees about the vertical axis is enough; 10 about the horizontal is not
    assert cov["next"][2:] == ["the board turned 30 to 45 degrees about the image's horizontal axis (the most now: 10)"]
    assert sum(map(sum, cov["cells"])) == 48 and cov["share"] == pytest.approx(np.mean(np.array(cov["cells"]) > 0))


def test_calibrate_camera_and_check_draw_the_coverage(tmp_path):
    left = ROOT / "calib" / "regression" / "opencv-chessboard"
    photos = sorted(str(p) for p in left.glob("left0*.jpg"))
    out = tmp_path / "cam.json"
    board = ROOT / "calib" / "boards" / "chessboard-10x7-25mm.json"
    cmd = [sys.executable, "-m", "workbench", "calibrate", "camera", *photos, "--board", str(board), "-o", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    said = (r.stdout + r.stderr).splitlines()
    assert any(line.startswith("coverage: corners reach ") and "next photos:" in line for line in said)
    prof = json.loads(out.read_text())
    assert prof["frame_coverage"]["next"] and (tmp_path / "cam-coverage.png").stat().st_size > 10_000
    pic = tmp_path / "check.png"
    others = sorted(str(p) for p in left.glob("left1*.jpg"))
    check = [sys.executable, "-m", "workbench", "calibrate", "check", str(out), *others, "-q"]
    r = subprocess.run([*check, "--coverage", str(pic)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert cv2.imread(str(pic)).shape[1] >= 1000
    # a picture over an input: refused, nothing written
    before = Path(others[0]).read_bytes()
    r = subprocess.run([*check, "--coverage", others[0]], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode != 0 and len(r.stderr.strip().splitlines()) == 1
    assert Path(others[0]).read_bytes() == before
