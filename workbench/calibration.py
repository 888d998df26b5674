"""Calibration: camera intrinsics from ChArUco photos, printer scale from a scanned target."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from workbench.calibration_coverage import board_normals, grid_rms, photo_coverage
from workbench.errors import WorkbenchError
from workbench.printing.boards import CharucoSpec, ChessboardSpec, board_points_mm, is_chessboard

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
    """Corners of a board in an image: ChArUco corners, or a chessboard's inner corners.

    Returns
    -------
    pixels : (n, 2) float
        Sub-pixel corner positions (OpenCV pixel centres).
    ids : (n,) int
        Their ids (rows of the definition's corners).
    problem : str or None
        Why there are none: no markers, markers of another board, markers but no
        corners (the layout or the square count may not match), no chessboard.
    """
    if is_chessboard(definition):
        return detect_chessboard(gray, definition)
    spec = CharucoSpec.from_definition(definition)
    corners, ids, _, mids = cv2.aruco.CharucoDetector(spec.opencv()).detectBoard(gray)
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
        return np.zeros((0, 2)), np.zeros(0, int), no_corners_reason(gray, spec, len(mids))
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


def no_corners_reason(gray: np.ndarray, spec: CharucoSpec, n_markers: int) -> str:
    """Why a photo shows markers of a ChArUco board but none of its corners; tries the other layout."""
    other = replace(spec, legacy=not spec.legacy)
    _, ids, _, _ = cv2.aruco.CharucoDetector(other.opencv()).detectBoard(gray)
    if ids is not None and len(ids):
        which = "the legacy (pre-4.6 OpenCV) layout" if other.legacy else "today's layout (OpenCV 4.6 and later)"
        return (
            f"{n_markers} markers found but no ChArUco corners: the board is printed in {which}; "
            f'set "legacy": {"true" if other.legacy else "false"} in the board definition'
        )
    return (
        f"{n_markers} markers found but no ChArUco corners: the board's layout (legacy, pre-4.6 OpenCV, for an "
        f"even number of rows) or its square count ({spec.squares[0]} x {spec.squares[1]}) may not match the definition"
    )


def detect_chessboard(gray: np.ndarray, definition: dict) -> tuple[np.ndarray, np.ndarray, str | None]:
    """A chessboard's inner corners (``cv2.findChessboardCornersSB``): all of them, or none.

    The board has no markers, so the whole board must be in the photo; a board whose
    inner corners are odd by even may be numbered from either end (a half turn), which
    changes each view's pose, not the intrinsics.
    """
    spec = ChessboardSpec.from_definition(definition)
    flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    ok, corners = cv2.findChessboardCornersSB(gray, spec.inner, flags=flags)
    if not ok or corners is None:
        nx, ny = spec.inner
        return (
            np.zeros((0, 2)),
            np.zeros(0, int),
            f"no chessboard of {nx} x {ny} inner corners (the whole board must be in the photo)",
        )
    px = corners.reshape(-1, 2).astype(np.float64)
    return top_left_first(gray, px, spec.inner[0]), np.arange(len(px)), None


def top_left_first(gray: np.ndarray, px: np.ndarray, across: int) -> np.ndarray:
    """A chessboard's corners numbered from its black top-left square.

    The detector numbers the inner corners from either end. The square diagonally
    outside corner 0 is the board's top-left one, black; where the square outside the
    last corner is the darker, the numbering runs from the other end (a half turn) and
    is reversed. A board whose two outer squares are both black (odd by odd squares) is
    the same after a half turn: either numbering is right.
    """

    def outer_square(a, b, c):  # centre of the square diagonally outside corner a, away from b (row) and c (column)
        return a - 0.5 * (b - a) - 0.5 * (c - a)

    first = outer_square(px[0], px[1], px[across])
    last = outer_square(px[-1], px[-2], px[-1 - across])
    H, W = gray.shape[:2]

    def level(p):
        x, y = int(round(p[0])), int(round(p[1]))
        if not (0 <= x < W and 0 <= y < H):
            return None
        return float(gray[max(y - 1, 0) : y + 2, max(x - 1, 0) : x + 2].mean())

    a, b = level(first), level(last)
    if a is not None and b is not None and b < a - 20:
        return px[::-1].copy()
    return px


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
    std, std_opencv : (4,) float
        Standard deviations of fx, fy, cx, cy (px): the larger of OpenCV's and the
        views' scatter, and OpenCV's alone.
    view_limit_px : float
        The largest reprojection RMS of a view that agrees with the others.
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
    std: np.ndarray | None = None  # (4,) fx, fy, cx, cy standard deviations (px): the larger of the two below
    std_opencv: np.ndarray | None = None  # (4,) OpenCV's, from the corner noise alone
    view_limit_px: float = 0.5  # largest RMS of a view that agrees with the others (calibrate check's limit)
    used_views: list = field(default_factory=list)  # the views used: (name, (n, 3) board mm, (n, 2) px)
    frame_coverage: dict = field(default_factory=dict)  # :func:`photo_coverage` of the views used


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
    normals = board_normals(views, width, height)
    if len(normals) < 2:
        return 0.0
    cos = np.clip(normals @ normals.T, -1.0, 1.0)
    return float(np.degrees(np.arccos(cos.min())))


def name_list(names: list[str], most: int = 3) -> str:
    """Names for a one-line message: the first ``most``, then how many more."""
    shown = ", ".join(names[:most])
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")


def check_sizes(images: list[tuple[str, np.ndarray]], expected: tuple[int, int] | None = None) -> tuple[int, int]:
    """The photos' common size (W, H); refuses, naming it, the first photo of another size.

    Parameters
    ----------
    images : list of (name, (H, W) uint8)
    expected : (W, H), optional
        The size the photos must have (a profile's image size); default the first photo's.
    """
    H0, W0 = images[0][1].shape[:2]
    W, H = expected if expected is not None else (W0, H0)
    for name, img in images:
        h, w = img.shape[:2]
        if (w, h) != (W, H):
            whose = "the profile is for" if expected is not None else f"{images[0][0]} (the first photo) is"
            raise WorkbenchError(
                f"{name}: {w} x {h} pixels, but {whose} {W} x {H}: another camera or another video mode"
            )
    return int(W), int(H)


def board_views(
    images: list[tuple[str, np.ndarray]],
    definition: dict,
    camera: tuple | None = None,
    grid_limit_px: float | None = None,
) -> tuple[list, list]:
    """The board's corners in each photo, and why a photo cannot serve as a view.

    A photo is left out (with its reason) when it shows no board, too few corners,
    corners on one line of the board, corners off the flat grid they were matched to
    (:func:`grid_rms` above ``grid_limit_px``), or the same pose as an earlier photo.

    Parameters
    ----------
    images : list of (name, (H, W) uint8)
    definition : dict
        The board.
    camera : (K, dist), optional
        A profile's intrinsics, to take the distortion out before the flat-grid test.
    grid_limit_px : float, optional
        The largest :func:`grid_rms` of a view, px (a profile's limit for a view's
        reprojection: a homography fits at least as well as a pose); by default
        :func:`view_rms_limit` of the photos' own median.

    Returns
    -------
    views : list of (name, (n, 3) float32 board points in mm, (n, 2) float32 pixels)
    per_view : list of dict
        name, corners, used, and reason when not used; in the photos' order.
    """
    board_mm = board_points_mm(definition)
    found = [(name, *detect_corners(img, definition)) for name, img in images]
    # (the flat-grid test against the photos' own median: a set taken through a strongly
    # distorting lens bends every view's grid alike; on a real webcam's chessboard, good
    # views fit to 0.05 to 0.2 px, the views read one square off to 2.3 to 3.5 px)
    grids = [grid_rms(board_mm[ids], px, camera) if not problem else np.nan for _, px, ids, problem in found]
    usable = [g for g in grids if np.isfinite(g)]
    grid_limit = grid_limit_px
    if grid_limit is None:
        grid_limit = view_rms_limit(np.array(usable)) if usable else np.inf
    views, per_view, seen = [], [], []
    for (name, px, ids, problem), grid in zip(found, grids, strict=True):
        if not problem and len(ids) < MIN_CORNERS:
            problem = f"too few corners ({len(ids)}, need {MIN_CORNERS})"
        if not problem and collinear(board_mm[ids]):
            problem = f"its {len(ids)} corners lie on one line of the board: no pose from them"
        if not problem and not grid <= grid_limit:
            problem = (
                f"its corners lie off the board's flat grid by {grid:.2f} px RMS (limit {grid_limit:.2f} px): "
                "matched to the wrong squares"
            )
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
        per_view.append({"name": name, "corners": int(len(ids)), "used": True, "grid_rms_px": round(grid, 4)})
    return views, per_view


def corner_coverage(views: list, width: int, height: int) -> float:
    """Share of the image's 8 x 6 grid cells that hold at least one corner of some view."""
    cells = np.zeros((6, 8), dtype=bool)
    for _, _, px in views:
        rows = np.clip((px[:, 1] / height * 6).astype(int), 0, 5)
        cols = np.clip((px[:, 0] / width * 8).astype(int), 0, 7)
        cells[rows, cols] = True
    return float(cells.mean())


CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)


def fit_intrinsics(views: list, width: int, height: int, flags: int, guess: tuple | None = None) -> tuple:
    """``cv2.calibrateCameraExtended`` over the views.

    ``guess`` (K, dist) starts the fit from known intrinsics (with
    ``cv2.CALIB_USE_INTRINSIC_GUESS`` in ``flags``; distortion held with the FIX flags).

    Returns
    -------
    rms : float
        Reprojection RMS over all corners, px.
    K : (3, 3) float
    dist : (5,) float
    rvecs, tvecs : list of (3, 1) float
        Each view's pose.
    std : (4,) float
        OpenCV's standard deviations of fx, fy, cx, cy (px), which assume independent
        corner errors of the RMS's size.
    errs : (n,) float
        Each view's reprojection RMS, px.

    Raises
    ------
    WorkbenchError
        OpenCV could not calibrate.
    """
    try:
        K0, d0 = (None, None) if guess is None else (guess[0].copy(), guess[1].copy())
        rms, K, dist, rvecs, tvecs, std, _, _ = cv2.calibrateCameraExtended(
            [v[1] for v in views], [v[2] for v in views], (width, height), K0, d0, flags=flags, criteria=CRITERIA
        )
    except cv2.error as exc:
        detail = str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV error"
        raise WorkbenchError(f"the calibration of {len(views)} views failed ({detail})") from None
    errs = []
    for (_name, obj, px), r, t in zip(views, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(obj, r, t, K, dist)
        errs.append(float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - px) ** 2, axis=1)))))
    return float(rms), K, dist.ravel()[:5], rvecs, tvecs, std.ravel()[:4].astype(np.float64), np.array(errs)


