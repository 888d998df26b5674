"""Surface normals of a triangle mesh: per triangle and per vertex (area-weighted)."""

from __future__ import annotations

import numpy as np


def face_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unit normal of each triangle.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles, counter-clockwise seen from the side the normal points to.

    Returns
    -------
    (#F, 3) float
        Unit normals; a degenerate triangle's is its (zero) cross product.
    """
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


def vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals, as both renderers shade the part.

    The cross product of two edges is twice the triangle's area along its normal, so summing
    the cross products at each vertex weighs each triangle by its area.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.

    Returns
    -------
    (#V, 3) float
        Unit normals (zero at a vertex of no triangle).
    """
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    n = np.zeros_like(V, dtype=np.float64)
    for k in range(3):
        np.add.at(n, F[:, k], fn)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
