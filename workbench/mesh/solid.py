"""Closed triangle meshes as solids: welding, outward orientation, one body, no self-intersection."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from workbench.errors import WorkbenchError
from workbench.mesh.topology import face_components, half_edges, unique_edges
from workbench.mesh.validate import _faces, _first

# cells a triangle's bounding box may span in the broad phase's grid of its level
_MAX_CELLS = 512


def weld(V: np.ndarray, F: np.ndarray, tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices at the same position, numbered by first appearance.

    STL and the tessellation of a STEP file repeat a vertex in every triangle (or every CAD face)
    that uses it; a solid's edges are only shared once its vertices are. Numbering by first
    appearance keeps a mesh without duplicates exactly as it was.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, any unit.
    F : (#F, 3) int
        Triangles.
    tol : float
        Vertices closer than this (unit of ``V``) are merged; 0 merges only identical positions.

    Returns
    -------
    V : (#W, 3) float
        The distinct positions (the first of each group of merged vertices), in order of first appearance.
    F : (#F, 3) int
        The same triangles on the merged vertices (a triangle may now repeat a vertex).
    """
    if tol > 0 and len(V):
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        pairs = cKDTree(V).query_pairs(tol, output_type="ndarray")
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(V), len(V)))
        _, group = connected_components(graph, directed=False)
    else:
        _, group = np.unique(V, axis=0, return_inverse=True)
        group = group.ravel()
    _, first, inverse = np.unique(group, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return V[np.sort(first)], rank[inverse.ravel()][F]


def is_closed(F: np.ndarray) -> bool:
    """Whether every edge of the mesh is shared by at least two triangles (no boundary).

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.

    Returns
    -------
    closed : bool
        True for a mesh without boundary edges (an empty mesh is not closed).
    """
    if len(F) == 0:
        return False
    _, _, count = unique_edges(F)
    return bool((count >= 2).all())


def check_solid(
    V: np.ndarray, F: np.ndarray, name: str = "mesh", log: Callable[[str], None] | None = None
) -> np.ndarray:
    """Orient a closed mesh's faces outward, or raise saying why it is not one solid.

    The checks, in order: finite coordinates, no triangle repeating a vertex, every edge shared by
    exactly two triangles, one connected body, an orientable surface, a non-zero enclosed volume,
    no two triangles crossing. Faces that run a shared edge the same way as their neighbour
    (flipped facets, common in STL exports) are turned to agree with it, and all faces are turned
    if the normals then point inward (negative signed volume); ``log`` says what was turned. Face
    and vertex order are kept: only the winding of the turned faces changes.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles of a mesh without boundary edges (:func:`is_closed`).
    name : str
        How to name the mesh in messages (usually its file, or a :class:`~workbench.mesh.io.MeshName`).
    log : callable(str), optional
        Receives one line per repair.

    Returns
    -------
    F : (#F, 3) int64
        The triangles, each counter-clockwise seen from outside the solid.

    Raises
    ------
    WorkbenchError
        Naming the mesh, what is wrong and where.
    """
    say = log or (lambda _m: None)
    F = np.asarray(F, dtype=np.int64)
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if len(bad):
        raise WorkbenchError(f"{name}: {len(bad)} vertices have NaN or infinite coordinates (vertex {_first(bad)})")
    repeated = np.flatnonzero((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0]))
    if len(repeated):
        raise WorkbenchError(
            f"{name}: {len(repeated)} faces of the solid repeat a vertex (degenerate facets: {_faces(name, repeated)})"
        )
    E, FE, count = unique_edges(F)
    over = np.flatnonzero(count > 2)
    if len(over):
        e = E[over[0]]
        faces = np.flatnonzero((FE == over[0]).any(axis=1))
        raise WorkbenchError(
            f"{name}: not a solid: {len(over)} edges are shared by more than two faces; edge ({e[0]}, {e[1]}) "
            f"by {count[over[0]]} ({_faces(name, faces, 4)})"
        )
    labels = face_components(F, FE)
    n_bodies = int(labels.max()) + 1
    if n_bodies > 1:
        raise WorkbenchError(f"{name}: {n_bodies} separate bodies ({_bodies(V, F, labels)}); give one part")
    flip = _orientation(F, FE, name)
    F = np.where(flip[:, None], F[:, ::-1], F)
    volume = _signed_volume(V, F)
    extent = V.max(axis=0) - V.min(axis=0)
    # relative to the bounding box: a solid enclosing 1e-9 of its box is a flat, doubled sheet
    if abs(volume) <= 1e-9 * float(np.prod(np.maximum(extent, 1e-300))):
        raise WorkbenchError(f"{name}: the closed surface encloses no volume (a sheet folded onto itself?)")
    if volume < 0:
        F = F[:, ::-1]
        flip = ~flip
    n_turned = int(flip.sum())
    if n_turned == len(F):
        say(f"{name}: all faces turned over (their normals pointed into the solid)")
    elif n_turned:
        # the flipped facets are the fewer: turned to agree with their neighbours, or (if the
        # rest pointed in) the only faces that pointed out
        wrong = np.flatnonzero(flip if 2 * n_turned <= len(F) else ~flip)
        inward = "; then all faces turned over (their normals pointed into the solid)" if 2 * n_turned > len(F) else ""
        say(
            f"{name}: {len(wrong)} flipped facets turned to agree with their neighbours ({_faces(name, wrong)}){inward}"
        )
    pairs, points = self_intersections(V, F, limit=1)
    if len(pairs):
        a, b = pairs[0]
        x, y, z = points[0]
        raise WorkbenchError(
            f"{name}: the solid intersects itself: {_faces(name, [a, b])} cross at ({x:.3f}, {y:.3f}, {z:.3f}) mm"
        )
    return np.ascontiguousarray(F)


