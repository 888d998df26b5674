"""Disc-shaped regions of a part's faces: the face graph, holes filled, pinches opened, rings cut open."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from workbench.errors import WorkbenchError
from workbench.mesh.topology import boundary_loops, unique_edges
from workbench.views.visibility import face_adjacency


def face_graph(F: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """Faces sharing an edge, and the edges.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.

    Returns
    -------
    adjacency : (#F, #F) sparse
        Non-zero where two faces share an edge (:func:`workbench.views.visibility.face_adjacency`).
    E : (#E, 2) int
        Undirected edges (see :func:`workbench.mesh.topology.unique_edges`).
    edge_faces : (#E, 2) int
        The two faces of each edge, -1 for the missing one on the boundary.
    """
    E, FE, _ = unique_edges(F)
    edge_faces = np.full((len(E), 2), -1, dtype=np.int64)
    f = np.repeat(np.arange(len(F)), 3)
    e = FE.ravel()
    order = np.argsort(e, kind="stable")
    e, f = e[order], f[order]
    first = np.r_[True, e[1:] != e[:-1]]
    edge_faces[e[first], 0] = f[first]
    edge_faces[e[~first], 1] = f[~first]
    return face_adjacency(FE), E, edge_faces


def components_of(adjacency: sp.csr_matrix, mask: np.ndarray) -> np.ndarray:
    """Connected component label of every face in ``mask`` (-1 elsewhere)."""
    idx = np.flatnonzero(mask)
    labels = np.full(len(mask), -1, dtype=np.int64)
    if len(idx):
        _, lab = connected_components(adjacency[idx][:, idx], directed=False)
        labels[idx] = lab
    return labels


def disc_region(
    F: np.ndarray,
    wanted: np.ndarray,
    area: np.ndarray,
    allowed: np.ndarray | None = None,
    graph=None,
    keep_holes: bool = False,
) -> np.ndarray:
    """The largest disc-shaped region made from a set of faces.

    Keeps the largest connected part (by area), fills its holes with allowed faces,
    and opens pinches (two fans of faces meeting at one vertex) by adding the faces
    around the vertex, so that the region is a topological disc: one boundary loop,
    Euler characteristic 1.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles of the part (a disc).
    wanted : (#F,) bool
        The faces asked for.
    area : (#F,) float
        Face areas, mm².
    allowed : (#F,) bool, optional
        Faces the region may take to fill holes and pinches (default: all).
    graph : tuple, optional
        :func:`face_graph` of ``F``, when the caller has it.
    keep_holes : bool
        Leave holes that hold faces not allowed (another film inside this one) open
        instead of refusing; :func:`cut_to_disc` then opens the ring.

    Returns
    -------
    region : (#F,) bool

    Raises
    ------
    WorkbenchError
        No face wanted, or a hole or pinch that only faces not allowed could close.
    """
    adjacency, E, edge_faces = graph if graph is not None else face_graph(F)
    allowed = np.ones(len(F), bool) if allowed is None else allowed
    on_rim = np.zeros(len(F), bool)
    on_rim[edge_faces[edge_faces[:, 1] < 0, 0]] = True
    region = wanted.copy()
    for _ in range(8):
        labels = components_of(adjacency, region)
        if labels.max() < 0:
            raise WorkbenchError("the region holds no face")
        sizes = np.bincount(labels[region], weights=area[region])
        region = labels == int(np.argmax(sizes))
        # holes: parts of the rest that border the region and do not reach the part's rim are
        # enclosed (a part that does not border it is another body of the mesh: a scan's eyes
        # and teeth, 39 closed pieces beside an ogre, are not holes in its skin)
        rest = components_of(adjacency, ~region)
        open_parts = np.unique(rest[on_rim & ~region])
        bordering = np.unique(rest[adjacency[np.flatnonzero(region)].indices])
        hole = (~region) & ~np.isin(rest, open_parts) & np.isin(rest, bordering[bordering >= 0])
        if (hole & ~allowed).any():
            if not keep_holes:
                raise WorkbenchError(f"the region encloses {int((hole & ~allowed).sum())} faces of another film")
            # fill only the holes that hold no other film
            blocked = np.unique(rest[hole & ~allowed])
            hole &= ~np.isin(rest, blocked)
        region |= hole
        pinched = _pinched_vertices(F, region, E, edge_faces)
        if len(pinched) == 0:
            return region
        around = np.isin(F, pinched).any(axis=1) & ~region
        if (around & ~allowed).all() and around.any():
            raise WorkbenchError(f"the region is pinched at vertex {int(pinched[0])} between other films")
        region |= around & allowed
    raise WorkbenchError("the region does not become a disc")


def _pinched_vertices(F: np.ndarray, region: np.ndarray, E: np.ndarray, edge_faces: np.ndarray) -> np.ndarray:
    """Vertices with more than two region-boundary edges (two fans meeting at a point)."""
    inside = np.where(edge_faces >= 0, region[np.maximum(edge_faces, 0)], False)
    rim = inside.sum(axis=1) == 1
    count = np.bincount(E[rim].ravel(), minlength=int(F.max()) + 1)
    return np.flatnonzero(count > 2)


def is_disc_region(F: np.ndarray, region: np.ndarray, graph=None) -> bool:
    """Whether some faces of a disc-shaped part form one disc.

    A connected region of a disc is planar: with no pinched vertex (two fans meeting at
    a point), it is a disc exactly when its Euler characteristic V - E + F is 1 (a
    region around a hole has 0 or less).

    Parameters
    ----------
    F : (#F, 3) int
        Triangles of the part (a disc).
    region : (#F,) bool
        The faces; assumed connected (two adjacent films are).
    graph : tuple, optional
        :func:`face_graph` of ``F``.

    Returns
    -------
    bool
    """
    _, E, edge_faces = graph if graph is not None else face_graph(F)
    if len(_pinched_vertices(F, region, E, edge_faces)):
        return False
    inside = np.where(edge_faces >= 0, region[np.maximum(edge_faces, 0)], False).any(axis=1)
    return len(np.unique(F[region])) - int(inside.sum()) + int(region.sum()) == 1


def submesh(V: np.ndarray, F: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mesh of some faces, its vertices renumbered in their original order.

    Parameters
    ----------
    V : (#V, 3) float
    F : (#F, 3) int
    faces : (k,) int
        Faces to keep, in this order.

    Returns
    -------
    Vs : (#Vs, 3) float
    Fs : (k, 3) int
    vertices : (#Vs,) int
        Original index of each kept vertex (increasing).
    """
    vertices, Fs = np.unique(F[faces], return_inverse=True)
    return V[vertices], Fs.reshape(-1, 3).astype(np.int64), vertices


def cut_to_disc(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Open a mesh with several boundary loops (a ring around another film) into a disc.

    Each extra loop is joined to the first by the shortest path along edges through
    the inside, and the mesh is cut along it: the path's vertices are repeated for
    the faces on one side, so the ring becomes a disc whose outline runs along both
    sides of the cut (a seam of this film with itself).

    Parameters
    ----------
    V : (#V, 3) float
    F : (#F, 3) int
        A connected manifold mesh of genus 0 with one or more boundary loops.

    Returns
    -------
    Vc : (#Vc, 3) float
        Vertices, the repeated ones after the input's.
    Fc : (#F, 3) int
        The same faces, renumbered along the cuts.
    source : (#Vc,) int
        Input vertex of each vertex.
    """
    from scipy.sparse.csgraph import dijkstra

    source = np.arange(len(V))
    for _ in range(64):
        loops = boundary_loops(F)
        if len(loops) <= 1:
            return V[source], F, source
        E, _, count = unique_edges(F)
        on_loop = np.zeros(len(source), bool)
        for loop in loops[1:]:
            on_loop[loop] = True
        first = np.zeros(len(source), bool)
        first[loops[0]] = True
        # the path may touch boundary vertices only at its two ends: edges between two
        # boundary vertices, and edges into boundary vertices other than the ends, are out
        rim = first | on_loop
        ok = ~(rim[E[:, 0]] & rim[E[:, 1]])
        P = V[source]
        w = np.linalg.norm(P[E[ok, 0]] - P[E[ok, 1]], axis=1)
        n = len(source)
        G = sp.csr_matrix((np.r_[w, w], (np.r_[E[ok, 0], E[ok, 1]], np.r_[E[ok, 1], E[ok, 0]])), shape=(n, n))
        target = loops[1]
        dist, pred, start = dijkstra(G, indices=loops[0], return_predecessors=True, min_only=True)
        end = target[np.argmin(dist[target])]
        if not np.isfinite(dist[end]):
            raise WorkbenchError("a ring-shaped film cannot be cut open (no path joins its two rims)")
        path = [int(end)]
        while pred[path[-1]] >= 0:
            path.append(int(pred[path[-1]]))
        path = path[::-1]  # from the first loop to the other
        F, new = _cut_along(F, path)
        source = np.r_[source, source[new]]
    raise WorkbenchError("a film with too many holes")


def _cut_along(F: np.ndarray, path: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Repeat the vertices of an edge path for the faces on its left; returns new F and the repeated vertices."""
    n = int(F.max()) + 1
    on_path = {(a, b) for a, b in zip(path[:-1], path[1:], strict=True)}
    on_path |= {(b, a) for a, b in on_path}
    forward = set(zip(path[:-1], path[1:], strict=True))
    left = set()
    # the face holding directed edge a→b lies on its left (counter-clockwise faces)
    for k in range(3):
        a, b = F[:, k], F[:, (k + 1) % 3]
        for f in np.flatnonzero(np.isin(a, path) & np.isin(b, path)):
            if (int(a[f]), int(b[f])) in forward:
                left.add(int(f))
    # around each path vertex, spread the left side through faces that share a non-path edge
    side = set(left)
    vf: dict[int, list[int]] = {v: [] for v in path}
    for f in np.flatnonzero(np.isin(F, path).any(axis=1)):
        for v in F[f]:
            if int(v) in vf:
                vf[int(v)].append(int(f))
    for v in path:
        fan = vf[v]
        grow = True
        while grow:
            grow = False
            for f in fan:
                if f in side:
                    continue
                for g in fan:
                    if g in side:
                        shared = set(map(int, F[f])) & set(map(int, F[g]))
                        if len(shared) == 2 and tuple(shared) not in on_path and tuple(shared)[::-1] not in on_path:
                            side.add(f)
                            grow = True
                            break
    Fc = F.copy()
    new = np.array(path, dtype=np.int64)
    remap = {v: n + i for i, v in enumerate(path)}
    for f in side:
        for k in range(3):
            v = int(Fc[f, k])
            if v in remap:
                Fc[f, k] = remap[v]
    return Fc, new


def is_disc(F: np.ndarray) -> bool:
    """One boundary loop and Euler characteristic 1."""
    E, _, _ = unique_edges(F)
    n_v = len(np.unique(F))
    try:
        loops = boundary_loops(F)
    except WorkbenchError:
        return False
    return len(loops) == 1 and n_v - len(E) + len(F) == 1
