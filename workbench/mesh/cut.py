"""Cutting a surface into a disc: seams between its rims, then across its handles, where the views see least."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra, minimum_spanning_tree

from workbench.errors import WorkbenchError
from workbench.mesh.selection import edge_faces
from workbench.mesh.topology import boundary_loops, unique_edges

# A millimetre of seam on surface a view sees face-on costs as much as 1 + SEEN_COST unseen
# millimetres (a view seeing the surface at angle θ from its normal: 1 + SEEN_COST cos θ). A
# seam shows in the print as a line where the film meets itself, and the views say where the
# part is looked at: a seam goes round through surface no view sees when that detour is at most
# five times as long, and crosses seen surface where it is seen most obliquely.
SEEN_COST = 4.0


@dataclass(frozen=True)
class CutOptions:
    """How seams are priced.

    Attributes
    ----------
    seen_cost : float
        Extra cost of a seam millimetre seen face-on, in unseen millimetres.
    max_seams : int
        Give up beyond this many seams (a surface with more holes or handles is no film).
    """

    seen_cost: float = SEEN_COST
    max_seams: int = 64


def split_along(F: np.ndarray, n_vertices: int, cut: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Repeat the vertices where cut edges (or a pinch) separate the faces around them.

    The corners of the faces at a vertex are joined across every uncut edge they share; each
    group of corners so joined (a wedge of the fan between two cuts, or one fan of a pinch) is
    one vertex. The wedge holding a vertex's first corner keeps its number, the others are
    numbered after ``n_vertices`` (by vertex, then first corner), so the result is deterministic.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles of an edge-manifold mesh.
    n_vertices : int
        Vertex count (``F.max() + 1`` at least).
    cut : (#E,) bool, optional
        Edges to cut, indexed as :func:`workbench.mesh.topology.unique_edges` of ``F``; none:
        only pinched vertices are split.

    Returns
    -------
    Fc : (#F, 3) int
        The same faces on the split vertices.
    source : (#Vc,) int
        Vertex of ``F`` each vertex of ``Fc`` repeats (``arange(n_vertices)`` first).
    """
    E, FE, _ = unique_edges(F)
    ef = edge_faces(F, FE, len(E))
    joined = ef[:, 1] >= 0
    if cut is not None:
        joined &= ~cut
    e = np.flatnonzero(joined)
    f1, f2 = ef[e, 0], ef[e, 1]
    rows, cols = [], []
    for end in (0, 1):
        u = E[e, end][:, None]
        rows.append(3 * f1 + np.argmax(F[f1] == u, axis=1))
        cols.append(3 * f2 + np.argmax(F[f2] == u, axis=1))
    n = 3 * len(F)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    G = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, labels = connected_components(G, directed=False)
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    src = F.ravel()[first]
    order = np.lexsort((first, src))
    primary = np.r_[True, src[order][1:] != src[order][:-1]]
    new_id = np.empty(len(first), dtype=np.int64)
    new_id[order[primary]] = src[order[primary]]
    extra = order[~primary]
    new_id[extra] = n_vertices + np.arange(len(extra))
    Fc = new_id[inverse.ravel()].reshape(-1, 3)
    return Fc, np.r_[np.arange(n_vertices), src[extra]]


def edge_costs(P: np.ndarray, E: np.ndarray, ef: np.ndarray, seen: np.ndarray, seen_cost: float) -> np.ndarray:
    """The price of cutting each edge: its length, more where the views see it.

    Parameters
    ----------
    P : (#V, 3) float
        Vertices, mm.
    E : (#E, 2) int
        Edges.
    ef : (#E, 2) int
        Their faces (-1: none).
    seen : (#F,) float
        How squarely the views see each face: the largest cosine between its normal and the
        direction to a camera that sees it, 0 where none does.
    seen_cost : float
        See :data:`SEEN_COST`.

    Returns
    -------
    (#E,) float
        Cost, mm (unseen-equivalent).
    """
    length = np.linalg.norm(P[E[:, 0]] - P[E[:, 1]], axis=1)
    s = np.maximum(np.where(ef[:, 0] >= 0, seen[ef[:, 0]], 0.0), np.where(ef[:, 1] >= 0, seen[ef[:, 1]], 0.0))
    return length * (1.0 + seen_cost * s)


