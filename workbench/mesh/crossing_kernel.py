"""The self-intersection test's inner loop, compiled: candidate pairs of one grid level met and tested one by one.

Imported by :func:`workbench.mesh.solid.self_intersections` only when a closed mesh is checked,
so that no other command loads numba for it. The broad phase's candidate pairs were materialised
as arrays of millions of pairs, filtered and tested in chunks (about 9 s for 360k triangles); met
and tested in one loop, they are never stored.
"""

from __future__ import annotations

import numba
import numpy as np

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


@numba.njit(**_JIT)
def _crossing(T, F, a, b, tol, point):
    """Whether triangles ``a`` and ``b`` cross (not merely touch, not coplanar), and where (into ``point``).

    The test of :func:`workbench.mesh.solid.self_intersections`, pair by pair: every edge of
    either triangle that runs from clearly one side of the other's plane to the other, and
    meets the plane inside that triangle (its edges included), within ``tol``; an edge touching
    a vertex the two share does not count, and triangles sharing an edge are not tested. The
    point is where the first such edge meets the plane: ``a``'s edges first, each opposite its
    corner 0, 1, 2.
    """
    shared_a = np.zeros(3, np.bool_)  # corner i of a is a corner of b
    shared_b = np.zeros(3, np.bool_)
    n_shared = 0
    for i in range(3):
        for j in range(3):
            if F[a, i] == F[b, j]:
                shared_a[i] = True
                shared_b[j] = True
                n_shared += 1
    if n_shared > 1:
        return False
    d = np.empty(3)
    side = np.empty(3, np.int64)
    for p in range(2):
        P, Q = (a, b) if p == 0 else (b, a)
        shared = shared_a if p == 0 else shared_b
        # Q's plane: its unit normal
        e1 = T[Q, 1] - T[Q, 0]
        e2 = T[Q, 2] - T[Q, 0]
        n = np.array([e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]])
        norm = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        if norm <= 0.0:
            continue
        n = n / norm
        for c in range(3):
            d[c] = (
                (T[P, c, 0] - T[Q, 0, 0]) * n[0] + (T[P, c, 1] - T[Q, 0, 1]) * n[1] + (T[P, c, 2] - T[Q, 0, 2]) * n[2]
            )
            # a corner within tol of the plane is on it: an edge crosses only from clearly one side
            side[c] = 1 if d[c] > tol else (-1 if d[c] < -tol else 0)
        for k in range(3):
            i, j = (k + 1) % 3, (k + 2) % 3
            if shared[i] or shared[j] or side[i] * side[j] >= 0:
                continue
            t = d[i] / (d[i] - d[j])
            x = T[P, i] + t * (T[P, j] - T[P, i])
            inside = True
            for m in range(3):
                u = T[Q, (m + 1) % 3]
                w = T[Q, (m + 2) % 3]
                wu = w - u
                xu = x - u
                # (w - u) x (x - u), along the normal: x on the inner side of this edge
                left = (
                    (wu[1] * xu[2] - wu[2] * xu[1]) * n[0]
                    + (wu[2] * xu[0] - wu[0] * xu[2]) * n[1]
                    + (wu[0] * xu[1] - wu[1] * xu[0]) * n[2]
                )
                if left < -tol * np.sqrt(wu[0] * wu[0] + wu[1] * wu[1] + wu[2] * wu[2]):
                    inside = False
                    break
            if inside:
                point[:] = x
                return True
    return False


