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

from workbench.conformal.intrinsic import IntrinsicTriangulation, corner_twins
from workbench.errors import WorkbenchError
from workbench.mesh.topology import unique_edges


def _sigmoid_of_log(x: float) -> float:
    # q / (1 + q) for q = e^x, without overflow either way
    return 1.0 / (1.0 + np.exp(-x)) if x >= 0 else np.exp(x) / (1.0 + np.exp(x))


class _Fans:
    """Corners around each vertex of a triangulation, counter-clockwise from its reference corner."""

    def __init__(self, F: np.ndarray, T: np.ndarray, lam: np.ndarray):
        self.F, self.T = F, T
        self.h = np.exp(0.5 * (lam - lam[:, [1, 2, 0]] - lam[:, [2, 0, 1]]))

    def next_ccw(self, f: int, k: int) -> tuple[int, int]:
        t = int(self.T[f, (k + 1) % 3])
        if t < 0:
            return -1, -1
        return t // 3, (t % 3 + 1) % 3


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
    T_in = corner_twins(F_in)
    fans_in = _Fans(F_in, T_in, lam_in)
    fans_out = _Fans(tri.F, tri.T, tri.lam)
    F_out, lam_out, T_out = tri.F, tri.lam, tri.T
    # Every input edge is located in T' by its direction at one end; one that leaves
    # along an edge of T' ending at its other end is that edge (T' may join the same
    # two vertices by several edges, so the vertex pair alone does not tell).
    todo = _edge_keys(F_in, n_vertices)
    lam_edge_in = _edge_lambda(F_in, lam_in, n_vertices)

    from workbench.conformal.intrinsic import reference_corners

    in_ref_face, in_ref_corner = reference_corners(F_in, T_in, n_vertices)
    offsets: dict[int, dict[int, float]] = {}

    def fan_offsets(a: int) -> dict[int, float]:
        # horocyclic offset of every edge a -> w, counter-clockwise from a's reference
        if a in offsets:
            return offsets[a]
        f, k = int(in_ref_face[a]), int(in_ref_corner[a])
        start, acc, out = (f, k), 0.0, {}
        while True:
            out.setdefault(int(F_in[f, (k + 1) % 3]), acc)
            acc += fans_in.h[f, k]
            nf, nk = fans_in.next_ccw(f, k)
            if nf < 0:
                out.setdefault(int(F_in[f, (k + 2) % 3]), acc)
                break
            f, k = nf, nk
            if (f, k) == start:
                break
        offsets[a] = out
        return out

    in_edge, t_in, out_id, t_out = [], [], [], []

    def record(a, b, y2, lam_ab, f, k, dv, dw, lam_av, lam_aw, v, w):
        in_edge.append((a, b))
        # along the input edge: β_b/β_a = 1 / (l_ab² y²) with a's horocycle at height 1
        t_in.append(_sigmoid_of_log(-lam_ab - np.log(y2)))
        # along the flat edge: β_w/β_v = (x - x_v) l_av² / ((x_w - x) l_aw²), then b̃_i ∝ β_i e^{-u_i}
        t = _sigmoid_of_log(np.log(dv) - np.log(dw) + lam_av - lam_aw + u[v] - u[w])
        twin = int(T_out[f, k])
        # one id per flat edge: its smaller corner slot, oriented as that corner's face runs it
        if twin < 3 * f + k:
            out_id.append(twin)
            t_out.append(1.0 - t)
        else:
            out_id.append(3 * f + k)
            t_out.append(t)

    for key in todo.tolist():
        a, b = divmod(int(key), n_vertices)
        s = fan_offsets(a)[b]
        lam_ab = lam_edge_in[key]
        # walk a's corners in T' to the one the direction leaves through
        f, k = int(tri.ref_face[a]), int(tri.ref_corner[a])
        r = float(tri.ref_offset[a]) + s
        for _ in range(4 * len(F_out)):
            h = fans_out.h[f, k]
            if r < h:
                break
            nf, nk = fans_out.next_ccw(f, k)
            if nf < 0:
                r = h * (1 - 1e-12)  # round-off past the last corner of a boundary vertex
                break
            r -= h
            f, k = nf, nk
        h = float(fans_out.h[f, k])
        v, w = int(F_out[f, (k + 1) % 3]), int(F_out[f, (k + 2) % 3])
        # leaving along an edge of T' that ends at b: the input edge is that edge
        if (r <= 1e-9 * h and v == b) or (h - r <= 1e-9 * h and w == b):
            continue
        lam_av, lam_aw = lam_out[f, (k + 2) % 3], lam_out[f, (k + 1) % 3]
        x_v, x_w, x = 0.0, h, min(max(r, 0.0), h)
        ce, ck = f, k  # the flat edge crossed next: opposite corner (ce, ck)
        for _step in range(len(F_out) + 1):
            dv, dw = max(x - x_v, 1e-300), max(x_w - x, 1e-300)
            record(a, b, dv * dw, lam_ab, ce, ck, dv, dw, lam_av, lam_aw, v, w)
            t = int(T_out[ce, ck])
            if t < 0:
                raise WorkbenchError(f"tracing input edge {a}-{b} over the flipped triangulation reached the boundary")
            g, m = divmod(t, 3)
            d = int(F_out[g, m])
            # g = (d, w, v): l_vd opposite w (corner m+1), l_dw opposite v (corner m+2)
            lam_vw, lam_vd, lam_dw = lam_out[g, m], lam_out[g, (m + 1) % 3], lam_out[g, (m + 2) % 3]
            lam_ad = 2.0 * np.logaddexp(0.5 * (lam_av + lam_dw), 0.5 * (lam_aw + lam_vd)) - lam_vw
            x_d = x_v + float(np.exp(0.5 * (lam_vd - lam_av - lam_ad)))
            if d == b and abs(x_d - x) <= 1e-6 * (x_w - x_v):
                break
            if x < x_d:
                w, lam_aw, x_w, ce, ck = d, lam_ad, x_d, g, (m + 1) % 3
            else:
                v, lam_av, x_v, ce, ck = d, lam_ad, x_d, g, (m + 2) % 3
        else:
            raise WorkbenchError(f"tracing input edge {a}-{b} over the flipped triangulation did not end")
    return {
        "in_edge": np.array(in_edge, dtype=np.int64).reshape(-1, 2),
        "t_in": np.array(t_in),
        "out_id": np.array(out_id, dtype=np.int64),
        "t_out": np.array(t_out),
    }


