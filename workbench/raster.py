"""Which triangle covers each pixel centre, and where inside it."""

from __future__ import annotations

import numpy as np

# candidate (triangle, pixel) pairs tested at once: bounds memory to a few hundred MB
CHUNK = 8_000_000


def rasterize_triangles(P: np.ndarray, F: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangle index and barycentric coordinates at every pixel centre.

    Pixel (row i, column j) has its centre at ``(x, y) = (j, i)`` in the pixel
    coordinates of ``P`` (DESIGN.md convention). A centre on an edge shared by two
    triangles goes to the one with the larger index, so the result is deterministic.

    Parameters
    ----------
    P : (#V, 2) float
        Vertex positions in pixel coordinates (x right, y down).
    F : (#F, 3) int
        Triangles.
    width, height : int
        Image size in pixels.

    Returns
    -------
    face : (height, width) int32
        Covering triangle, -1 where none.
    bary : (height, width, 3) float32
        Barycentric coordinates in that triangle (0 where none).
    """
    face = np.full((height, width), -1, dtype=np.int32)
    bary = np.zeros((height, width, 3), dtype=np.float32)
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    # barycentrics (l1, l2) of q solve [b-a, c-a] (l1, l2) = q - a
    d1, d2 = b - a, c - a
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    ok = np.abs(det) > 0
    lo = np.ceil(np.minimum(np.minimum(a, b), c)).astype(np.int64)
    hi = np.floor(np.maximum(np.maximum(a, b), c)).astype(np.int64)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, [width - 1, height - 1])
    nx = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0)
    ny = np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    count = np.where(ok, nx * ny, 0)
    tris = np.flatnonzero(count)
    cum = np.cumsum(count[tris])
    start = 0
    while start < len(tris):
        stop = int(np.searchsorted(cum, (cum[start - 1] if start else 0) + CHUNK, side="right"))
        stop = max(stop, start + 1)
        t = tris[start:stop]
        n = count[t]
        tid = np.repeat(t, n)
        offset = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
        px = lo[tid, 0] + offset % nx[tid]
        py = lo[tid, 1] + offset // nx[tid]
        qx = px - a[tid, 0]
        qy = py - a[tid, 1]
        l1 = (qx * d2[tid, 1] - qy * d2[tid, 0]) / det[tid]
        l2 = (d1[tid, 0] * qy - d1[tid, 1] * qx) / det[tid]
        l0 = 1.0 - l1 - l2
        eps = -1e-9
        inside = (l0 >= eps) & (l1 >= eps) & (l2 >= eps)
        px, py, tid = px[inside], py[inside], tid[inside]
        face[py, px] = tid
        bary[py, px] = np.stack([l0[inside], l1[inside], l2[inside]], axis=1)
        start = stop
    return face, bary