JACKKNIFE_GROUPS = 10


def jackknife_std(views: list, width: int, height: int, flags: int, guess: tuple | None = None) -> np.ndarray | None:
    """Standard deviations of fx, fy, cx, cy (px) from the views' own scatter (grouped jackknife).

    The views are dealt into G = min(n, JACKKNIFE_GROUPS) groups of neighbours in their
    order (photos taken one after another share a pose's neighbourhood; frames of a video are
    near duplicates, and dealt one by one into every group they would leave each refit its
    left-out views' twins: on a webcam's video split into blocks of 10 frames, the check's z
    scattered 2 to 2.8 times its stated deviation); each group is left out
    in turn and the intrinsics refitted; the spread of the G refits, scaled by
    sqrt((G - 1) / G · Σ(θ_g - θ̄)²), estimates the standard error of the full fit. Unlike
    OpenCV's figures it includes what real photos add to the corner noise (a board not
    flat, corner errors that repeat within a photo): on real photos OpenCV's figures fall
    short by a factor 2 to 8.

    Returns
    -------
    (4,) float or None
        None when fewer than 3 refits succeed.
    """
    n = len(views)
    G = min(n, JACKKNIFE_GROUPS)
    if G < 3:
        return None
    thetas = []
    for g in range(G):
        rest = [v for k, v in enumerate(views) if k * G // n != g]
        try:
            _, K, *_ = fit_intrinsics(rest, width, height, flags, guess)
        except WorkbenchError:
            continue
        thetas.append([K[0, 0], K[1, 1], K[0, 2], K[1, 2]])
    if len(thetas) < 3:
        return None
    t = np.asarray(thetas)
    m = len(t)
    return np.sqrt((m - 1) / m * np.sum((t - t.mean(axis=0)) ** 2, axis=0))


def view_rms_limit(errs: np.ndarray) -> float:
    """Largest reprojection RMS (px) of a view that agrees with the others: 3 x the median, at least 0.5."""
    return max(3.0 * float(np.median(errs)), 0.5)


def calibrate_camera(images: list[tuple[str, np.ndarray]], definition: dict) -> CameraCalibration:
    """Camera intrinsics from photos of a board (``cv2.calibrateCameraExtended``).

    Views with fewer than MIN_CORNERS corners are left out with the reason; after a
    first calibration, views whose RMS exceeds three times the median (and 0.5 px) are
    left out as outliers and the calibration is redone. k3 is fitted only when the
    corners reach at least 70 % of the image (8 x 6 cells): otherwise it is
    unconstrained at the borders and only trades off against k1 and k2. The
    uncertainty of fx, fy, cx, cy is the larger of OpenCV's and the views' own scatter
    (:func:`jackknife_std`): what ``calibrate check`` measures drift against.

    Parameters
    ----------
    images : list of (name, (H, W) uint8)
        The photos, all of one size.
    definition : dict
        Board definition (corners in the board frame, mm).

    Returns
    -------
    CameraCalibration

    Raises
    ------
    WorkbenchError
        Images of different sizes (naming the first odd one), or fewer than MIN_VIEWS
        usable views.
    """
    W, H = check_sizes(images)
    views, per_view = board_views(images, definition)
    return calibrate_views(views, per_view, W, H)


def calibrate_views(views: list, per_view: list, W: int, H: int) -> CameraCalibration:
    """:func:`calibrate_camera` on corners already found (:func:`board_views`).

    ``views`` and ``per_view`` are changed in place (outliers left out, each view's RMS).
    Split from :func:`calibrate_camera` so that a measurement of the check's power
    (``benchmarks/bench_calibrate_check.py``) runs this very code on many subsets of
    the photos without detecting their corners again.

    Raises
    ------
    WorkbenchError
        Fewer than MIN_VIEWS usable views, views too alike, or no plausible camera.
    """
    if len(views) < MIN_VIEWS:
        reasons = [f"{v['name']}: {v['reason']}" for v in per_view if not v["used"]]
        raise WorkbenchError(
            f"{len(views)} usable views of the board, need at least {MIN_VIEWS}"
            + (f" ({name_list(reasons)})" if reasons else "")
        )
    check_views_vary(views, W, H)
    coverage = corner_coverage(views, W, H)
    flags = 0 if coverage >= K3_COVERAGE else cv2.CALIB_FIX_K3
    for _round in range(2):
        rms, K, dist, rvecs, tvecs, std, errs = fit_intrinsics(views, W, H, flags)
        limit = view_rms_limit(errs)
        bad = [k for k, e in enumerate(errs) if e > limit]
        if _round == 1 or not bad or len(views) - len(bad) < MIN_VIEWS:
            break
        for k in sorted(bad, reverse=True):
            name = views[k][0]
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
                v["rms_px"] = float(e)
    cal = CameraCalibration(K, dist, (W, H), rms, per_view, bool(flags), coverage, residuals)
    cal.std_opencv = std
    jack = jackknife_std(views, W, H, flags)
    cal.std = std if jack is None else np.maximum(std, jack)
    cal.view_limit_px = view_rms_limit(errs)
    cal.used_views = list(views)
    cal.frame_coverage = photo_coverage(views, W, H)
    check_camera_calibration(cal, tilt_spread_deg(views, W, H))
    over = [v["name"] for v in per_view if v["used"] and v["rms_px"] > cal.view_limit_px]
    if over:
        cal.warnings.append(
            f"{len(over)} of {len(views)} views would fail calibrate check (reprojection RMS above "
            f"{cal.view_limit_px:.2f} px): {name_list(over)}"
        )
    return cal


INTRINSICS = ("fx", "fy", "cx", "cy")
HOLD_DISTORTION = (
    cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_FIX_TANGENT_DIST
)
# fewer photos than this cannot tell their own scatter (one photo's focal length hangs on its tilt)
MIN_FOCAL_VIEWS = 3
TOLERANCE_SIGMA = 3.0  # a re-measured intrinsic this many standard deviations from the profile's has drifted


def pose_rms(obj: np.ndarray, px: np.ndarray, K: np.ndarray, dist: np.ndarray) -> float | None:
    """Reprojection RMS (px) of one view posed with fixed intrinsics (SQPnP, then LM); None without a pose."""
    obj, px = obj.astype(np.float64), px.astype(np.float64)
    try:
        _, rvec, tvec = cv2.solvePnP(obj, px, K, dist, flags=cv2.SOLVEPNP_SQPNP)
        rvec, tvec = cv2.solvePnPRefineLM(obj, px, K, dist, rvec, tvec)
        proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    except cv2.error:
        return None
    return float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - px) ** 2, axis=1))))