def _edge_ids(E: np.ndarray, a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Rows of ``E`` (sorted, as unique_edges makes them) of the edges (a, b)."""
    keys = E[:, 0] * n + E[:, 1]
    return np.searchsorted(keys, np.minimum(a, b) * n + np.maximum(a, b))


def _graph(E: np.ndarray, w: np.ndarray, usable: np.ndarray, n: int) -> sp.csr_matrix:
    a, b, w = E[usable, 0], E[usable, 1], w[usable]
    return sp.csr_matrix((np.r_[w, w], (np.r_[a, b], np.r_[b, a])), shape=(n, n))


def _walk(pred: np.ndarray, v: int) -> list[int]:
    """Vertices from ``v`` back to its tree's root (a predecessor array of scipy's dijkstra)."""
    path = [int(v)]
    while pred[path[-1]] >= 0:
        path.append(int(pred[path[-1]]))
    return path


def join_rims(
    V: np.ndarray, F: np.ndarray, seen: np.ndarray, options: CutOptions
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Cut a surface with several boundary loops along seams that join them into one.

    Each round joins the first loop to the one nearest it (Dijkstra from all its vertices at
    once, priced by :func:`edge_costs`) and cuts along that path: the two loops and the
    path's two sides become one loop. The next round starts from that loop, so each seam is
    the cheapest from all the rims joined so far (Prim's algorithm on the rims): ``loops - 1``
    seams, the fewest that leave one rim.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        A connected, edge-manifold, oriented surface.
    seen : (#F,) float
        How squarely the views see each face (see :func:`edge_costs`).
    options : CutOptions

    Returns
    -------
    Fc : (#F, 3) int
        The faces on the cut vertices.
    source : (#Vc,) int
        Vertex of ``V`` each repeats.
    seams : list of (k,) int
        Each seam's vertices in ``V``'s numbering, from rim to rim.
    """
    source = np.arange(len(V))
    seams: list[np.ndarray] = []
    while True:
        loops = boundary_loops(F)
        if len(loops) <= 1:
            return F, source, seams
        if len(seams) >= options.max_seams:
            raise WorkbenchError(f"the surface has more than {options.max_seams} holes to join")
        n = len(source)
        E, FE, count = unique_edges(F)
        ef = edge_faces(F, FE, len(E))
        first = np.zeros(n, bool)
        first[loops[0]] = True
        other = np.zeros(n, bool)
        other[np.concatenate(loops[1:])] = True
        a, b = E[:, 0], E[:, 1]
        # inside edges only; one that joins two rim vertices only from the first loop to another
        # (a chord between two vertices of one loop would cut a piece off)
        usable = (count == 2) & (
            ~(first | other)[a] | ~(first | other)[b] | (first[a] & other[b]) | (other[a] & first[b])
        )
        w = edge_costs(V[source], E, ef, seen, options.seen_cost)
        dist, pred = dijkstra(_graph(E, w, usable, n), indices=loops[0], min_only=True, return_predecessors=True)[:2]
        targets = np.flatnonzero(other)
        end = targets[np.argmin(dist[targets])]
        if not np.isfinite(dist[end]):
            raise WorkbenchError("the surface's rims cannot be joined (no path inside it links them)")
        path = np.asarray(_walk(pred, end)[::-1])
        cut = np.zeros(len(E), bool)
        cut[_edge_ids(E, path[:-1], path[1:], n)] = True
        F, again = split_along(F, n, cut)
        seams.append(source[path])
        source = source[again]


