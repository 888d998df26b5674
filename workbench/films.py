"""Several films on one part: disc-shaped regions of the surface, chosen by hand or split automatically."""

from __future__ import annotations

import heapq
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from workbench.conformal.flatten import CrowdingError, FlattenOptions, FlattenResult, ScaleMode, flatten
from workbench.conformal.layout import polygon_self_intersections
from workbench.errors import WorkbenchError
from workbench.mesh.topology import boundary_loops, unique_edges
from workbench.mesh.validate import zero_area_faces
from workbench.views.visibility import face_adjacency

# A film is within its material when the stretch (3D length / print length) stays in
# [MIN_STRETCH, max_stretch] on all but this share of its surface (design's warning rule).
MIN_STRETCH = 0.8
MAX_OFF_SHARE = 0.01
# Smallest film the automatic split makes, in faces: below it a region is not split again.
MIN_FILM_FACES = 24
# Pieces the bisection may have at once, per film the plan may end with: bisection cuts far
# more than it must (a scanned figure's 7 films came from 70 pieces, a bust's 5 from 42) and
# merge_films joins them again; the bound only keeps a hopeless part from splitting for ever.
PIECES_PER_FILM = 10


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


def _components(adjacency: sp.csr_matrix, mask: np.ndarray) -> np.ndarray:
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
        labels = _components(adjacency, region)
        if labels.max() < 0:
            raise WorkbenchError("the region holds no face")
        sizes = np.bincount(labels[region], weights=area[region])
        region = labels == int(np.argmax(sizes))
        # holes: parts of the rest that border the region and do not reach the part's rim are
        # enclosed (a part that does not border it is another body of the mesh: a scan's eyes
        # and teeth, 39 closed pieces beside an ogre, are not holes in its skin)
        rest = _components(adjacency, ~region)
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


def stretch_window(stretch: np.ndarray, area: np.ndarray, max_stretch: float) -> tuple[float, float]:
    """The scale that keeps the most surface within the material, and that share.

    Scaling a print by ``s`` divides every stretch by ``s``; the band
    [MIN_STRETCH, max_stretch] is a window of fixed width in log stretch, slid over
    the area-weighted distribution of log stretch to cover the most area.

    Parameters
    ----------
    stretch : (#F,) float
        Stretch per face at the current scale (3D length / print length).
    area : (#F,) float
        Face areas, weights.
    max_stretch : float
        The material's limit.

    Returns
    -------
    s : float
        Factor to multiply the print's size by.
    share : float
        Share of the area within the band after scaling.
    """
    ok = np.isfinite(stretch) & (stretch > 0)
    x = np.log(stretch[ok])
    w = area[ok]
    order = np.argsort(x)
    x, w = x[order], w[order]
    cw = np.r_[0.0, np.cumsum(w)]
    width = np.log(max_stretch / MIN_STRETCH)
    # window [x_i, x_i + width] starting at each face's log stretch
    end = np.searchsorted(x, x + width, side="right")
    covered = cw[end] - cw[np.arange(len(x))]
    i = int(np.argmax(covered))
    # centre the covered faces in the band: the slack (band width minus their spread) is
    # split evenly, so that round-off does not push the extreme faces out; the lowest,
    # x_i, goes to log MIN_STRETCH + slack / 2, and scaling by s subtracts log s
    slack = width - (x[end[i] - 1] - x[i])
    return float(np.exp(x[i] - np.log(MIN_STRETCH) - 0.5 * slack)), float(covered[i] / area.sum())


@dataclass
class FilmFit:
    """One automatic film: its faces and its map at the chosen scale."""

    faces: np.ndarray
    flat: FlattenResult
    scale: ScaleMode
    within: float


