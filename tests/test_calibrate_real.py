"""calibrate camera and check on real photos: against OpenCV's own pipeline, and what drift the check catches.

Two sets: OpenCV's sample chessboard photos (640 x 480, kept in calib/regression/), and,
where the shared data sits beside this checkout (``shared/calibration/``, or the folder
``WORKBENCH_SHARED`` names), Udacity's camera_cal chessboard photos (1280 x 720, MIT
licence; its README says where they come from). How often the check fails a true or a
drifted profile over random splits of a set is ``benchmarks/bench_calibrate_check.py``.
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import ROOT
from test_calibrate import CHESSBOARD, REAL, drifted, profile_intrinsics

from workbench.calibration import board_views
from workbench.cli import main
from workbench.printing.boards import load_board

spec = importlib.util.spec_from_file_location("bench_calibrate_check", ROOT / "benchmarks" / "bench_calibrate_check.py")
bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench)

SHARED = Path(os.environ.get("WORKBENCH_SHARED") or ROOT.parent / "shared") / "calibration"
UDACITY = SHARED / "udacity-carnd-camera-cal"
no_udacity = pytest.mark.skipif(not UDACITY.is_dir(), reason="the shared calibration photos are not here")


def number(p: Path) -> int:
    return int(re.search(r"(\d+)", p.stem).group(1))


def test_the_checks_false_alarms_and_power_on_real_photos():
    # OpenCV's 12 usable left photos dealt 12 times into a profile of 7 and a check on 5
    views, W, H, _ = bench.load_views(sorted(map(str, REAL.glob("left*.jpg"))), load_board(CHESSBOARD))
    assert (W, H, len(views)) == (640, 480, 12)
    m = bench.measure(views, W, H, 7, splits=12, seed=0)
    assert m["splits"] == 12
    # the true profile passes (at most one false alarm in 12: the nominal rate is about 1 %)
    assert m["fail"]["true"] <= 1 / 12
    # the check's standard deviations are honest (z of a true profile about 1), OpenCV's alone are not
    for k in ("fx", "fy", "cx", "cy"):
        assert 0.6 < m["z_rms"][k] < 1.6, m
        assert m["z_rms_opencv"][k] > 2.0, m
    # what such a split can catch: fx to about 2 %, the principal point to about 13 px. 1 % and 8 px
    # lie inside these photos' own scatter (the null scatter of fx alone is 3 px, 0.6 %)
    assert 1.2 < m["detectable"]["fx_pct"] < 3.5 and 6.0 < m["detectable"]["cx"] < 25.0
    assert m["null_rms_px"]["fx"] / m["fx"] > 0.003


@pytest.fixture(scope="module")
def udacity(tmp_path_factory):
    """The Udacity photos of 1280 x 720, and their corners (found once, by calibrate camera's code)."""
    photos = sorted(UDACITY.glob("calibration*.jpg"), key=number)
    grey = [(str(p), cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)) for p in photos]
    full = [(n, g) for n, g in grey if g.shape == (720, 1280)]
    views, per_view = board_views(full, load_board(CHESSBOARD))
    return photos, full, views, per_view, tmp_path_factory.mktemp("udacity")


@no_udacity
def test_real_1280_photos_calibrate_like_opencv(udacity, capsys):
    photos, full, views, per_view, tmp = udacity
    # two of the 20 photos are 1281 x 721 (cropped otherwise): refused, by name
    out = tmp / "all.json"
    assert main(["calibrate", "camera", *map(str, photos), "--board", str(CHESSBOARD), "-o", str(out), "-q"]) == 1
    odd = str(UDACITY / "calibration7.jpg")
    assert f"{odd}: 1281 x 721 pixels, but {photos[0]} (the first photo) is 1280 x 720" in capsys.readouterr().err
    # the 18 of 1280 x 720: two show part of the board only and are left out
    assert len(full) == 18 and len(views) == 16
    assert sorted(Path(v["name"]).name for v in per_view if not v["used"]) == ["calibration1.jpg", "calibration5.jpg"]
    out = tmp / "udacity.json"
    assert main(["calibrate", "camera", *[n for n, _ in full], "--board", str(CHESSBOARD), "-o", str(out), "-q"]) == 0
    ours = profile_intrinsics(out)
    # OpenCV's own pipeline on the same corners: calibrateCamera with its default flags
    _, K, *_ = cv2.calibrateCamera([v[1] for v in views], [v[2] for v in views], (1280, 720), None, None)
    theirs = np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2]])
    assert np.abs(ours[:2] / theirs[:2] - 1).max() < 0.005 and np.abs(ours[2:] - theirs[2:]).max() < 0.005 * 1280
    prof = json.loads(out.read_text())
    assert 0.7 < prof["rms_px"] < 1.0  # a real lens and board: far from the renders' 0.09 px


@no_udacity
def test_the_check_on_real_1280_photos(udacity, tmp_path, capsys):
    photos, full, *_ = udacity
    names = [n for n, _ in full if Path(n).name not in ("calibration1.jpg", "calibration5.jpg")]
    made, held = names[:10], names[10:]  # 2-13 make the profile, 14 and 16-20 check it
    prof = tmp_path / "made.json"
    assert main(["calibrate", "camera", *made, "--board", str(CHESSBOARD), "-o", str(prof), "-q"]) == 0
    assert main(["calibrate", "check", str(prof), *held]) == 0
    err = capsys.readouterr().err
    assert "re-measured on 6 photos" in err and "within tolerance on 6 photos" in err
    # these photos know fx to about 2 % (26 px): 10 % fails, though every photo's RMS stays low
    assert main(["calibrate", "check", str(drifted(prof, tmp_path, 1.10)), *held, "-q"]) == 1
    assert "re-measured fx " in capsys.readouterr().err
    # a photo of another size is refused, by name
    odd = str(UDACITY / "calibration15.jpg")
    assert main(["calibrate", "check", str(prof), *held, odd, "-q"]) == 1
    assert f"{odd}: 1281 x 721 pixels, but the profile is for 1280 x 720" in capsys.readouterr().err
