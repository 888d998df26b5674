"""The automatic split of a part into films: view borders made straight, bisection across the layout, the joins."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from workbench.conformal.flatten import FlattenOptions, FlattenResult
from workbench.errors import WorkbenchError
from workbench.films.fit import MAX_OFF_SHARE, FilmFit, fit_film
from workbench.films.joins import MIN_FILM_FACES, absorb_small_films, join_within_budget, merge_films
from workbench.films.regions import components_of, disc_region, face_graph
from workbench.mesh.topology import unique_edges
from workbench.mesh.validate import zero_area_faces

# Pieces the bisection may have at once, per film the plan may end with: bisection cuts far
# more than it must (a scanned figure's 7 films came from 70 pieces, a bust's 5 from 42) and
# the joins take them together again; the bound only keeps a hopeless part from splitting for ever.
PIECES_PER_FILM = 10


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
    bodies = components_of(graph[0], decorated)
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
    done = absorb_small_films(V, F, done, graph, area, max_stretch, options, say, off)
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