def probe_film(
    V: np.ndarray,
    F: np.ndarray,
    faces: np.ndarray,
    max_stretch: float,
    options: FlattenOptions,
    max_off_share: float = MAX_OFF_SHARE,
) -> tuple[ScaleMode | None, float, str, FlattenResult | None]:
    """The first half of :func:`fit_film`: the free layout, the best scale, its share in the band, no overlap.

    A region passes with at most ``max_off_share`` of its surface outside the band (by
    default a film's own rule; :func:`join_within_budget` lets a film take more where the
    plan as a whole stays within its share).

    Returns
    -------
    scale : ScaleMode or None
        The print scale that keeps the most surface within the band, when the region
        passes (the share in the band and an outline clear of itself).
    within : float
        That share (0 when the layout failed).
    reason : str
        Why it does not fit, or "".
    layout : FlattenResult or None
        The free layout at area scale.
    """
    Vs, Fs, _ = submesh(V, F, faces)
    probe = replace(options, outline="free", scale=ScaleMode("area"), min_print_mm=0.0, check_overlap=False)
    try:
        flat = flatten(Vs, Fs, probe)
    except WorkbenchError as exc:
        return None, 0.0, str(exc).split(": ", 1)[-1], None
    s, within = stretch_window(flat.stretch, flat.area_3d, max_stretch)
    # (the share is a ratio of two sums of the same areas: 1e-9 of round-off is no surface)
    if within < 1 - max_off_share - 1e-9:
        return None, within, f"{1 - within:.1%} of it leaves the stretch band", flat
    loop = boundary_loops(flat.F)[0]
    if len(polygon_self_intersections(flat.uv[loop])):
        return None, within, "its outline overlaps itself", flat
    return ScaleMode("width", flat.width_mm * s), within, "", flat


def final_film(
    V: np.ndarray, F: np.ndarray, faces: np.ndarray, scale: ScaleMode, within: float, options: FlattenOptions
) -> tuple[FilmFit | None, str]:
    """The second half of :func:`fit_film`: the film's map at its scale, refused if it crowds."""
    Vs, Fs, _ = submesh(V, F, faces)
    try:
        final = flatten(Vs, Fs, replace(options, outline="free", scale=scale))
    except CrowdingError as exc:
        return None, f"{exc.share:.1%} of it is crowded"
    except WorkbenchError as exc:
        return None, str(exc).split(": ", 1)[-1]
    return FilmFit(faces=faces, flat=final, scale=scale, within=within), ""


def fit_film(
    V: np.ndarray,
    F: np.ndarray,
    faces: np.ndarray,
    max_stretch: float,
    options: FlattenOptions,
    max_off_share: float = MAX_OFF_SHARE,
) -> tuple[FilmFit | None, str, FlattenResult | None]:
    """Flatten a region onto a free outline at the scale that suits its material best.

    It fits with at most ``max_off_share`` of it outside the band (:func:`probe_film`).

    Returns
    -------
    fit : FilmFit or None
        The film, when it fits.
    reason : str
        Why it does not fit (out of the stretch band, outline over itself, crowded).
    layout : FlattenResult or None
        The region's free layout (area scale), for the cut that splits it.
    """
    scale, within, why, flat = probe_film(V, F, faces, max_stretch, options, max_off_share)
    if scale is None:
        return None, why, flat
    fit, why = final_film(V, F, faces, scale, within, options)
    return fit, why, flat


def split_in_two(
    faces: np.ndarray, layout: FlattenResult | None, points: np.ndarray, normals: np.ndarray, area: np.ndarray
):
    """Two halves of a region, cut by a straight line across its flat layout.

    A straight cut across a planar embedding leaves simply connected pieces, so both
    halves stay discs (up to pinches that :func:`disc_region` opens). Among lines in
    12 directions at the 30, 50 and 70 % area quantiles, the one whose halves are
    each closest to flat is kept: least area-weighted normal dispersion,
    Σ_half (A_half - |Σ A n|), the area a half would lose if its normals all lined
    up; a film's stretch spread grows with it. Without a layout (the solve failed),
    the same over the face centroids projected on the surface's two longest
    principal axes.

    Parameters
    ----------
    faces : (k,) int
        The region's faces.
    layout : FlattenResult or None
        Its free layout (faces in the order of ``faces``, possibly subdivided).
    points : (k, 3) float
        Face centroids in 3D, for the fallback.
    normals : (k, 3) float
        Unit face normals.
    area : (k,) float
        Face areas.

    Returns
    -------
    (a, b) : two non-empty (k_a,), (k_b,) int arrays of faces, or None.
    """
    if layout is not None:
        c2 = layout.uv[layout.F].mean(axis=1)
        w = layout.area_3d
        weight = np.bincount(layout.parent, weights=w, minlength=len(faces))
        pts = (
            np.stack([np.bincount(layout.parent, weights=w * c2[:, k], minlength=len(faces)) for k in range(2)], axis=1)
            / np.maximum(weight, 1e-300)[:, None]
        )
    else:
        d3 = points - np.average(points, axis=0, weights=area)
        axes = np.linalg.eigh((d3 * area[:, None]).T @ d3)[1][:, -2:]
        pts = d3 @ axes
    An = normals * area[:, None]
    best, best_score = None, np.inf
    for theta in np.linspace(0.0, np.pi, 12, endpoint=False):
        t = pts @ np.array([np.cos(theta), np.sin(theta)])
        order = np.argsort(t, kind="stable")
        cw = np.cumsum(area[order])
        for q in (0.3, 0.5, 0.7):
            k = min(int(np.searchsorted(cw, q * cw[-1])), len(t) - 2)
            side = np.zeros(len(t), bool)
            side[order[: k + 1]] = True
            score = (
                area[side].sum()
                - np.linalg.norm(An[side].sum(axis=0))
                + area[~side].sum()
                - np.linalg.norm(An[~side].sum(axis=0))
            )
            if score < best_score - 1e-12:
                best, best_score = side, score
    if best is None or best.all() or not best.any():
        return None
    return faces[best], faces[~best]


