"""Films joined again after the split: by each film's own rule, then within the plan's share."""

from __future__ import annotations

import heapq
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from workbench.conformal.flatten import FlattenOptions, ScaleMode
from workbench.errors import WorkbenchError
from workbench.films.fit import MAX_OFF_SHARE, FilmFit, final_film, fit_film, off_band_mm2, probe_film
from workbench.films.regions import disc_region, face_graph, is_disc_region

# Smallest film the automatic split makes, in faces: below it a region is not split again, and a
# film that small (what pinch repairs cut off) joins a neighbour.
MIN_FILM_FACES = 24


def absorb_small_films(V, F, done, graph, area, max_stretch, options, say, max_off_share) -> list[FilmFit]:
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


def _finish(V, F, film, options, say) -> list[FilmFit]:
    """The films of a join: its own map at its scale, or, if that crowds, its two parts'."""
    if isinstance(film, FilmFit):
        return [film]
    fit, why = final_film(V, F, film.faces, film.scale, film.within, options)
    if fit is not None:
        return [fit]
    say(f"a joined film of {len(film.faces)} faces is refused ({why}): its two parts stay apart")
    return _finish(V, F, film.parts[0], options, say) + _finish(V, F, film.parts[1], options, say)


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
    films = list(films)
    spent = sum(off_band_mm2(f) for f in films)
    tried: set = set()  # pairs of films tried: not tried again
    while len(films) > 1:
        for k, j in _neighbours_smallest_first(films, graph[0], len(F)):
            small, other = films[k], films[j]
            # (a film only grows: its size and first face name it; the pair either way round)
            key = frozenset({(len(f.faces), int(f.faces[0])) for f in (small, other)})
            if key in tried:
                continue
            tried.add(key)
            faces = np.union1d(other.faces, small.faces)
            region = np.zeros(len(F), bool)
            region[faces] = True
            if not is_disc_region(F, region, graph):
                continue
            scale, within, _, flat = probe_film(V, F, faces, max_stretch, options, max_off_share=1.0)
            if scale is None:
                continue
            # the plan's surface outside the band with the union's in place of the two films'
            after = spent - off_band_mm2(small) - off_band_mm2(other) + (1.0 - within) * float(flat.area_3d.sum())
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
            break
        else:
            return films  # (no pair joins)
    return films


def _neighbours_smallest_first(films: list[FilmFit], adjacency, n_faces: int):
    """Pairs (k, j) of touching films: the smallest film k first, its neighbours j the largest first."""
    film_of = np.full(n_faces, -1)
    for k, f in enumerate(films):
        film_of[f.faces] = k
    for k in sorted(range(len(films)), key=lambda k: (len(films[k].faces), k)):
        near = film_of[adjacency[films[k].faces].indices]
        for j in sorted(np.unique(near[(near >= 0) & (near != k)]), key=lambda j: (-len(films[j].faces), j)):
            yield k, int(j)
