"""Common subdivision of the input triangulation and the flipped one: the exact map of input triangles.

After Ptolemy flips (:mod:`workbench.conformal.intrinsic`) the flat layout is a
triangulation ``T'`` of the input's vertices whose edges are not the input's. Both
triangulations are triangulations of one decorated ideal hyperbolic surface, and
every edge of either is a hyperbolic geodesic between two ideal vertices. A
Euclidean triangle with lengths ``l`` corresponds to its ideal triangle by the
projective map ``b ↦ [Σ b_i p_i]`` (``b`` barycentric, ``p_i`` light-cone vectors with
``-<p_i, p_j> ∝ l_ij²``); scaling by ``u`` multiplies ``p_i`` by ``e^{u_i}``. Geodesics
are lines of that projective model, so every input edge is a straight segment inside
each flat triangle it crosses and every flat edge is straight inside each input
triangle: the cells cut by both are convex polygons in both, and on each cell the
map is one projective map (Gillespie, Springborn, Crane 2021, §5).

The crossings are found by tracing each input edge ``a → b`` that ``T'`` lacks: in the
upper half plane with ``a`` at infinity and its horocycle at height 1, the triangles
of ``T'`` around ``a`` have their other vertices on the real line, spaced by their
horocyclic arcs, and the input edge is the vertical line at the horocyclic offset of
its direction. A vertex ``d`` beyond edge ``v w`` is placed by the λ-length ``l_ad`` of the
virtual edge from ``a``, from Ptolemy's relation (a sum of positive terms: stable).
"""

from __future__ import annotations

import numpy as np

from workbench.conformal.intrinsic import IntrinsicTriangulation, corner_twins, reference_corners
from workbench.errors import WorkbenchError
from workbench.mesh.topology import unique_edges


def trace_input_edges(
    F_in: np.ndarray, lam_in: np.ndarray, tri: IntrinsicTriangulation, u: np.ndarray, n_vertices: int
) -> dict:
    """Crossings of the input edges with the edges of a flipped triangulation.

    Parameters
    ----------
    F_in : (#F, 3) int
        Input triangles.
    lam_in : (#F, 3) float
        Their Penner coordinates ``2 log l`` (the lengths ``tri`` started from).
    tri : IntrinsicTriangulation
        The triangulation after flips, started from ``F_in``, ``lam_in``.
    u : (#V,) float
        Log scale factors of the flat metric.
    n_vertices : int
        #V.

    Returns
    -------
    dict
        ``in_edge`` (#X, 2) int: input edge ``(a, b)`` of each crossing;
        ``t_in`` (#X,) float: its position from ``a`` to ``b`` (Euclidean
        barycentric in the input triangle); ``out_id`` (#X,) int: the flat edge
        crossed, as the smaller of its two corner slots ``3 f + k`` in ``tri.F``;
        ``t_out`` (#X,) float: position along that edge as face ``f`` runs it
        (from ``F[f, k+1]`` to ``F[f, k+2]``), in the flat (scaled) triangle.
    """
    from workbench.conformal._trace import trace  # numba: loaded only when a mesh needs flips

    T_in = corner_twins(F_in)
    in_ref_face, in_ref_corner = reference_corners(F_in, T_in, n_vertices)
    # Every input edge is located in T' by its direction at one end; one that leaves
    # along an edge of T' ending at its other end is that edge (T' may join the same
    # two vertices by several edges, so the vertex pair alone does not tell).
    E, FE, _ = unique_edges(F_in)
    lam_e = np.empty(len(E))
    lam_e[FE.ravel()] = lam_in.ravel()
    edge, t_in, out_id, t_out, failed = trace(
        E,
        lam_e,
        F_in,
        T_in,
        np.ascontiguousarray(lam_in),
        in_ref_face,
        in_ref_corner,
        tri.F,
        tri.T,
        tri.lam,
        tri.ref_face,
        tri.ref_corner,
        tri.ref_offset,
        np.ascontiguousarray(u, dtype=np.float64),
    )
    if failed >= 0:
        a, b = (int(x) for x in E[failed])
        raise WorkbenchError(f"tracing input edge {a}-{b} over the flipped triangulation failed")
    return {"in_edge": E[edge], "t_in": t_in, "out_id": out_id, "t_out": t_out}