def _with_neighbour(leftover: np.ndarray, queue: list, adjacency: sp.csr_matrix) -> tuple[np.ndarray, bool]:
    """A small leftover joins a queued region it touches (taken out of the queue); a large one stands alone."""
    faces = np.flatnonzero(leftover)
    if len(faces) < MIN_FILM_FACES:
        touching = np.zeros(len(leftover), bool)
        touching[adjacency[faces].indices] = True
        for k, (other, _) in enumerate(queue):
            if touching[other].any():
                queue.pop(k)
                return np.union1d(other, faces), False
    return faces, False


def smoothed_owner(owner: np.ndarray, edge_faces: np.ndarray, FE: np.ndarray, region: np.ndarray) -> np.ndarray:
    """Owners along view borders made straight: a face goes with two of its three neighbours.

    A border between two views' faces zig-zags through single triangles (each face owned by
    the view that sees it first). Cut along it, a film's free outline has notches one triangle
    deep, and at a notch the conformal map folds the outline onto itself: a scanned bust's
    front view lost its film to sub-millimetre self-touches at three such notches. A face of the
    region whose two neighbours (across two of its edges) share another owner takes that
    owner, until no face does. Each round changes faces no two of which are neighbours (of two
    that would, the lower-numbered), so each change takes at least one edge out of the borders
    and the rounds end (two neighbours changed together swapped owners and came back).

    Parameters
    ----------
    owner : (#F,) int
        Owning view per face, -1 for none.
    edge_faces : (#E, 2) int
        The two faces of each edge, -1 for none (:func:`face_graph`).
    FE : (#F, 3) int
        Each face's edges (:func:`workbench.mesh.topology.unique_edges`).
    region : (#F,) bool
        The faces that may change, and whose owners count.

    Returns
    -------
    (#F,) int
        The owners, those outside ``region`` unchanged.
    """
    owner = np.asarray(owner).copy()
    f = np.arange(len(FE))[:, None]
    # the face across each edge of each face (-1: none)
    across = np.where(edge_faces[FE, 0] == f, edge_faces[FE, 1], edge_faces[FE, 0])
    inside = region[np.maximum(across, 0)] & (across >= 0)
    todo = np.flatnonzero(region)
    moving = np.zeros(len(owner), bool)
    while True:
        # (a neighbour outside the region, or none, matches nothing: -2, -3 and -4 differ)
        nb = np.where(inside, owner[np.maximum(across, 0)], np.array([-2, -3, -4]))[todo]
        a, b, c = nb[:, 0], nb[:, 1], nb[:, 2]
        pair = np.where(a == b, a, np.where(a == c, a, np.where(b == c, b, -2)))
        take = (pair >= -1) & (pair != owner[todo])
        if not take.any():
            return owner
        moving[:] = False
        moving[todo[take]] = True
        # (not beside a lower-numbered face that changes too)
        nb_moving = moving[np.maximum(across[todo[take]], 0)] & (across[todo[take]] >= 0)
        first = ~(nb_moving & (across[todo[take]] < todo[take][:, None])).any(axis=1)
        owner[todo[take][first]] = pair[take][first]