@numba.njit(**_JIT)
def _crossings_into(T, F, lo, hi, level, L, corner, keys, tri, qkeys, qtri, qcell, tol, pairs, points):
    """The loop of :func:`level_crossings`: pairs written while ``pairs`` has room; how many there are."""
    first = np.searchsorted(keys, qkeys)
    point = np.empty(3)
    n = 0
    for q in range(len(qkeys)):
        a = qtri[q]
        k = first[q]
        while k < len(keys) and keys[k] == qkeys[q]:
            b = tri[k]
            k += 1
            # a pair of one level meets itself from both sides: keep one side
            if level[a] == L and a >= b:
                continue
            # each pair once: in the cell holding the low corner of the boxes' overlap; boxes that overlap
            here = True
            for c in range(3):
                if max(corner[a, c], corner[b, c]) != qcell[q, c] or lo[a, c] > hi[b, c] or lo[b, c] > hi[a, c]:
                    here = False
                    break
            if not here:
                continue
            lo_t, hi_t = (a, b) if a < b else (b, a)
            if _crossing(T, F, lo_t, hi_t, tol, point):
                if n < pairs.shape[0]:
                    pairs[n, 0] = lo_t
                    pairs[n, 1] = hi_t
                    points[n] = point
                n += 1
    return n


def level_crossings(T, F, lo, hi, level, L, corner, keys, tri, qkeys, qtri, qcell, tol):
    """The crossing pairs one grid level's cells hold, each met once, and a point of each.

    Parameters
    ----------
    T : (#F, 3, 3) float
        The triangles' corners, mm.
    F : (#F, 3) int
        Their vertex indices (shared vertices).
    lo, hi : (#F, 3) float
        Their bounding boxes.
    level : (#F,) int
        Each triangle's level in the grid hierarchy.
    L : int
        This level.
    corner : (#F, 3) int
        The cell of this level holding each box's low corner.
    keys, tri : (n,) int
        The cells of this level's triangles and the triangle of each, sorted by key.
    qkeys, qtri : (m,) int
        The cells of the triangles of this level and every finer one (the queries) and their
        triangle.
    qcell : (m, 3) int
        Each query's cell.
    tol : float
        Distances below it are zero, mm.

    Returns
    -------
    pairs : (#P, 2) int64
        The crossing pairs ``(low, high)``.
    points : (#P, 3) float
        A point of each, mm.
    """
    cap = 1024
    while True:
        pairs, points = np.empty((cap, 2), np.int64), np.empty((cap, 3))
        n = _crossings_into(T, F, lo, hi, level, L, corner, keys, tri, qkeys, qtri, qcell, tol, pairs, points)
        if n <= cap:
            return pairs[:n], points[:n]
        cap = n  # (a mesh crossing itself in many places: once more, with room for all)


@numba.njit(**_JIT)
def box_cells(lo, hi, idx, origin, s, n_cells):
    """The grid cells the boxes of triangles ``idx`` span: key, triangle and cell (x, y, z) of each, box by box.

    Parameters
    ----------
    lo, hi : (#F, 3) float
        Bounding boxes.
    idx : (k,) int
        The triangles.
    origin : (3,) float
        The grid's origin.
    s : float
        Its cell size.
    n_cells : (3,) int
        Its cells along each axis.

    Returns
    -------
    keys : (n,) int64
        ``(x n_y + y) n_z + z`` of each cell.
    tri : (n,) int64
        Its triangle.
    cell : (n, 3) int64
        Its (x, y, z).
    """
    i0 = np.empty((len(idx), 3), np.int64)
    span = np.empty((len(idx), 3), np.int64)
    total = 0
    for r in range(len(idx)):
        for c in range(3):
            i0[r, c] = np.int64(np.floor((lo[idx[r], c] - origin[c]) / s))
            span[r, c] = np.int64(np.floor((hi[idx[r], c] - origin[c]) / s)) - i0[r, c] + 1
        total += span[r, 0] * span[r, 1] * span[r, 2]
    keys = np.empty(total, np.int64)
    tri = np.empty(total, np.int64)
    cell = np.empty((total, 3), np.int64)
    n = 0
    for r in range(len(idx)):
        for x in range(i0[r, 0], i0[r, 0] + span[r, 0]):
            for y in range(i0[r, 1], i0[r, 1] + span[r, 1]):
                for z in range(i0[r, 2], i0[r, 2] + span[r, 2]):
                    keys[n] = (x * n_cells[1] + y) * n_cells[2] + z
                    tri[n] = idx[r]
                    cell[n, 0], cell[n, 1], cell[n, 2] = x, y, z
                    n += 1
    return keys, tri, cell