def self_intersections(V: np.ndarray, F: np.ndarray, limit: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of triangles that cross each other, and a point of each crossing.

    Broad phase: each triangle goes to the level of a hierarchy of uniform grids whose cells are
    at least its bounding box's size, so that it spans at most 2 x 2 x 2 cells there, and meets
    the triangles of its own and every coarser level in the cells it spans: a few sorts and
    binary searches, whatever the spread of triangle sizes (CAD tessellations mix long slivers on
    flat faces with small triangles on fillets). Each candidate pair is met and tested at once in
    a compiled loop (:mod:`workbench.mesh.crossing_kernel`), never stored: 360k triangles in
    3.7 to 4.0 s against 9 to 10 s for the pairs as arrays. Narrow phase: bounding boxes, then
    the two triangles' planes (a triangle wholly on one side of the other's plane is out), then
    every edge of either crossing the other triangle's plane inside the other triangle. Two
    triangles that cross without being coplanar always have such an edge. Triangles sharing an
    edge can only meet in their common plane and are not tested; triangles sharing one vertex
    are tested by their edges opposite it. Coplanar overlaps and mere touching are not reported.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions, mm.
    F : (#F, 3) int
        Triangles.
    limit : int, optional
        Return only the first this many pairs.

    Returns
    -------
    pairs : (#P, 2) int64
        Crossing triangles ``(a, b)``, ``a < b``, sorted.
    points : (#P, 3) float64
        A point of each crossing, mm (where the first crossing edge meets the other triangle).
    """
    from workbench.mesh.crossing_kernel import level_crossings

    F = np.asarray(F, dtype=np.int64)
    V = np.asarray(V, dtype=np.float64)
    if len(F) < 2:
        return np.zeros((0, 2), np.int64), np.zeros((0, 3))
    T = np.ascontiguousarray(V[F])
    lo, hi = T.min(axis=1), T.max(axis=1)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))) or 1.0
    tol = 1e-9 * diag
    found_pairs, found_points = [np.zeros((0, 2), np.int64)], [np.zeros((0, 3))]
    # the finest cells about the size of most triangles; at most 2**20 cells along the part
    s0 = max(float(np.quantile((hi - lo).max(axis=1), 0.9)), diag * 2.0**-20, 1e-300)
    level = _levels(lo, hi, s0)
    for grid in _grid_levels(lo, hi, level, s0):
        pairs, points = level_crossings(T, F, lo, hi, level, *grid, tol)
        found_pairs.append(pairs)
        found_points.append(points)
    pairs, points = np.concatenate(found_pairs), np.concatenate(found_points)
    order = np.lexsort((pairs[:, 1], pairs[:, 0]))[:limit]
    return pairs[order], points[order]


def _levels(lo: np.ndarray, hi: np.ndarray, s0: float) -> np.ndarray:
    """Each triangle's level L: the finest grid (cells of s0 2^L) where its box spans at most _MAX_CELLS cells."""
    extent = hi - lo
    # a sliver along a flat face stays among small cells, which few triangles share with it
    level = np.full(len(lo), -1, np.int64)
    L = 0
    while (level < 0).any():
        cells = np.prod(np.ceil(extent / (s0 * 2.0**L)) + 1, axis=1)
        level[(level < 0) & (cells <= _MAX_CELLS)] = L
        L += 1
    return level


def _grid_levels(lo: np.ndarray, hi: np.ndarray, level: np.ndarray, s0: float):
    """Per level of the grid hierarchy, what :func:`level_crossings` meets pairs in.

    Each triangle goes to its level (:func:`_levels`); there it meets the triangles of its own
    and of every finer level in the cells its box spans.

    Yields
    ------
    tuple
        ``(L, corner, keys, tri, qkeys, qtri, qcell)`` (see
        :func:`workbench.mesh.crossing_kernel.level_crossings`).
    """
    from workbench.mesh.crossing_kernel import box_cells

    origin = lo.min(axis=0)
    for L in np.unique(level):
        s = s0 * 2.0 ** int(L)
        n_cells = np.floor((hi.max(axis=0) - origin) / s).astype(np.int64) + 2
        corner = np.floor((lo - origin) / s).astype(np.int64)  # the cell of each box's low corner
        keys, tri, _ = box_cells(lo, hi, np.flatnonzero(level == L), origin, s, n_cells)
        order = np.argsort(keys, kind="stable")
        qkeys, qtri, qcell = box_cells(lo, hi, np.flatnonzero(level <= L), origin, s, n_cells)
        yield int(L), corner, keys[order], tri[order], qkeys, qtri, qcell


def _orientation(F: np.ndarray, FE: np.ndarray, name: str) -> np.ndarray:
    """Which faces to turn so that each edge is run both ways; raise if no choice does (one-sided)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    nF = len(F)
    H = half_edges(F).reshape(-1, 2)
    edge = FE.ravel()
    order = np.argsort(edge, kind="stable")
    # every edge has exactly two corners here (checked): consecutive after sorting
    c0, c1 = order[0::2], order[1::2]
    f0, f1 = c0 // 3, c1 // 3
    same_way = H[c0, 0] == H[c1, 0]  # both faces run the edge the same way: one must turn
    # the double cover: node f is "face f as it is", node nF + f "face f turned"; a face as it is
    # and its neighbour turned are linked where they run their edge the same way
    rows = np.concatenate([f0, f0 + nF])
    cols = np.concatenate([np.where(same_way, f1 + nF, f1), np.where(same_way, f1, f1 + nF)])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(2 * nF, 2 * nF))
    _, label = connected_components(graph, directed=False)
    if (label[:nF] == label[nF:]).any():
        f = int(np.flatnonzero(label[:nF] == label[nF:])[0])
        raise WorkbenchError(
            f"{name}: the faces cannot be oriented consistently: the surface is one-sided (as a Moebius strip "
            f"or a Klein bottle), turning around through {_faces(name, [f])}; not the surface of a solid"
        )
    # the body's first face keeps its winding; a face turns if it is linked to face 0 turned
    return label[:nF] == label[nF]


def _signed_volume(V: np.ndarray, F: np.ndarray) -> float:
    """Volume enclosed by a closed, consistently oriented mesh (negative if its normals point in)."""
    # about the centroid: smaller terms, less cancellation, than about the origin
    T = V[F] - V.mean(axis=0)
    return float(np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])).sum() / 6.0)


def _bodies(V: np.ndarray, F: np.ndarray, labels: np.ndarray, limit: int = 4) -> str:
    """``100 x 60 x 30 mm, 12 faces; 20 x 20 x 20 mm, 12 faces`` for the first bodies."""
    parts = []
    for k in range(min(int(labels.max()) + 1, limit)):
        P = V[F[labels == k]].reshape(-1, 3)
        dx, dy, dz = P.max(axis=0) - P.min(axis=0)
        parts.append(f"{dx:.4g} x {dy:.4g} x {dz:.4g} mm, {int((labels == k).sum())} faces")
    more = "; ..." if labels.max() + 1 > limit else ""
    return "; ".join(parts) + more