def ray_shift_px(K0, dist0, K1, dist1, width: int, height: int, n: int = 17) -> float:
    """Largest shift (px) across the image between two lens models seeing the same rays.

    Each point of an n x n grid over the image is taken back to its ray through the first
    model and projected again through the second: a focal length error shows as a shift
    growing towards the borders, a principal point error as a shift everywhere.
    """
    xs, ys = np.meshgrid(np.linspace(0, width - 1, n), np.linspace(0, height - 1, n))
    px = np.stack([xs.ravel(), ys.ravel()], axis=1).reshape(-1, 1, 2)
    rays = cv2.undistortPoints(px, K0, dist0, None, None, None, CRITERIA).reshape(-1, 2)
    obj = np.column_stack([rays, np.ones(len(rays))])
    back, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), K1, dist1)
    return float(np.linalg.norm(back.reshape(-1, 2) - px.reshape(-1, 2), axis=1).max())


@dataclass
class CameraCheck:
    """A camera profile re-measured on new photos of its board.

    Attributes
    ----------
    per_photo : list of dict
        name, corners, used, reason (left out), rms_px (posed with the stored
        intrinsics), ok.
    limit_px : float
        The per-photo RMS limit.
    remeasured : dict or None
        For each re-measured intrinsic (fx, fy, cx, cy; fx alone with few photos),
        ``value``, ``profile``, ``delta`` (px), ``sigma`` (combined standard deviation,
        px), ``z``, ``limit`` (the largest |z| that is no drift: :func:`z_limits`) and
        ``dof`` (the combined deviation's degrees of freedom); and ``views``, ``rms_px``,
        ``ray_shift_px`` (largest shift across the image), ``measured`` (the names). None
        when even a focal length could not be fitted.
    why_not : str or None
        Why fx, fy, cx, cy were not all re-measured.
    tolerance_sigma : float
    drift : list of str
        What drifted (empty: within tolerance).
    """

    per_photo: list
    limit_px: float
    remeasured: dict | None
    why_not: str | None
    tolerance_sigma: float
    drift: list
    used_views: list = field(default_factory=list)  # the views checked: (name, (n, 3) board mm, (n, 2) px)
    frame_coverage: dict = field(default_factory=dict)  # :func:`photo_coverage` of them


