"""Calibration: camera intrinsics from ChArUco photos, printer scale from a scanned target."""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from workbench.errors import WorkbenchError
from workbench.printing.boards import CharucoSpec

MIN_CORNERS = 8
MIN_VIEWS = 5
K3_COVERAGE = 0.7  # share of a 8 x 6 grid of the image that corners must reach before k3 is fitted


def detect_corners(gray: np.ndarray, definition: dict) -> tuple[np.ndarray, np.ndarray, str | None]:
    """ChArUco corners of a board in an image.

    Returns
    -------
    pixels : (n, 2) float
        Sub-pixel corner positions (OpenCV pixel centres).
    ids : (n,) int
        Their ids (rows of ``charuco_corners`` in the definition).
    problem : str or None
        Why there are none: no markers, or markers of another board.
    """
    det = cv2.aruco.CharucoDetector(CharucoSpec.from_definition(definition).opencv())
    corners, ids, _, mids = det.detectBoard(gray)
    ours = set(int(i) for i in definition["markers"]["ids"])
    if mids is None or len(mids) == 0:
        return np.zeros((0, 2)), np.zeros(0, int), "no markers of the board"
    if not ours & set(int(i) for i in mids.ravel()):
        return (
            np.zeros((0, 2)),
            np.zeros(0, int),
            f"markers of another board (ids {int(mids.min())} to {int(mids.max())})",
        )
    if ids is None:
        return np.zeros((0, 2)), np.zeros(0, int), "no ChArUco corners"
    return corners.reshape(-1, 2).astype(np.float64), ids.ravel(), None


@dataclass
class CameraCalibration:
    """Intrinsics of a camera, and how well they explain the views.

    Attributes
    ----------
    K : (3, 3) float
    dist : (5,) float
        k1, k2, p1, p2, k3 (k3 = 0 and fixed unless the corners cover the image).
    image_size : (W, H)
    rms_px : float
        Reprojection RMS over the views used.
    per_view : list of dict
        name, corners, rms_px, used, reason (when not used).
    k3_fixed : bool
    coverage : float
        Share of the image's 8 x 6 grid cells holding corners.
    residuals : list of (points (n, 2), residual vectors (n, 2))
        Per used view, for the residual picture.
    """

    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]
    rms_px: float
    per_view: list
    k3_fixed: bool
    coverage: float
    residuals: list = field(default_factory=list)


def calibrate_camera(images: list[tuple[str, np.ndarray]], definition: dict) -> CameraCalibration:
    """Camera intrinsics from photos of a ChArUco board (``cv2.calibrateCamera``).

    Views with fewer than MIN_CORNERS corners are left out with the reason; after a
    first calibration, views whose RMS exceeds three times the median (and 0.5 px) are
    left out as outliers and the calibration is redone. k3 is fitted only when the
    corners reach at least 70 % of the image (8 x 6 cells): otherwise it is
    unconstrained at the borders and only trades off against k1 and k2.

    Parameters
    ----------
    images : list of (name, (H, W) uint8)
        The photos, all of one size.
    definition : dict
        Board definition (ChArUco corners in the board frame, mm).

    Returns
    -------
    CameraCalibration

    Raises
    ------
    WorkbenchError
        Images of different sizes, or fewer than MIN_VIEWS usable views.
    """
    sizes = {img.shape[:2] for _, img in images}
    if len(sizes) != 1:
        raise WorkbenchError(f"the photos have different sizes: {sorted((w, h) for h, w in sizes)}")
    H, W = sizes.pop()
    board_mm = np.asarray(definition["charuco_corners"]["board_mm"], dtype=np.float64)
    views, per_view = [], []
    for name, img in images:
        px, ids, problem = detect_corners(img, definition)
        if problem or len(ids) < MIN_CORNERS:
            per_view.append(
                {
                    "name": name,
                    "corners": int(len(ids)),
                    "used": False,
                    "reason": problem or f"too few corners ({len(ids)}, need {MIN_CORNERS})",
                }
            )
            continue
        obj = np.column_stack([board_mm[ids], np.zeros(len(ids))]).astype(np.float32)
        views.append((name, obj, px.astype(np.float32)))
        per_view.append({"name": name, "corners": int(len(ids)), "used": True})
    usable = [v for v in per_view if v["used"]]
    if len(usable) < MIN_VIEWS:
        reasons = "; ".join(f"{v['name']}: {v['reason']}" for v in per_view if not v["used"])
        raise WorkbenchError(
            f"{len(usable)} usable views of the board, need at least {MIN_VIEWS}" + (f" ({reasons})" if reasons else "")
        )
    cells = np.zeros((6, 8), dtype=bool)
    for _, _, px in views:
        cells[np.clip((px[:, 1] / H * 6).astype(int), 0, 5), np.clip((px[:, 0] / W * 8).astype(int), 0, 7)] = True
    coverage = float(cells.mean())
    flags = 0 if coverage >= K3_COVERAGE else cv2.CALIB_FIX_K3
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    for _round in range(2):
        used = [v for v in views]
        rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
            [v[1] for v in used], [v[2] for v in used], (W, H), None, None, flags=flags, criteria=crit
        )
        errs = []
        for (_name, obj, px), r, t in zip(used, rvecs, tvecs, strict=True):
            proj, _ = cv2.projectPoints(obj, r, t, K, dist)
            errs.append(float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - px) ** 2, axis=1)))))
        limit = max(3.0 * float(np.median(errs)), 0.5)
        bad = [k for k, e in enumerate(errs) if e > limit]
        if _round == 1 or not bad or len(used) - len(bad) < MIN_VIEWS:
            break
        for k in sorted(bad, reverse=True):
            name = used[k][0]
            for v in per_view:
                if v["name"] == name:
                    v.update(used=False, reason=f"outlier: reprojection RMS {errs[k]:.2f} px > {limit:.2f} px")
            views.pop(k)
    residuals = []
    for (name, obj, px), r, t, e in zip(views, rvecs, tvecs, errs, strict=True):
        proj, _ = cv2.projectPoints(obj, r, t, K, dist)
        residuals.append((px, proj.reshape(-1, 2) - px))
        for v in per_view:
            if v["name"] == name:
                v["rms_px"] = e
    return CameraCalibration(K, dist.ravel()[:5], (W, H), float(rms), per_view, bool(flags), coverage, residuals)


