"""Camera pose from the fixture's ChArUco corners."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workbench.camera import Camera
from workbench.printing.boards import CharucoSpec


@dataclass
class Pose:
    """Where the camera was, from the markers it saw.

    Attributes
    ----------
    camera : Camera
        Intrinsics and distortion of the profile, pose estimated (mesh frame).
    rms_px : float
        Reprojection RMS of the corners used, pixels.
    n_corners : int
        ChArUco corners used.
    n_markers : int
        Markers detected.
    marker_ids : (m,) int
        Their ids.
    n_dropped : int
        Corners left out as outliers (:func:`corner_outliers`).
    """

    camera: Camera
    rms_px: float
    n_corners: int
    n_markers: int
    marker_ids: np.ndarray
    n_dropped: int = 0


class PoseError(Exception):
    """No pose: the reason, for an INVALID verdict."""


# a corner's reprojection error (a 2-D length) against the corners' own scatter: with each axis
# normal of deviation sigma the length is Rayleigh, its median 1.1774 sigma, and it exceeds
# 3.717 sigma (the chi-square of 2 degrees of freedom at 0.999) once in a thousand
RAYLEIGH_MEDIAN = 1.1774
OUTLIER_SIGMAS = 3.717
# the scatter's floor, px: sub-pixel corners of a perfect render scatter 0.015 px; below a
# hundredth the median of a few corners says nothing of the rest
MIN_CORNER_SIGMA_PX = 0.01
# rounds of leaving outliers out, each pose solved again without the last round's: a bound on the
# work (perfect photos of the default design, 2 to 99 Mpx, took 1 to 3 and left 1 to 3 of ~28 out)
OUTLIER_ROUNDS = 3


def corner_outliers(residual_px: np.ndarray) -> np.ndarray:
    """Which corners lie beyond chance of the others' scatter about the pose.

    A corner that the part hides in part, its shadow, or the plate's edge crosses is off by
    a share of a square, whatever the photo's size: at 12 Mpx two such corners of 28 made the
    RMS 0.069 px (0.020 without them) and the camera 15 µm off (2.5 µm); at 48 Mpx 0.134 px, and
    at 99 Mpx a perfect photo's 1.5 px made it INVALID.

    Parameters
    ----------
    residual_px : (n,) float
        Each corner's reprojection error, px.

    Returns
    -------
    (n,) bool
        True for an outlier: beyond OUTLIER_SIGMAS of the scatter the median gives.
    """
    sigma = max(float(np.median(residual_px)) / RAYLEIGH_MEDIAN, MIN_CORNER_SIGMA_PX)
    return residual_px > OUTLIER_SIGMAS * sigma


def estimate_pose(gray: np.ndarray, fixture: dict, K: np.ndarray, dist: np.ndarray, min_corners: int = 8) -> Pose:
    """Pose of the camera that took ``gray`` relative to the fixture (the job's mesh frame).

    ChArUco corners (sub-pixel, about 0.03 px) against their mesh positions: SQPnP for a
    start, then Levenberg-Marquardt (``cv2.solvePnPRefineLM``) on all corners; then once more
    without the corners beyond chance of the others' scatter (:func:`corner_outliers`).

    Parameters
    ----------
    gray : (H, W) uint8
        The photo.
    fixture : dict
        Board definition with mesh positions (``fixture.json`` of the design).
    K : (3, 3) float
        Camera matrix of the profile.
    dist : (5,) float
        Its distortion.
    min_corners : int
        Fewer corners than this is no pose.

    Returns
    -------
    Pose

    Raises
    ------
    PoseError
        No markers, markers of another board, too few corners.
    """
    spec = CharucoSpec.from_definition(fixture)
    det = cv2.aruco.CharucoDetector(spec.opencv())
    corners, ids, mcorners, mids = det.detectBoard(gray)
    ours = set(int(i) for i in fixture["markers"]["ids"])
    if mids is not None and len(mids) and not ours & set(int(i) for i in mids.ravel()):
        raise PoseError(
            f"markers found ({len(mids)}) but none of this fixture's (ids {min(ours)} to {max(ours)}): another board"
        )
    if mids is None or len(mids) == 0:
        # maybe markers of another dictionary or id range: say so when we can tell
        dic = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, fixture["dictionary"]))
        _, any_ids, _ = cv2.aruco.ArucoDetector(dic).detectMarkers(gray)
        if any_ids is not None and len(any_ids):
            raise PoseError(
                f"markers found ({len(any_ids)}) but none of this fixture's (ids {fixture['markers']['ids'][0]}"
                f" to {fixture['markers']['ids'][-1]}): another board"
            )
        raise PoseError("no fixture markers found in the photo")
    n = 0 if ids is None else len(ids)
    if n < min_corners:
        raise PoseError(f"too few ChArUco corners ({n}, need {min_corners}): is the fixture in the photo and sharp?")
    ids = ids.ravel()
    obj = np.asarray(fixture["charuco_corners"]["mesh_mm"], dtype=np.float64)[ids]
    img = corners.reshape(-1, 2).astype(np.float64)
    # solved on every corner, then again without the outliers of each pose, until none is left
    # (a hidden corner pulls the first pose, and its neighbour shows only against the second)
    keep = np.ones(n, bool)
    rvec, tvec, residual = _solve(obj, img, K, dist)
    for _ in range(OUTLIER_ROUNDS):
        out = corner_outliers(residual)
        if not out.any() or keep.sum() - out.sum() < min_corners:
            break
        keep[np.flatnonzero(keep)[out]] = False
        rvec, tvec, residual = _solve(obj[keep], img[keep], K, dist)
    rms = float(np.sqrt(np.mean(residual**2)))
    R = cv2.Rodrigues(rvec)[0]
    h, w = gray.shape[:2]
    cam = Camera(np.asarray(K, dtype=np.float64), R, tvec.ravel(), w, h, np.asarray(dist, dtype=np.float64).ravel())
    return Pose(cam, rms, int(keep.sum()), len(mids), mids.ravel(), n - int(keep.sum()))


def _solve(obj: np.ndarray, img: np.ndarray, K: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, ...]:
    """SQPnP then Levenberg-Marquardt: rvec, tvec and each corner's reprojection error (px); PoseError where
    OpenCV cannot solve."""
    try:
        ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_SQPNP)
        if ok:
            rvec, tvec = cv2.solvePnPRefineLM(
                obj, img, K, dist, rvec, tvec, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
            )
    except cv2.error as exc:
        # OpenCV asserts on what it cannot solve (corners on one line, a degenerate K): this photo's verdict
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "OpenCV error"
        raise PoseError(f"the pose could not be solved from the {len(obj)} corners ({reason})") from None
    if not ok or not (np.isfinite(rvec).all() and np.isfinite(tvec).all()):
        raise PoseError("the pose could not be solved from the corners")
    proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    return rvec, tvec, np.linalg.norm(proj.reshape(-1, 2) - img, axis=1)