def stored_view_limit(profile: dict, tolerance_px: float | None = None) -> float:
    """The largest reprojection RMS of a photo that agrees with a profile, px: ``tolerance_px`` or the profile's own."""
    if tolerance_px is not None:
        return float(tolerance_px)
    stored_limit = profile.get("view_rms_limit_px")
    return float(stored_limit or view_rms_limit(np.array([float(profile.get("rms_px") or 0.0)])))


def check_camera(
    images: list[tuple[str, np.ndarray]],
    definition: dict,
    profile: dict,
    tolerance_px: float | None = None,
    tolerance_sigma: float = TOLERANCE_SIGMA,
) -> CameraCheck:
    """Re-measure a camera profile on photos of its board.

    Two tests. Each photo is posed with the stored intrinsics and its reprojection RMS
    must stay within ``tolerance_px`` (default: the profile's own limit for a view that
    agrees with the others). A pose absorbs most of an intrinsics error (a focal length
    5 % off moves the RMS from 0.25 to below 0.5 px), so the intrinsics are also
    re-measured from the photos, the profile's distortion held, and each must lie within
    ``tolerance_sigma`` combined standard deviations (the profile's and the
    re-measurement's, each from its views' scatter) of the stored value, widened to
    Student's t where a deviation comes from few photos (:func:`z_limits`). With MIN_VIEWS
    usable photos whose board normals turn at least MIN_TILT_SPREAD_DEG, fx, fy, cx and cy
    are re-measured; with MIN_FOCAL_VIEWS or more, or too little tilt, the focal length
    alone (principal point and aspect held): the intrinsic a pose absorbs by moving closer
    or farther, which each tilted photo still fixes. With fewer, the per-photo test alone.

    Parameters
    ----------
    images : list of (name, (H, W) uint8)
    definition : dict
        The profile's board.
    profile : dict
        A camera profile (``calibrate camera``'s JSON).
    tolerance_px, tolerance_sigma : float, optional

    Returns
    -------
    CameraCheck

    Raises
    ------
    WorkbenchError
        A photo of another size than the profile's (naming it), or no photo showing the board.
    """
    check_sizes(images, tuple(int(v) for v in profile["image_size"]))
    K0 = np.asarray(profile["K"], dtype=np.float64)
    dist0 = np.zeros(5)
    d = np.asarray(profile.get("dist") or [], dtype=np.float64).ravel()[:5]
    dist0[: len(d)] = d
    views, per_photo = board_views(images, definition, (K0, dist0), stored_view_limit(profile, tolerance_px))
    if not views:
        raise WorkbenchError(
            "no photo shows the board: "
            + name_list([f"{v['name']}: {v['reason']}" for v in per_photo if not v["used"]])
        )
    checked = check_views(views, per_photo, profile, tolerance_px, tolerance_sigma)
    W, H = (int(v) for v in profile["image_size"])
    return replace(checked, used_views=list(views), frame_coverage=photo_coverage(views, W, H))


