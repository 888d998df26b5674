"""Pinhole cameras in OpenCV's convention: x right, y down, z forward, X_c = R X_w + t."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from workbench import schemas
from workbench.errors import WorkbenchError
from workbench.jsonfile import read_json


@dataclass(frozen=True)
class Camera:
    """A calibrated pinhole camera and the image it sees.

    Attributes
    ----------
    K : (3, 3) float
        Intrinsics in pixels of this camera's image (pixel centres at integers).
    R : (3, 3) float
        World-to-camera rotation.
    t : (3,) float
        World-to-camera translation, mm: ``X_c = R X_w + t``.
    width, height : int
        Image size in pixels.
    dist : (5,) float
        OpenCV distortion (k1, k2, p1, p2, k3); zero for a designed view.
    """

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))

    @classmethod
    def look_at(cls, position, look_at, up, fov_deg: float, width: int, height: int) -> Camera:
        """Camera at ``position`` looking at ``look_at`` with ``up`` towards the image top.

        Parameters
        ----------
        position, look_at, up : (3,) float
            Eye and target in mm, and a direction that appears pointing up (-y).
        fov_deg : float
            Horizontal field of view, degrees, across the full image width.
        width, height : int
            Image size; square pixels, principal point at the image centre
            ((W - 1) / 2, (H - 1) / 2).

        Returns
        -------
        Camera
        """
        position = np.asarray(position, dtype=np.float64)
        z = np.asarray(look_at, dtype=np.float64) - position
        z /= np.linalg.norm(z)
        # y (down) is minus the part of `up` across the viewing direction; x = y × z
        y = -(np.asarray(up, dtype=np.float64) - (np.dot(up, z)) * z)
        y /= np.linalg.norm(y)
        x = np.cross(y, z)
        R = np.stack([x, y, z])
        # the image spans W pixels, from -0.5 to W - 0.5, across the horizontal field
        f = 0.5 * width / np.tan(0.5 * np.radians(fov_deg))
        K = np.array([[f, 0.0, 0.5 * (width - 1)], [0.0, f, 0.5 * (height - 1)], [0.0, 0.0, 1.0]])
        return cls(K=K, R=R, t=-R @ position, width=int(width), height=int(height))

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates, mm; (3,)."""
        return -self.R.T @ self.t

    def to_camera(self, X: np.ndarray) -> np.ndarray:
        """World points (n, 3) to camera coordinates (n, 3), mm."""
        return X @ self.R.T + self.t

    def project(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates of world points (no distortion).

        Parameters
        ----------
        X : (n, 3) float
            World points, mm.

        Returns
        -------
        xy : (n, 2) float
            Pixel coordinates (x right, y down, centres at integers).
        z : (n,) float
            Depth along the optical axis, mm (≤ 0 behind the camera).
        """
        Xc = self.to_camera(X)
        z = Xc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = (Xc[:, :2] / z[:, None]) @ self.K[:2, :2].T + self.K[:2, 2]
        return xy, z

    def scaled(self, s: float) -> Camera:
        """The same camera seeing an image resampled by ``s`` (0.5 = half the pixels).

        Pixel centres map as ``x' = (x + 0.5) s - 0.5``.
        """
        S = np.array([[s, 0.0, 0.5 * s - 0.5], [0.0, s, 0.5 * s - 0.5], [0.0, 0.0, 1.0]])
        w, h = max(int(round(self.width * s)), 1), max(int(round(self.height * s)), 1)
        return Camera(K=S @ self.K, R=self.R, t=self.t, width=w, height=h, dist=self.dist)

    def packed(self) -> np.ndarray:
        """(16,) float: fx, fy, cx, cy, R row-major, t; the form compiled kernels read."""
        K = self.K
        return np.concatenate([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]], self.R.ravel(), self.t])

    def to_dict(self) -> dict:
        """JSON form, the same as a camera profile: K, dist, R, t, image_size [W, H]."""
        return {
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "R": self.R.tolist(),
            "t": self.t.tolist(),
            "image_size": [self.width, self.height],
        }


def intrinsics_problem(K: np.ndarray, width: int, height: int) -> str | None:
    """Why ``K`` cannot be a camera's intrinsics for a ``width`` x ``height`` image, or None.

    The focal lengths must be positive (a zero or negative one mirrors or collapses the
    image), the last row (0, 0, 1), no skew beyond a pixel's worth, and the principal
    point within the image's own size of the image (a calibration gone wrong puts it far off).
    """
    K = np.asarray(K, dtype=np.float64)
    if not np.isfinite(K).all():
        return "K: holds NaN or infinite values"
    fx, fy = K[0, 0], K[1, 1]
    if not (fx > 0 and fy > 0):
        return f"K: focal lengths fx {fx:g}, fy {fy:g} must be positive"
    if not np.allclose(K[2], [0.0, 0.0, 1.0]) or abs(K[1, 0]) > 1e-9:
        return f"K: must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got last rows {K[1:].tolist()}"
    if not 0.02 < fx / fy < 50:
        return f"K: fx {fx:g} and fy {fy:g} differ by more than any real lens does"
    if not (-width <= K[0, 2] <= 2 * width and -height <= K[1, 2] <= 2 * height):
        return f"K: principal point ({K[0, 2]:g}, {K[1, 2]:g}) is far outside the {width} x {height} image"
    return None


def _dist5(d: dict) -> np.ndarray:
    dist = np.asarray(d["dist"], dtype=np.float64).ravel()[:5]
    return np.concatenate([dist, np.zeros(5 - dist.size)])


def load_camera(path: Path) -> Camera:
    """A camera file: K (3x3), R (3x3), t (3), image_size [W, H], optional dist (up to 5)."""
    d = read_json(path, "camera file", schemas.CAMERA_FILE)
    R = np.asarray(d["R"], dtype=np.float64)
    if np.abs(R @ R.T - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        raise WorkbenchError(f"{path}: R: not a rotation matrix")
    w, h = (int(v) for v in d["image_size"])
    K = np.asarray(d["K"], dtype=np.float64)
    problem = intrinsics_problem(K, w, h)
    if problem:
        raise WorkbenchError(f"{path}: {problem}")
    return Camera(K=K, R=R, t=np.asarray(d["t"], dtype=np.float64), width=w, height=h, dist=_dist5(d))


def load_camera_profile(path: Path) -> Camera:
    """Intrinsics only (K, dist, image_size): a calibration profile or a PHOTO.json.

    Raises
    ------
    WorkbenchError
        Missing, malformed, or intrinsics no camera has (see :func:`intrinsics_problem`);
        names the file and the key.
    """
    d = read_json(path, "camera profile", schemas.CAMERA_PROFILE)
    w, h = (int(v) for v in d["image_size"])
    K = np.asarray(d["K"], dtype=np.float64)
    problem = intrinsics_problem(K, w, h)
    if problem:
        raise WorkbenchError(f"{path}: {problem}")
    return Camera(K, np.eye(3), np.zeros(3), w, h, _dist5(d))
