"""The part's rigid motion on its plate: one convention for the renderer that moves it and the validator.

Motion convention (the same for ``workbench render --part-offset-mm/--part-rotation-deg`` and
validation.json's ``seating``): a design point ``X`` (mesh frame, mm) is at
``X_photo = R X + t``. ``R = Rz(rz) Ry(ry) Rx(rx)`` (turns about the mesh frame's x, then y,
then z axes, right-handed, degrees in files), about the part's centre ``c``, the centre of the
design mesh's bounding box: ``t = c + offset - R c``. So ``offset_mm`` is how far the part's
centre moved and ``rotation_deg`` how it turned about it.
"""

from __future__ import annotations

import cv2
import numpy as np

from workbench.camera import Camera


def part_centre(V: np.ndarray) -> np.ndarray:
    """The seating's rotation centre: the centre of the design mesh's bounding box, mm; (3,)."""
    V = np.asarray(V, dtype=np.float64)
    return 0.5 * (V.min(axis=0) + V.max(axis=0))


def rotation_from_deg(rotation_deg) -> np.ndarray:
    """``Rz Ry Rx`` of turns (rx, ry, rz) in degrees about the mesh frame's axes; (3, 3)."""
    rx, ry, rz = np.radians(np.asarray(rotation_deg, dtype=np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def rotation_to_deg(R: np.ndarray) -> np.ndarray:
    """(rx, ry, rz) in degrees with ``R = Rz Ry Rx`` (ry within ±90°); (3,)."""
    ry = -np.arcsin(np.clip(R[2, 0], -1.0, 1.0))
    rx = np.arctan2(R[2, 1], R[2, 2])
    rz = np.arctan2(R[1, 0], R[0, 0])
    return np.degrees([rx, ry, rz])


def part_motion(offset_mm, rotation_deg, centre) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` of the part moved by ``offset_mm`` and turned by ``rotation_deg`` about ``centre``.

    ``X_photo = R X + t`` with ``t = centre + offset - R centre``.
    """
    c = np.asarray(centre, dtype=np.float64)
    off = np.zeros(3)
    o = np.asarray(offset_mm, dtype=np.float64).ravel()
    off[: len(o)] = o
    R = rotation_from_deg(rotation_deg)
    return R, c + off - R @ c


def motion_entry(offset_mm, rotation_deg, V: np.ndarray) -> dict:
    """A motion of the part about its centre as files record it (render's ``part_pose``, validate's ``part_held``).

    Parameters
    ----------
    offset_mm : (3,) float
        How far the part's centre moves, mm (mesh frame).
    rotation_deg : (3,) float
        Its turn about the centre, degrees (R = Rz Ry Rx).
    V : (n, 3) float
        Design vertices, mm: the centre is their bounding box's.

    Returns
    -------
    dict
        ``R`` (3 x 3), ``t_mm`` (``X_moved = R X + t``), ``offset_mm``, ``rotation_deg``, ``centre_mm``.
    """
    c = part_centre(V)
    R, t = part_motion(offset_mm, rotation_deg, c)
    return {
        "R": R.tolist(),
        "t_mm": t.tolist(),
        "offset_mm": [float(x) for x in offset_mm],
        "rotation_deg": [float(x) for x in rotation_deg],
        "centre_mm": c.tolist(),
    }


def motion_parameters(R: np.ndarray, t: np.ndarray, centre) -> tuple[np.ndarray, np.ndarray]:
    """``(offset_mm, rotation_deg)`` of a motion ``(R, t)`` about ``centre``: the inverse of :func:`part_motion`."""
    c = np.asarray(centre, dtype=np.float64)
    return R @ c + np.asarray(t) - c, rotation_to_deg(R)


def seated_camera(camera: Camera, R: np.ndarray, t: np.ndarray) -> Camera:
    """The camera that sees the design mesh as the board-posed ``camera`` sees the moved part.

    ``X_c = Rc (R X + t) + tc = (Rc R) X + (Rc t + tc)``: every downstream step (warps, tiles,
    dense field, film placement, seams, defects) then uses the seated part unchanged.
    """
    return Camera(camera.K, camera.R @ R, camera.R @ t + camera.t, camera.width, camera.height, camera.dist)


def skew(v: np.ndarray) -> np.ndarray:
    """(n, 3) vectors to (n, 3, 3) cross-product matrices."""
    z = np.zeros(len(v))
    rows = [[z, -v[:, 2], v[:, 1]], [v[:, 2], z, -v[:, 0]], [-v[:, 1], v[:, 0], z]]
    return np.stack([np.stack(r, -1) for r in rows], axis=1)


def rodrigues(w: np.ndarray) -> np.ndarray:
    """A rotation vector (3,), radians, to its (3, 3) rotation matrix."""
    return cv2.Rodrigues(np.asarray(w, dtype=np.float64).reshape(3, 1))[0]
