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

import threading

import numba
import numpy as np

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
# (the small helpers are compiled as functions of their own, not inlined into each kernel at
# numba's level: LLVM still inlines them, and a fresh machine's first design compiles in 15 s
# against 26 s; measured, a 12 Mpx render takes 10.5 s against 10.0 s, the print's kernel
# 0.146 s against 0.135 s at 35 Mpx, validate the same)
# numba's parallel loops start one at a time in a process: its work-queue threading layer (the
# fork-safe one, which validate's forked workers use) aborts when two threads start parallel
# loops at once, and validate runs some of a photo's work on a second thread
PARALLEL = threading.Lock()


@numba.njit(**_JIT)
def _edge_coefficients(P, ia, ib, sign):
    """Edge function of the directed edge a→b, times ``sign``, as (s, lx, ly, dx, dy, owns).

    ``w(p) = s (dx (y - ly) - dy (x - lx))`` with (lx, ly) the endpoint of smaller index
    and (dx, dy) the vector to the other: the two faces sharing an edge evaluate it
    from the same operands, so their w are exact negatives (negation and rounding
    commute), and w is exactly 0 at both endpoints. ``owns`` (1 or 0): whether the edge
    owns the pixel centres on it (top-left rule on its direction in the face's
    positive orientation).
    """
    lo = min(ia, ib)
    hi = max(ia, ib)
    dx = P[hi, 0] - P[lo, 0]
    dy = P[hi, 1] - P[lo, 1]
    s = sign if ia < ib else -sign  # a→b is lo→hi or its reverse
    ex = s * dx
    ey = s * dy
    owns = 1.0 if (ey > 0.0 or (ey == 0.0 and ex < 0.0)) else 0.0
    return (s, P[lo, 0], P[lo, 1], dx, dy, owns)


@numba.njit(**_JIT)
def _setup(P, F, f, width, height):
    """Bounding box in pixels and twice the signed area of face f; x1 < x0 when nothing to do."""
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


@numba.njit(**_JIT)
def _face_edges(P, F, f, sign):
    """Coefficients of the three edge functions of face f (edge k opposite vertex k)."""
    i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
    e0 = _edge_coefficients(P, i1, i2, sign)
    e1 = _edge_coefficients(P, i2, i0, sign)
    e2 = _edge_coefficients(P, i0, i1, sign)
    return e0, e1, e2


@numba.njit(**_JIT)
def _clip(lo, hi, e, y):
    # w = a x + r along the row, with a = -s dy and r = s (dx (y - ly) + dy lx)
    a = -e[0] * e[4]
    r = e[0] * (e[3] * (y - e[2]) + e[4] * e[1])
    if a > 0.0:
        lo = max(lo, -r / a - 1.0)
    elif a < 0.0:
        hi = min(hi, -r / a + 1.0)
    elif r < 0.0:
        hi = lo - 1.0
    return lo, hi


@numba.njit(**_JIT)
def _row_span(e0, e1, e2, y, x0, x1):
    """Columns of row y that may be inside (the exact test decides): the bounding box
    cut by each edge's half-plane, one pixel wider on each side for rounding."""
    lo, hi = _clip(float(x0), float(x1), e0, y)
    lo, hi = _clip(lo, hi, e1, y)
    lo, hi = _clip(lo, hi, e2, y)
    return int(np.ceil(lo)), int(np.floor(hi))


@numba.njit(**_JIT)
def _weight(e, x, y):
    """Edge function value and whether the pixel passes this edge."""
    w = e[0] * (e[3] * (y - e[2]) - e[4] * (x - e[1]))
    return w, w > 0.0 or (w == 0.0 and e[5] != 0.0)


@numba.njit(parallel=True, **_JIT)
def _rasterize(P, F, width, height, face, bary):
    for f in numba.prange(F.shape[0]):
        x0, x1, y0, y1, area2 = _setup(P, F, f, width, height)
        if x1 < x0:
            continue
        sign = 1.0 if area2 > 0 else -1.0
        inv = 1.0 / abs(area2)
        e0, e1, e2 = _face_edges(P, F, f, sign)
        for py in range(y0, y1 + 1):
            y = float(py)
            xs, xe = _row_span(e0, e1, e2, y, x0, x1)
            for px in range(xs, xe + 1):
                x = float(px)
                w0, ok0 = _weight(e0, x, y)
                w1, ok1 = _weight(e1, x, y)
                w2, ok2 = _weight(e2, x, y)
                if ok0 and ok1 and ok2:
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
    P, F = np.ascontiguousarray(P, dtype=np.float64), np.ascontiguousarray(F, dtype=np.int64)
    with PARALLEL:
        _rasterize(P, F, width, height, face, bary)
    return face, bary


@numba.njit(**_JIT)
def _zbuffer(P, invz, F, width, height, face, depth):
    # serial: faces overlap in the image and the nearest must win
    for f in range(F.shape[0]):
        i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
        if invz[i0] <= 0.0 or invz[i1] <= 0.0 or invz[i2] <= 0.0:
            continue  # behind the camera (the caller refuses cameras inside the part)
        x0, x1, y0, y1, area2 = _setup(P, F, f, width, height)
        if x1 < x0:
            continue
        sign = 1.0 if area2 > 0 else -1.0
        inv = 1.0 / abs(area2)
        e0, e1, e2 = _face_edges(P, F, f, sign)
        for py in range(y0, y1 + 1):
            y = float(py)
            xs, xe = _row_span(e0, e1, e2, y, x0, x1)
            for px in range(xs, xe + 1):
                x = float(px)
                w0, ok0 = _weight(e0, x, y)
                w1, ok1 = _weight(e1, x, y)
                w2, ok2 = _weight(e2, x, y)
                if ok0 and ok1 and ok2:
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


def interpolate(face: np.ndarray, bary: np.ndarray, F: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per-vertex values at every pixel of a rasterisation, through its triangle's barycentrics.

    One compiled pass: numpy's gathers and temporaries took 0.3 s for the 1.4 million pixels
    of a print's analysis grid, this a hundredth of that.

    Parameters
    ----------
    face : (height, width) int
        Triangle per pixel, -1 where none (:func:`rasterize_triangles`).
    bary : (height, width, 3) float
        Barycentric coordinates in it.
    F : (#F, 3) int
        Triangles.
    values : (#V, C) float
        Per-vertex values.

    Returns
    -------
    (height, width, C) float64
        ``b0 · values[F[f, 0]] + b1 · values[F[f, 1]] + b2 · values[F[f, 2]]``; NaN where no triangle.
    """
    out = np.full((*face.shape, values.shape[1]), np.nan)
    _interpolate(
        np.ascontiguousarray(face),
        np.ascontiguousarray(bary, dtype=np.float64),
        np.ascontiguousarray(F, dtype=np.int64),
        np.ascontiguousarray(values, dtype=np.float64),
        out,
    )
    return out


@numba.njit(**_JIT)
def _interpolate(face, bary, F, values, out):
    for i in range(face.shape[0]):
        for j in range(face.shape[1]):
            f = face[i, j]
            if f < 0:
                continue
            a, b, c = F[f, 0], F[f, 1], F[f, 2]
            b0, b1, b2 = bary[i, j, 0], bary[i, j, 1], bary[i, j, 2]
            for k in range(values.shape[1]):
                out[i, j, k] = b0 * values[a, k] + b1 * values[b, k] + b2 * values[c, k]