def common_subdivision(
    V: np.ndarray,
    F_in: np.ndarray,
    F_out: np.ndarray,
    X: np.ndarray,
    crossings: dict,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Triangulated common subdivision of the input and the flat triangulation.

    Parameters
    ----------
    V : (#V, 3) float
        Input vertex positions.
    F_in : (#F, 3) int
        Input triangles.
    F_out : (#F, 3) int
        The flipped triangulation (``tri.F``).
    X : (#V, 2) float
        Flat positions of the vertices (the layout of ``F_out``).
    crossings : dict
        :func:`trace_input_edges`.

    Returns
    -------
    V_sub : (#V + #X, 3) float
        The input vertices, in their order, then one vertex per crossing, on its
        input edge.
    F_sub : (#S, 3) int
        Triangles: each input triangle that no flat edge crosses as it is, the
        others cut into the convex cells of the common subdivision, each fanned
        into triangles; counter-clockwise like the input.
    uv_sub : (#V + #X, 2) float
        Flat positions of every vertex of ``V_sub``.
    parent : (#S,) int
        The input triangle each one lies in.
    """
    n = len(V)
    a, b = crossings["in_edge"].T
    t_in, t_out, out_id = crossings["t_in"], crossings["t_out"], crossings["out_id"]
    of, ok = np.divmod(out_id, 3)
    v, w = F_out[of, (ok + 1) % 3], F_out[of, (ok + 2) % 3]
    nx = len(t_in)
    V_sub = np.concatenate([V, (1 - t_in)[:, None] * V[a] + t_in[:, None] * V[b]])
    uv_sub = np.concatenate([X, (1 - t_out)[:, None] * X[v] + t_out[:, None] * X[w]])
    if nx == 0:
        return V_sub, F_in.copy(), uv_sub, np.arange(len(F_in))
    ids = n + np.arange(nx)

    # input faces beside each input edge, with the corner opposite, for the edges crossed
    E_in, FE_in, _ = unique_edges(F_in)
    ekey = E_in[:, 0] * n + E_in[:, 1]
    ikey = np.minimum(a, b) * n + np.maximum(a, b)
    crossed = np.isin(ekey[FE_in], ikey)
    faces_of_edge: dict[int, list[tuple[int, int]]] = {}
    for f, k in zip(*np.nonzero(crossed), strict=True):
        faces_of_edge.setdefault(int(ekey[FE_in[f, k]]), []).append((int(f), int(F_in[f, k])))

    # points on each input face's edges, by position from the edge's first vertex (as the face runs)
    on_edge: dict[int, list[tuple[float, int]]] = {}
    pos = np.where(a < b, t_in, 1 - t_in)  # from the lower-numbered end
    for key, p, i in zip(ikey.tolist(), pos.tolist(), ids.tolist(), strict=True):
        on_edge.setdefault(key, []).append((p, i))

    # chords: consecutive points along each flat edge, in the input face holding both
    chords: dict[int, list[tuple[int, int]]] = {}
    order = np.lexsort((t_out, out_id))
    sorted_id = out_id[order]
    bounds = np.flatnonzero(np.diff(sorted_id)) + 1
    for start, stop in zip(np.concatenate([[0], bounds]).tolist(), np.append(bounds, nx).tolist(), strict=True):
        end = stop - 1
        run = order[start : end + 1]
        p, q = int(v[order[start]]), int(w[order[start]])
        # the path p -> crossings -> q; each step lies in one input face
        pts = [p, *ids[run].tolist(), q]
        edges = [None, *ikey[run].tolist(), None]
        for i in range(len(pts) - 1):
            face = _face_between(faces_of_edge, edges[i], edges[i + 1], pts[i], pts[i + 1])
            if face < 0:
                raise WorkbenchError(f"common subdivision: flat edge {p}-{q} leaves the input faces it crosses")
            chords.setdefault(face, []).append((pts[i], pts[i + 1]))

    # untouched input faces stay as they are; the others are cut into cells, fanned
    touched = np.zeros(len(F_in), dtype=bool)
    touched[list(chords)] = True
    F_new, parent_new = [], []
    for f in np.flatnonzero(touched).tolist():
        poly = []
        for j in range(3):
            p, q = int(F_in[f, j]), int(F_in[f, (j + 1) % 3])
            poly.append(p)
            pts = sorted(on_edge.get(min(p, q) * n + max(p, q), []))
            if p > q:
                pts = pts[::-1]
            poly.extend(i for _, i in pts)
        for cell in _split_polygon(poly, chords[f]):
            for i in range(1, len(cell) - 1):
                F_new.append((cell[0], cell[i], cell[i + 1]))
                parent_new.append(f)
    keep = np.flatnonzero(~touched)
    F_sub = np.concatenate([F_in[keep], np.array(F_new, dtype=np.int64).reshape(-1, 3)])
    parent = np.concatenate([keep, np.array(parent_new, dtype=np.int64)])
    # in input face order (a stable sort keeps each face's cells in their order)
    order = np.argsort(parent, kind="stable")
    return V_sub, F_sub[order], uv_sub, parent[order]


def _face_between(faces_of_edge, e1, e2, p1, p2) -> int:
    # the input face containing segment p1 -> p2, where p1 lies on input edge e1 (or is
    # the vertex p1 when e1 is None) and p2 on e2 (or is the vertex p2)
    if e1 is None:
        for f, opposite in faces_of_edge[e2]:
            if opposite == p1:
                return f
        return -1
    if e2 is None:
        for f, opposite in faces_of_edge[e1]:
            if opposite == p2:
                return f
        return -1
    common = {f for f, _ in faces_of_edge[e1]} & {f for f, _ in faces_of_edge[e2]}
    return common.pop() if len(common) == 1 else -1


def _split_polygon(poly: list[int], chords: list[tuple[int, int]]) -> list[list[int]]:
    # cells of a convex polygon (vertex ids counter-clockwise) cut by non-crossing chords
    cells, stack = [], [(poly, chords)]
    while stack:
        p, cs = stack.pop()
        where = {x: i for i, x in enumerate(p)}
        for c in cs:
            i, j = sorted((where[c[0]], where[c[1]]))
            if j - i == 1 or (i == 0 and j == len(p) - 1):
                continue  # a chord along a side of this cell
            A, B = p[i : j + 1], p[j:] + p[: i + 1]
            rest = [d for d in cs if d is not c]
            inA, inB = set(A), set(B)
            stack.append((A, [d for d in rest if d[0] in inA and d[1] in inA]))
            stack.append((B, [d for d in rest if d[0] in inB and d[1] in inB]))
            break
        else:
            cells.append(p)
    return cells