def split_films(
    V: np.ndarray,
    F: np.ndarray,
    decorated: np.ndarray,
    owner_view: np.ndarray,
    max_stretch: float,
    options: FlattenOptions,
    max_films: int = 48,
    log: Callable[[str], None] | None = None,
    within_share: float = 1.0 - MAX_OFF_SHARE,
) -> list[FilmFit]:
    """Partition the decorated surface into disc-shaped films that each stay within the material.

    Greedy recursive bisection: a region that does not fit (stretch out of
    [MIN_STRETCH, max_stretch] on more than 1 - ``within_share`` of it at its best scale, an
    outline over itself, or crowded) is split: first along the borders between views (a seam
    there crosses no view's image, made straight first by :func:`smoothed_owner`), then by
    straight cuts across its flat layout. Bisection cuts more than it must;
    :func:`merge_films` then joins adjacent films again while their union is a disc that
    fits, seams inside a view first.

    Parameters
    ----------
    V : (#V, 3) float
        The part, mm.
    F : (#F, 3) int
        Its triangles (a disc).
    decorated : (#F,) bool
        Faces to cover (those some view owns).
    owner_view : (#F,) int
        First owning view per face, -1 for none.
    max_stretch : float
        The material's limit.
    options : FlattenOptions
        Solver settings (outline and scale are chosen here).
    max_films : int
        Give up when the plan, joined again, has more films than this (or the split more
        than PIECES_PER_FILM times as many pieces).
    log : callable, optional
        Progress lines.
    within_share : float
        The share of the surface the plan keeps within the band: each film of the split keeps
        it of itself, and :func:`join_within_budget` joins films while the whole plan does.

    Returns
    -------
    list of FilmFit
        Ordered by their first face.

    Raises
    ------
    WorkbenchError
        A region too small to split that does not fit, or too many films.
    """
    say = log or (lambda _m: None)
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normals = cross / np.maximum(2 * area, 1e-300)[:, None]
    centroids = V[F].mean(axis=1)
    # a face of zero area (three vertices on one line: a scan's cap) has no map, whatever the
    # film: splitting around it would go on to the film limit and then blame the material
    graph = face_graph(F)
    # each body of the part that the views decorate starts a region of its own (a scan's loose
    # eyes and teeth are films too: the largest body alone left them on no film)
    bodies = _components(graph[0], decorated)
    if bodies.max() < 0:
        disc_region(F, decorated, area, graph=graph)  # (it says that no face is decorated)
    start = np.zeros(len(F), bool)
    firsts = []
    for b in range(int(bodies.max()) + 1):
        region = disc_region(F, bodies == b, area, graph=graph)
        firsts.append(np.flatnonzero(region))
        start |= region
    flat = zero_area_faces(V, F)
    flat = flat[start[flat]]
    if len(flat):
        x, y, z = centroids[flat[0]]
        raise WorkbenchError(
            f"{len(flat)} decorated faces have zero area (their three corners on one line; the first at "
            f"({x:.3f}, {y:.3f}, {z:.3f}) mm): no film is flattened over them; remove them from the mesh"
        )
    off = 1.0 - within_share
    _, FE, _ = unique_edges(F)
    owner_view = smoothed_owner(owner_view, graph[2], FE, start)
    done: list[FilmFit] = []
    claimed = np.zeros(len(F), bool)
    queue = [(faces, True) for faces in firsts]
    attempts = 0
    pieces = PIECES_PER_FILM * max_films
    while queue:
        attempts += 1
        if attempts > 4 * pieces:
            raise WorkbenchError(f"no split into at most {max_films} films keeps max_stretch {max_stretch:g}")
        faces, by_views = queue.pop(0)
        mask = np.zeros(len(F), bool)
        mask[faces] = True
        mask &= ~claimed
        if not mask.any():
            continue
        try:
            region = disc_region(F, mask, area, allowed=~claimed, graph=graph)
        except WorkbenchError as exc:
            # a ring around a finished film (or pinched between films): cut it across
            faces = np.flatnonzero(mask)
            halves = None
            if len(faces) >= 2:
                halves = split_in_two(faces, None, centroids[faces], normals[faces], area[faces])
            if halves is None:
                raise WorkbenchError(f"{len(faces)} faces near vertex {int(F[faces[0], 0])}: {exc}") from None
            say(f"{len(faces)} faces are no disc ({exc}): split in two")
            queue.extend((h, False) for h in halves)
            continue
        faces = np.flatnonzero(region)
        leftover = mask & ~region  # parts the disc repair dropped: queued again
        if leftover.any():
            queue.append(_with_neighbour(leftover, queue, graph[0]))
        fit, why, layout = fit_film(V, F, faces, max_stretch, options, off)
        if fit is not None:
            claimed[faces] = True
            done.append(fit)
            say(f"film {len(done)}: {len(faces)} faces, {100 * fit.within:.1f} % of it within the stretch band")
            continue
        if len(done) + len(queue) + 2 > pieces:
            raise WorkbenchError(
                f"more than {max_films} films would be needed to keep max_stretch {max_stretch:g} (the split "
                f"reached {pieces} pieces, {len(done)} of them films, before joining them again)"
            )
        views = np.unique(owner_view[faces])
        views = views[views >= 0]
        if by_views and len(views) > 1:
            say(f"{len(faces)} faces do not fit one film ({why}): split along the views' borders")
            for v in views:
                queue.append((faces[owner_view[faces] == v], False))
            if (owner_view[faces] < 0).any():
                queue.append((faces[owner_view[faces] < 0], False))
            continue
        # down to single triangles if need be (a triangle always fits: it is flat);
        # films of a few faces then join a neighbour that still fits (see the end)
        halves = None if len(faces) < 2 else split_in_two(faces, layout, centroids[faces], normals[faces], area[faces])
        if halves is not None:
            # (a straight cut across the layout leaves a staircase of whole triangles on the
            # part, whose notches fold a later join's outline over itself: Homer's films could
            # not be joined, 11 of them, 23 of 46 tries "overlaps itself", 2 to 22 edges apart
            # along the outline; the cut made straight as the views' borders are, 6)
            side = np.full(len(F), -1)
            side[halves[0]], side[halves[1]] = 0, 1
            side = smoothed_owner(side, graph[2], FE, side >= 0)
            a, b = np.flatnonzero(side == 0), np.flatnonzero(side == 1)
            if len(a) and len(b):
                halves = (a, b)
        if halves is None:
            raise WorkbenchError(
                f"a region of {len(faces)} faces near vertex {int(F[faces[0], 0])} does not fit one film ({why}) "
                "and cannot be split further"
            )
        say(f"{len(faces)} faces do not fit one film ({why}): split in two")
        queue.extend((h, False) for h in halves)
    done = _absorb_small_films(V, F, done, graph, area, max_stretch, options, say, off)
    done = merge_films(V, F, done, owner_view, max_stretch, options, graph=graph, log=say, max_off_share=off)
    budget = off * float(area[start].sum())
    done = join_within_budget(V, F, done, budget, max_stretch, options, graph=graph, log=say)
    if len(done) > max_films:
        raise WorkbenchError(
            f"more than {max_films} films would be needed to keep max_stretch {max_stretch:g} ({len(done)} after "
            "joining what could be joined)"
        )
    done.sort(key=lambda f: int(f.faces[0]))
    return done


