"""What a set of board photos covers: corners on the flat grid, the frame's cells and the board's tilts."""

from __future__ import annotations

import cv2
import numpy as np


def grid_rms(board_mm: np.ndarray, px: np.ndarray, camera: tuple | None = None) -> float:
    """How far a view's corners lie from the flat grid they were matched to, px.

    A flat board's corners in a photo (its distortion taken out) are the board's points
    through a homography, whatever the camera's intrinsics and pose; a detection that matched
    corners to the wrong squares (a steeply tilted chessboard read one square off along a
    row) fits none. The RMS of the best homography's residual, in the photo's pixels.

    Parameters
    ----------
    board_mm : (n, 2) float
        The corners' points on the board, mm.
    px : (n, 2) float
        The corners in the photo, px.
    camera : (K, dist), optional
        (3, 3) and (5,) float: the distortion to take out first (pixels kept in K's units).

    Returns
    -------
    float
        px; 0 for four corners or fewer (any four fit a homography).
    """
    px = np.asarray(px, np.float64).reshape(-1, 2)
    if len(px) <= 4:
        return 0.0
    if camera is not None:
        K, dist = camera
        px = cv2.undistortPoints(px.reshape(-1, 1, 2), K, dist, P=K).reshape(-1, 2)
    src = np.asarray(board_mm, np.float64).reshape(-1, 2)
    Hm, _ = cv2.findHomography(src, px, 0)
    if Hm is None:
        return float("inf")
    fit = cv2.perspectiveTransform(src.reshape(-1, 1, 2), Hm).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum((fit - px) ** 2, axis=1))))


# the frame's grid of corner_coverage, rows x columns
COVERAGE_GRID = (6, 8)
# a board tilted this much about each axis of the image (its normal's turn from the optical
# axis) fixes the focal length well: Zhang's constraints vanish for a fronto-parallel board and
# OpenCV's and Bouguet's guides take boards tilted up to about 45 degrees; beyond 60 the corners
# foreshorten and blur (the webcam video's frames at 62 degrees were misread)
TILT_ADVISED_DEG = 30.0


def board_normals(views: list, width: int, height: int) -> np.ndarray:
    """Each view's board normal in the camera frame, posed with a nominal camera.

    As :func:`workbench.calibration.tilt_spread_deg` poses them.

    Returns
    -------
    (n, 3) float
        Unit normals, turned to face the camera (z < 0); views without a pose left out.
    """
    K0 = np.array([[width, 0.0, 0.5 * (width - 1)], [0.0, width, 0.5 * (height - 1)], [0.0, 0.0, 1.0]])
    normals = []
    for _name, obj, px in views:
        try:
            ok, rvec, _ = cv2.solvePnP(obj.astype(np.float64), px.astype(np.float64), K0, None)
        except cv2.error:
            ok = False
        if ok:
            n = cv2.Rodrigues(rvec)[0][:, 2]
            normals.append(-n if n[2] > 0 else n)
    return np.array(normals).reshape(-1, 3)


def _words(names: list[str], all_of: str) -> str:
    """``a``, ``a and b``, ``a, b and c``; ``all_of`` ("four") for all four."""
    if len(names) == 4:
        return all_of
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def photo_coverage(views: list, width: int, height: int) -> dict:
    """Which parts of the frame and which tilts a set of photos covers, and what the next photos should add.

    The distortion is fixed by corners near the frame's borders and corners (where it is
    largest), the focal length by boards tilted about both of the image's axes. The frame is
    cut into COVERAGE_GRID cells; a frame corner (its 2 x 2 cells) or border (the middle cells
    along it) without any corner is named, and so is an axis about which no board tilts
    TILT_ADVISED_DEG.

    Parameters
    ----------
    views : list of (name, (n, 3) float board points mm, (n, 2) float px)
    width, height : int
        The photos' size, px.

    Returns
    -------
    dict
        ``cells``: (rows, cols) list of int, corners per cell (row 0 at the top);
        ``share``: the share of cells with a corner; ``tilt_x_deg``, ``tilt_y_deg``: each
        view's tilt about the image's horizontal (x) and vertical (y) axis, degrees (signed);
        ``missing``: the frame's corners and borders without a corner ("top-left", ...);
        ``next``: sentences saying what the next photos should add (empty: nothing).
    """
    rows, cols = COVERAGE_GRID
    cells = np.zeros((rows, cols), np.int64)
    for _, _, px in views:
        r = np.clip((np.asarray(px)[:, 1] / height * rows).astype(int), 0, rows - 1)
        c = np.clip((np.asarray(px)[:, 0] / width * cols).astype(int), 0, cols - 1)
        np.add.at(cells, (r, c), 1)
    hit = cells > 0
    places = {
        "top-left": hit[:2, :2],
        "top-right": hit[:2, -2:],
        "bottom-left": hit[-2:, :2],
        "bottom-right": hit[-2:, -2:],
        "top": hit[0, 2:-2],
        "bottom": hit[-1, 2:-2],
        "left": hit[2:-2, 0],
        "right": hit[2:-2, -1],
    }
    missing = [name for name, cells_there in places.items() if not cells_there.any()]
    n = board_normals(views, width, height)
    # a normal (nx, ny, nz) facing the camera (nz < 0): the board turned about the image's
    # vertical axis by atan2(nx, -nz), about its horizontal axis by atan2(ny, -nz)
    tilt_y = np.degrees(np.arctan2(n[:, 0], -n[:, 2])) if len(n) else np.zeros(0)
    tilt_x = np.degrees(np.arctan2(n[:, 1], -n[:, 2])) if len(n) else np.zeros(0)
    advice = []
    corners = [m for m in missing if "-" in m]
    borders = [m for m in missing if "-" not in m]
    if corners:
        advice.append(f"the board in the frame's {_words(corners, 'four')} corner{'s' if len(corners) > 1 else ''}")
    if borders:
        advice.append(f"the board along the frame's {_words(borders, 'four')} border{'s' if len(borders) > 1 else ''}")
    for axis, tilts in (("vertical", tilt_y), ("horizontal", tilt_x)):
        most = float(np.abs(tilts).max()) if len(tilts) else 0.0
        if most < TILT_ADVISED_DEG:
            advice.append(
                f"the board turned {TILT_ADVISED_DEG:g} to 45 degrees about the image's {axis} axis "
                f"(the most now: {most:.0f})"
            )
    return {
        "cells": cells.tolist(),
        "share": float(hit.mean()),
        "tilt_x_deg": [round(float(t), 2) for t in tilt_x],
        "tilt_y_deg": [round(float(t), 2) for t in tilt_y],
        "missing": missing,
        "next": advice,
    }
