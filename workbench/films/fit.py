"""One film on a region: its free map at the scale that keeps the most surface within the material, and the rest."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workbench.conformal.flatten import CrowdingError, FlattenOptions, FlattenResult, ScaleMode, flatten
from workbench.conformal.layout import polygon_self_intersections
from workbench.errors import WorkbenchError
from workbench.films.regions import components_of, submesh
from workbench.mesh.topology import boundary_loops, unique_edges
from workbench.views.visibility import face_adjacency

# A film is within its material when the stretch (3D length / print length) stays in
# [MIN_STRETCH, max_stretch] on all but this share of its surface (design's warning rule; with
# films = "auto", the plan's share is the job's within_share).
MIN_STRETCH = 0.8
MAX_OFF_SHARE = 0.01


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


def off_band_mm2(fit: FilmFit) -> float:
    """The surface of a film outside the material's band, mm²."""
    return (1.0 - fit.within) * float(fit.flat.area_3d.sum())


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
    lab = components_of(face_adjacency(FE), out)
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