def _absorb_small_films(V, F, done, graph, area, max_stretch, options, say, max_off_share) -> list[FilmFit]:
    """Films of fewer than MIN_FILM_FACES faces (what pinch repairs cut off) join a neighbour that still fits."""
    adjacency = graph[0]
    film_of = np.full(len(F), -1)
    for k, f in enumerate(done):
        film_of[f.faces] = k
    gone = set()
    for k in sorted(range(len(done)), key=lambda k: len(done[k].faces)):
        small = done[k]
        if len(small.faces) >= MIN_FILM_FACES:
            break
        near = film_of[adjacency[small.faces].indices]
        near = [j for j in np.unique(near[(near >= 0) & (near != k)]) if j not in gone]
        for j in sorted(near, key=lambda j: -len(done[j].faces)):
            faces = np.union1d(done[j].faces, small.faces)
            try:
                region = disc_region(F, np.isin(np.arange(len(F)), faces), area, allowed=film_of < 0, graph=graph)
            except WorkbenchError:
                continue  # together they would ring another film
            if region.sum() != len(faces):
                continue
            fit, _, _ = fit_film(V, F, faces, max_stretch, options, max_off_share)
            if fit is not None:
                done[j] = fit
                film_of[faces] = j
                gone.add(k)
                say(f"a film of {len(small.faces)} faces joins its neighbour ({len(faces)} faces)")
                break
    return [f for k, f in enumerate(done) if k not in gone]


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


