"""calibrate check on real frames: misread boards left out, and the drift the check can see stated."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from workbench.calibration import board_views, check_power, grid_rms
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
