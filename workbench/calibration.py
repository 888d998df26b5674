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
# two views whose common corners lie this close (median, px) are one pose taken twice: no new information
DUPLICATE_PX = 2.0
# the board's normal must turn this much between views, or the focal length is not determined
# (fronto-parallel or same-tilt views leave it to trade off against the distance)
MIN_TILT_SPREAD_DEG = 5.0
WARN_TILT_SPREAD_DEG = 15.0
# horizontal fields of view a board calibration can determine (a focal length beyond is a failed fit)
FOV_RANGE_DEG = (2.0, 170.0)
# what pdf accepts as a printer's scale (workbench.schemas.PRINTER_PROFILE), and a plausible skew
PRINTER_SCALE = (0.8, 1.25)
MAX_SKEW_DEG = 2.0
# what printers do: a laser or inkjet printer's scale error stays within a few tenths of a
# percent. Beyond 2 %, the likelier cause is the target (printed with fit-to-page, or
# another board's definition: a 15.9 mm target measured against 15 mm reads +6 %)
PLAUSIBLE_PRINTER_PCT = 2.0
COMMON_DPI = (72, 96, 100, 150, 200, 240, 300, 360, 400, 600, 720, 800, 1200, 1600, 2400, 4800)


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


def printer_scale_warnings(m: PrinterScale) -> list[str]:
    """Why a measured printer scale that pdf would accept is still unlike a printer's; empty when it is not.

    A scale beyond PLAUSIBLE_PRINTER_PCT in x or y: ``calibrate printer`` says so, and
    ``--strict`` refuses it until a second scan (``calibrate check``) confirms it.
    """
    out = []
    for axis, s in (("x", m.scale_x), ("y", m.scale_y)):
        pct = 100 * (s - 1)
        if abs(pct) > PLAUSIBLE_PRINTER_PCT:
            out.append(
                f"scale {axis} {pct:+.2f} % is beyond what printers do (within ±{PLAUSIBLE_PRINTER_PCT:g} %): was the "
                "target printed at 100 % (no fit to page), and is the board definition this target's? confirm with "
                "a second scan (workbench calibrate check PROFILE SCAN)"
            )
    return out


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
    tilt_spread_deg: float = 0.0
    warnings: list = field(default_factory=list)


def collinear(board_points: np.ndarray) -> bool:
    """Whether board points lie on one line (one row or column of corners): no homography, no pose."""
    centred = board_points - board_points.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    return len(s) < 2 or s[1] <= 1e-6 * max(s[0], 1e-12)


def duplicate_of(ids: np.ndarray, px: np.ndarray, earlier: list) -> str | None:
    """The name of an earlier view with the same pose (common corners within DUPLICATE_PX), or None."""
    for name, ids0, px0 in earlier:
        common, a, b = np.intersect1d(ids, ids0, return_indices=True)
        if len(common) >= 0.8 * max(len(ids), len(ids0)):
            if float(np.median(np.linalg.norm(px[a] - px0[b], axis=1))) <= DUPLICATE_PX:
                return name
    return None


def tilt_spread_deg(views: list, width: int, height: int) -> float:
    """Largest angle between the board's normals (in the camera frame) over all pairs of views.

    Each view is posed with a nominal camera (focal length the image width, principal point
    at the centre), not the calibrated one: views too alike make the calibration itself
    wrong (fx 82,000 px for fronto-parallel views), and their poses with it. A wrong focal
    length bends the angles a little but keeps fronto-parallel views fronto-parallel.
    """
    K0 = np.array([[width, 0.0, 0.5 * (width - 1)], [0.0, width, 0.5 * (height - 1)], [0.0, 0.0, 1.0]])
    normals = []
    for _name, obj, px in views:
        try:
            ok, rvec, _ = cv2.solvePnP(obj.astype(np.float64), px.astype(np.float64), K0, None)
        except cv2.error:
            ok = False
        if ok:
            normals.append(cv2.Rodrigues(rvec)[0][:, 2])
    if len(normals) < 2:
        return 0.0
    normals = np.array(normals)
    cos = np.clip(normals @ normals.T, -1.0, 1.0)
    return float(np.degrees(np.arccos(cos.min())))


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
    seen: list = []
    for name, img in images:
        px, ids, problem = detect_corners(img, definition)
        if not problem and len(ids) < MIN_CORNERS:
            problem = f"too few corners ({len(ids)}, need {MIN_CORNERS})"
        if not problem and collinear(board_mm[ids]):
            problem = f"its {len(ids)} corners lie on one line of the board: no pose from them"
        if not problem:
            twin = duplicate_of(ids, px, seen)
            if twin is not None:
                problem = f"near-duplicate of {twin} (the same pose: corners within {DUPLICATE_PX:g} px)"
        if problem:
            per_view.append({"name": name, "corners": int(len(ids)), "used": False, "reason": problem})
            continue
        seen.append((name, ids, px))
        obj = np.column_stack([board_mm[ids], np.zeros(len(ids))]).astype(np.float32)
        views.append((name, obj, px.astype(np.float32)))
        per_view.append({"name": name, "corners": int(len(ids)), "used": True})
    usable = [v for v in per_view if v["used"]]
    if len(usable) < MIN_VIEWS:
        reasons = "; ".join(f"{v['name']}: {v['reason']}" for v in per_view if not v["used"])
        raise WorkbenchError(
            f"{len(usable)} usable views of the board, need at least {MIN_VIEWS}" + (f" ({reasons})" if reasons else "")
        )
    check_views_vary(views, W, H)
    cells = np.zeros((6, 8), dtype=bool)
    for _, _, px in views:
        cells[np.clip((px[:, 1] / H * 6).astype(int), 0, 5), np.clip((px[:, 0] / W * 8).astype(int), 0, 7)] = True
    coverage = float(cells.mean())
    flags = 0 if coverage >= K3_COVERAGE else cv2.CALIB_FIX_K3
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    for _round in range(2):
        used = [v for v in views]
        try:
            rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
                [v[1] for v in used], [v[2] for v in used], (W, H), None, None, flags=flags, criteria=crit
            )
        except cv2.error as exc:
            detail = str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV error"
            raise WorkbenchError(f"the calibration of {len(used)} views failed ({detail})") from None
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
    cal = CameraCalibration(K, dist.ravel()[:5], (W, H), float(rms), per_view, bool(flags), coverage, residuals)
    check_camera_calibration(cal, tilt_spread_deg(views, W, H))
    return cal