def _shared_seams(
    E: np.ndarray, edge_faces: np.ndarray, film_of: np.ndarray, length: np.ndarray, in_view: np.ndarray
) -> dict[tuple[int, int], tuple[float, float]]:
    """Seam length (all, and inside one view's region) between every two films that touch, keyed (low, high)."""
    inner = edge_faces[:, 1] >= 0
    a = film_of[np.maximum(edge_faces[:, 0], 0)]
    b = film_of[np.maximum(edge_faces[:, 1], 0)]
    seam = inner & (a != b) & (a >= 0) & (b >= 0)
    lo, hi = np.minimum(a[seam], b[seam]), np.maximum(a[seam], b[seam])
    n = int(film_of.max()) + 1
    key = lo * n + hi
    keys, inv = np.unique(key, return_inverse=True)
    total = np.bincount(inv, weights=length[seam])
    inside = np.bincount(inv, weights=length[seam] * in_view[seam])
    return {(int(k // n), int(k % n)): (float(t), float(i)) for k, t, i in zip(keys, total, inside, strict=True)}


def merge_films(
    V: np.ndarray,
    F: np.ndarray,
    films: list[FilmFit],
    owner_view: np.ndarray,
    max_stretch: float,
    options: FlattenOptions,
    graph=None,
    log: Callable[[str], None] | None = None,
    max_off_share: float = MAX_OFF_SHARE,
) -> list[FilmFit]:
    """Join adjacent films whose union is one disc that still fits the material.

    Greedy: the two films with the longest seam inside a view's region (a seam a view's
    image crosses), then the longest seam overall, are tried first; their union must be
    a disc (:func:`is_disc_region`) and fit as :func:`fit_film` asks (within
    [MIN_STRETCH, max_stretch] on all but ``max_off_share`` of it at its best scale, no
    overlap of its outline, every face printed). A joined film's seams with its neighbours are tried
    again; a pair that does not fit is tried again only once one of them has grown. The map at
    the final scale (:func:`final_film`, which checks that every face prints) is made
    once per resulting film, not per join: should it crowd, the film falls back to the
    two it was joined from.

    Parameters
    ----------
    V : (#V, 3) float
        The part, mm.
    F : (#F, 3) int
        Its triangles (a disc).
    films : list of FilmFit
        Films that each fit, on disjoint faces.
    owner_view : (#F,) int
        First owning view per face, -1 for none.
    max_stretch : float
        The material's limit.
    options : FlattenOptions
        Solver settings.
    graph : tuple, optional
        :func:`face_graph` of ``F``.
    log : callable, optional
        Progress lines.
    max_off_share : float
        The share of a joined film that may leave the band (:func:`probe_film`).

    Returns
    -------
    list of FilmFit
        Fewer films or the same: those not joined in their order, then the joined ones.
    """
    say = log or (lambda _m: None)
    graph = graph if graph is not None else face_graph(F)
    _, E, edge_faces = graph
    length = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    ov = owner_view[np.maximum(edge_faces, 0)]
    in_view = (edge_faces[:, 1] >= 0) & (ov[:, 0] == ov[:, 1]) & (ov[:, 0] >= 0)
    film_of = np.full(len(F), -1, dtype=np.int64)
    current = dict(enumerate(films))
    for k, f in current.items():
        film_of[f.faces] = k
    # longest seam inside a view first (ties: longest seam, then the films' order)
    heap = [(-i, -t, a, b) for (a, b), (t, i) in _shared_seams(E, edge_faces, film_of, length, in_view).items()]
    heapq.heapify(heap)
    next_id = len(films)
    while heap:
        _, _, a, b = heapq.heappop(heap)
        if a not in current or b not in current:
            continue  # one of them has joined another film since
        faces = np.union1d(current[a].faces, current[b].faces)
        region = np.zeros(len(F), bool)
        region[faces] = True
        if not is_disc_region(F, region, graph):
            continue
        scale, within, _, _ = probe_film(V, F, faces, max_stretch, options, max_off_share)
        if scale is None:
            continue
        say(f"films of {len(current[a].faces)} and {len(current[b].faces)} faces join ({len(faces)} faces)")
        current[next_id] = _Joined(faces, scale, within, (current.pop(a), current.pop(b)))
        film_of[faces] = next_id
        # the joined film's seams with its neighbours, tried in the same order
        mine = region[np.maximum(edge_faces, 0)]
        on = (edge_faces[:, 1] >= 0) & (mine[:, 0] != mine[:, 1])
        j = film_of[np.where(mine[on, 0], edge_faces[on, 1], edge_faces[on, 0])]
        for k in np.unique(j[j >= 0]):
            here = j == k
            heapq.heappush(
                heap, (-float(length[on][here & in_view[on]].sum()), -float(length[on][here].sum()), int(k), next_id)
            )
        next_id += 1
    out: list[FilmFit] = []
    for k in sorted(current):
        out += _finish(V, F, current[k], options, say)
    return out


@dataclass
class _Joined:
    """Two films (or joins) whose union passed :func:`probe_film`, its map not made yet."""

    faces: np.ndarray
    scale: ScaleMode
    within: float
    parts: tuple


def off_band_mm2(fit: FilmFit) -> float:
    """The surface of a film outside the material's band, mm²."""
    return (1.0 - fit.within) * float(fit.flat.area_3d.sum())


def join_within_budget(
    V: np.ndarray,
    F: np.ndarray,
    films: list[FilmFit],
    budget_mm2: float,
    max_stretch: float,
    options: FlattenOptions,
    graph=None,
    log: Callable[[str], None] | None = None,
) -> list[FilmFit]:
    """Fewer films for the share the plan keeps: a film joins a neighbour where the plan stays within its budget.

    :func:`merge_films` joins films that each keep ``within_share`` of themselves within the band; what
    it leaves are small pieces (a figure's claws and ears: 69 to 400 faces beside films of
    18,000) that no neighbour takes at that rule, though the surface they would put outside
    the band is a few mm². The plan's rule is the part's: at most ``budget_mm2`` of all its
    surface outside the band. So the smallest film first, each tries its neighbours, the
    largest first: their union must be a disc whose outline clears itself and that prints
    (:func:`final_film`), and the plan's surface outside the band, with the union's in place
    of the two's, must stay within the budget. Until no film joins.

    Parameters
    ----------
    V, F : arrays
        The part (a disc), mm.
    films : list of FilmFit
        The films, on disjoint faces.
    budget_mm2 : float
        The plan's surface outside the band at most, mm².
    max_stretch : float
        The material's limit.
    options : FlattenOptions
        Solver settings (outline and scale are chosen here).
    graph : tuple, optional
        :func:`face_graph` of ``F``.
    log : callable, optional
        Progress lines.

    Returns
    -------
    list of FilmFit
        Fewer films or the same: those not joined, then the joined ones.
    """
    say = log or (lambda _m: None)
    graph = graph if graph is not None else face_graph(F)
    adjacency = graph[0]
    films = list(films)
    spent = sum(off_band_mm2(f) for f in films)
    tried: set = set()  # pairs of films tried: not tried again
    joined = True
    while joined and len(films) > 1:
        joined = False
        film_of = np.full(len(F), -1)
        for k, f in enumerate(films):
            film_of[f.faces] = k
        for k in sorted(range(len(films)), key=lambda k: (len(films[k].faces), k)):
            small = films[k]
            near = film_of[adjacency[small.faces].indices]
            near = np.unique(near[(near >= 0) & (near != k)])
            for j in sorted(near, key=lambda j: (-len(films[j].faces), j)):
                # (a film only grows: its size and first face name it; the pair either way round)
                key = frozenset(
                    {(len(small.faces), int(small.faces[0])), (len(films[j].faces), int(films[j].faces[0]))}
                )
                if key in tried:
                    continue
                tried.add(key)
                faces = np.union1d(films[j].faces, small.faces)
                region = np.zeros(len(F), bool)
                region[faces] = True
                if not is_disc_region(F, region, graph):
                    continue
                scale, within, _, flat = probe_film(V, F, faces, max_stretch, options, max_off_share=1.0)
                if scale is None:
                    continue
                after = spent - off_band_mm2(small) - off_band_mm2(films[j])
                after += (1.0 - within) * float(flat.area_3d.sum())
                if after > budget_mm2:
                    continue
                fit, _ = final_film(V, F, faces, scale, within, options)
                if fit is None:
                    continue
                say(
                    f"a film of {len(small.faces)} faces joins its neighbour ({len(faces)} faces, "
                    f"{100 * within:.1f} % of it within the stretch band)"
                )
                spent = after
                films = [f for i, f in enumerate(films) if i not in (j, k)] + [fit]
                joined = True
                break
            if joined:
                break
    return films


def _finish(V, F, film, options, say) -> list[FilmFit]:
    """The films of a join: its own map at its scale, or, if that crowds, its two parts'."""
    if isinstance(film, FilmFit):
        return [film]
    fit, why = final_film(V, F, film.faces, film.scale, film.within, options)
    if fit is not None:
        return [fit]
    say(f"a joined film of {len(film.faces)} faces is refused ({why}): its two parts stay apart")
    return _finish(V, F, film.parts[0], options, say) + _finish(V, F, film.parts[1], options, say)


def seams(F: np.ndarray, V: np.ndarray, film_of_face: np.ndarray, owner_view: np.ndarray) -> dict:
    """Seams between films: total length and the part inside one view's region.

    Parameters
    ----------
    F : (#F, 3) int
    V : (#V, 3) float
    film_of_face : (#F,) int
        Film per face, -1 for none.
    owner_view : (#F,) int
        First owning view per face, -1 for none.

    Returns
    -------
    dict
        ``length_mm`` (all seams), ``in_view_mm`` (seams with the same view on both
        sides: visible in that view's image), ``per_film_mm`` (seam length around
        each film).
    """
    _, E, edge_faces = face_graph(F)
    inner = edge_faces[:, 1] >= 0
    a, b = edge_faces[inner, 0], edge_faces[inner, 1]
    fa, fb = film_of_face[a], film_of_face[b]
    seam = (fa != fb) & (fa >= 0) & (fb >= 0)
    length = np.linalg.norm(V[E[inner, 0]] - V[E[inner, 1]], axis=1)
    in_view = seam & (owner_view[a] == owner_view[b]) & (owner_view[a] >= 0)
    n = int(film_of_face.max()) + 1
    per = np.bincount(fa[seam], weights=length[seam], minlength=n) + np.bincount(
        fb[seam], weights=length[seam], minlength=n
    )
    return {
        "length_mm": float(length[seam].sum()),
        "in_view_mm": float(length[in_view].sum()),
        "per_film_mm": per.tolist(),
    }


def pack_films(sizes_px: list[tuple[int, int]], gap_px: int) -> tuple[list[tuple[int, int]], tuple[int, int]]:
    """Places for film prints on one sheet of pixels (shelf packing, tallest first).

    Parameters
    ----------
    sizes_px : list of (rows, cols)
        Print size of each film, pixels.
    gap_px : int
        Free pixels between films.

    Returns
    -------
    offsets : list of (row, col)
        Top-left pixel of each film, in the input order.
    shape : (rows, cols)
        The sheet.
    """
    total = sum((r + gap_px) * (c + gap_px) for r, c in sizes_px)
    width = max(max(c for _, c in sizes_px), int(np.sqrt(total) * 1.2))
    order = sorted(range(len(sizes_px)), key=lambda k: (-sizes_px[k][0], k))
    offsets: list[tuple[int, int]] = [(0, 0)] * len(sizes_px)
    row = col = shelf = 0
    for k in order:
        r, c = sizes_px[k]
        if col > 0 and col + c > width:
            row, col, shelf = row + shelf + gap_px, 0, 0
        offsets[k] = (row, col)
        col += c + gap_px
        shelf = max(shelf, r)
    rows = max(o[0] + s[0] for o, s in zip(offsets, sizes_px, strict=True))
    cols = max(o[1] + s[1] for o, s in zip(offsets, sizes_px, strict=True))
    return offsets, (rows, cols)


def outside_band(
    V: np.ndarray, F: np.ndarray, stretch: np.ndarray, area: np.ndarray, ok: np.ndarray, max_stretch: float
) -> tuple[np.ndarray, np.ndarray]:
    """The connected regions of a film's surface whose stretch leaves the band [MIN_STRETCH, max_stretch].

    Parameters
    ----------
    V : (#V, 3) float
        The film's mesh, mm on the part.
    F : (#F, 3) int
        Its triangles.
    stretch : (#F,) float
        Stretch per face, 3D length / print length.
    area : (#F,) float
        Surface area per face, mm².
    ok : (#F,) bool
        Faces the stretch is known on (not collapsed in the plane).
    max_stretch : float
        The material's limit.

    Returns
    -------
    labels : (#F,) int
        Region per face, -1 within the band (or unknown); regions by decreasing area.
    figures : (#regions, 5) float
        Per region: area (mm²), the centroid (x, y, z, mm on the part, area-weighted), and the
        stretch farthest outside the band (log-wise: 2.0 and 0.4 are as far beyond 1.0).
    """
    out = ok & ((stretch > max_stretch) | (stretch < MIN_STRETCH))
    _, FE, _ = unique_edges(F)
    lab = _components(face_adjacency(FE), out)
    n = int(lab.max()) + 1
    if n == 0:
        return lab, np.zeros((0, 5))
    idx = np.flatnonzero(out)
    a = np.bincount(lab[idx], weights=area[idx], minlength=n)
    c = V[F[idx]].mean(axis=1)
    centre = np.stack([np.bincount(lab[idx], weights=area[idx] * c[:, k], minlength=n) for k in range(3)], 1)
    centre /= np.maximum(a, 1e-300)[:, None]
    # (the worst face per region: the largest |log stretch|, its stretch kept)
    worst = np.zeros(n)
    far = np.abs(np.log(stretch[idx]))
    order = np.lexsort((far, lab[idx]))
    last = np.r_[lab[idx][order][1:] != lab[idx][order][:-1], True]
    worst[lab[idx][order][last]] = stretch[idx][order][last]
    rank = np.lexsort((np.arange(n), -a))
    relabel = np.empty(n, np.int64)
    relabel[rank] = np.arange(n)
    lab[idx] = relabel[lab[idx]]
    return lab, np.column_stack([a, centre, worst])[rank]