def check_views(
    views: list,
    per_photo: list,
    profile: dict,
    tolerance_px: float | None = None,
    tolerance_sigma: float = TOLERANCE_SIGMA,
) -> CameraCheck:
    """:func:`check_camera` on corners already found (:func:`board_views`); ``per_photo`` is changed in place.

    Split from :func:`check_camera` so that a measurement of the check's power
    (``benchmarks/bench_calibrate_check.py``) runs this very code on many subsets.
    """
    W, H = (int(v) for v in profile["image_size"])
    K0 = np.asarray(profile["K"], dtype=np.float64)
    dist0 = np.zeros(5)
    d = np.asarray(profile.get("dist") or [], dtype=np.float64).ravel()[:5]
    dist0[: len(d)] = d
    tolerance_px = stored_view_limit(profile, tolerance_px)
    drift = []
    # the used entries are the views, in order (by name, a photo given twice was the wrong one of two)
    used_entries = [v for v in per_photo if v["used"]]
    for (_, obj, px), entry in zip(views, used_entries, strict=True):
        e = pose_rms(obj, px, K0, dist0)
        entry["rms_px"] = e
        entry["ok"] = e is not None and e <= tolerance_px
    bad = [v["name"] for v in per_photo if v["used"] and not v["ok"]]
    if bad:
        drift.append(
            f"reprojection RMS above {tolerance_px:.2f} px in {len(bad)} of {len(views)} photos ({name_list(bad)})"
        )
    remeasured, why_not = None, None
    spread = tilt_spread_deg(views, W, H)
    # the profile's distortion held: the errors it shares with the profile's fx, fy, cx, cy
    # cancel in the difference, and a few photos need not reach the borders
    flags, names = HOLD_DISTORTION, INTRINSICS
    if len(views) < MIN_FOCAL_VIEWS:
        why_not = (
            f"{len(views)} usable photos: re-measuring the focal length needs {MIN_FOCAL_VIEWS}, "
            f"fx, fy, cx, cy {MIN_VIEWS}"
        )
        return CameraCheck(per_photo, float(tolerance_px), None, why_not, float(tolerance_sigma), drift)
    if len(views) < MIN_VIEWS or spread < MIN_TILT_SPREAD_DEG:
        why_not = (
            f"{len(views)} usable photos, re-measuring fx, fy, cx, cy needs {MIN_VIEWS}"
            if len(views) < MIN_VIEWS
            else f"the board's normal turns {spread:.1f} degrees at most between photos, need {MIN_TILT_SPREAD_DEG:g}"
        )
        # fewer photos still fix one focal length (each tilted view gives two of Zhang's
        # constraints): the principal point and the aspect held, a pose cannot absorb it
        flags, names = HOLD_DISTORTION | cv2.CALIB_FIX_PRINCIPAL_POINT | cv2.CALIB_FIX_ASPECT_RATIO, ("fx",)
    try:
        rms, K, dist, _, _, std, _ = fit_intrinsics(views, W, H, flags, (K0, dist0))
    except WorkbenchError as exc:
        why_not = f"{why_not}; {exc}" if why_not else str(exc)
        return CameraCheck(per_photo, float(tolerance_px), None, why_not, float(tolerance_sigma), drift)
    stored = profile.get("intrinsics_std") or {}
    std0 = np.array([float(stored.get(k, 0.0)) for k in INTRINSICS])
    stored_cv = profile.get("intrinsics_std_opencv") or {}
    std0_cv = np.array([float(stored_cv.get(k, 0.0)) for k in INTRINSICS])
    n_profile = sum(1 for v in profile.get("views") or [] if v.get("used"))
    # each standard deviation's degrees of freedom: a jackknife over G groups has G - 1
    # where it is the larger (OpenCV's, from thousands of corners, has as good as infinitely many)
    dof0 = np.where(std0 > std0_cv, max(min(n_profile, JACKKNIFE_GROUPS) - 1, 1), np.inf)
    jack = jackknife_std(views, W, H, flags, (K0, dist0))
    dof = np.full(4, np.inf)
    if jack is not None:
        dof = np.where(jack > std, min(len(views), JACKKNIFE_GROUPS) - 1.0, np.inf)
        std = np.maximum(std, jack)
    if stored and n_profile and (jack is None or len(names) < len(INTRINSICS)):
        # too few photos for their own scatter to be trusted: at least what the profile's photos
        # showed, for as many photos as these (a standard deviation shrinks as 1 / sqrt(views)),
        # and the confidence of the profile's (its degrees of freedom), not of a jackknife of 3 or 4
        std = np.maximum(std, std0 * np.sqrt(n_profile / len(views)))
        dof = dof0
    theta = np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2]])
    theta0 = np.array([K0[0, 0], K0[1, 1], K0[0, 2], K0[1, 2]])
    sigma = np.sqrt(std**2 + std0**2)
    z = (theta - theta0) / np.maximum(sigma, 1e-12)
    limit, nu = z_limits(tolerance_sigma, std0, dof0, std, dof)
    remeasured = {
        k: {
            "value": float(theta[i]),
            "profile": float(theta0[i]),
            "delta": float(theta[i] - theta0[i]),
            "sigma": float(sigma[i]),
            "z": float(z[i]),
            "limit": float(limit[i]),
            "dof": float(nu[i]),
            "sigma_profile": float(std0[i]),
            "sigma_photos": float(std[i]),
        }
        for i, k in enumerate(INTRINSICS)
        if k in names
    }
    remeasured.update(
        views=len(views),
        rms_px=rms,
        ray_shift_px=ray_shift_px(K0, dist0, K, dist, W, H),
        profile_uncertainty=bool(stored),
        measured=list(names),
    )
    off = [
        f"{k} {theta[i]:.2f} against {theta0[i]:.2f} px ({z[i]:+.1f} sigma, limit {limit[i]:.1f})"
        for i, k in enumerate(INTRINSICS)
        if k in names and abs(z[i]) > limit[i]
    ]
    if off:
        drift.append("re-measured " + ", ".join(off) + f" (tolerance {tolerance_sigma:g} sigma)")
    return CameraCheck(per_photo, float(tolerance_px), remeasured, why_not, float(tolerance_sigma), drift)


