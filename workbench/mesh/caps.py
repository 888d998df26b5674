"""A scan's caps flipped away: triangles with a corner on their opposite edge, the surface unchanged."""

from __future__ import annotations

import numpy as np

from workbench.mesh.topology import unique_edges
from workbench.mesh.validate import ZERO_AREA, face_areas, zero_area_faces

# a zero-area triangle whose shortest edge is below this share of its longest is a needle (two
# corners at one point, as far as the flip's new triangles could tell): no flip mends it
CAP_SLACK = 1e-6


def flip_caps(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, int]:
    """Triangles of zero area whose corner lies on the opposite edge (caps), flipped with the neighbour there.

    A scanner's mesh holds a few caps: corner c on edge ab of triangle (a, b, c). No map
    flattens a triangle without area. The neighbour across ab, (b, a, d), and the cap make a
    quad a, d, b, c whose diagonal ab is flipped to cd: the triangles (a, d, c) and (d, b, c)
    split (b, a, d) at c, so they cover exactly what the two covered. The flip is made only
    where both new triangles have an area by :func:`~workbench.mesh.validate.zero_area_faces`'
    own measure (d near the line ab, or c near a or b, would leave one flat again, and the next
    round would flip it back). The faces keep their places in ``F`` (each cap and its neighbour
    are replaced where they are), the vertices are untouched.

    A cap on the surface's boundary, one whose flip would join two vertices already joined
    (the mesh would no longer be a manifold), or one whose neighbour is a cap along the same
    line, stays; so does a needle (two corners at one point), which no flip mends.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles, consistently oriented.

    Returns
    -------
    F : (#F, 3) int64
        The triangles with the caps flipped away (a copy).
    flipped : int
        Caps flipped.
    """
    F = np.array(F, dtype=np.int64, copy=True)
    flipped = 0
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))) if len(V) else 0.0
    flat = ZERO_AREA * diag * diag  # (zero_area_faces' own measure)
    while True:
        caps = zero_area_faces(V, F)
        if not len(caps):
            return F, flipped
        E, FE, _ = unique_edges(F)
        # the faces of the caps' edges (the edge opposite corner k of face f is FE[f, k])
        owners: dict[int, list[int]] = {}
        for f in np.flatnonzero(np.isin(FE, FE[caps]).any(axis=1)):
            for e in FE[f]:
                owners.setdefault(int(e), []).append(int(f))
        joined = {(int(i), int(j)) for i, j in np.sort(E, axis=1)}
        is_cap = set(map(int, caps))
        touched: set = set()  # faces a flip of this round changed: their edges are found again next round
        for f in map(int, caps):
            a, b, c = _cap_corners(V, F[f])
            if a is None or f in touched:
                continue  # a needle, or changed already
            k = int(np.flatnonzero(F[f] == c)[0])
            others = [g for g in owners.get(int(FE[f, k]), []) if g != f]
            if len(others) != 1:
                continue  # on the boundary (or not a manifold there)
            g = others[0]
            d = int(next(v for v in F[g] if v not in (a, b)))
            if (min(c, d), max(c, d)) in joined or g in is_cap or g in touched:
                continue
            if (face_areas(V, np.array([[a, d, c], [d, b, c]])) <= flat).any():
                continue  # one of the two would be a cap again
            F[f] = (a, d, c)
            F[g] = (d, b, c)
            joined.add((min(c, d), max(c, d)))
            touched |= {f, g}
            flipped += 1
        if not touched:
            return F, flipped


def _cap_corners(V: np.ndarray, face: np.ndarray):
    """The corners (a, b, c) of a cap in its own order (a -> b the edge c lies on), or Nones for a needle."""
    p = V[face]
    length = np.linalg.norm(p[[1, 2, 0]] - p[[2, 0, 1]], axis=1)  # the edge opposite each corner
    k = int(np.argmax(length))
    longest = float(length[k])
    # (three points on a line: the corner opposite the longest edge lies between the other two)
    if longest <= 0.0 or float(length.min()) <= CAP_SLACK * longest:
        return None, None, None  # a corner on another corner: a needle
    c = int(face[k])
    a, b = int(face[(k + 1) % 3]), int(face[(k + 2) % 3])
    return a, b, c
