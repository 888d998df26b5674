"""Film placement per film for designs with several films: the tiles of each film fitted on their own,
and the misregistration across the seams between them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.camera import Camera
from workbench.mesh.topology import half_edges, unique_edges
from workbench.validate.score import TILE, Score, ViewSurface, _bilinear, fit_film, tile_print_points


def film_boxes_mm(films: list[dict], px_per_mm: float) -> list[tuple[float, float, float, float]]:
    """Each film's print on the atlas: (x0, y0, width, height), mm, x right, y down from the atlas's top-left."""
    return [
        (
            f["atlas_px"][1] / px_per_mm,
            f["atlas_px"][0] / px_per_mm,
            f["width_px"] / px_per_mm,
            f["height_px"] / px_per_mm,
        )
        for f in films
    ]


def film_at(p: np.ndarray, boxes: list[tuple[float, float, float, float]]) -> np.ndarray:
    """The film whose print holds each atlas point.

    Parameters
    ----------
    p : (n, 2) float
        Atlas print points, mm (x right, y down); NaN allowed.
    boxes : list of (x0, y0, width, height)
        :func:`film_boxes_mm`.

    Returns
    -------
    (n,) int
        Film index, -1 for none (between films, or NaN).
    """
    out = np.full(len(p), -1, dtype=np.int64)
    with np.errstate(invalid="ignore"):
        for k, (x0, y0, w, h) in enumerate(boxes):
            out[(p[:, 0] >= x0) & (p[:, 0] < x0 + w) & (p[:, 1] >= y0) & (p[:, 1] < y0 + h)] = k
    return out


def fit_per_film(sc: Score, surface: ViewSurface, films: list[dict], px_per_mm: float) -> list[dict]:
    """Placement of every film a photo's view shows, each fitted on its own tiles.

    A tile belongs to the film whose print holds the design point at its centre, and
    counts only if the whole tile shows that film: a tile across a seam inside the
    view sees two films that may have moved apart, and would pull both fits. The
    film's placement (offset, rotation and scale about its own print's centre) is
    fitted as for a single film (:func:`workbench.validate.score.fit_film`), in that
    film's print coordinates.

    Parameters
    ----------
    sc : Score
        The photo's tiles (centres and shifts, view pixels; misregistration mm).
    surface : ViewSurface
        The view's surface and atlas print coordinates.
    films : list of dict
        design.json's ``films``.
    px_per_mm : float
        The design's print resolution.

    Returns
    -------
    list of dict
        Per film: name, tiles, misregistration (mm statistics), and when at least four
        of its tiles were measured, offset_mm [x, y], rotation_deg, scale_pct, rms_mm;
        ``measured`` says which.
    """
    out = []
    c, d = sc.centres, sc.shift_px
    if len(c) == 0:
        return [{"name": f["name"], "tiles": 0, "measured": False} for f in films]
    boxes = film_boxes_mm(films, px_per_mm)
    p0, p1, J, good = tile_print_points(surface, c, d)
    owner = film_at(p0, boxes)
    # 5 x 5 points over each tile (its corners included): all on the tile's film
    s = np.linspace(-(TILE - 1) / 2, (TILE - 1) / 2, 5)
    gx, gy = (g.ravel() for g in np.meshgrid(s, s))
    px = _bilinear(surface.print_mm, (c[:, 0:1] + gx).ravel(), (c[:, 1:2] + gy).ravel())
    whole = (film_at(px, boxes).reshape(len(c), -1) == owner[:, None]).all(axis=1)
    for k, (f, (x0, y0, w, h)) in enumerate(zip(films, boxes, strict=True)):
        mine = good & whole & (owner == k)
        rec: dict = {"name": f["name"], "tiles": int(mine.sum())}
        if mine.any():
            m = sc.shift_mm[mine]
            rec["misregistration_mm"] = {
                "median": float(np.median(m)),
                "p95": float(np.percentile(m, 95)),
                "max": float(m.max()),
            }
        if mine.sum() >= 4:
            origin = np.array([x0, y0])
            fit = fit_film(p0[mine] - origin, p1[mine] - origin, (w, h), jacobians=J[mine])
            rec.update({k: fit[k] for k in ("offset_mm", "rotation_deg", "scale_pct", "rms_mm") if k in fit})
        rec["measured"] = "offset_mm" in rec
        out.append(rec)
    return out


@dataclass
class SeamEdges:
    """The edges where two films meet on the part, each seen from both films.

    Attributes
    ----------
    films : (n, 2) int
        The two films of each seam edge, the lower index first.
    X : (n, 3) float
        Edge midpoint on the part, mm.
    length : (n,) float
        Edge length on the part, mm.
    p : (n, 2, 2) float
        The midpoint on each film's print: atlas mm, x right, y down.
    J : (n, 2, 3, 2) float
        On each side, part mm per print mm (the film's triangle at the edge): a print
        displacement ``e`` moves the ink on the part by ``J @ e``.
    """

    films: np.ndarray
    X: np.ndarray
    length: np.ndarray
    p: np.ndarray
    J: np.ndarray


def film_seams(V: np.ndarray, F: np.ndarray, uv_mm: np.ndarray, height_mm: float, films: list[dict]) -> SeamEdges:
    """Seam edges of a films design, from its atlas mesh (each film with its own copy of its vertices).

    A seam edge is a boundary edge of two films whose end points are the same points of
    the part (the copies design writes hold equal coordinates). Boundary edges met
    once are the part's rim; those met twice within one film are the cut that opened
    a ring (left out: a film does not move against itself).

    Parameters
    ----------
    V : (#V, 3) float
        decorated.obj's vertices, mm.
    F : (#F, 3) int
        Its faces; film k holds faces ``films[k]["atlas_faces"]``.
    uv_mm : (#V, 2) float
        flat.obj's layout on the atlas, mm (y up).
    height_mm : float
        The atlas's height.
    films : list of dict
        design.json's ``films``.

    Returns
    -------
    SeamEdges
    """
    film_of = np.full(len(F), -1, dtype=np.int64)
    for k, f in enumerate(films):
        lo, hi = f["atlas_faces"]
        film_of[lo:hi] = k
    _, FE, count = unique_edges(F)
    H = half_edges(F).reshape(-1, 2)
    rim = count[FE.ravel()] == 1
    H, face = H[rim], np.flatnonzero(rim) // 3
    # the part's point of each vertex: copies across films have equal coordinates
    _, point = np.unique(V, axis=0, return_inverse=True)
    point = point.ravel()
    a, b = point[H[:, 0]], point[H[:, 1]]
    key = np.minimum(a, b) * (int(point.max()) + 1) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    key, H, face = key[order], H[order], face[order]
    pair = np.flatnonzero(key[1:] == key[:-1])
    i, j = pair, pair + 1
    fi, fj = film_of[face[i]], film_of[face[j]]
    keep = (fi != fj) & (fi >= 0) & (fj >= 0)
    i, j = i[keep], j[keep]
    swap = film_of[face[i]] > film_of[face[j]]
    i, j = np.where(swap, j, i), np.where(swap, i, j)
    q = np.column_stack([uv_mm[:, 0], height_mm - uv_mm[:, 1]])  # print mm, y down

    def jacobian(f):
        P, Q = V[F[f]], q[F[f]]
        dP = np.stack([P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]], axis=2)  # (n, 3, 2)
        dQ = np.stack([Q[:, 1] - Q[:, 0], Q[:, 2] - Q[:, 0]], axis=2)  # (n, 2, 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            return dP @ np.linalg.pinv(dQ)

    J = np.stack([jacobian(face[i]), jacobian(face[j])], axis=1)
    # a triangle collapsed in its print has no map to carry a displacement: its edge is left out
    ok = np.isfinite(J).all(axis=(1, 2, 3))
    i, j, J = i[ok], j[ok], J[ok]
    return SeamEdges(
        films=np.column_stack([film_of[face[i]], film_of[face[j]]]),
        X=0.5 * (V[H[i, 0]] + V[H[i, 1]]),
        length=np.linalg.norm(V[H[i, 1]] - V[H[i, 0]], axis=1),
        p=np.stack([0.5 * (q[H[i, 0]] + q[H[i, 1]]), 0.5 * (q[H[j, 0]] + q[H[j, 1]])], axis=1),
        J=J,
    )


def placement_error(rec: dict, size_mm: tuple[float, float], p: np.ndarray) -> np.ndarray:
    """Print displacement of a fitted film at its print points: the ink shown at design point p is from q, q - p.

    The inverse of :func:`workbench.validate.score.fit_film`'s model: q = c + M (p - c - d),
    M = R(θ) / k in print coordinates (x right, y down), c the print's centre.

    Parameters
    ----------
    rec : dict
        A measured film of :func:`fit_per_film` (offset_mm, rotation_deg, scale_pct).
    size_mm : (width, height)
        The film's print size, mm.
    p : (n, 2) float
        Points of the film's print (x right, y down from its top-left), mm.

    Returns
    -------
    (n, 2) float
        q - p, mm on the print; the ink at the design point p comes from p + that.
    """
    c = 0.5 * np.asarray(size_mm, dtype=np.float64)
    t = np.radians(rec["rotation_deg"])
    M = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]) / (1 + rec["scale_pct"] / 100)
    return c + (p - c - np.asarray(rec["offset_mm"])) @ M.T - p


def seams_seen(X: np.ndarray, camera: Camera, surface: ViewSurface, valid: np.ndarray) -> np.ndarray:
    """Which part points the designed view sees unhidden and the warped photo shows.

    A point is seen when the surface point at its pixel is within two pixel footprints
    of it (else something nearer the camera hides it).

    Parameters
    ----------
    X : (n, 3) float
        Points on the part, mm.
    camera : Camera
        The designed view.
    surface : ViewSurface
        Its surface points per pixel.
    valid : (H, W) bool
        Where the warped photo has data.

    Returns
    -------
    (n,) bool
    """
    H, W = valid.shape
    xy, z = camera.project(X)
    ok = (z > 0) & np.isfinite(xy).all(axis=1)
    j = np.clip(np.round(np.nan_to_num(xy[:, 0])).astype(np.int64), 1, W - 2)
    i = np.clip(np.round(np.nan_to_num(xy[:, 1])).astype(np.int64), 1, H - 2)
    ok &= (np.abs(xy[:, 0] - j) <= 0.5) & (np.abs(xy[:, 1] - i) <= 0.5) & valid[i, j]
    S = surface.X
    foot = np.fmax(np.linalg.norm(S[i, j + 1] - S[i, j], axis=1), np.linalg.norm(S[i + 1, j] - S[i, j], axis=1))
    with np.errstate(invalid="ignore"):
        ok &= np.linalg.norm(S[i, j] - X, axis=1) <= 2 * foot
    return ok


def seam_misregistration(
    edges: SeamEdges,
    fits: list[dict],
    films: list[dict],
    px_per_mm: float,
    seen: np.ndarray,
) -> list[dict]:
    """Misregistration across each seam a photo shows: how far apart the two films' inks land.

    At each seam edge's midpoint, each film's fitted placement (:func:`fit_per_film`)
    gives the print displacement of its ink (:func:`placement_error`), carried onto
    the part through that film's own map (``J``); the seam's misregistration there is
    the distance between the two, part mm. A film moved by 0.5 mm in its print and a
    neighbour in place give 0.5 mm times the moved film's scale at the seam (part mm
    per print mm).

    Parameters
    ----------
    edges : SeamEdges
        :func:`film_seams` of the design.
    fits : list of dict
        :func:`fit_per_film` of the photo.
    films : list of dict
        design.json's ``films``.
    px_per_mm : float
        The design's print resolution.
    seen : (n,) bool
        The seam edges the photo shows (:func:`seams_seen` of their midpoints).

    Returns
    -------
    list of dict
        Per seam (two films) with a part the photo shows: ``films`` (the two names),
        ``length_mm`` (the whole seam), ``seen_mm``, and, when the photo measured both
        films, ``misregistration_mm`` (``mean``, length-weighted, and ``max`` over the
        seen edges); else ``unmeasured`` names the films with fewer than four tiles.
    """
    boxes = film_boxes_mm(films, px_per_mm)
    n = len(films)
    key = edges.films[:, 0] * n + edges.films[:, 1]
    out = []
    for k in np.unique(key[seen]):
        a, b = int(k // n), int(k % n)
        on = key == k
        here = on & seen
        rec: dict = {
            "films": [films[a]["name"], films[b]["name"]],
            "length_mm": float(edges.length[on].sum()),
            "seen_mm": float(edges.length[here].sum()),
        }
        missing = [fits[x]["name"] for x in (a, b) if not fits[x].get("measured")]
        if missing:
            rec["unmeasured"] = missing
        else:
            ink = []
            for side, x in enumerate((a, b)):
                x0, y0, w, h = boxes[x]
                e = placement_error(fits[x], (w, h), edges.p[here, side] - [x0, y0])
                ink.append(np.einsum("nij,nj->ni", edges.J[here, side], e))
            m = np.linalg.norm(ink[0] - ink[1], axis=1)
            w = edges.length[here]
            rec["misregistration_mm"] = {"mean": float((m * w).sum() / w.sum()), "max": float(m.max())}
        out.append(rec)
    return out
