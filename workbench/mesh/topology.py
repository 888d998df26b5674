"""Combinatorics of triangle meshes: edges, boundary loops, components, manifoldness."""

from __future__ import annotations

import numpy as np


def half_edges(F: np.ndarray) -> np.ndarray:
    """Directed edges of every face corner.

    Parameters
    ----------
    F : (#F, 3) int
        Triangle vertex indices.

    Returns
    -------
    H : (#F, 3, 2) int
        ``H[f, k] = (F[f, k+1], F[f, k+2])`` (indices mod 3): the edge opposite
        corner ``k`` of face ``f``, oriented as the face runs.
    """
    return np.stack([F[:, [1, 2, 0]], F[:, [2, 0, 1]]], axis=-1)


def unique_edges(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Undirected edges and, per face corner, the edge opposite it.

    Parameters
    ----------
    F : (#F, 3) int
        Triangle vertex indices.

    Returns
    -------
    E : (#E, 2) int
        Undirected edges, ``E[:, 0] < E[:, 1]``, sorted lexicographically.
    FE : (#F, 3) int
        ``FE[f, k]`` is the row of ``E`` opposite corner ``k`` of face ``f``.
    count : (#E,) int
        Number of face corners that use each edge (1 on the boundary, 2 inside,
        more on a non-manifold edge).
    """
    H = half_edges(F).reshape(-1, 2)
    lo, hi = H.min(axis=1), H.max(axis=1)
    # one int64 key per edge: np.unique on a 1-D key is ~10x faster than on rows
    n = int(F.max()) + 1
    keys, inverse, count = np.unique(lo * n + hi, return_inverse=True, return_counts=True)
    E = np.stack([keys // n, keys % n], axis=1)
    return E, inverse.reshape(-1, 3), count


def boundary_half_edges(F: np.ndarray, FE: np.ndarray | None = None, count: np.ndarray | None = None) -> np.ndarray:
    """Directed edges with no twin: the boundary, oriented as its faces run.

    Parameters
    ----------
    F : (#F, 3) int
        Triangle vertex indices of an edge-manifold, consistently oriented mesh.
    FE, count : optional
        :func:`unique_edges` of ``F``, when already computed.

    Returns
    -------
    B : (#B, 2) int
        Boundary half-edges (from, to). With counter-clockwise faces the interior
        lies to the left of each, so the loops they form run counter-clockwise.
    """
    H = half_edges(F).reshape(-1, 2)
    if FE is None or count is None:
        _, FE, count = unique_edges(F)
    return H[count[FE.ravel()] == 1]


def boundary_loops(F: np.ndarray, B: np.ndarray | None = None) -> list[np.ndarray]:
    """Boundary loops, each as an ordered vertex list following face orientation.

    Parameters
    ----------
    F : (#F, 3) int
        Triangle vertex indices of a manifold, consistently oriented mesh.
    B : (#B, 2) int, optional
        :func:`boundary_half_edges` of ``F``, when already computed.

    Returns
    -------
    loops : list of (#L,) int
        One array per loop, starting at its smallest vertex index, ordered so that
        the interior is on the left (counter-clockwise for CCW faces). Sorted by
        first vertex.
    """
    if B is None:
        B = boundary_half_edges(F)
    if len(B) == 0:
        return []
    nxt = dict(zip(B[:, 0].tolist(), B[:, 1].tolist(), strict=True))
    seen: set[int] = set()
    loops = []
    for start in sorted(nxt):
        if start in seen:
            continue
        loop = [start]
        seen.add(start)
        v = nxt[start]
        while v != start:
            if v in seen:  # a boundary that runs into itself: not a manifold (checked meshes never do)
                raise ValueError(f"the boundary through vertex {v} is not a simple loop")
            loop.append(v)
            seen.add(v)
            v = nxt[v]
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def face_components(F: np.ndarray, FE: np.ndarray | None = None) -> np.ndarray:
    """Connected components of faces, linked through shared edges.

    Parameters
    ----------
    F : (#F, 3) int
        Triangle vertex indices.
    FE : (#F, 3) int, optional
        :func:`unique_edges` of ``F``, when already computed.

    Returns
    -------
    labels : (#F,) int
        Component label of each face, numbered by first appearance.
    """
    # SciPy here, not at the top: commands that only read meshes and images (validate) start
    # a tenth of a second sooner without it
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    if FE is None:
        _, FE, _ = unique_edges(F)
    nF = len(F)
    # face-edge incidence; faces sharing an edge are connected
    I = sp.csr_matrix((np.ones(3 * nF), (np.repeat(np.arange(nF), 3), FE.ravel())))
    _, labels = connected_components(I @ I.T, directed=False)
    # relabel by first appearance so the numbering does not depend on scipy's
    _, first = np.unique(labels, return_index=True)
    order = np.argsort(np.argsort(first))
    return order[labels]