def z_limits(
    tolerance_sigma: float, std0: np.ndarray, dof0: np.ndarray, std: np.ndarray, dof: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The largest |z| of a re-measured intrinsic that is no drift, and its degrees of freedom.

    ``tolerance_sigma`` is a confidence in the units of a normal distribution: 3 leaves a
    true profile 0.27 % of failing an intrinsic. A standard deviation estimated from the
    scatter of a few photos (the jackknife, G - 1 degrees of freedom) is itself uncertain,
    and a z divided by it has Student's t distribution, whose tails are heavier: with 5
    photos (4 degrees of freedom) |z| exceeds 3 in 4 % of true profiles, not 0.27 %. So
    the limit is the t quantile of the same tail probability, with the degrees of freedom
    of the combined standard deviation (Welch-Satterthwaite); it is ``tolerance_sigma``
    itself when both deviations are OpenCV's (infinitely many).

    Parameters
    ----------
    tolerance_sigma : float
    std0, dof0 : (4,) float
        The profile's standard deviations of fx, fy, cx, cy and their degrees of freedom.
    std, dof : (4,) float
        The re-measurement's.

    Returns
    -------
    limit, dof : (4,) float
    """
    from scipy.stats import norm, t

    a, b = np.asarray(std0, float) ** 2, np.asarray(std, float) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = np.where(np.isfinite(dof0), a**2 / dof0, 0.0) + np.where(np.isfinite(dof), b**2 / dof, 0.0)
        nu = np.where(den > 0, (a + b) ** 2 / np.where(den > 0, den, 1.0), np.inf)
    tail = norm.sf(tolerance_sigma)
    limit = np.where(np.isfinite(nu), t.isf(tail, np.where(np.isfinite(nu), nu, 1.0)), tolerance_sigma)
    return limit, nu


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
    board = board_points_mm(definition)[ids]
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