def _edge_keys(F: np.ndarray, n: int) -> np.ndarray:
    E, _, _ = unique_edges(F)
    return E[:, 0] * n + E[:, 1]


def _edge_lambda(F: np.ndarray, lam: np.ndarray, n: int) -> dict[int, float]:
    a, b = F[:, [1, 2, 0]].ravel(), F[:, [2, 0, 1]].ravel()
    key = np.minimum(a, b) * n + np.maximum(a, b)
    return dict(zip(key.tolist(), lam.ravel().tolist(), strict=True))


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

    # input faces beside each input edge, with the corner opposite
    E_in, FE_in, _ = unique_edges(F_in)
    ekey = E_in[:, 0] * n + E_in[:, 1]
    faces_of_edge: dict[int, list[tuple[int, int]]] = {}
    for f, k in zip(*np.nonzero(np.ones_like(FE_in, dtype=bool)), strict=True):
        faces_of_edge.setdefault(int(ekey[FE_in[f, k]]), []).append((int(f), int(F_in[f, k])))

    # points on each input face's edges, by position from the edge's first vertex (as the face runs)
    on_edge: dict[int, list[tuple[float, int]]] = {}
    for c in range(nx):
        lo, hi = min(a[c], b[c]), max(a[c], b[c])
        pos = t_in[c] if a[c] == lo else 1 - t_in[c]  # from lo to hi
        on_edge.setdefault(int(lo * n + hi), []).append((float(pos), int(ids[c])))

    # chords: consecutive points along each flat edge, in the input face holding both
    chords: dict[int, list[tuple[int, int]]] = {}
    order = np.lexsort((t_out, out_id))
    ikey = np.minimum(a, b) * n + np.maximum(a, b)
    start = 0
    while start < nx:
        end = start
        while end + 1 < nx and out_id[order[end + 1]] == out_id[order[start]]:
            end += 1
        run = order[start : end + 1]
        p, q = int(v[order[start]]), int(w[order[start]])
        # the path p -> crossings -> q; each step lies in one input face
        pts = [p, *(int(ids[c]) for c in run), q]
        edges = [None, *(int(ikey[c]) for c in run), None]
        for i in range(len(pts) - 1):
            face = _face_between(faces_of_edge, edges[i], edges[i + 1], pts[i], pts[i + 1])
            if face < 0:
                raise WorkbenchError(f"common subdivision: flat edge {p}-{q} leaves the input faces it crosses")
            chords.setdefault(face, []).append((pts[i], pts[i + 1]))
        start = end + 1

    F_sub, parent = [], []
    touched = set(chords)
    for f in range(len(F_in)):
        if f not in touched:
            F_sub.append(F_in[f])
            parent.append(f)
            continue
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
                F_sub.append((cell[0], cell[i], cell[i + 1]))
                parent.append(f)
    return V_sub, np.array(F_sub, dtype=np.int64), uv_sub, np.array(parent, dtype=np.int64)


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