def cut_handles(
    V: np.ndarray, F: np.ndarray, seen: np.ndarray, options: CutOptions
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Cut a surface with one rim and handles (genus g) into a disc along 2g seams.

    Tree-cotree (Eppstein 2003) with the greedy choice of Erickson and Whittlesey (2005): T is
    the cheapest-path tree from the rim (Dijkstra from all rim vertices, priced by
    :func:`edge_costs`); every edge e = (a, b) outside T closes a loop rim → a → b → rim of
    cost d(a) + w(e) + d(b). The dual edges outside T, most expensive loops first, make a
    spanning tree of the faces (the cotree, a maximum spanning tree); with V - E + F = 1 - 2g
    exactly 2g edges are left in neither tree, and their loops, the cheapest such system, cut
    the handles open. Cut along all of them, the surface is a disc.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        A connected, edge-manifold, oriented surface with one boundary loop.
    seen : (#F,) float
        How squarely the views see each face (see :func:`edge_costs`).
    options : CutOptions

    Returns
    -------
    Fc : (#F, 3) int
        The faces on the cut vertices.
    source : (#Vc,) int
        Vertex of ``V`` each repeats.
    seams : list of (k,) int
        Each seam's vertices in ``V``'s numbering, from the rim round the handle to the rim.
    """
    n = len(V)
    E, FE, count = unique_edges(F)
    chi = len(np.unique(F)) - len(E) + len(F)
    if chi == 1:
        return F, np.arange(n), []
    if (1 - chi) // 2 * 2 > options.max_seams:
        raise WorkbenchError(f"the surface has {(1 - chi) // 2} handles; at most {options.max_seams // 2} are cut")
    ef = edge_faces(F, FE, len(E))
    loops = boundary_loops(F)
    inner = count == 2
    w = edge_costs(V, E, ef, seen, options.seen_cost)
    dist, pred = dijkstra(
        _graph(E, w, inner, n), indices=np.concatenate(loops), min_only=True, return_predecessors=True
    )[:2]
    has = np.flatnonzero(pred >= 0)
    tree = np.zeros(len(E), bool)
    tree[_edge_ids(E, has, pred[has], n)] = True
    dual = np.flatnonzero(inner & ~tree)
    loop_cost = dist[E[dual, 0]] + w[dual] + dist[E[dual, 1]]
    # a maximum spanning tree as scipy's minimum one: weights flipped, kept above zero (zero is no edge)
    flipped = loop_cost.max() + 1.0 - loop_cost
    nf = len(F)
    fa, fb = ef[dual, 0], ef[dual, 1]
    T = minimum_spanning_tree(sp.csr_matrix((flipped, (fa, fb)), shape=(nf, nf))).tocoo()
    face_key = np.minimum(fa, fb) * nf + np.maximum(fa, fb)
    in_cotree = np.isin(face_key, np.minimum(T.row, T.col) * nf + np.maximum(T.row, T.col))
    left = dual[~in_cotree]
    left = left[np.argsort(loop_cost[~in_cotree], kind="stable")]
    cut = np.zeros(len(E), bool)
    seams = []
    for e in left:
        path = np.asarray(_walk(pred, E[e, 0])[::-1] + _walk(pred, E[e, 1]))
        cut[_edge_ids(E, path[:-1], path[1:], n)] = True
        seams.append(path)
    Fc, source = split_along(F, n, cut)
    return Fc, source, seams


def is_disc(F: np.ndarray) -> bool:
    """One boundary loop and Euler characteristic V - E + F = 1 (a connected, manifold mesh)."""
    E, _, count = unique_edges(F)
    if (count > 2).any():
        return False
    try:
        loops = boundary_loops(F)
    except ValueError:
        return False
    return len(loops) == 1 and len(np.unique(F)) - len(E) + len(F) == 1


def cut_to_disc(
    V: np.ndarray, F: np.ndarray, seen: np.ndarray, options: CutOptions = CutOptions()
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """A connected surface with a rim cut into a disc: pinches split, rims joined, handles cut.

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        A connected, edge-manifold, consistently oriented surface with at least one boundary loop.
    seen : (#F,) float
        How squarely the views see each face, 0 to 1 (see :func:`edge_costs`).
    options : CutOptions

    Returns
    -------
    Fc : (#F, 3) int
        The same faces, on vertices repeated along the seams.
    source : (#Vc,) int
        Vertex of ``V`` each vertex of the disc is (``arange(len(V))`` first).
    seams : list of (k,) int
        Each seam's vertices in ``V``'s numbering: first those joining rims, then those
        across handles.

    Raises
    ------
    WorkbenchError
        An edge of more than two faces, no rim, or a surface the seams do not make a disc.
    """
    E, _, count = unique_edges(F)
    if (count > 2).any():
        e = E[np.argmax(count > 2)]
        raise WorkbenchError(f"the surface has edges of more than two faces (edge {e[0]}-{e[1]}): not a manifold")
    if not (count == 1).any():
        raise WorkbenchError("the surface is closed: it has no rim to cut it open from")
    # a pinch (two fans of faces meeting at one vertex) is two vertices of the film
    F1, s1 = split_along(F, len(V), None)
    F2, s2, rims = join_rims(V[s1], F1, seen, options)
    F3, s3, handles = cut_handles(V[s1][s2], F2, seen, options)
    source = s1[s2][s3]
    if not is_disc(F3):
        raise WorkbenchError("the surface does not become a disc when cut (is it one connected piece?)")
    return F3, source, [s1[p] for p in rims] + [s1[s2][p] for p in handles]


def path_length(V: np.ndarray, path: np.ndarray) -> float:
    """Length of a vertex path, mm (``V`` in mm)."""
    return float(np.linalg.norm(np.diff(V[path], axis=0), axis=1).sum())