@dataclass
class PrinterScale:
    """A printer's scale, measured on a scan of its printed target.

    Attributes
    ----------
    scale_x, scale_y : float
        Printed length / intended length along the target's x and y.
    skew_deg : float
        Angle between the printed axes minus 90°.
    rotation_deg : float
        How the target lay on the scanner (not the printer's fault).
    rms_mm : float
        Residual of the affine fit.
    corners : int
        Corners used.
    """

    scale_x: float
    scale_y: float
    skew_deg: float
    rotation_deg: float
    rms_mm: float
    corners: int


def measure_printer(scan: np.ndarray, definition: dict, dpi: float) -> PrinterScale:
    """Scale of a printed ChArUco target from a flat scan at a known resolution.

    Corner positions in the scan (mm, from the scan's dpi; pixel centres at
    (i + 0.5) · 25.4 / dpi) against the board's: an affine fit, whose columns' lengths
    are the printed scales along the board's x and y and whose angle is the skew.

    Raises
    ------
    WorkbenchError
        No target, another board, too few corners.
    """
    px, ids, problem = detect_corners(scan, definition)
    if problem:
        raise WorkbenchError(f"the scan shows {problem}")
    if len(ids) < MIN_CORNERS:
        raise WorkbenchError(f"too few corners of the target in the scan ({len(ids)}, need {MIN_CORNERS})")
    board = np.asarray(definition["charuco_corners"]["board_mm"], dtype=np.float64)[ids]
    mm = (px + 0.5) * 25.4 / dpi
    A = np.column_stack([board, np.ones(len(board))])
    sol, *_ = np.linalg.lstsq(A, mm, rcond=None)  # mm = board @ M + t, M = sol[:2]
    M = sol[:2].T  # columns: images of the board's x and y axes
    res = A @ sol - mm
    ax, ay = M[:, 0], M[:, 1]
    cos = float(ax @ ay / (np.linalg.norm(ax) * np.linalg.norm(ay)))
    return PrinterScale(
        scale_x=float(np.linalg.norm(ax)),
        scale_y=float(np.linalg.norm(ay)),
        skew_deg=float(np.degrees(np.arccos(np.clip(cos, -1, 1))) - 90.0),
        rotation_deg=float(np.degrees(np.arctan2(ax[1], ax[0]))),
        rms_mm=float(np.sqrt(np.mean(np.sum(res**2, axis=1)))),
        corners=int(len(ids)),
    )
