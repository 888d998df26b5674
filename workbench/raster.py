"""Triangle rasterisation at pixel centres: face ids, barycentrics and depth buffers.

Pixel (row i, column j) has its centre at ``(x, y) = (j, i)`` in pixel coordinates
(DESIGN.md). A pixel centre belongs to a triangle when it is strictly inside, or on
an edge that the top-left rule gives to that triangle: of two consistently oriented
triangles sharing an edge, exactly one owns the centres on it. The edge functions of
a shared edge are computed from the same endpoint in both triangles, so they are
exact negatives of each other and the rule never gives a centre to both or neither.
Each pixel is therefore written by one triangle only, which makes the parallel
kernels deterministic.

The kernels are compiled with numba: the per-pixel loops of a 35-megapixel print
take 0.2 s there against 10 s for the equivalent vectorised numpy.
"""

from __future__ import annotations

import numba
import numpy as np

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


@numba.njit(inline="always", **_JIT)
def _edge(ax, ay, bx, by, ia, ib, px, py):
    # cross(b - a, p - a), always evaluated from the endpoint with the smaller index:
    # cross(b - a, p - a) = -cross(a - b, p - b), bit for bit from the same operands
    if ia < ib:
        return (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    return -((ax - bx) * (py - by) - (ay - by) * (px - bx))


@numba.njit(inline="always", **_JIT)
def _owns_edge(dx, dy):
    # top-left rule on the edge direction of a positively oriented triangle
    return dy > 0.0 or (dy == 0.0 and dx < 0.0)


@numba.njit(inline="always", **_JIT)
def _setup(P, F, f, width, height):
    """Bounding box in pixels and orientation of face f; x1 < x0 when nothing to do."""
    i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
    ax, ay = P[i0, 0], P[i0, 1]
    bx, by = P[i1, 0], P[i1, 1]
    cx, cy = P[i2, 0], P[i2, 1]
    area2 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    x0 = max(int(np.ceil(min(ax, bx, cx))), 0)
    x1 = min(int(np.floor(max(ax, bx, cx))), width - 1)
    y0 = max(int(np.ceil(min(ay, by, cy))), 0)
    y1 = min(int(np.floor(max(ay, by, cy))), height - 1)
    if not (area2 != 0.0 and np.isfinite(area2)):
        x1 = x0 - 1
    return x0, x1, y0, y1, area2


@numba.njit(inline="always", **_JIT)
def _inside(P, F, f, sign, px, py):
    """Barycentric weights (unnormalised, positive inside) and the inside test."""
    i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
    ax, ay = P[i0, 0], P[i0, 1]
    bx, by = P[i1, 0], P[i1, 1]
    cx, cy = P[i2, 0], P[i2, 1]
    w0 = sign * _edge(bx, by, cx, cy, i1, i2, px, py)
    w1 = sign * _edge(cx, cy, ax, ay, i2, i0, px, py)
    w2 = sign * _edge(ax, ay, bx, by, i0, i1, px, py)
    ok = True
    if w0 < 0.0 or (w0 == 0.0 and not _owns_edge(sign * (cx - bx), sign * (cy - by))):
        ok = False
    elif w1 < 0.0 or (w1 == 0.0 and not _owns_edge(sign * (ax - cx), sign * (ay - cy))):
        ok = False
    elif w2 < 0.0 or (w2 == 0.0 and not _owns_edge(sign * (bx - ax), sign * (by - ay))):
        ok = False
    return w0, w1, w2, ok


@numba.njit(parallel=True, **_JIT)
def _rasterize(P, F, width, height, face, bary):
    for f in numba.prange(F.shape[0]):
        x0, x1, y0, y1, area2 = _setup(P, F, f, width, height)
        sign = 1.0 if area2 > 0 else -1.0
        inv = 1.0 / abs(area2) if area2 != 0 else 0.0
        for py in range(y0, y1 + 1):
            for px in range(x0, x1 + 1):
                w0, w1, w2, ok = _inside(P, F, f, sign, float(px), float(py))
                if ok:
                    face[py, px] = f
                    bary[py, px, 0] = w0 * inv
                    bary[py, px, 1] = w1 * inv
                    bary[py, px, 2] = w2 * inv


def rasterize_triangles(P: np.ndarray, F: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangle index and barycentric coordinates at every pixel centre.

    Parameters
    ----------
    P : (#V, 2) float
        Vertex positions in pixel coordinates (x right, y down).
    F : (#F, 3) int
        Triangles, all of one orientation where they overlap edges (a consistently
        oriented planar layout).
    width, height : int
        Image size in pixels.

    Returns
    -------
    face : (height, width) int32
        Covering triangle, -1 where none.
    bary : (height, width, 3) float64
        Barycentric coordinates in that triangle (0 where none).
    """
    face = np.full((height, width), -1, dtype=np.int32)
    bary = np.zeros((height, width, 3))
    _rasterize(
        np.ascontiguousarray(P, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64), width, height, face, bary
    )
    return face, bary


@numba.njit(**_JIT)
def _zbuffer(P, invz, F, width, height, face, depth):
    # serial: faces overlap in the image and the nearest must win
    for f in range(F.shape[0]):
        i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
        if invz[i0] <= 0.0 or invz[i1] <= 0.0 or invz[i2] <= 0.0:
            continue  # behind the camera (the caller refuses cameras inside the part)
        x0, x1, y0, y1, area2 = _setup(P, F, f, width, height)
        sign = 1.0 if area2 > 0 else -1.0
        inv = 1.0 / abs(area2) if area2 != 0 else 0.0
        for py in range(y0, y1 + 1):
            for px in range(x0, x1 + 1):
                w0, w1, w2, ok = _inside(P, F, f, sign, float(px), float(py))
                if ok:
                    # 1/z is affine in screen space: interpolate it, then invert
                    z = 1.0 / ((w0 * invz[i0] + w1 * invz[i1] + w2 * invz[i2]) * inv)
                    if z < depth[py, px]:
                        depth[py, px] = z
                        face[py, px] = f


def depth_buffer(P: np.ndarray, z: np.ndarray, F: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Nearest surface at every pixel centre of a camera image (a z-buffer).

    Parameters
    ----------
    P : (#V, 2) float
        Projected vertex positions, pixels.
    z : (#V,) float
        Vertex depths along the optical axis (camera z), mm; faces with a vertex at
        z <= 0 are skipped.
    F : (#F, 3) int
        Triangles, either orientation (back faces occlude too).
    width, height : int
        Image size.

    Returns
    -------
    face : (height, width) int32
        Nearest face, -1 where none.
    depth : (height, width) float64
        Its depth (perspective-correct), +inf where none.
    """
    face = np.full((height, width), -1, dtype=np.int32)
    depth = np.full((height, width), np.inf)
    with np.errstate(divide="ignore"):
        invz = np.where(z > 0, 1.0 / z, -1.0)
    _zbuffer(
        np.ascontiguousarray(P, dtype=np.float64),
        invz,
        np.ascontiguousarray(F, dtype=np.int64),
        width,
        height,
        face,
        depth,
    )
    return face, depth
