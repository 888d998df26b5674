"""The regions taken for light, not ink, and why: the lamp's mirror cone, folds, uniform ink."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.validate import photometric
from workbench.validate.dense.exposure import _residual
from workbench.validate.dense.options import CREASE_DEG, LOST_MIN_CONTRAST, MAX_NOT_COUNTED, MIRROR_DEG, SCRATCH_MM
from workbench.validate.print_warp import PrintGrid, _csum
from workbench.validate.shading import irradiance


def grid_creases(grid: PrintGrid) -> np.ndarray:
    """How far the surface's normal turns from its mean around each grid pixel (:func:`crease_band`), degrees.

    Parameters
    ----------
    grid : PrintGrid

    Returns
    -------
    (rows, cols) float32
        Degrees, made once per grid and kept on it (``grid.crease_deg``; NaN off the part).
    """
    if grid.crease_deg is None:
        grid.crease_deg = crease_band(grid.X, grid.px_per_mm)
    return grid.crease_deg


def grid_folds(grid: PrintGrid) -> np.ndarray:
    """Where the surface under the grid folds (:func:`crease_band` at CREASE_DEG or more); (rows, cols) bool."""
    return np.nan_to_num(grid_creases(grid)) >= CREASE_DEG


def facet_normals(X: np.ndarray, ii: np.ndarray, jj: np.ndarray, side: np.ndarray) -> np.ndarray:
    """The surface's own normal at grid pixels, from its derivatives on the grid, on the side of ``side``.

    dX/dcol × dX/drow by central differences (one-sided at the grid's border), as
    :func:`crease_band` takes them: on a mesh, the normal of the triangle under the pixel (of
    both, blended, astride an edge). Its sign is the grid's orientation's (the print's rows run
    down, the flat layout's y up: on a print grid it points into the part), so it is turned to
    the side of the given normals.

    Parameters
    ----------
    X : (H, W, 3) float
        Surface point under each grid pixel, mm (NaN off the part).
    ii, jj : (n,) int
        The pixels.
    side : (n, 3) float
        Normals whose side the result takes (the smooth normals: out of the part).

    Returns
    -------
    (n, 3) float32
        Unit normals (NaN where a neighbour is off the part).
    """
    H, W = X.shape[:2]
    du = X[ii, np.minimum(jj + 1, W - 1)] - X[ii, np.maximum(jj - 1, 0)]
    dv = X[np.minimum(ii + 1, H - 1), jj] - X[np.maximum(ii - 1, 0), jj]
    n = np.cross(du, dv).astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.where((n * side).sum(axis=1, keepdims=True) < 0, -n, n)


def light_range(
    normal: np.ndarray, X: np.ndarray, coef: np.ndarray, where: np.ndarray, reach_px: int
) -> tuple[np.ndarray, np.ndarray]:
    """The least and the largest light the surface around each pixel receives, relative to the light the model gives it.

    A photo's pixel shows the surface within its blur: where the surface folds, its light there
    is a blend of what its points receive, by their own normals (a real part's facets) or by the
    smooth normals both renderers shade with, which turn fast across a fold; the model shades the
    pixel by its smooth normal alone. The light the pixel shows lies between the least and the
    largest of those, per channel.

    Parameters
    ----------
    normal : (H, W, 3) float32
        The smooth normal under each grid pixel (NaN off the part).
    X : (H, W, 3) float
        The surface point under each grid pixel, mm.
    coef : (3, 9) float
        The photo's light (:func:`workbench.validate.shading.fit_shading`).
    where : (H, W) bool
        The pixels asked about.
    reach_px : int
        How far the photo's pixel reaches over the surface, grid px (its blur).

    Returns
    -------
    lo, hi : (n, 3) float32
        At ``where``'s pixels (in :func:`numpy.nonzero`'s order): the least (at most 1) and the
        largest (at least 1) light around, over the model's (where the model's is below a
        hundredth of the largest around, over that hundredth).
    """
    H, W = where.shape
    kernel = np.ones((2 * reach_px + 1, 2 * reach_px + 1), np.uint8)
    near = cv2.dilate(where.astype(np.uint8), kernel).astype(bool) & np.isfinite(normal[..., 0])
    ni, nj = np.nonzero(near)
    smooth = irradiance(normal[ni, nj], coef)
    own = irradiance(facet_normals(X, ni, nj, normal[ni, nj]), coef)
    ok = np.isfinite(own).all(axis=1)
    least = np.where(ok[:, None], np.minimum(smooth, own), smooth)
    most = np.where(ok[:, None], np.maximum(smooth, own), smooth)
    ii, jj = np.nonzero(where)
    lo = np.empty((len(ii), 3), np.float32)
    hi = np.empty((len(ii), 3), np.float32)
    # (per channel through one image: the window's least and largest are an erosion and a dilation)
    buf = np.empty((H, W), np.float32)
    big = np.float32(3e38)
    for c in range(3):
        buf.fill(big)
        buf[ni, nj] = least[:, c]
        lo[:, c] = cv2.erode(buf, kernel)[ii, jj]
        buf.fill(-big)
        buf[ni, nj] = most[:, c]
        hi[:, c] = cv2.dilate(buf, kernel)[ii, jj]
    # (a light below a hundredth of the largest around is that hundredth, as the shading's own
    # factor is floored: :func:`workbench.validate.shading.shading_factor`; the least light too)
    floor = np.float32(0.01) * np.maximum(hi, np.float32(1e-12))
    base = np.maximum(irradiance(normal[ii, jj], coef), floor)
    return np.clip(np.maximum(lo, floor) / base, 0.0, 1.0), np.maximum(hi / base, np.float32(1.0))


# The light on the path from the least light around a pixel to the largest, g(t) = lo^(1-t) hi^t
# per channel, brightens each channel of the model steadily with t, so each channel's distance to
# a target falls, then rises, and so does the largest of the three: one least, which a golden-
# section search finds. FOLD_SEARCH_T is where it stops: the model moves by about v Δ(ln g) / 2.2
# grey levels (v ≈ 255 lin^(1/2.2)), at most 255 ln(100) / 2.2 = 534 over the whole path (the
# least light is floored at a hundredth of the largest, as :func:`light_range` floors it), so
# 1e-3 of the path leaves the least within about half a grey level
FOLD_SEARCH_T = 1e-3
GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


def least_residual_under_light(
    target: np.ndarray,
    light: np.ndarray,
    gain: np.ndarray,
    offset: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> np.ndarray:
    """The least residual between ``target`` and the model of the photo under a light ``lo`` to ``hi`` times its own.

    The model is ``gain · grey(light · g) + offset`` (the exposure fit of the print as the
    shading shows it: ``light`` the print's linear light times the shading); g runs over the
    geometric path from ``lo`` to ``hi`` per channel, searched by golden sections to
    FOLD_SEARCH_T of the path (the residual has one least along it: see above).

    Parameters
    ----------
    target : (n, 3) float32
        Grey levels: what the model is to explain.
    light : (n, 3) float32
        The print's linear light times the model's shading.
    gain, offset : (n, 3) float32
        The exposure fit's gain over the shaded print and its offset (grey levels).
    lo, hi : (n, 3) float32
        The least and the largest light, relative to the model's (:func:`light_range`).

    Returns
    -------
    (n,) float32
        Grey levels, the largest channel's (:func:`workbench.validate.dense.exposure._residual`).
    """
    llo = np.log(np.maximum(lo, 1e-6)).astype(np.float32)
    lhi = np.log(np.maximum(hi, 1e-6)).astype(np.float32)
    target = target.astype(np.float32)

    def at(t: np.ndarray) -> np.ndarray:
        g = np.exp((1.0 - t)[:, None] * llo + t[:, None] * lhi)
        return _residual(target, (gain * photometric.grey_levels(light * g) + offset).astype(np.float32))

    n = len(target)
    a, b = np.zeros(n, np.float32), np.ones(n, np.float32)
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = at(c), at(d)
    # (the ends too: where the least lies at one, the search closes on it from inside)
    best = np.minimum(at(a), at(b))
    while float((b - a).max(initial=0.0)) > FOLD_SEARCH_T:
        left = fc <= fd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        # (the kept point is the new interval's other golden point: one new residual a round)
        c_new = np.where(left, b - GOLDEN * (b - a), d)
        d_new = np.where(left, c, a + GOLDEN * (b - a))
        fk = np.where(left, fc, fd)
        t_new = np.where(left, c_new, d_new)
        f_new = at(t_new)
        fc, fd = np.where(left, f_new, fk), np.where(left, fk, f_new)
        c, d = c_new, d_new
    return np.minimum(best, np.minimum(fc, fd))


def taken_along_fold(
    explained: np.ndarray, may_be_film: np.ndarray, may_be_line: np.ndarray, thin: np.ndarray, gone: np.ndarray
) -> np.ndarray:
    """The pixels a fold's light may take for light: where it explains the photo and the stated maps find nothing.

    A scratch's pixel only where a scratch is not found (``may_be_line``), a pixel of ink gone
    only where ink gone is not (``may_be_film``), any other colour where the light explains it
    (it hides no ink gone): so that the rule takes nothing the detection maps state they find.

    Parameters
    ----------
    explained, may_be_film, may_be_line : (H, W) bool
        :func:`workbench.validate.dense.pipeline._fold_light`'s answer.
    thin, gone : (H, W) bool
        A scratch's pixels, and the pixels stepped towards the bare film.

    Returns
    -------
    (H, W) bool
    """
    return explained & np.where(thin, may_be_line, np.where(gone, may_be_film, True))


# each test that takes a region for light, in the words validation.json gives it
LIGHT_RULES = {
    "beyond_film": "brighter than the bare film could be there (as the ink around shows the film): light added",
    "photometric": "light added over the ink (on a matte film: a gain of the ink) explains the region "
    "significantly better than ink gone (the photometric model's likelihood ratio: the photo keeps the ink's "
    "texture, or goes beyond the film)",
    "beyond_film_line": "a thin line brighter than the bare film could be: light, not a scratch",
    "thin_told": "a thin line that keeps the ink's variation along it: a glint, not a scratch",
    "mirrors_highlights": "ink gone and light look alike here (the photometric model tells neither) and the surface "
    "mirrors the photo's lamp there as at its sure light: not counted, and not measured",
    "mirrors_room": "ink gone and light look alike here: the region is no brighter than a glossy film's reflection of "
    "the room (Fresnel's share at the angle the photo sees it, of the brightest white the photo shows) could make "
    "it: not counted, and not measured",
    "along_fold": "light along a fold of the surface (its two sides face the lamp differently)",
    "shift_not_explained": "the flow follows light, shading or blur here, not the film: moving the print takes away "
    "less than two thirds of what the print where it is leaves",
    "shift_as_light": "a slide and a light that varies smoothly over the region look alike here (moving the print "
    "takes away less than two thirds of what such a light leaves) and the surface mirrors the photo's lamp there as "
    "at its sure light: not counted",
}


def not_counted_regions(why: dict, light: np.ndarray, px_per_mm: float, min_mm2: float, verdicts=None) -> list[dict]:
    """The regions taken for light, each with the test that decided it (:data:`LIGHT_RULES`).

    Parameters
    ----------
    why : dict of str to (H, W) bool
        Per test, the pixels it took for light (later tests win where they overlap).
    light : (H, W) bool
        Every pixel taken for light.
    px_per_mm : float
        The grid's resolution.
    min_mm2 : float
        Smaller regions are not listed.
    verdicts : photometric.RegionVerdicts, optional
        The photometric model's judgements: the one under a region joins its ``decided_by``.

    Returns
    -------
    list of dict
        At most MAX_NOT_COUNTED, largest first: ``centre_mm`` (print, x right, y down),
        ``area_mm2`` (print) and ``decided_by`` (``rule``, ``words`` and, where the model judged
        it, ``judgement``).
    """
    names = [k for k in why if k in LIGHT_RULES]
    which = np.zeros(light.shape, np.uint8)
    for i, name in enumerate(names):
        which[why[name] & light] = i + 1
    n, lab, st, cen = cv2.connectedComponentsWithStats(light.astype(np.uint8), connectivity=8)
    mm2 = 1.0 / (px_per_mm * px_per_mm)
    out = []
    for r in np.argsort(-st[1:, cv2.CC_STAT_AREA], kind="stable") + 1:
        area = float(st[r, cv2.CC_STAT_AREA]) * mm2
        if area < min_mm2 or len(out) >= MAX_NOT_COUNTED:
            break
        x0, y0, w, h, _ = st[r]
        box = (slice(y0, y0 + h), slice(x0, x0 + w))
        votes = np.bincount(which[box][lab[box] == r], minlength=len(names) + 1)
        if votes[1:].sum() == 0:
            continue
        rule = names[int(votes[1:].argmax())]
        decided = {"rule": rule, "words": LIGHT_RULES[rule]}
        if verdicts is not None:
            inside = np.zeros(light.shape, bool)
            inside[box] = lab[box] == r
            if (j := photometric.judgement_at(inside, verdicts)) is not None:
                decided["judgement"] = j
        cx, cy = cen[r]
        out.append(
            {
                "centre_mm": [round(float(cx + 0.5) / px_per_mm, 2), round(float(cy + 0.5) / px_per_mm, 2)],
                "area_mm2": round(area, 2),
                "decided_by": decided,
            }
        )
    return out


def _gradient_at(X: np.ndarray, ii: np.ndarray, jj: np.ndarray, axis: int) -> np.ndarray:
    """``np.gradient(X, axis=axis)[ii, jj]`` computed at those pixels only (unit spacing, first-order edges).

    Parameters
    ----------
    X : (H, W, C) float
    ii, jj : (n,) int
        The pixels.
    axis : int
        0 (down the rows) or 1 (along a row).

    Returns
    -------
    (n, C) float
        The same numbers as numpy's: a central difference halved inside, a one-sided one at the edges.
    """
    k = jj if axis == 1 else ii
    size = X.shape[axis]
    lo, hi = np.maximum(k - 1, 0), np.minimum(k + 1, size - 1)
    d = X[ii, hi] - X[ii, lo] if axis == 1 else X[hi, jj] - X[lo, jj]
    d[(k > 0) & (k < size - 1)] /= 2.0
    return d


def reflected_directions(X: np.ndarray, camera_center: np.ndarray, ii=None, jj=None) -> np.ndarray:
    """Per grid pixel, the direction the camera's ray leaves the surface in after a mirror reflection.

    Parameters
    ----------
    X : (H, W, 3) float
        Surface point under each grid pixel, mm (NaN off the part).
    camera_center : (3,) float
        The camera centre, mm.
    ii, jj : (n,) int, optional
        Only these pixels (the same numbers as the whole grid's there).

    Returns
    -------
    (H, W, 3) float32, or (n, 3) at ``ii, jj``
        Unit vectors (NaN off the part): a lamp in that direction shows its highlight there.
    """
    if ii is None:
        ii, jj = (a.ravel() for a in np.indices(X.shape[:2]))
        return reflected_directions(X, camera_center, ii, jj).reshape(X.shape)
    # the surface normal from the grid's own tangents: ∂X/∂x × ∂X/∂y, turned towards the camera
    with np.errstate(invalid="ignore"):
        n = np.cross(_gradient_at(X, ii, jj, 1), _gradient_at(X, ii, jj, 0))
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        v = np.asarray(camera_center, np.float64)[None, :] - X[ii, jj]
        v /= np.linalg.norm(v, axis=-1, keepdims=True)
        nv = _csum(n * v)[..., None]
        n = np.where(nv < 0, -n, n)
        # mirror of the view direction about the normal: r = 2 (n·v) n - v
        r = 2.0 * np.abs(nv) * n - v
    return r.astype(np.float32)


def mirrors_highlights(
    candidates: np.ndarray, highlights: np.ndarray, X: np.ndarray, camera_center: np.ndarray
) -> np.ndarray:
    """The candidate regions that reflect the camera's rays where the photo's highlights do.

    A highlight is where the surface mirrors a lamp into the camera: every highlight of one
    lamp reflects the camera's rays towards it. A region whose mean reflected direction lies
    within MIRROR_DEG of that of a highlight pixel faces the same lamp.

    Parameters
    ----------
    candidates : (H, W) bool
        Pixels of the regions to test (8-connected regions).
    highlights : (H, W) bool
        The photo's sure highlight pixels.
    X : (H, W, 3) float
        Surface point under each grid pixel, mm.
    camera_center : (3,) float
        The camera centre, mm.

    Returns
    -------
    (H, W) bool
        Pixels of the candidate regions that face a lamp the photo's highlights show.
    """
    out = np.zeros(candidates.shape, bool)
    if not candidates.any() or not highlights.any():
        return out
    # (the reflected rays at the highlights' and the regions' pixels only: the whole grid's
    # took a third of a second)
    sure = reflected_directions(X, camera_center, *np.nonzero(highlights))
    sure = sure[np.isfinite(sure).all(axis=1)]
    # (a few thousand directions are plenty: neighbouring highlight pixels reflect alike)
    sure = sure[:: max(1, len(sure) // 4096)]
    if not len(sure):
        return out
    cos_max = np.cos(np.radians(MIRROR_DEG))
    n, lab, boxes, _ = cv2.connectedComponentsWithStats(candidates.astype(np.uint8), connectivity=8)
    for k in range(1, n):
        x0, y0, w, h = boxes[k, :4]
        box = (slice(y0, y0 + h), slice(x0, x0 + w))
        region = lab[box] == k
        ii, jj = np.nonzero(region)
        d = reflected_directions(X, camera_center, ii + y0, jj + x0)
        d = d[np.isfinite(d).all(axis=1)].astype(np.float64)
        if not len(d):
            continue
        m = d.mean(axis=0)
        m /= max(np.linalg.norm(m), 1e-12)
        if float((sure @ m).max()) >= cos_max:
            out[box] |= region
    return out


def mirror_cone(highlights: np.ndarray, X: np.ndarray, camera_center: np.ndarray, step: int = 4) -> np.ndarray:
    """Where the surface mirrors the camera's rays within MIRROR_DEG of those of the photo's highlights.

    There a region of the colour residual is taken for light (:func:`mirrors_highlights`),
    so ink that is gone there is not found: the stated limit leaves it out. Judged on every
    ``step``-th pixel (neighbours reflect alike) and spread to the rest.

    Parameters
    ----------
    highlights : (H, W) bool
        The photo's sure highlights.
    X : (H, W, 3) float
        Surface point under each grid pixel, mm.
    camera_center : (3,) float
        mm.
    step : int

    Returns
    -------
    (H, W) bool
    """
    from scipy.spatial import cKDTree

    H, W = highlights.shape
    out = np.zeros((H, W), bool)
    if not highlights.any():
        return out
    r = reflected_directions(X[::step, ::step], camera_center)
    hs = highlights[::step, ::step] & np.isfinite(r).all(axis=2)
    # (the fallback's rays at the highlights only: the same numbers as the whole grid's there)
    sure = r[hs] if hs.any() else reflected_directions(X, camera_center, *np.nonzero(highlights))
    sure = sure[np.isfinite(sure).all(axis=1)]
    if not len(sure):
        return out
    ok = np.isfinite(r).all(axis=2)
    # (unit vectors: the chord between two directions θ apart is 2 sin(θ / 2))
    d, _ = cKDTree(sure[:: max(1, len(sure) // 4096)]).query(
        r[ok], distance_upper_bound=2.0 * np.sin(np.radians(MIRROR_DEG) / 2.0)
    )
    small = np.zeros(ok.shape, np.uint8)
    small[ok] = np.isfinite(d)
    return cv2.resize(small, (W, H), interpolation=cv2.INTER_NEAREST).astype(bool)


def lamp_cone(highlights, X, camera_center, gray, px_per_mm) -> tuple[np.ndarray, np.ndarray]:
    """The stated limit's lamp: :func:`mirror_cone`, and where it holds uniform ink (:func:`uniform_ink`).

    Apart so that it can run beside :func:`analyse`'s rest (only its result needs it).

    Returns
    -------
    cone, flat : (H, W) bool
        Within the lamp's mirror cone; and there over uniform ink.
    """
    cone = mirror_cone(highlights, X, camera_center)
    return cone, cone & uniform_ink(gray, px_per_mm)


def regions_mostly_in(regions: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The connected regions of ``regions`` with half their pixels or more in ``mask``.

    Parameters
    ----------
    regions, mask : (H, W) bool

    Returns
    -------
    (H, W) bool
    """
    n, lab = cv2.connectedComponents(regions.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros(regions.shape, bool)
    size = np.bincount(lab.ravel(), minlength=n)
    on = np.bincount(lab[mask], minlength=n)
    keep = on >= 0.5 * size
    keep[0] = False
    return keep[lab]


def along_fold(regions: np.ndarray, fold: np.ndarray) -> np.ndarray:
    """The connected regions of ``regions`` that lie along a fold: half their pixels or more in ``fold``."""
    return regions_mostly_in(regions, fold)


def crease_band(X: np.ndarray, px_per_mm: float, reach_mm: float = 0.75) -> np.ndarray:
    """The surface's normal turned from its mean over about ``reach_mm`` around each grid pixel, degrees.

    Half a crease's dihedral angle along it (the mean of the two sides' normals lies between
    them), falling to 0 ``reach_mm`` or so to either side; a smooth surface's curvature turns
    it by under a degree over a millimetre on the corpus's parts.

    Parameters
    ----------
    X : (H, W, 3) float
        Surface point under each grid pixel, mm (NaN off the part).
    px_per_mm : float
    reach_mm : float

    Returns
    -------
    (H, W) float32
        Degrees; NaN off the part.
    """
    # the normal from the surface's own derivatives on the grid: dX/dcol x dX/drow
    Xf = np.nan_to_num(X.astype(np.float32))
    du = np.gradient(Xf, axis=1)
    dv = np.gradient(Xf, axis=0)
    n = np.cross(du, dv)
    length = np.sqrt((n * n).sum(axis=2, keepdims=True))
    n = np.where(length > 1e-12, n / np.maximum(length, 1e-12), 0.0).astype(np.float32)
    on = np.isfinite(X).all(axis=2)
    s = max(1.0, reach_mm * px_per_mm)
    # (the mean over the part only: a blur of the normals and of the part's mask)
    w = cv2.GaussianBlur(on.astype(np.float32), (0, 0), s)
    m = cv2.GaussianBlur(n * on[..., None], (0, 0), s) / np.maximum(w, 1e-6)[..., None]
    m /= np.maximum(np.sqrt((m * m).sum(axis=2, keepdims=True)), 1e-12)
    cos = np.clip((n * m).sum(axis=2), -1.0, 1.0)
    out = np.degrees(np.arccos(cos)).astype(np.float32)
    out[~on] = np.nan
    return out


def uniform_ink(gray: np.ndarray, px_per_mm: float) -> np.ndarray:
    """Where the design's grey levels vary by less than LOST_MIN_CONTRAST over a scratch's window (SCRATCH_MM)."""
    s = 0.5 * SCRATCH_MM * px_per_mm
    m = cv2.GaussianBlur(gray, (0, 0), s)
    v = cv2.GaussianBlur(gray * gray, (0, 0), s) - m * m
    return np.sqrt(np.maximum(v, 0.0)) < LOST_MIN_CONTRAST
