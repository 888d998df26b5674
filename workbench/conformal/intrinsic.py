"""Intrinsic Delaunay triangulation of a mesh: edge flips that keep the surface, change the triangles."""

from __future__ import annotations

from collections import deque

import numpy as np

from workbench.mesh.topology import unique_edges


def corner_twins(F: np.ndarray) -> np.ndarray:
    """Twin of every face corner's opposite edge.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles of an edge-manifold, consistently oriented mesh.

    Returns
    -------
    T : (#F, 3) int
        ``T[f, k] = 3 g + m`` when the edge opposite corner ``k`` of ``f`` is the
        edge opposite corner ``m`` of ``g``; -1 on the boundary.
    """
    _, FE, _ = unique_edges(F)
    e = FE.ravel()
    order = np.argsort(e, kind="stable")
    same = e[order][1:] == e[order][:-1]
    a, b = order[:-1][same], order[1:][same]
    T = np.full(3 * len(F), -1, dtype=np.int64)
    T[a], T[b] = b, a
    return T.reshape(-1, 3)


def intrinsic_delaunay(
    F: np.ndarray, L: np.ndarray, force: np.ndarray | None = None, max_flips: int | None = None
) -> tuple[np.ndarray, np.ndarray, int]:
    """Flip interior edges until every one is Delaunay in the mesh's own metric.

    An edge is Delaunay when the two angles facing it sum to at most π, i.e. its
    cotangent weight is non-negative. Flipping replaces the diagonal of the two
    triangles' quadrilateral by the other one, whose length follows from the law
    of cosines in the quadrilateral unfolded flat: the surface, its vertices and
    its metric stay the same; only the triangles change. Flips that would join two
    vertices already joined are skipped, so edges stay unique vertex pairs.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.
    L : (#F, 3) float
        Length of the edge opposite each corner.
    force : (#F, 3) bool, optional
        Edges to flip once first whatever their angles (when the quadrilateral is
        convex), e.g. the edge facing a boundary vertex that has a single face.
    max_flips : int, optional
        Safety bound; default 50 #F.

    Returns
    -------
    F2 : (#F, 3) int
        Triangles of the intrinsic Delaunay triangulation (same vertices, same
        boundary, counter-clockwise).
    L2 : (#F, 3) float
        Their edge lengths.
    flips : int
        Number of flips made.
    """
    F = np.array(F, dtype=np.int64)
    L = np.array(L, dtype=np.float64)
    T = corner_twins(F)
    # vertex-pair set to refuse flips that would duplicate an edge
    edges = {(min(a, b), max(a, b)) for a, b in F[:, [1, 2]].tolist() + F[:, [2, 0]].tolist() + F[:, [0, 1]].tolist()}
    limit = max_flips if max_flips is not None else 50 * len(F)

    def angle(f: int, k: int) -> float:
        a, b, c = L[f, k], L[f, (k + 1) % 3], L[f, (k + 2) % 3]
        return float(np.arccos(np.clip((b * b + c * c - a * a) / (2 * b * c), -1.0, 1.0)))

    queue: deque[tuple[int, int, bool]] = deque()
    if force is not None:
        queue.extend((int(f), int(k), True) for f, k in zip(*np.nonzero(force), strict=True))
    queue.extend((f, k, False) for f in range(len(F)) for k in range(3) if T[f, k] > 3 * f + k)
    flips = 0
    while queue and flips < limit:
        f, k, forced = queue.popleft()
        t = int(T[f, k])
        if t < 0:
            continue
        g, m = divmod(t, 3)
        alpha_f, alpha_g = angle(f, k), angle(g, m)
        if not forced and alpha_f + alpha_g <= np.pi + 1e-12:
            continue
        # f = (a, b, c) with a at corner k; g = (d, c, b) with d at corner m
        k1, k2, m1, m2 = (k + 1) % 3, (k + 2) % 3, (m + 1) % 3, (m + 2) % 3
        a, b, c, d = int(F[f, k]), int(F[f, k1]), int(F[f, k2]), int(F[g, m])
        if (min(a, d), max(a, d)) in edges:
            continue
        # angles at b and at c in the unfolded quad; the flip is valid when both are < π
        beta = angle(f, k1) + angle(g, m2)
        gamma = angle(f, k2) + angle(g, m1)
        if beta >= np.pi or gamma >= np.pi:
            continue
        l_ab, l_ca = L[f, k2], L[f, k1]
        l_bd, l_dc = L[g, m1], L[g, m2]
        l_ad = float(np.sqrt(max(l_ab * l_ab + l_bd * l_bd - 2 * l_ab * l_bd * np.cos(beta), 0.0)))
        # outer edges: ab (f opp c), ca (f opp b), bd (g opp c), dc (g opp b)
        t_ab, t_ca, t_bd, t_dc = T[f, k2], T[f, k1], T[g, m1], T[g, m2]
        # new faces f' = (a, b, d), g' = (d, c, a), corners 0, 1, 2
        F[f] = (a, b, d)
        F[g] = (d, c, a)
        L[f] = (l_bd, l_ad, l_ab)
        L[g] = (l_ca, l_ad, l_dc)
        T[f] = (t_bd, 3 * g + 1, t_ab)
        T[g] = (t_ca, 3 * f + 1, t_dc)
        for slot, twin in ((3 * f, t_bd), (3 * f + 2, t_ab), (3 * g, t_ca), (3 * g + 2, t_dc)):
            if twin >= 0:
                T.flat[twin] = slot
        edges.discard((min(b, c), max(b, c)))
        edges.add((min(a, d), max(a, d)))
        flips += 1
        queue.extend([(f, 0, False), (f, 2, False), (g, 0, False), (g, 2, False)])
    return F, L, flips
