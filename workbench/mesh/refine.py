"""A mesh split until every edge is at most a given length, its shape unchanged."""

from __future__ import annotations

import numpy as np

from workbench.mesh.solid import weld
from workbench.mesh.topology import unique_edges


def subdivide_to_edge(V: np.ndarray, F: np.ndarray, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """Split each triangle with an edge longer than ``max_edge`` in four at its edges' midpoints, until none is.

    A CAD export spans a flat side with two triangles; what is chosen on the surface in whole
    faces, or measured along edges, needs them smaller. A midpoint lies on its edge, so flat
    faces stay where they were and a curved surface keeps its tessellation's shape; a long edge
    is split from both of its faces, so no crack opens. A mesh with no longer edge is returned
    as it is (the same arrays).

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.
    max_edge : float
        The longest edge allowed, mm.

    Returns
    -------
    V : (#W, 3) float
        The vertices, mm: the mesh's, then the midpoints (each once).
    F : (#G, 3) int
        The triangles, oriented as the ones they were split from.
    """
    E, _, _ = unique_edges(F)
    if not len(E) or float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).max()) <= max_edge:
        return V, F
    from trimesh.remesh import subdivide_to_size

    Vs, Fs = subdivide_to_size(np.asarray(V, np.float64), np.asarray(F, np.int64), max_edge, max_iter=20)
    # (a midpoint is (a + b) / 2 from either face, the same bits: merged exactly)
    return weld(np.asarray(Vs, np.float64), np.asarray(Fs, np.int64))
