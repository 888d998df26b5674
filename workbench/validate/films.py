"""Film placement per film for designs with several films: the tiles of each film fitted on their own."""

from __future__ import annotations

import numpy as np

from workbench.validate.score import Score, ViewSurface, fit_film, tile_print_points


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


def fit_per_film(sc: Score, surface: ViewSurface, films: list[dict], px_per_mm: float) -> list[dict]:
    """Placement of every film a photo's view shows, each fitted on its own tiles.

    A tile belongs to the film whose print holds the design point at its centre; the
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
        of its tiles were measured, offset_mm [x, y], rotation_deg, scale_pct, rms_mm.
    """
    out = []
    c, d = sc.centres, sc.shift_px
    if len(c) == 0:
        return [{"name": f["name"], "tiles": 0} for f in films]
    p0, p1, J, good = tile_print_points(surface, c, d)
    for f, (x0, y0, w, h) in zip(films, film_boxes_mm(films, px_per_mm), strict=True):
        mine = good & (p0[:, 0] >= x0) & (p0[:, 0] < x0 + w) & (p0[:, 1] >= y0) & (p0[:, 1] < y0 + h)
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
        out.append(rec)
    return out