def check_views_vary(views: list, width: int, height: int) -> float:
    """The views' tilt spread (degrees); refuses views too alike before any calibration.

    Raises
    ------
    WorkbenchError
        The board's normal turns less than MIN_TILT_SPREAD_DEG between views.
    """
    spread = tilt_spread_deg(views, width, height)
    if spread < MIN_TILT_SPREAD_DEG:
        raise WorkbenchError(
            f"the board faces the camera the same way in every view (its normal turns {spread:.1f} degrees at "
            f"most): the focal length is not determined; {TILT_ADVICE}"
        )
    return spread


TILT_ADVICE = "tilt the board (or the camera) by 20 to 45 degrees in different directions between photos"


def check_camera_calibration(cal: CameraCalibration, spread: float) -> None:
    """Refuse intrinsics no camera has, or views too alike to determine them; warn when barely enough.

    Raises
    ------
    WorkbenchError
        Non-finite or non-positive focal lengths, a field of view outside FOV_RANGE_DEG,
        or a principal point off the image.
    """
    from workbench.camera import intrinsics_problem

    W, H = cal.image_size
    problem = intrinsics_problem(cal.K, W, H)
    if problem is None and np.isfinite(cal.K).all():
        fov = float(np.degrees(2 * np.arctan(0.5 * W / cal.K[0, 0]))) if cal.K[0, 0] > 0 else 0.0
        lo, hi = FOV_RANGE_DEG
        if not lo <= fov <= hi:
            problem = f"fx {cal.K[0, 0]:.0f} px is a field of view of {fov:.2f} degrees, outside {lo:g} to {hi:g}"
    if problem is not None or not np.isfinite(cal.dist).all():
        raise WorkbenchError(
            f"the calibration gives no plausible camera: {problem or 'dist: not finite'}; {TILT_ADVICE}"
        )
    cal.tilt_spread_deg = spread
    if spread < WARN_TILT_SPREAD_DEG:
        cal.warnings.append(f"little tilt variety ({spread:.1f} degrees at most between views): {TILT_ADVICE}")


def likely_dpi(dpi: float, scale: float) -> float:
    """The common scanner resolution that would make a measured ``scale`` at ``dpi`` nearest 1."""
    true_dpi = dpi * scale  # lengths in mm scale as 1 / dpi
    return min(COMMON_DPI, key=lambda d: abs(np.log(d / true_dpi)))


def check_printer_scale(m: PrinterScale, dpi: float, tagged: bool, scan: str) -> None:
    """Refuse a measured printer scale that ``workbench pdf`` would refuse, with its likely cause.

    Parameters
    ----------
    m : PrinterScale
        The measurement.
    dpi : float
        The resolution it assumed.
    tagged : bool
        Whether the scan file records its dpi (then a wrong --dpi was already refused).
    scan : str
        The scan, for the message.

    Raises
    ------
    WorkbenchError
        Scale outside PRINTER_SCALE, or skew beyond MAX_SKEW_DEG.
    """
    lo, hi = PRINTER_SCALE
    for axis, s in (("x", m.scale_x), ("y", m.scale_y)):
        if not lo <= s <= hi:
            guess = likely_dpi(dpi, float(np.sqrt(m.scale_x * m.scale_y)))
            cause = (
                f"the likely cause is the resolution: the scan records no dpi and --dpi {dpi:g} was given; "
                f"at {guess:g} dpi the scale would be {100 * (s * dpi / guess - 1):+.2f} %"
                if not tagged
                else "is the scan of this board's target, printed at 100 % (no fit to page)?"
            )
            raise WorkbenchError(
                f"{scan}: measured scale {axis} {100 * (s - 1):+.1f} % is not a printer's (pdf accepts "
                f"{lo:g} to {hi:g}); {cause}"
            )
    if abs(m.skew_deg) > MAX_SKEW_DEG:
        raise WorkbenchError(
            f"{scan}: measured skew {m.skew_deg:+.2f} degrees is not a printer's (at most {MAX_SKEW_DEG:g}): "
            "was the target flat on the scanner?"
        )


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
