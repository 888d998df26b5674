"""The photo in print coordinates: a dense misregistration field, colour residuals, local defects, coverage.

Every photo is mapped onto the print (each print pixel takes the photo's colour of its
surface point), so one grid serves every view and every photo of a part. There:

- **Misregistration** at every pixel with texture: DIS optical flow (OpenCV) between the
  warped photo and the print, both normalised for local exposure. A per-pixel structure
  tensor of the print says what the flow can know: texture in two directions gives the full
  vector; along a single edge only the component across it (the aperture problem), which is
  what is kept there (``normal``); no texture, nothing (``colour_only``).
- **Colour**: the photo against the print blurred like it, after a local per-channel gain
  and offset fit (shading, vignetting, exposure) on the print moved by the flow (so a shift
  is not also a colour error). Residuals beyond what noise and the fit explain are colour
  defects; where the photo shows the bare film's colour, ink is missing.
- **Masks**: highlights (saturated, or a broad additive glare) and deep shadows are not
  scored; neither is surface that turns its back to the camera (occluded), nor what the photo
  sees next to a step in depth (the part's outline, a fold: its pixels mix two surfaces),
  nor a band along the edge of what is seen; each is reported as unmeasured with its reason.

The print's grid, the photo warped onto it and its visibility states are in
:mod:`workbench.validate.print_warp`; the film's placement in :mod:`workbench.validate.placement`.
All functions here are numeric (arrays in, arrays out); the command does the I/O.
Conventions: print pixel (i, j) of the analysis grid has its centre at
((j + 0.5), (i + 0.5)) / ``px_per_mm`` mm from the trim's top-left corner (x right, y down).
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from workbench.render.defects import FILM_RGB
from workbench.validate import detection, photometric
from workbench.validate.placement import placement_field
from workbench.validate.print_warp import (
    COLOUR_ONLY,
    DEFECT,
    EDGE,
    FULL,
    HIGHLIGHT,
    MEASURED,
    NORMAL,
    OFF_PART,
    SHADOWED,
    STATE_NAMES,
    UNRESOLVED,
    PrintGrid,
    _csum,
    _length,
    rim_band,
)

REGISTRATION_BLUR_PX = 1.0  # both images smoothed alike before the flow (as the tiles are)
NORM_SIGMA_PX = 6.0  # window of the local exposure normalisation before the flow
TENSOR_SIGMA_PX = 3.0  # window of the structure tensor
# structure-tensor eigenvalue (grey levels² per px², in the photo's contrast at its resolution)
# where the dense flow is the pixel's own: DIS fills weakly textured areas from their
# neighbours (its smoothness term), so below this the flow there is theirs, however low the
# noise (measured: a 1 mm bubble's flow spread 3 mm into plain paper below it). It is about
# an edge of 10 grey levels' contrast, the least a designer draws on purpose.
MIN_EDGE = 4.0
MIN_TWO_WAY = 4.0  # the same for the smaller eigenvalue: the full vector
# the share of a slide the window's slide (about a millimetre, below) answers, as the detection limit
# states it: measured on the corpus's slid discs (bubbles of 4 to 12 mm, the window's slide inside
# the inner 70 % of each against the truth), where the window's texture has two directions within a
# factor of 10, 0.67 to 0.96 on the workbench renderer at 3000 x 2250 (7 of 8 bubbles; 0.40 on the
# eighth) and 0.71 to 0.80 on Mitsuba at 2000 x 1500 (5 of 7; 0.25 and 3.4 on the others), median
# 0.75 of the 15. Where its directions are 20 to 84 times apart (a soft edge that turns by a few
# degrees over the window) it answered -0.06, 0.05 and 0.42 (3 bubbles): WINDOW_GAIN_ALONG_EDGE,
# their median, below WINDOW_TWO_WAY_STATED. With the noise alone the limit stated bubbles found
# that the window answered at two thirds of their slide or less, and three escaped at 3000 x 2250
# (corpus of 2026-12-04)
WINDOW_GAIN = 0.75
WINDOW_GAIN_ALONG_EDGE = 0.05
WINDOW_TWO_WAY_STATED = 0.1  # the window's weaker eigenvalue over its stronger
# a defect is significant when the misregistration (or colour residual) exceeds the tolerance
# by more than this many of its standard uncertainties: one-sided 0.13 % per pixel, so a perfect
# photo's chance exceedances are single pixels, which the defects' opening removes
SIGNIFICANCE_Z = 3.0
# the stated limit is what is found with 95 % probability: a defect exactly at the significance
# threshold is found half the time, one 1.645 standard uncertainties beyond it 95 % of the time
DETECT_Z = 1.645
# the least noise assumed, grey levels: 8-bit quantisation of the photo and of the print
# (0.29 each) and their resampling through the warp
NOISE_FLOOR = 0.5
# the gain a pixel may have of its own beyond the exposure fit: shading within a crease (seen
# on the face mask: 0.63 of the fitted brightness over 8 mm² under the jaw)
SHADING = 1.6
# the dense flow's own accuracy floor, grid px: DIS (medium preset) on locally normalised
# 8-bit images errs by 0.02 to 0.04 px RMS on band-limited textures however low the noise
# (measured in tests/test_uncertainty.py: 0.040 px for features 1.5 px across, 0.019 px for
# 3 px, at noise 1, where the least-squares bound is 0.005 px); the larger is taken
FLOW_FLOOR_PX = 0.04
# the flow's floor in the photo's own pixels: its sampling, interpolation, demosaicing, JPEG and
# the renderer's or lens's pixel-level detail move an edge by a fraction of a photo pixel that no
# window averages away (its errors are correlated over the flow's window). Measured on perfect
# photos, per component: 0.12 to 0.18 photo px at 12 Mpx (a 1.2 photo px per grid px) and 0.17
# to 0.25 where a 2000 x 1500 photo sees a face mask's flank at 0.25 photo px per grid px, where
# the grid-pixel floor alone predicted a third of that
PHOTO_FLOOR_PX = 0.15
UNRESOLVED_KEEP = 0.25  # share of the print's gradient energy a photo must keep to resolve its detail
EXPOSURE_SIGMA_PX = 40.0  # window of the local gain/offset fit: larger than any defect it must not absorb
COLOUR_TOL = 40.0  # grey levels (0-255) beyond the exposure model that make a colour defect
SATURATED = 250  # a channel this bright is clipped (its colour is not known)
# a glint along a thin line over textured ink keeps the ink's texture (thin_told; measured:
# correlation 0.85 to 0.97 between the photo and the design in highlights on checkers); bare film
# shows none of it
KEPT_TEXTURE = 0.6
# ... at a contrast of at least this share of the design's (a highlight near clipping compresses it:
# 0.57 to 1.1 measured)
KEPT_CONTRAST = 0.4
# the film's colour is taken where the design is this near it in every channel (a short
# extrapolation of the exposure fit), from at least this many pixels (a median of chromaticity
# settles to a grey level within a few hundred; fewer leave the fit's own white)
FILM_NEAR = 0.75
MIN_FILM_PX = 500
MAX_FILM_SAMPLES = 100_000
MIN_CORE_PX = 10  # a thin line is told light or ink on its core where it holds this many pixels (thin_told)
# a fold: the surface's normal turned this far from its mean over 0.75 mm (half the fold's
# dihedral angle; smooth curvature turns it under a degree there): light along it is told from ink by
# nothing in one photo (along_fold)
CREASE_DEG = 10.0
# a shift defect's flow must take away this share of the residual over its region (measured: bubbles
# of 4 to 12 mm on their renders 0.76 to 0.92, the flow over faint dark texture on a perfect part 0.61)
SHIFT_EXPLAINS = 2.0 / 3.0
# texture lost: a local gain below LOST_GAIN of the photo's median where the design's contrast in the
# exposure window is at least LOST_MIN_CONTRAST grey levels (its standard deviation), and below
# LOST_GAIN of the light that is there (the photo's local mean over the design's): a shadow dims the
# design's contrast with its mean, paint over it takes the contrast and leaves its own mean (a
# Mitsuba photo of the lion's top: a fold at a third of the photo's light, its lilac-to-green edge
# at gain 0.3 of the photo's and 1 of its own light, was a 5.8 mm² "colour" defect)
LOST_GAIN = 0.3
# a colour region whose mean reflected ray lies within this of a sure highlight's faces the same lamp
# (measured: highlights on flat pale ink 0.6 to 3.7 deg from the photo's clipped or texture-keeping
# ones; dropouts 16 to 103 deg)
MIRROR_DEG = 8.0
LOST_MIN_CONTRAST = 15.0
SHADOW = 35.0  # the film's white predicted darker than this is a deep shadow
MIN_DEFECT_MM2 = 1.0  # smaller regions are noise, not defects
SHIFT_CLOSE_MM = 1.0  # gaps between textured parts of a shifted region that are closed when sizing it
MISSING_GAP_MM = 1.5  # pieces of ink gone this close are one defect (see find_defects)
MIN_SHIFT_WINDOWS = 2.0  # independent flow windows of evidence a shift defect needs (see find_defects)


def grid_folds(grid: PrintGrid) -> np.ndarray:
    """Where the surface under the grid folds (:func:`crease_band` at CREASE_DEG or more); (rows, cols) bool.

    Made once per grid and kept on it.
    """
    if grid.fold is None:
        grid.fold = crease_band(grid.X, grid.px_per_mm) >= CREASE_DEG
    return grid.fold


def agreement(flow_px: np.ndarray, full: np.ndarray, px_per_mm: float, p0, p1, boxes_mm) -> dict:
    """How the dense field agrees with the tile registration, in print mm.

    Each tile is compared with the median of the dense field over the tile's footprint on
    the print, at the pixels where the field is known in full (texture in two directions).

    Parameters
    ----------
    flow_px : (rows, cols, 2) float
        Dense misregistration, grid px.
    full : (rows, cols) bool
        Where the dense field is known in full.
    px_per_mm : float
        Grid resolution.
    p0, p1 : (n, 2) float
        Per tile, the print point at its centre and the print point the photo shows there
        (print mm): the tile's misregistration on the print is p1 - p0.
    boxes_mm : (n, 4) float
        Per tile, its footprint's bounding box on the print (x0, y0, x1, y1), mm.

    Returns
    -------
    dict
        tiles compared, median and p95 of the difference's length (print mm).
    """
    rows, cols = full.shape
    diffs = []
    for k in range(len(p0)):
        x0, y0, x1, y1 = (np.asarray(boxes_mm[k]) * px_per_mm).round().astype(int)
        x0, y0 = max(x0, 0), max(y0, 0)
        x1, y1 = min(x1, cols), min(y1, rows)
        if x1 <= x0 or y1 <= y0:
            continue
        f = full[y0:y1, x0:x1]
        if f.sum() < 20:
            continue
        dense_mm = np.median(flow_px[y0:y1, x0:x1][f], axis=0) / px_per_mm
        diffs.append(float(np.linalg.norm(dense_mm - (p1[k] - p0[k]))))
    if not diffs:
        return {"tiles": 0, "median_mm": None, "p95_mm": None}
    d = np.array(diffs)
    return {"tiles": len(d), "median_mm": float(np.median(d)), "p95_mm": float(np.percentile(d, 95))}


def local_normalise(gray: np.ndarray, sigma: float, weight: np.ndarray | None = None) -> np.ndarray:
    """Grey image with its local mean removed and its local contrast scaled to 1, as uint8 for DIS.

    Parameters
    ----------
    gray : (H, W) float32
    sigma : float
        Window, pixels.
    weight : (H, W) float32 or bool, optional
        Which pixels the window's mean and contrast are taken over (:func:`masked_normalise`);
        every pixel when not given.

    Returns
    -------
    (H, W) uint8
        128 + 40 · (g - mean) / std, clipped.
    """
    if weight is not None:
        return np.clip(128.0 + 40.0 * masked_normalise(gray, weight.astype(np.float32), sigma), 0, 255).astype(np.uint8)
    m = cv2.GaussianBlur(gray, (0, 0), sigma)
    d = gray - m
    s = np.sqrt(cv2.GaussianBlur(d * d, (0, 0), sigma))
    # a floor on the contrast: flat areas stay flat instead of amplifying noise
    n = d / np.maximum(s, 6.0)
    return np.clip(128.0 + 40.0 * n, 0, 255).astype(np.uint8)


def masked_normalise(gray: np.ndarray, w: np.ndarray, sigma: float) -> np.ndarray:
    """``gray`` less its local mean, over its local contrast, both weighted by ``w``; (H, W) float32.

    Parameters
    ----------
    gray : (H, W) float32
    w : (H, W) float32
        Weights in [0, 1]: a pixel of weight 0 (not scored: another surface, glare, nothing)
        moves neither the mean nor the contrast of its neighbours' windows.
    sigma : float
        Window, pixels.
    """
    sw = cv2.GaussianBlur(w, (0, 0), sigma) + 1e-6
    m = cv2.GaussianBlur(gray * w, (0, 0), sigma) / sw
    d = gray - m
    s = np.sqrt(cv2.GaussianBlur(d * d * w, (0, 0), sigma) / sw)
    # (a floor on the contrast: flat areas stay flat instead of amplifying noise)
    return d / np.maximum(s, 6.0)


def structure_tensor(gray: np.ndarray, sigma: float, direction: bool = True):
    """Eigenvalues and dominant direction of the smoothed structure tensor.

    Parameters
    ----------
    gray : (H, W) float32
        Grey levels.
    sigma : float
        Gaussian window, pixels.
    direction : bool
        Whether to compute ``e1``.

    Returns
    -------
    l1, l2 : (H, W) float32
        Larger and smaller eigenvalue, grey levels² per px².
    e1 : (H, W, 2) float32 or None
        Unit eigenvector of ``l1``: the direction across the dominant edge.
    """
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3) / 8
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3) / 8
    H, W = gray.shape
    q = 4 if sigma >= 8 else 1  # a wide window: sums at a quarter of the resolution, interpolated back

    def win(p):
        if q == 1:
            return cv2.GaussianBlur(p, (0, 0), sigma)
        small = cv2.GaussianBlur(cv2.resize(p, (W // q, H // q), interpolation=cv2.INTER_AREA), (0, 0), sigma / q)
        return cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)

    a, b, c = win(gx * gx), win(gx * gy), win(gy * gy)
    half_tr = (a + c) / 2
    disc = np.sqrt(((a - c) / 2) ** 2 + b * b)
    l1, l2 = half_tr + disc, np.maximum(half_tr - disc, 0)
    if not direction:
        return l1, l2, None
    # the eigenvector of l1 makes the angle θ with x, tan 2θ = 2b / (a - c)
    theta = 0.5 * np.arctan2(2 * b, a - c)
    e1 = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    return l1, l2, e1.astype(np.float32)


def tensor_weighted_flow(
    gray: np.ndarray, flow: np.ndarray, sigma: float, weight: np.ndarray | None = None
) -> np.ndarray:
    """The slide each window's texture supports: its pixels' flows combined through their gradients.

    A pixel's gradient g says of the flow only its component along g (the aperture problem);
    the vector that agrees best with every pixel of a Gaussian window w, in least squares,
    minimises Σ w (g · (v - m))², so v = (Σ w g gᵀ)⁻¹ Σ w g gᵀ m: the flows weighted by their
    structure tensors. Where the window's texture has one direction only, the component
    across it (the other is set to 0).

    Parameters
    ----------
    gray : (H, W) float32
        The print, as the flow's texture gate saw it.
    flow : (H, W, 2) float32
        Grid px.
    sigma : float
        The window, Gaussian sigma, grid px.
    weight : (H, W) bool, optional
        The pixels the windows take (all by default).

    Returns
    -------
    (H, W, 2) float32
    """
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3) / 8
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3) / 8
    if weight is not None:
        gx, gy = gx * weight, gy * weight
    xx, xy, yy = gx * gx, gx * gy, gy * gy
    mx, my = flow[..., 0], flow[..., 1]
    H, W = gray.shape
    q = 4 if sigma >= 8 else 1  # a wide window at a quarter of the resolution (as structure_tensor)

    def win(p):
        if q == 1:
            return cv2.GaussianBlur(p, (0, 0), sigma)
        small = cv2.GaussianBlur(cv2.resize(p, (W // q, H // q), interpolation=cv2.INTER_AREA), (0, 0), sigma / q)
        return cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)

    a, b, c = win(xx), win(xy), win(yy)
    nx, ny = win(xx * mx + xy * my), win(xy * mx + yy * my)
    det = a * c - b * b
    tr = a + c
    two_way = det > 1e-3 * tr * tr
    # (one direction: the tensor is about λ e eᵀ with e ∝ its larger column, λ its trace)
    ex, ey = np.where(a >= c, a, b), np.where(a >= c, b, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        norm = np.sqrt(ex * ex + ey * ey)
        ex, ey = ex / norm, ey / norm
        along = (ex * nx + ey * ny) / tr
        vx = np.where(two_way, (c * nx - b * ny) / det, along * ex)
        vy = np.where(two_way, (a * ny - b * nx) / det, along * ey)
    out = np.stack([vx, vy], axis=-1)
    return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)


FLOW_RESOLUTION = 0.75  # below this many photo px per grid px the flow runs at the photo's resolution


def flow_factor(scale: float) -> int:
    """By how much the grid is reduced for the flow: to about one photo pixel a pixel where the photo is coarser.

    A flow on a grid several times finer than the photo compares patches of a few photo
    pixels, blurred over several grid pixels, normalised over a window not much larger: on
    a 2000 x 1500 photo that samples a face mask's print at a third of a pixel per grid
    pixel, DIS wandered by 2 px where its uncertainty said 0.1. At about one photo pixel per
    pixel its patches, windows and the uncertainty's calibration hold again.
    """
    return max(1, int(round(1.0 / scale))) if 0 < scale < FLOW_RESOLUTION else 1


def _reduce(img: np.ndarray, factor: int) -> np.ndarray:
    H, W = img.shape[:2]
    return cv2.resize(img, (max(1, -(-W // factor)), max(1, -(-H // factor))), interpolation=cv2.INTER_AREA)


def _enlarge_flow(flow: np.ndarray, shape: tuple) -> np.ndarray:
    """A flow of a reduced grid on the full grid: resampled, its vectors scaled to full-grid px."""
    H, W = shape
    h, w = flow.shape[:2]
    out = cv2.resize(flow, (W, H), interpolation=cv2.INTER_LINEAR)
    out[..., 0] *= W / w
    out[..., 1] *= H / h
    return out


MEDIAN_FLOW_MM = 2.0  # the window of the flow's median the colour's model follows


def median_flow(flow: np.ndarray, px_per_mm: float) -> np.ndarray:
    """The flow's median over a window of about MEDIAN_FLOW_MM, grid px.

    A median keeps a slid region's edge where it is (a bubble's rim stays sharp) and drops
    what is narrower than half the window: the flow's wiggle where a scratch or the rim of a
    dropout looks like the neighbouring ink moved over the film. Taken on the grid reduced
    so that a 5 x 5 median spans the window (OpenCV's float median stops at 5), then
    resampled back.

    Parameters
    ----------
    flow : (H, W, 2) float32
        Grid px.
    px_per_mm : float
        The grid's resolution.

    Returns
    -------
    (H, W, 2) float32
    """
    k = max(1, int(round(MEDIAN_FLOW_MM * px_per_mm / 5.0)))
    small = _reduce(flow, k) if k > 1 else flow
    med = np.dstack([cv2.medianBlur(np.ascontiguousarray(small[..., c]), 5) for c in range(2)])
    if k == 1:
        return med
    H, W = flow.shape[:2]
    return cv2.resize(med, (W, H), interpolation=cv2.INTER_LINEAR)


def print_texture(ref_gray: np.ndarray, window_px: float, factor: int = 1):
    """The print's structure tensor eigenvalues over the flow's window (l1, l2) and over four times it.

    What :func:`analyse` asks of the print's own texture, apart so that it can run beside the
    flow (it needs neither the flow nor the photo).

    Parameters
    ----------
    ref_gray : (H, W) float32
        The print smoothed as the flow sees it.
    window_px : float
        The flow's window, Gaussian sigma, grid px.
    factor : int
        The flow's reduction of the grid (:func:`flow_factor`): l1 and l2 are scaled by its
        square, to grey levels² per pixel of the flow's grid (the gates hold for the images the
        flow compares); the wide window's l2 is not.

    Returns
    -------
    l1, l2, l1_wide, l2_wide : (H, W) float32
        Grey levels² per px² (:func:`structure_tensor`).
    """
    l1, l2, _ = structure_tensor(ref_gray, window_px, direction=False)
    # (scaled as analyse always did: two products, whose roundings a single factor² would change)
    l1, l2 = l1 * factor * factor, l2 * factor * factor
    l1_wide, l2_wide, _ = structure_tensor(ref_gray, 4 * window_px, direction=False)
    return l1, l2, l1_wide, l2_wide


def window_gain(l1_wide: np.ndarray, l2_wide: np.ndarray) -> np.ndarray:
    """The share of a slide the wide window's slide answers, as the detection limit states it.

    Parameters
    ----------
    l1_wide, l2_wide : (H, W) float32
        The wide window's structure tensor eigenvalues (:func:`print_texture`).

    Returns
    -------
    (H, W) float32
        WINDOW_GAIN where the window's texture has two directions within WINDOW_TWO_WAY_STATED,
        WINDOW_GAIN_ALONG_EDGE where not.
    """
    return np.where(l2_wide >= WINDOW_TWO_WAY_STATED * l1_wide, WINDOW_GAIN, WINDOW_GAIN_ALONG_EDGE).astype(np.float32)


def dense_flow(
    ref_gray: np.ndarray, warped_gray: np.ndarray, scored: np.ndarray, normalised: bool = False, factor: int = 1
):
    """Where each photo pixel's content sits in the design: misregistration per pixel, grid px.

    DIS optical flow from the warped photo to the print, both normalised for local
    exposure; outside ``scored`` the photo is replaced by the print (no data there must not
    drag the flow). The flow ``g`` satisfies ``print(y + g(y)) ≈ photo(y)``: the content
    the photo shows at y was designed at y + g, so it is displaced by ``m = -g``, the
    convention of the tile registration (``photo(x + m) ≈ design(x)``), evaluated where the
    photo shows the content: a defect is located where it is on the film.

    Parameters
    ----------
    ref_gray, warped_gray : (H, W) float32
        Print and warped photo, grey levels.
    scored : (H, W) bool
        Where the photo has data.

    normalised : bool
        Also return the two normalised images the flow compared.
    factor : int
        The flow runs on the grid reduced by this (:func:`flow_factor`; the images are
        expected smoothed to it already) and is resampled back.

    Returns
    -------
    (H, W, 2) float32
        Misregistration m, grid pixels (x right, y down).
    ref_n, photo_n : (h, w) uint8
        With ``normalised``: the print and the photo as the flow saw them, on the grid reduced
        by ``factor`` (the full grid where it is 1).
    """
    r, w = flow_images(ref_gray, warped_gray, scored, factor)
    g = dis_flow(w, r)
    if factor > 1:
        g = _enlarge_flow(g, ref_gray.shape)
    return (-g, r, w) if normalised else -g


def flow_images(
    ref_gray: np.ndarray, warped_gray: np.ndarray, scored: np.ndarray, factor: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """The print and the photo as :func:`dense_flow` compares them: on the grid reduced by ``factor``,
    locally normalised, the photo replaced by the print outside ``scored``; (h, w) uint8 each."""
    if factor > 1:
        ref_gray, warped_gray = _reduce(ref_gray, factor), _reduce(warped_gray, factor)
        scored = _reduce(scored.astype(np.float32), factor) > 0.5
    # (both over the scored pixels alone: beside a surface that is not scored, what the photo
    # shows there, another surface or nothing, moves neither image's window)
    w = scored.astype(np.float32)
    r = local_normalise(ref_gray, NORM_SIGMA_PX, w)
    return r, np.where(scored, local_normalise(warped_gray, NORM_SIGMA_PX, w), r)


def dis_flow(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """DIS optical flow (OpenCV, medium preset) g with ``b(x + g(x)) ≈ a(x)``; (h, w, 2) float32."""
    return cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM).calc(a, b, None)


def exposure_fit(model: np.ndarray, photo: np.ndarray, weight: np.ndarray, sigma: float):
    """Local per-channel gain and offset that turn the design into the photo (shading, vignetting, exposure).

    A weighted linear regression of ``photo`` on ``model`` in a Gaussian window, per
    channel; where the window has no contrast (a plain colour) the gain falls back to
    the global one (a ridge term), so the offset carries the exposure there.

    Parameters
    ----------
    model, photo : (H, W, 3) float32
        Design (blurred and moved like the photo) and photo, grey levels.
    weight : (H, W) float32
        1 where the pixel may inform the fit, 0 elsewhere.
    sigma : float
        Window, pixels.

    Returns
    -------
    gain, offset : (H, W, 3) float32
    contrast : (H, W, 3) float32
        The design's standard deviation in the window (grey levels): where it is large the
        local gain is the data's, not the global fallback.
    """
    H, W = weight.shape
    # the fields are smooth on the window's scale: sums at a quarter of the resolution, then
    # interpolated back (four times faster, and the same to a fraction of a grey level)
    q = 4 if sigma >= 16 else 1
    small = (max(W // q, 1), max(H // q, 1))

    # (the sums' reductions and the fields' enlargements take the three channels at once, which
    # OpenCV's resizing computes channel by channel alike; its Gaussian blur does not: one channel
    # at a time)
    def down(a):
        return cv2.resize(a, small, interpolation=cv2.INTER_AREA) if q > 1 else a

    def blur(a):
        return cv2.GaussianBlur(np.ascontiguousarray(a), (0, 0), sigma / q)

    def back(channels):
        a = np.stack(channels, axis=-1)
        return cv2.resize(a, (W, H), interpolation=cv2.INTER_LINEAR) if q > 1 else a

    w = weight.astype(np.float32)
    sw = blur(down(w)) + 1e-6
    wm = w[..., None] * model
    sums = [down(a) for a in (wm, w[..., None] * photo, wm * model, wm * photo)]
    gains, offsets, contrasts = [], [], []
    for c in range(3):
        sx, sy, sxx, sxy = (blur(a[..., c]) for a in sums)
        mx, my = sx / sw, sy / sw
        vxx = sxx / sw - mx * mx
        cxy = sxy / sw - mx * my
        # the global fit from the same (blurred) sums: their totals are the image's totals
        n = max(float(sw.sum()), 1e-6)
        gx, gy = float(sx.sum()) / n, float(sy.sum()) / n
        gvar = float(sxx.sum()) / n - gx * gx
        g0 = (float(sxy.sum()) / n - gx * gy) / max(gvar, 1e-6)
        ridge = 25.0  # grey levels²: below this much contrast in the window the global gain wins
        g = (cxy + ridge * g0) / (np.maximum(vxx, 0) + ridge)
        gains.append(g)
        offsets.append(my - g * mx)
        contrasts.append(np.sqrt(np.maximum(vxx, 0)))
    return back(gains), back(offsets), back(contrasts)


def estimate_blur(ref_gray: np.ndarray, warped_gray: np.ndarray, mask: np.ndarray) -> float:
    """Gaussian sigma (grid px) that makes the print look most like the warped photo."""
    at = np.flatnonzero(mask)  # (the masked pixels once: a boolean index finds them again each time)
    if len(at) < 100:
        return 0.0
    w = warped_gray.ravel()[at]
    w = w - w.mean()
    best, best_s = -2.0, 0.0
    for s in (0.0, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0):
        g = (cv2.GaussianBlur(ref_gray, (0, 0), s) if s else ref_gray).ravel()[at]
        d = g - g.mean()
        ncc = float((d * w).sum() / np.sqrt((d * d).sum() * (w * w).sum() + 1e-12))
        if ncc > best:
            best, best_s = ncc, s
    return best_s


@dataclass
class DenseResult:
    """One photo on the print grid.

    Attributes
    ----------
    warped : (rows, cols, 3) uint8
        The photo on the print.
    state : (rows, cols) uint8
        Per pixel, one of the states (OFF_PART ... DEFECT).
    shift_px : (rows, cols, 2) float32
        Misregistration, grid px (the normal component where only that is known; NaN where
        not measured).
    shift_mm : (rows, cols) float32
        Its length on the surface, mm (NaN where not measured).
    sigma_mm : (rows, cols) float32
        Standard uncertainty of ``shift_mm``, mm on the surface (NaN where not measured):
        the photo's noise through the texture the photo resolves there, what the model does
        not explain (a PSF or colour the design does not predict), and the flow's
        forward-backward disagreement.
    colour_residual : (rows, cols) float32
        Largest channel residual after the exposure fit, grey levels (NaN where not scored).
    missing : (rows, cols) bool
        The photo shows the bare film where the design has ink.
    labels : (rows, cols) int32
        Defect number + 1 per pixel (0: none).
    flow_px : (rows, cols, 2) float32
        The flow's own misregistration vector everywhere (also where the texture does not
        determine it), grid px.
    texture : (rows, cols) uint8
        What the print's texture lets the flow know where the photo is scored: 2 the full
        vector, 1 the component across an edge, 0 nothing.
    defects : list of dict
        Each defect: centre_mm (print), area_mm2 (print), area_surface_mm2, bbox_mm, kind,
        peak_mm and mean_mm (misregistration), colour_peak (grey levels), significance_z and
        confidence.
    blur_px : float
        The photo's blur on the grid, sigma.
    noise : float
        The photo's noise on the grid, grey levels (standard deviation at the flow's scale).
    resolution : dict
        How finely the photo samples the print (photo px per surface mm, median), what it
        cannot resolve (share of the scored print) and the resolution that would resolve it.
    detection_limit : dict
        The smallest defects this photo can find: area (mm² on the print), misregistration
        (mm on the surface), and the shares of the print where it finds a slide and ink that
        is gone (:mod:`workbench.validate.detection`).
    shift_limit_mm : (rows, cols) float32
        The smallest slide of the film found at each pixel, mm on the surface (NaN: none).
    dropout_found : (rows, cols) bool
        Where ink that is gone is found.
    window_px : float
        The flow's window, Gaussian sigma, grid px: a measurement's independent neighbourhood.
    normal_dir : (rows, cols, 2) float32
        The dominant edge's unit normal, where only the component across it is measured.
    scratch_found : (rows, cols) bool
        Where a scratch (a thin line of ink gone) is found.
    not_counted : list of dict
        The regions of the colour residual taken for light, not counted as defects
        (:func:`not_counted_regions`): ``centre_mm``, ``area_mm2`` (print) and ``decided_by``
        (``rule``, the test that decided, and ``words``).
    """

    warped: np.ndarray
    state: np.ndarray
    shift_px: np.ndarray
    shift_mm: np.ndarray
    colour_residual: np.ndarray
    missing: np.ndarray
    labels: np.ndarray
    defects: list
    blur_px: float
    flow_px: np.ndarray
    texture: np.ndarray
    sigma_mm: np.ndarray | None = None
    noise: float = 0.0
    resolution: dict | None = None
    detection_limit: dict | None = None
    shift_limit_mm: np.ndarray | None = None
    dropout_found: np.ndarray | None = None
    window_px: float = TENSOR_SIGMA_PX
    normal_dir: np.ndarray | None = None
    scratch_found: np.ndarray | None = None
    not_counted: list | None = None


def effective_samples(window_px: float, noise_corr_px) -> np.ndarray | float:
    """Independent noise samples in a Gaussian window of sigma ``window_px``: N = 4π s² / c², at least 1.

    ``noise_corr_px`` (a number or (H, W)) is the noise's correlation length in grid px,
    relative to the flow's own smoothing of 1 px (REGISTRATION_BLUR_PX, with which the
    uncertainty's prediction was checked against the flow's error): more smoothing, or a
    photo coarser than the grid (one photo pixel spans 1 / footprint grid pixels, all of them
    carrying its one noise sample), leaves the window fewer independent samples. (Without
    it the flow where a 2000 x 1500 photo sees a face mask's flank at a quarter of a photo
    pixel per grid pixel claimed 0.1 px and erred by 2.)
    """
    c = np.maximum(np.asarray(noise_corr_px, np.float32), 1.0)
    return np.maximum(4.0 * np.pi * window_px * window_px / (c * c), 1.0)


def flow_floor(footprint: np.ndarray, factor: int = 1) -> np.ndarray:
    """The flow's own floor at each grid pixel, grid px: DIS's on the grid it runs on, and the photo's pixel's.

    FLOW_FLOOR_PX of the flow's grid (``factor`` grid px each) and PHOTO_FLOOR_PX of the
    photo's (1 / ``footprint`` grid px each), in quadrature.
    """
    with np.errstate(divide="ignore"):
        photo = np.where(footprint > 0, PHOTO_FLOOR_PX / footprint, np.inf)
    return np.hypot(FLOW_FLOOR_PX * factor, photo).astype(np.float32)


def noise_correlation(reg_px: float, footprint: np.ndarray | None) -> np.ndarray | float:
    """The photo's noise correlation on the grid, px: the flow's smoothing, or one photo pixel where that is larger."""
    if footprint is None:
        return max(reg_px, 1.0)
    with np.errstate(divide="ignore"):
        return np.maximum(reg_px, np.where(footprint > 0, 1.0 / footprint, 1.0)).astype(np.float32)


def flow_uncertainty(
    pred_s: np.ndarray,
    photo_s: np.ndarray,
    weight: np.ndarray,
    window_px: float,
    correlation_px: float = 1.0,
    noise_corr_px=1.0,
    floor_px=FLOW_FLOOR_PX,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """Standard uncertainty of a local flow estimate, along the weakest and the strongest direction.

    A flow estimated over a window with weights w is a least-squares fit of the photo's
    grey levels to the model's moved by d: photo ≈ model + ∇model · d. With residuals of
    variance σ² that are independent from pixel to pixel (noise), its covariance is
    σ² (Σ w ∇∇ᵀ)⁻¹ (Σ w² ∇∇ᵀ) (Σ w ∇∇ᵀ)⁻¹ = σ² / (N T), with T the window's structure
    tensor (a weighted mean) and N = (Σ w)² / Σ w² = 4π s² the window's effective number
    of pixels (Gaussian window of sigma s). A residual the model does not explain (its PSF,
    shading or colour differ from the photo's) is not independent from pixel to pixel: it
    is correlated over the photo's blur c, so the window holds only M = s² / c² independent
    samples of it (at least 1). So, along an eigenvector of T with eigenvalue λ,
    var = σ_n² / (N λ) + max(r² - σ_n², 0) / (M λ), where r² is the window's mean squared
    residual and σ_n the photo's noise; plus the flow's own floor, FLOW_FLOOR_PX², which
    no texture or noise level goes below.

    Parameters
    ----------
    pred_s : (H, W) float32
        The model of the photo (the print moved by the flow, blurred like the photo, in the
        photo's exposure), grey levels, smoothed like the images the flow compares.
    photo_s : (H, W) float32
        The photo on the print, smoothed alike.
    weight : (H, W) bool
        Pixels that may inform the estimate.
    window_px : float
        The flow's window, Gaussian sigma, grid px.
    correlation_px : float
        Over how far the model's error is correlated: the photo's blur, grid px (at least 1).
    noise_corr_px : float or (H, W) float
        Over how far the photo's noise is correlated on the grid (:func:`noise_correlation`):
        the window then holds :func:`effective_samples` independent samples of it.
    floor_px : float or (H, W) float
        The flow's own floor, grid px (:func:`flow_floor`).

    Returns
    -------
    sigma_weak, sigma_strong : (H, W) float32
        Uncertainty of the full vector (along the weakest direction) and of the component
        across the dominant edge, grid px (inf without texture).
    e1 : (H, W, 2) float32
        The dominant edge's normal.
    noise : float
        σ_n, grey levels: the robust spread of the residual over ``weight`` (a median, which
        edges and defects, a minority, do not move), at least NOISE_FLOOR.
    l1, l2 : (H, W) float32
        The structure tensor's eigenvalues, grey levels² per px².
    """
    res = photo_s - pred_s
    w = weight.astype(np.float32)
    noise = float(1.4826 * np.median(np.abs(res[weight]))) if weight.any() else NOISE_FLOOR
    noise = max(noise, NOISE_FLOOR)
    sw = cv2.GaussianBlur(w, (0, 0), window_px) + 1e-6
    r2 = cv2.GaussianBlur(res * res * w, (0, 0), window_px) / sw
    mismatch = np.maximum(r2 - noise * noise, 0.0)
    l1, l2, e1 = structure_tensor(pred_s, window_px)
    n_eff = effective_samples(window_px, noise_corr_px)
    m_eff = np.maximum(1.0, (window_px / np.maximum(correlation_px, noise_corr_px)) ** 2)
    floor2 = floor_px * floor_px
    with np.errstate(divide="ignore", invalid="ignore"):
        weak = np.sqrt(noise * noise / (n_eff * l2) + mismatch / (m_eff * l2) + floor2)
        strong = np.sqrt(noise * noise / (n_eff * l1) + mismatch / (m_eff * l1) + floor2)
    weak = np.where(np.isfinite(weak), weak, np.inf).astype(np.float32)
    strong = np.where(np.isfinite(strong), strong, np.inf).astype(np.float32)
    return weak, strong, e1, noise, l1, l2


def forward_backward(
    flow_m: np.ndarray, ref_n: np.ndarray, photo_n: np.ndarray, factor: int = 1, back=None
) -> np.ndarray:
    """How far the flow from the photo to the print and the flow back disagree, grid px.

    With m the misregistration at the photo's pixel y (its content was designed at
    z = y - m), the flow back from the print, b (print(z) ≈ photo(z + b(z))), carries z back
    to y: b(y - m(y)) = m(y) where both are right. Where the texture is ambiguous (repeated
    strokes, detail the photo does not resolve) the two flows settle on different answers.

    Parameters
    ----------
    flow_m : (H, W, 2) float32
        Misregistration from :func:`dense_flow`, grid px.
    ref_n, photo_n : (h, w) uint8
        The locally normalised print and photo the forward flow compared (on the grid
        reduced by ``factor``, :func:`dense_flow`).
    factor : int
        The grid's reduction for the flow (:func:`flow_factor`).
    back : (h, w, 2) float32, optional
        The flow back, ``dis_flow(ref_n, photo_n)``, when the caller has it already.

    Returns
    -------
    (H, W) float32
        |b(y - m(y)) - m(y)|, grid px.
    """
    H, W = flow_m.shape[:2]
    # print(x) ≈ photo(x + b(x)): b carries a print pixel to where the photo shows it
    b = dis_flow(ref_n, photo_n) if back is None else back
    if factor > 1:
        b = _enlarge_flow(b, (H, W))
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    back = cv2.remap(b, jj - flow_m[..., 0], ii - flow_m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    bx, by = back[..., 0], back[..., 1]
    return np.hypot(bx - flow_m[..., 0], by - flow_m[..., 1]).astype(np.float32)


BLUR_LEVELS = (0.0, 0.75, 1.0, 1.5, 2.0, 3.0, 4.5, 6.0)  # grid px: the blurs a local PSF is rounded to


PRINT_BLUR_PX = 0.5  # the print's own blur, grid px: see local_psf


def local_psf(blur: float, scale: float, footprint: np.ndarray) -> np.ndarray:
    """The photo's blur at each grid pixel, Gaussian sigma in grid px.

    ``blur`` is measured over the whole photo, where it samples the print at ``scale``
    photo pixels per grid pixel (its median). It has two parts. The print's own, fixed on
    the print: a print pixel is a box (sigma 0.29 px) that the film shows interpolated (a
    triangle, 0.41 px) and the ink spreads a little, PRINT_BLUR_PX in all (never more than
    was measured). And the camera's (lens, sensor, demosaicing, the warp's anti-aliasing),
    fixed in photo pixels, so that where the photo samples the print at ``footprint`` it is
    ``scale / footprint`` times what it is at the median. Variances add:
    ``b² = b0² + (blur² - b0²) (scale / footprint)²``.

    (Where a deep part is seen partly from far and partly from near, the photo can be three
    times finer than its median on the print: the near surface's blur is then a third,
    and the print's detail there is resolved. Holding it to the median's blur made the
    model blurrier than the photo, and the print's sharp checker there "ink gone".)

    Parameters
    ----------
    blur : float
        Measured blur, grid px.
    scale : float
        Median photo px per grid px.
    footprint : (H, W) float
        Photo px per grid px per pixel (0: not seen).

    Returns
    -------
    (H, W) float32
        At most BLUR_LEVELS[-1].
    """
    b0 = min(blur, PRINT_BLUR_PX)
    camera2 = blur * blur - b0 * b0
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(footprint > 0, scale / footprint, 1.0)
    b = np.sqrt(b0 * b0 + camera2 * r * r)
    return np.clip(b, 0.0, BLUR_LEVELS[-1]).astype(np.float32)


def blur_levels(sigma: np.ndarray) -> np.ndarray:
    """Index into BLUR_LEVELS of the level nearest each sigma; (H, W) int8."""
    levels = np.asarray(BLUR_LEVELS, np.float32)
    return np.digitize(sigma, 0.5 * (levels[1:] + levels[:-1])).astype(np.int8)


def blur_locally(img: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """An image blurred by a Gaussian whose sigma varies over it (rounded to BLUR_LEVELS).

    Parameters
    ----------
    img : (H, W) or (H, W, C) float32
    sigma : (H, W) float
        Per pixel, grid px.

    Returns
    -------
    Same shape as ``img``.
    """
    k = blur_levels(sigma)
    # (the levels present by a count: np.unique sorts every pixel)
    present = np.flatnonzero(np.bincount(k.ravel().view(np.uint8), minlength=len(BLUR_LEVELS)))
    out = None
    for i in present:
        s = float(BLUR_LEVELS[i])
        b = cv2.GaussianBlur(img, (0, 0), s) if s > 0 else img
        if out is None:
            out = b.copy() if len(present) > 1 else b
        else:
            m = k == i
            np.copyto(out, b, where=m[..., None] if img.ndim == 3 else m)
    return out


def gradient_energy(gray: np.ndarray, blur_px: float) -> np.ndarray:
    """Local gradient energy of an image blurred by ``blur_px``: the structure tensor's trace, grey levels² per px²."""
    b = cv2.GaussianBlur(gray, (0, 0), blur_px) if blur_px > 0 else gray
    gx = cv2.Sobel(b, cv2.CV_32F, 1, 0, ksize=3) / 8
    gy = cv2.Sobel(b, cv2.CV_32F, 0, 1, ksize=3) / 8
    return cv2.GaussianBlur(gx * gx + gy * gy, (0, 0), TENSOR_SIGMA_PX)


def unresolved_detail(ref_gray: np.ndarray, blur_px: np.ndarray, min_texture: float):
    """Where the print has detail that the photo's blur there cannot resolve, and the blur that would.

    Detail finer than about two of the photo's pixels loses most of its gradient in the
    photo; the flow there follows the photo's PSF rather than the print. A print pixel is
    unresolved where the print has texture (gradient energy ``min_texture``) and the print
    blurred like the photo keeps less than UNRESOLVED_KEEP of it.

    Parameters
    ----------
    ref_gray : (H, W) float32
        The print, grey levels.
    blur_px : (H, W) float
        The photo's blur on the grid at each pixel (:func:`local_psf`), Gaussian sigma, grid px.
    min_texture : float
        Gradient energy (grey levels² per px², structure-tensor trace) that counts as detail.

    Returns
    -------
    unresolved : (H, W) bool
    needed_blur : (H, W) float32
        Where unresolved, the largest blur (grid px) at which the detail would keep
        UNRESOLVED_KEEP of its energy (0.5: not even then): the photo's blur must come down to
        it; 0.5 elsewhere.
    """
    energy = gradient_energy(ref_gray, 0.5)
    H, W = ref_gray.shape
    k = blur_levels(blur_px)
    candidates = (energy >= min_texture) & (blur_px > 0.5) & (k > 0)
    unresolved = np.zeros((H, W), bool)
    needed = np.full((H, W), 0.5, np.float32)
    if not candidates.any():
        return unresolved, needed
    top = int(k[candidates].max())
    kept = {}
    for i in range(1, top + 1):
        e = gradient_energy(ref_gray, float(BLUR_LEVELS[i]))
        m = candidates & (k == i)
        unresolved[m] = e[m] < UNRESOLVED_KEEP * energy[m]
        kept[i] = e
    for i in range(1, top + 1):
        # the detail survives this level's blur: a photo this sharp would resolve it
        ok = unresolved & (kept[i] >= UNRESOLVED_KEEP * energy)
        needed[ok] = BLUR_LEVELS[i]
    return unresolved, needed


@dataclass
class FlowStart:
    """What :func:`analyse` starts from: the masks, the images the flow compares and the flow itself.

    Attributes
    ----------
    seen, sat, inner : (H, W) bool
        Scored pixels; clipped highlights (with their margin); scored pixels with scored
        neighbours 2 px each way (the blur's and the exposure fit's).
    rg, pg : (H, W) float32
        The print and the photo, grey.
    rgb_, pgb_ : (H, W) float32
        Both smoothed alike by ``reg`` before the flow.
    ref_n, pho_n : (h, w) uint8
        Both as the flow compares them (:func:`flow_images`).
    texture : Future
        :func:`print_texture` of ``rgb_``.
    m : (H, W, 2) float32
        The flow: the photo at y shows the print at y - m(y), grid px.
    reg : float
        The registration blur, grid px.
    flow_k : int
        The flow's reduction of the grid (:func:`flow_factor`).
    win : float
        The flow's window, grid px.
    """

    seen: np.ndarray
    sat: np.ndarray
    inner: np.ndarray
    rg: np.ndarray
    pg: np.ndarray
    rgb_: np.ndarray
    pgb_: np.ndarray
    ref_n: np.ndarray
    pho_n: np.ndarray
    texture: object
    m: np.ndarray
    reg: float
    flow_k: int
    win: float


def flow_start(
    ref: np.ndarray, pho: np.ndarray, warped: np.ndarray, state: np.ndarray, scale: float, later
) -> FlowStart:
    """The masks, images and flow of :func:`analyse` for a print ``ref`` (H, W, 3) float32 against the photo.

    Parameters
    ----------
    ref : (H, W, 3) float32
        The print on the grid (or the print as the film's placement puts it).
    pho, warped : (H, W, 3) float32 and uint8
        The photo on the grid.
    state : (H, W) uint8
        Visibility states (FULL: scored).
    scale : float
        Photo pixels per grid pixel.
    later : Executor
        Where the print's texture is computed beside the flow.

    Returns
    -------
    FlowStart
    """
    seen = state == FULL
    rg = cv2.cvtColor(ref, cv2.COLOR_RGB2GRAY)
    pg = cv2.cvtColor(pho, cv2.COLOR_RGB2GRAY)
    # highlights: white-out, every channel clipped (and a margin around, where the glare still adds light)
    # (an opening first: a highlight is broad; a white scratch that clips is a defect, not glare)
    sat = ((_cmin(warped) >= SATURATED) & seen).astype(np.uint8)
    sat = cv2.morphologyEx(sat, cv2.MORPH_OPEN, np.ones((9, 9), np.uint8))
    sat = cv2.dilate(sat, np.ones((7, 7), np.uint8)).astype(bool)
    inner = cv2.erode(seen.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    # the flow on both images smoothed alike (unbiased whatever the photo's blur; estimating
    # that blur first is not: misregistration makes more blur look better)
    reg = max(REGISTRATION_BLUR_PX, REGISTRATION_BLUR_PX / max(scale, 1e-3))
    rgb_ = cv2.GaussianBlur(rg, (0, 0), reg)
    pgb_ = cv2.GaussianBlur(pg, (0, 0), reg)
    # (at about the photo's resolution where it is coarser than the grid, its windows with it)
    flow_k = flow_factor(scale)
    win = TENSOR_SIGMA_PX * flow_k
    ref_n, pho_n = flow_images(rgb_, pgb_, seen & ~sat, flow_k)
    # (the flow compares locally normalised images, so whether it is the pixel's own depends
    # on the print's texture, not on the photo's exposure)
    texture = later.submit(print_texture, rgb_, win, flow_k)
    g = dis_flow(pho_n, ref_n)
    m = -(_enlarge_flow(g, rg.shape) if flow_k > 1 else g)  # as dense_flow
    return FlowStart(seen, sat, inner, rg, pg, rgb_, pgb_, ref_n, pho_n, texture, m, reg, flow_k, win)


def analyse(
    grid: PrintGrid,
    warped: np.ndarray,
    state: np.ndarray,
    tolerance_mm: float,
    scale: float = 1.0,
    footprint: np.ndarray | None = None,
    camera_center: np.ndarray | None = None,
) -> DenseResult:
    """Dense misregistration with its uncertainty, colour residuals, masks and defects of one photo on the print.

    Parameters
    ----------
    grid : PrintGrid
    warped : (rows, cols, 3) uint8
        The photo on the print (:func:`warp_to_print`).
    state : (rows, cols) uint8
        Its visibility states.
    tolerance_mm : float
        Misregistration beyond this (mm on the surface) by more than SIGNIFICANCE_Z of its
        uncertainty is a defect.
    scale : float
        Photo pixels per grid pixel (:func:`warp_to_print`): where the photo is coarser than
        the grid, both images are smoothed to its resolution before the flow (detail the photo
        cannot resolve would otherwise move edges).
    footprint : (rows, cols) float, optional
        Photo pixels per grid pixel at each grid pixel (:func:`warp_to_print`); ``scale``
        everywhere when not given.
    camera_center : (3,) float, optional
        The photo's camera centre, mm in the mesh frame: a colour region that mirrors the
        lamp like the photo's own highlights is one of them (:func:`mirrors_highlights`).

    Returns
    -------
    DenseResult
    """
    # what needs neither the flow nor the photo's fit (the flow back, the print's own texture, its
    # unresolved detail) is computed on a second thread meanwhile: numpy and OpenCV release the
    # GIL in their loops, so on two cores that work costs little wall time; the same numbers
    with ThreadPoolExecutor(max_workers=1) as later:
        return _analyse(grid, warped, state, tolerance_mm, scale, footprint, camera_center, later)


def _analyse(grid, warped, state, tolerance_mm, scale, footprint, camera_center, later) -> DenseResult:
    """:func:`analyse`, with ``later`` the executor of the work that can run beside it."""
    state = rim_band(state)
    pho = warped.astype(np.float32)
    ref = grid.reference.astype(np.float32)
    fs = flow_start(ref, pho, warped, state, scale, later)
    H, W = state.shape
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    # (surface mm per grid px: print mm times the film's local stretch)
    mm_per_px = (grid.surface_per_print / grid.px_per_mm).astype(np.float32)
    # placement is not a defect: each film's placement (an affine field over the film, fitted to
    # this first flow where the print has texture both ways) is judged as placement, and the
    # analysis starts again from the print placed so, when that placement moves it anywhere by
    # more than a measuring pixel's uncertainty may be. Local defects are then what remains: a
    # film 0.8 mm off is no 10,000 mm² "shift", a bubble on it is still found, and the print's
    # texture the flow and its windows weigh is the texture the photo shows there (the print
    # where it is, 9 grid px from it, drew a slide along every rim)
    two_way = fs.seen & ~fs.sat & (fs.texture.result()[1] >= MIN_TWO_WAY)
    ones = np.ones((H, W), np.float32)
    early, _ = placement_field(
        fs.m, np.zeros_like(fs.m), two_way, np.zeros_like(two_way), ones, grid.film, np.inf, fs.win
    )
    if np.any(np.hypot(early[..., 0], early[..., 1]) * mm_per_px > tolerance_mm / SIGNIFICANCE_Z):
        mx, my = jj - early[..., 0], ii - early[..., 1]
        ref = cv2.remap(ref, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        # (what the placement brings in from beyond the film's outline is no print: the film's rim as placed)
        on = np.isfinite(grid.X[..., 0]).astype(np.uint8)
        from_film = cv2.remap(on, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0) > 0
        state[(state == FULL) & ~from_film] = OFF_PART
        state = rim_band(state)
        state[(state == OFF_PART) & on.astype(bool)] = EDGE
        fs = flow_start(ref, pho, warped, state, scale, later)
    else:
        early = np.zeros_like(early)
    seen, sat, inner, rg, pg, rgb_, pgb_ = fs.seen, fs.sat, fs.inner, fs.rg, fs.pg, fs.rgb_, fs.pgb_
    ref_n, pho_n, texture, m, reg, flow_k, win = fs.ref_n, fs.pho_n, fs.texture, fs.m, fs.reg, fs.flow_k, fs.win
    back = later.submit(dis_flow, ref_n, pho_n)
    # the print moved by the flow: what the photo shows if only misregistration happened;
    # then the photo's blur, measured on the aligned pair
    # (the colour's model follows the flow's median over about 2 mm: a film's slide is smooth at
    # that scale, and the flow's own wiggle along a scratch or a dropout's rim, which pulls the
    # neighbouring ink over the bare film, would explain the ink that is gone away)
    mc = median_flow(m, grid.px_per_mm)
    moved = cv2.remap(ref, jj - mc[..., 0], ii - mc[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    blur = estimate_blur(cv2.cvtColor(moved, cv2.COLOR_RGB2GRAY), pg, inner & ~sat)
    # the blur where the photo samples the print coarser than its median (a surface seen
    # obliquely or from farther): a photo pixel spans 1 / footprint grid pixels there, so its
    # blur on the grid grows in proportion (one blur for a whole photo of a deep part made
    # the creases seen at a slant "colour defects": the print's detail the photo cannot show)
    fp = footprint if footprint is not None else np.full((H, W), scale, np.float32)
    # (rounded to the level of the median where the photo is not scored: nothing there asks for more)
    local_blur = np.where(inner, local_psf(blur, scale, fp), np.float32(blur))
    # detail the photo cannot resolve: its flow follows the photo's PSF, not the print
    detail = later.submit(unresolved_detail, rg, local_blur, MIN_EDGE)
    moved = blur_locally(moved, local_blur)
    # exposure: a robust local fit (a second pass without the first pass's outliers)
    weight = (inner & ~sat).astype(np.float32)
    gain, offset, _ = exposure_fit(moved, pho, weight, EXPOSURE_SIGMA_PX)
    res = _residual(pho, gain * moved + offset)
    weight = weight * (res < COLOUR_TOL)
    gain, offset, contrast = exposure_fit(moved, pho, weight, EXPOSURE_SIGMA_PX)
    pred = gain * moved + offset
    res = _residual(pho, pred)
    # the design's texture gone from the photo: light scales it (shading, vignetting) or adds
    # to it (glare), never takes it away; where the window's design has contrast, a local gain
    # that collapses against the photo's own is the decoration painted over, covered or torn
    # off, which the fit would otherwise absorb into its offset
    determined = contrast >= LOST_MIN_CONTRAST
    g0 = photo_gain(gain, determined, seen & ~sat)
    # (the light that is there: the photo's local mean over the design's, in the fit's window; the
    # weights cancel in the ratio, and a design darker than a grey level there is taken as one)
    fw = (seen & ~sat).astype(np.float32)[..., None]
    sw = cv2.GaussianBlur(fw, (0, 0), EXPOSURE_SIGMA_PX)[..., None]
    brightness = cv2.GaussianBlur(pho * fw, (0, 0), EXPOSURE_SIGMA_PX) / np.maximum(
        cv2.GaussianBlur(moved * fw, (0, 0), EXPOSURE_SIGMA_PX), sw + 1e-6
    )
    lost = texture_lost(gain, determined, seen & ~sat, g0, brightness)
    white = gain * np.float32(255.0) + offset  # the film's white as the exposure fit extrapolates it
    # the photometric model (:mod:`workbench.validate.photometric`): the bare film as the ink around
    # each pixel shows it, in linear light (the exposure fit's white is extrapolated in grey levels
    # from the ink's level to the film's, over dark ink wrong by tens of grey levels: a dropout
    # there looked brighter than its film). Light for sure is what is brighter than the bare film
    # could be, in every channel (a clipped channel where the film stays below clipping); what
    # clips where the film may clip too, a white dropout included, is judged with its region below
    noise0 = float(1.4826 * np.median(res[weight > 0])) if (weight > 0).any() else NOISE_FLOOR
    sheen = photometric.linear(np.maximum(_cmin(offset), 0.0))  # the light the exposure fit adds over the ink
    film_lit = photometric.film_level(pho, moved, weight > 0, noise0, 0.5 * EXPOSURE_SIGMA_PX, white, sheen)
    if (unknown := film_lit.sigma >= photometric.UNKNOWN).any():
        # (where no ink around tells the film, the exposure fit's white in the film's one colour)
        film_lit.film[unknown] = film_colour(white, moved, weight > 0, unknown)[unknown]
    past_film = seen & photometric.beyond_film(pho, film_lit, noise0, SIGNIFICANCE_Z)
    highlight = past_film & ~lost
    # (what decided each pixel taken for light, for validation.json's not_counted)
    why_light = {"beyond_film": highlight}
    shadow = seen & ~highlight & (_cmax(white) < SHADOW)
    state[highlight] = HIGHLIGHT
    state[shadow] = SHADOWED
    scored = state == FULL
    # the colour test (with the scratch test and where ink that is gone would be found) needs
    # nothing of the flow's uncertainty: beside it; and after it a window's slide (below)
    colour_test = later.submit(colour_residuals, pho, pred, gain, offset, res, weight, scored, fp, grid.px_per_mm)
    # (the slide's windows leave out the light known by then and the flow's reach around it,
    # below; the light known now is most often all of it: the slide for it is computed beside
    # the rest, and again below only where telling light from ink adds to it)
    r_lit = max(1, int(round(4 * win)))
    lit_disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r_lit + 1,) * 2)
    # (white-out is no light for sure, the bare film may clip too, but its rim moves with the light
    # that clips it, not with the print: the flow's windows leave it out as they leave out light)
    lit_now = cv2.dilate(((state == HIGHLIGHT) | sat).astype(np.uint8), lit_disc).astype(bool)
    slide = later.submit(tensor_weighted_flow, rgb_, m, 4 * win, ~lit_now)
    # what the flow can know there: the photo's noise and what the model does not explain,
    # through the texture the photo resolves (the model is the print blurred like the photo,
    # in the photo's own contrast), and where the flow back disagrees, half that disagreement
    pred_s = cv2.GaussianBlur(cv2.cvtColor(pred, cv2.COLOR_RGB2GRAY), (0, 0), reg)
    corr = noise_correlation(reg, fp)
    floor = flow_floor(fp, flow_k)
    weak, strong, e1, noise, l1, l2 = flow_uncertainty(
        pred_s, pgb_, scored & (weight > 0), win, max(1.0, float(np.hypot(blur, reg))), corr, floor
    )
    fb = forward_backward(m, ref_n, pho_n, flow_k, back.result())
    weak = np.hypot(weak, 0.5 * fb)
    strong = np.hypot(strong, 0.5 * fb)
    # a pixel measures misregistration where the flow there is its own (MIN_EDGE) and its
    # uncertainty lets a shift of twice the tolerance stand out at SIGNIFICANCE_Z
    # (σ ≤ tolerance / Z); the full vector where the weakest direction does, the component
    # across the edge where only that one does
    usable = tolerance_mm / SIGNIFICANCE_Z
    # (p1, p2 in grey levels² per pixel of the flow's grid: the gates hold for the images the
    # flow compares)
    p1, p2, l1_wide, l2_wide = texture.result()
    full = scored & (p2 >= MIN_TWO_WAY) & (weak * mm_per_px <= usable)
    normal = scored & ~full & (p1 >= MIN_EDGE) & (strong * mm_per_px <= usable)
    unresolved, needed_blur = detail.result()
    unresolved &= scored
    full &= ~unresolved
    normal &= ~unresolved
    stated = scored.copy()  # (before light is told from ink: that depends on the defect)
    measurable = stated & ~unresolved
    # a window of about a millimetre's slide (below): its uncertainty is the photo's noise
    # through the window's weaker direction, and the floor, none of it raised by a defect
    with np.errstate(divide="ignore", invalid="ignore"):
        wide_sigma = np.sqrt(noise * noise / (effective_samples(4 * win, corr) * l2_wide) + floor * floor) * mm_per_px
    wide_sigma = np.nan_to_num(wide_sigma, nan=np.inf).astype(np.float32)
    # the detection limit, stated for a sound part (needed only for the result: beside the rest)
    shift_limit = later.submit(
        stated_shift_limit, tolerance_mm, noise, l1, l2, effective_samples(win, corr), floor, mm_per_px, wide_sigma,
        measurable & (p2 >= MIN_TWO_WAY), measurable, usable, l1_wide, l2_wide,
    )  # fmt: skip
    # (the misregistration reported is the whole of it: the placement's and the rest)
    m_total = m + early
    shift = np.full((H, W, 2), np.nan, np.float32)
    np.copyto(shift, m_total, where=full[..., None])
    mn = _csum(m_total * e1)[..., None] * e1  # the component across the edge
    np.copyto(shift, mn, where=normal[..., None])
    state[scored & ~full & ~normal] = COLOUR_ONLY
    state[unresolved] = UNRESOLVED
    state[full] = FULL
    state[normal] = NORMAL
    texture = np.zeros((H, W), np.uint8)
    texture[normal] = 1
    texture[full] = 2
    shift_mm = np.hypot(shift[..., 0], shift[..., 1]) * mm_per_px
    sigma_mm = np.full((H, W), np.nan, np.float32)
    np.copyto(sigma_mm, weak * mm_per_px, where=full)
    np.copyto(sigma_mm, strong * mm_per_px, where=normal)
    colour_scored = scored  # colour is judged wherever the photo is scored (unresolved detail too)
    ct = colour_test.result()
    alpha, colour_limit, colour_noise, res_raw, res, gone, colour_bad = ct[:7]
    inked, dropout_found, thin, thin_found = ct[7:]
    colour = np.where(colour_scored, res, np.nan).astype(np.float32)
    # light, not ink, again: a glossy film's highlight adds the light's colour over the ink's,
    # broad and soft-edged; ink that is gone replaces the ink's colour by the film's, with
    # the sharp edge of the ink's own rim
    # (the light's colour only where light_or_ink asks: at the failed pixels, which it closes by
    # a pixel; the whole image's took a twentieth of a second)
    # each region judged by the photometric model: light added against ink gone, by the likelihood
    # ratio on its core with the photo's own noise (one independent sample per photo pixel where
    # the photo is coarser than the grid) and the model's error around it
    light_rgb = np.median(film_lit.film[seen][::97], axis=0) if seen.any() else np.ones(3, np.float32)
    light_rgb = np.maximum(light_rgb, 1.0) / max(float(light_rgb.max()), 1.0)
    verdicts = photometric.judge_regions(
        colour_bad, gone, pho, pred, film_lit.film, light_rgb, colour_limit, colour_noise, film_lit.sigma,
        colour_scored & ~colour_bad, local_blur, np.minimum(fp * fp, 1.0), SIGNIFICANCE_Z,
    )  # fmt: skip
    glossed = verdicts.light.copy()
    gone = gone & ~glossed
    why_light["photometric"] = glossed.copy()
    told_gone = np.zeros_like(gone)  # regions the model tells for ink gone
    for r, j in verdicts.judgements.items():
        if j["hypothesis"] == "ink gone":
            told_gone |= verdicts.labels == r
    # (a region stepped only part of the way towards the film is judged by the colour test
    # that allows shading, like any other colour)
    colour_bad = (colour_scored & (res > colour_limit)) | gone
    colour_bad &= ~glossed
    if lost.any():
        # judged against the design at the photo's own gain: the fit's collapsed gain would
        # have explained the lost texture away
        local_mean = cv2.GaussianBlur(moved, (0, 0), EXPOSURE_SIGMA_PX)
        res_lost = _residual(pho, pred + (g0 - gain) * (moved - local_mean))
        beyond = (lost & colour_scored & ~glossed & (res_lost > colour_limit)).astype(np.uint8)
        # (the limit's allowance at the design's edges cuts a painted-over checker into its
        # squares; the lost texture between them is one region)
        lost &= cv2.morphologyEx(beyond, cv2.MORPH_CLOSE, np.ones((7, 7), np.uint8)).astype(bool) & colour_scored
        colour_bad |= lost
        res = np.where(lost, res_lost, res)
        colour = np.where(colour_scored, res, np.nan).astype(np.float32)
    if camera_center is not None:
        # thin lines of ink gone are told by the ink along them: a glint keeps the ink's
        # variation, a scratch shows the film; one over uniform ink is not told, and like a
        # region the photometric model cannot tell, is left to the lamp (below)
        told = thin_told(thin, pho, pred, alpha >= 0.5, int(round(0.5 * MISSING_GAP_MM * grid.px_per_mm)))
        # (a line told ink gone stays ink gone where the model took the region it joins for
        # light: a scratch across a glossy sheen is one region with it)
        told_ink = told == 2
        # (but a line brighter than the bare film could be is light: text washed out under a glint)
        washed = regions_mostly_in(told_ink, past_film)
        told_ink &= ~washed
        why_light["beyond_film_line"] = washed
        why_light["thin_told"] = (told == 1) & ~glossed
        glossed |= washed
        glossed &= ~told_ink
        gone |= told_ink
        colour_bad |= told_ink
        glossed |= told == 1
        # the light the photo shows for sure: beyond the film, and regions light explains better
        sure = highlight | glossed
        # the stated limit, honestly: where the surface mirrors the lamp of the photo's sure
        # highlights, ink that is gone is not told from light (a line over uniform ink neither)
        # (needed only for the result: beside the rest, applied below)
        cone = later.submit(lamp_cone, sure, grid.X, camera_center, rg, grid.px_per_mm)
        # a region the photo cannot tell (ink gone or light) is taken for light only where the
        # surface mirrors that lamp: elsewhere no light the photo shows can reach the camera from
        # it, and it stays ink gone
        not_told = (verdicts.not_told | (told == 3)) & colour_bad & ~glossed & ~told_ink
        mirrored = mirrors_highlights(not_told, sure, grid.X, camera_center)
        why_light["mirrors_highlights"] = mirrored
        glossed |= mirrored
        colour_bad &= ~glossed
        gone &= ~glossed
    # light along a fold: where the surface folds, its two sides face the light differently and a
    # ridge catches it in a line, sharper than the exposure fit follows and, over uniform ink, as
    # bright as film (perfect photos of the scanned lion: lines of 5 to 14 mm² along folds whose
    # normals turn 14 to 22° from their mean). A colour region that lies along one is light; ink
    # gone there is not told from it in one photo, and the stated limit says so (below)
    fold = grid_folds(grid)
    # (never a region the model tells for ink gone)
    folded = colour_bad & ~glossed & ~told_gone
    along = along_fold(folded & ~told_ink if camera_center is not None else folded, fold)
    glossed |= along
    colour_bad &= ~glossed
    gone &= ~glossed
    why_light["along_fold"] = along
    # what was taken for light, and by which test (the regions of the colour residual; a clipped or
    # glaring area is listed where it covers a region too)
    not_counted = not_counted_regions(why_light, glossed | highlight, grid.px_per_mm, MIN_DEFECT_MM2, verdicts)
    state[glossed] = HIGHLIGHT
    colour_scored = colour_scored & ~glossed
    scored = scored & ~glossed
    full &= ~glossed
    normal &= ~glossed
    for a in (shift, shift_mm, sigma_mm, colour):
        a[glossed] = np.nan
    texture[glossed] = 0
    missing = gone
    # a slide over a window of about a millimetre: the least-squares vector its pixels' texture
    # supports (each pixel's flow through its gradients: :func:`tensor_weighted_flow`), with the
    # window's own uncertainty (the photo's noise through its weaker direction, and the
    # floor, which no window averages away). Along an edge a pixel knows only the component
    # across it, which a slide parallel to it leaves 0 (a bubble cut into stripes), and DIS's
    # own vector there is its guess (it drifted 13 px over a photograph's soft background); a
    # window whose edges turn knows the whole slide. Usable where its uncertainty is, as a
    # pixel's (no gate on the texture's grey levels: a photograph's soft edges measure well)
    # (light, not ink, moves an edge for the flow too: DIS follows a glint along a ridge as if
    # the print had slid under it, 0.5 mm on a glossy photo's perfect part; the windows leave
    # out what light covers and the reach of the flow's patches around it)
    lit = cv2.dilate(((state == HIGHLIGHT) | sat).astype(np.uint8), lit_disc).astype(bool)
    # (the slide computed beside the rest where the light is the same: the same numbers)
    m_wide = slide.result() if np.array_equal(lit, lit_now) else tensor_weighted_flow(rgb_, m, 4 * win, ~lit)
    # (local defects in the flow from the placed print; the misregistration reported is the whole of it)
    local_shift = np.where(normal[..., None], _csum(m * e1)[..., None] * e1, m)
    local_mm = np.where(full | normal, np.hypot(local_shift[..., 0], local_shift[..., 1]) * mm_per_px, np.nan)
    wide_ok = scored & ~unresolved & ~lit & (wide_sigma <= usable)
    wide_mm = np.hypot(m_wide[..., 0], m_wide[..., 1]) * mm_per_px
    z_wide = np.where(wide_ok, (wide_mm - tolerance_mm) / wide_sigma, np.nan)
    # the honest measures (the full vector, the component across an edge, a window's slide)
    # significantly beyond the tolerance: a region without any is the flow's guess, not a defect
    z_shift = (local_mm - tolerance_mm) / sigma_mm
    # (a window's slide spreads past a slid region's rim by about its own radius: eroded by
    # half the window's width, the window's evidence stays inside the region it measured)
    e = max(1, int(round(2 * win)))
    wide_evidence = cv2.erode(
        (wide_ok & (z_wide > SIGNIFICANCE_Z)).astype(np.uint8),
        cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * e + 1, 2 * e + 1)),
    ).astype(bool)
    own_evidence = (full | normal) & ~lit & (z_shift > SIGNIFICANCE_Z)
    evidence = own_evidence | wide_evidence
    shift_bad = evidence
    z_region = np.fmax(z_shift, z_wide)
    # (sized by the flow's own vector, whose edges are sharp: the window's blurs a bubble's rim)
    m_mm = np.hypot(m[..., 0], m[..., 1]) * mm_per_px
    # (a line is thin on the part only where the film is not spread out: the thin test works on
    # the print, and where the film stretches 6 to 11-fold over the face mask's nose 0.75 mm of
    # print is 4 to 8 mm of surface, which shading crosses: a perfect photo's lines there came
    # out at z 8.8 to 9.8 without the broad allowance, 2.0 to 2.5 with it; the scratch that
    # needed it lies where the film is 0.76 of the print)
    line = thin & missing & (grid.surface_per_print <= THIN_MAX_STRETCH)
    z_colour = colour_z(res, res_raw, missing, line, colour_limit, colour_noise)
    labels, defects = find_defects(
        shift_bad,
        colour_bad,
        missing,
        local_mm,
        res,
        grid,
        alpha,
        evidence,
        z_region,
        z_colour,
        win,
        m_mm,
        scored,
        own_evidence,
    )
    # a moved film explains the photo: the print moved by the region's flow must take most of
    # the residual away; a flow that explains little follows shading, gloss or the photo's
    # blur over faint texture, not the film
    keep = []
    ink_left = np.zeros_like(missing)
    for i, d in enumerate(defects):
        if d["kind"] == "shift":
            d["explained_share"] = shift_explained(
                ref_n, pho_n, m, (labels == i + 1) & (full | normal | wide_ok), flow_k
            )
            if d["explained_share"] is not None and d["explained_share"] < SHIFT_EXPLAINS:
                # (its ink that is gone is still gone: a scratch drags the flow around it over
                # five times its own area, and the region took the flow's kind; 12.6 mm² of a
                # 20 mm scratch went with a 72 mm² region its flow did not explain)
                ink_left |= (labels == i + 1) & colour_bad & missing
                continue
        keep.append(i)
    if len(keep) < len(defects):
        relabel = np.zeros(len(defects) + 1, np.int32)
        relabel[np.asarray(keep, np.int64) + 1] = np.arange(1, len(keep) + 1)
        labels = relabel[labels]
        defects = [defects[i] for i in keep]
    if ink_left.any():
        # the ink that is gone under shift regions set aside, as regions of its own
        lab_ink, more = find_defects(
            np.zeros_like(ink_left), ink_left, ink_left, shift_mm, res, grid, alpha, None, None, z_colour, win
        )
        more = [d for d in more if d["kind"] == "missing"]
        if more:
            labels = np.where((labels == 0) & (lab_ink > 0) & (lab_ink <= len(more)), lab_ink + len(defects), labels)
            defects = defects + more
    for i, d in enumerate(defects):
        # what the photometric model said of a region of ink gone
        if d["kind"] == "missing" and (j := photometric.judgement_at(labels == i + 1, verdicts)) is not None:
            d["photometric"] = j
    # (only where the photo was scored: a filled hole may hold a highlight, which stays masked)
    state[(labels > 0) & np.isin(state, (COLOUR_ONLY, UNRESOLVED, NORMAL, FULL))] = DEFECT
    # how finely the photo samples the print, and what it cannot resolve
    photo_px_per_mm = np.where(scored, fp / mm_per_px, np.nan)
    median_res = float(np.nanmedian(photo_px_per_mm)) if scored.any() else None
    needed, factor = None, None
    if unresolved.any():
        # the photo's blur scales with its pixel: to bring it from ``blur`` down to what the
        # detail needs, the photo needs blur / needed_blur times as many pixels per mm
        k = local_blur[unresolved] / needed_blur[unresolved]
        factor = float(np.percentile(k, 90))
        needed = median_res * factor if median_res else None
    n_scored = max(int(scored.sum()), 1)
    resolution = {
        "photo_px_per_mm": median_res,
        "unresolved_share": float(unresolved.sum() / n_scored),
        "needed_resolution_factor": factor,
        "needed_photo_px_per_mm": needed,
        "note": (
            "detail of the print finer than about two photo pixels (strokes of small text) is "
            "'unresolved': its misregistration is not measured; a photo needed_resolution_factor times as "
            "fine (needed_photo_px_per_mm on the median) would resolve 90 % of it"
        ),
    }
    med_sigma = float(np.nanmedian(sigma_mm)) if np.isfinite(sigma_mm).any() else None
    # a defect must cover MIN_DEFECT_MM2 and span a few photo pixels each way (the opening
    # and closing in find_defects work on 3 x 3 grid pixels) to be found
    px_mm = (1.0 / median_res) if median_res else None
    limit_mm = shift_limit.result()
    limit_mm[lit] = np.nan  # (the flow near light is not the print's: see lit above)
    if camera_center is not None:
        in_cone, flat_in_cone = cone.result()
        dropout_found &= ~in_cone
        thin_found &= ~flat_in_cone
    dropout_found &= ~fold
    thin_found &= ~fold
    ink_step = float(np.median(colour_limit[stated])) if stated.any() else COLOUR_TOL
    limit = {
        "min_area_mm2": max(MIN_DEFECT_MM2, (3.0 * px_mm) ** 2 if px_mm else 0.0, (3.0 / grid.px_per_mm) ** 2),
        "min_shift_mm": (tolerance_mm + SIGNIFICANCE_Z * med_sigma) if med_sigma is not None else None,
        "significance_z": SIGNIFICANCE_Z,
        **detection.summary(
            limit_mm, dropout_found & stated, stated, inked & stated, max(2 * COLOUR_TOL, ink_step), thin_found & stated
        ),
        "note": (
            "stated for a sound part from the design, the photo's noise, blur and sampling: a slide of the film is "
            "found where the print has texture the photo resolves (min_shift_mm_*: over the pixels that find one), "
            "ink that is gone where its step to the bare film exceeds min_ink_step_grey_levels, a scratch (a line of "
            "ink gone, thinner than about 0.7 mm) wherever the ink differs from the film by twice the noise and "
            "placement (but over uniform ink within the lamp's reflection, where a glint looks the same); the maps "
            "are in detection.npz"
        ),
    }
    return DenseResult(
        warped,
        state,
        shift,
        shift_mm.astype(np.float32),
        colour,
        missing,
        labels,
        defects,
        blur,
        m_total,
        texture,
        sigma_mm,
        noise,
        resolution,
        limit,
        limit_mm,
        dropout_found & stated,
        win,
        np.where(normal[..., None], e1, np.float32(0.0)).astype(np.float32),
        thin_found & stated,
        not_counted,
    )


# each test that takes a region for light, in the words validation.json gives it
LIGHT_RULES = {
    "beyond_film": "brighter than the bare film could be there (as the ink around shows the film): light added",
    "photometric": "light added over the ink explains the region significantly better than ink gone (the "
    "photometric model's likelihood ratio: the photo keeps the ink's texture, or goes beyond the film)",
    "beyond_film_line": "a thin line brighter than the bare film could be: light, not a scratch",
    "thin_told": "a thin line that keeps the ink's variation along it: a glint, not a scratch",
    "mirrors_highlights": "ink gone and light look alike here (the photometric model tells neither) and the surface "
    "mirrors the photo's lamp there as at its sure light: not counted, and not measured",
    "along_fold": "light along a fold of the surface (its two sides face the lamp differently)",
}
MAX_NOT_COUNTED = 50  # regions listed at most (the largest); all of them are in the coverage map as highlight


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


def stated_shift_limit(
    tolerance_mm, noise, l1, l2, n_eff, floor, mm_per_px, wide_sigma, two_way, measurable, usable, l1_wide, l2_wide
) -> np.ndarray:
    """The detection limit's smallest slide found at each pixel, stated for a sound part (:func:`analyse`).

    The photo's noise through the texture it resolves (the mismatch and the flow back, which a
    defect itself raises, left out: :func:`workbench.validate.detection.expected_flow_sigma`),
    and the window's slide's uncertainty ``wide_sigma``, of which the window answers
    :func:`window_gain` of its eigenvalues ``l1_wide``, ``l2_wide``;
    :func:`workbench.validate.detection.shift_limit` at SIGNIFICANCE_Z + DETECT_Z.

    Returns
    -------
    (H, W) float32
        mm on the surface; NaN where no slide is found.
    """
    weak_e, _ = detection.expected_flow_sigma(noise, l1, l2, n_eff, floor)
    return detection.shift_limit(
        tolerance_mm, SIGNIFICANCE_Z + DETECT_Z, weak_e * mm_per_px, wide_sigma, two_way, measurable, usable,
        window_gain(l1_wide, l2_wide),
    )  # fmt: skip


def colour_residuals(pho, pred, gain, offset, res, weight, scored, fp, px_per_mm):
    """The colour test of :func:`analyse` before highlights are told from ink: residuals, limits, ink gone.

    Apart so that it can run beside the flow's uncertainty (it needs none of it).

    Parameters
    ----------
    pho, pred : (H, W, 3) float32
        The photo on the print and the model (the print moved, blurred like the photo, in its exposure).
    gain, offset : (H, W, 3) float32
        The exposure fit.
    res : (H, W) float32
        The model's largest channel residual.
    weight : (H, W) float32
        The exposure fit's weights (its inliers).
    scored : (H, W) bool
        Where colour is judged.
    fp : (H, W) float32
        Photo pixels per grid pixel.
    px_per_mm : float
        The grid's resolution (the scratch test's width).

    Returns
    -------
    alpha : (H, W) float32
        Share of the ink gone per pixel (a scratch's against its surroundings where larger).
    colour_limit : (H, W) float32
        The colour test's limit per pixel, grey levels.
    colour_noise : float
        The residual's noise, grey levels.
    res_raw, res : (H, W) float32
        The residual without and with each pixel's own gain (within SHADING).
    gone, colour_bad : (H, W) bool
        Pixels stepped towards the bare film beyond the limit (a scratch's too), and pixels
        beyond it.
    inked : (H, W) bool
        Scored pixels whose ink differs from the bare film.
    dropout_found : (H, W) bool
        Where ink that is gone would be found (the detection limit's map).
    thin, thin_found : (H, W) bool
        A scratch's ink gone, and where a scratch would be found (:func:`thin_ink_loss`).
    """
    colour_scored = scored
    # ink missing: the photo matches the bare film's colour, the design does not
    film = np.asarray(FILM_RGB, np.float32)
    film_pred = gain * film + offset
    # how much of the ink is gone, per pixel: the photo's step from the design's colour towards
    # the bare film's, as a share of the whole step (0 to 1; blur spreads it, its sum keeps the area)
    step = film_pred - pred
    step2 = _csum(step * step)
    inked = colour_scored & (_cmax(np.abs(step)) > 2 * COLOUR_TOL)
    with np.errstate(invalid="ignore", divide="ignore"):
        alpha = np.where(inked, _csum((pho - pred) * step) / step2, 0.0)
    alpha = np.clip(np.nan_to_num(alpha), 0.0, 1.0).astype(np.float32)
    # beyond what blur and the flow's residual error explain: at an edge a fraction of a pixel
    # of either changes the colour by a share of the edge's contrast, so the tolerance grows
    # with the model's gradient (half a pixel's worth of it); and beyond the photo's noise at
    # SIGNIFICANCE_Z (the largest of three channels' noise is about 1.5 σ)
    gx = _cmax(np.abs(cv2.Sobel(pred, cv2.CV_32F, 1, 0, ksize=3) / 8))
    gy = _cmax(np.abs(cv2.Sobel(pred, cv2.CV_32F, 0, 1, ksize=3) / 8))
    colour_noise = float(1.4826 * np.median(res[weight > 0])) if (weight > 0).any() else NOISE_FLOOR
    # (half a pixel: of the grid, or of the photo where it samples the print coarser, as
    # where it sees the surface at a slant: it places the print no better than that)
    with np.errstate(divide="ignore"):
        position = np.maximum(0.5, np.where(fp > 0, 0.5 / fp, 0.5)).astype(np.float32)
    colour_limit = COLOUR_TOL + position * np.hypot(gx, gy) + SIGNIFICANCE_Z * colour_noise
    # ink that is gone is found where the step from the ink to the bare film is beyond the limit
    dropout_found = inked & (_residual(film_pred, pred) > colour_limit + DETECT_Z * colour_noise)
    # light, not ink: a crease's own shading changes faster than the exposure fit's window
    # follows, and scales every channel alike; so the colour test allows each pixel a gain of
    # its own within SHADING (ink that is gone, or another ink, is not a gain: film white
    # over a grey ink is twice its brightness, over a colour another hue)
    with np.errstate(invalid="ignore", divide="ignore"):
        k_px = _csum(pho * pred) / np.maximum(_csum(pred * pred), 1.0)
    k_px = np.clip(np.nan_to_num(k_px, nan=1.0), 1.0 / SHADING, SHADING)[..., None]
    res_raw = res
    res = _residual(pho, k_px * pred)
    # (a step towards the bare film's colour is ink gone whatever gain might mimic it: film
    # white over a light ink is a gain of 1.2)
    gone = colour_scored & (res_raw > colour_limit) & (alpha > 0.5)
    # a scratch: ink gone along a line thinner than any shading, highlight or exposure error,
    # judged against its own surroundings, with no tolerance for what is broad
    thin_limit = position * np.hypot(gx, gy) + SIGNIFICANCE_Z * colour_noise
    thin, thin_found, thin_alpha = thin_ink_loss(pho, pred, film_pred, colour_scored, px_per_mm, thin_limit)
    gone |= thin
    # (its share of the ink gone, against its surroundings: over pale ink the plain share is not taken)
    alpha = np.maximum(alpha, thin_alpha)
    colour_bad = (colour_scored & (res > colour_limit)) | gone
    return (
        alpha, colour_limit, colour_noise, res_raw, res, gone, colour_bad, inked, dropout_found, thin, thin_found,
    )  # fmt: skip


def colour_z(
    res: np.ndarray,
    res_raw: np.ndarray,
    missing: np.ndarray,
    thin: np.ndarray,
    colour_limit: np.ndarray,
    noise: float,
) -> np.ndarray:
    """Per pixel, by how many standard uncertainties the colour residual exceeds its tolerance.

    z = (r - t) / σ, with t the tolerance (the colour limit less its SIGNIFICANCE_Z · σ, so
    a pixel at the limit has z = SIGNIFICANCE_Z). Ink that is gone is judged by the raw
    residual (the colour test's shading allowance would explain most of it away); a
    scratch's line against the thin test's own tolerance, which holds no COLOUR_TOL: a line
    thinner than any shading or exposure error needs no allowance for them (with it, a
    0.5 mm scratch found exactly at 4000 x 3000, whose blurred core steps 60 % of the way to
    the film, came out at z 2.76 and passed).

    Parameters
    ----------
    res, res_raw : (H, W) float32
        The colour residual with the shading allowance, and without (grey levels).
    missing, thin : (H, W) bool
        Ink that is gone, and the part of it on a scratch's thin line (thin on the part too:
        where the film is stretched less than THIN_MAX_STRETCH).
    colour_limit : (H, W) float32
        The colour test's limit (grey levels).
    noise : float
        The colour residual's noise σ (grey levels).

    Returns
    -------
    (H, W) float32
    """
    r = np.where(missing, res_raw, res)
    limit = colour_limit - np.where(thin, np.float32(COLOUR_TOL), np.float32(0))
    return ((r - limit) / max(noise, NOISE_FLOOR) + SIGNIFICANCE_Z).astype(np.float32)


def photo_gain(gain: np.ndarray, determined: np.ndarray, fitted: np.ndarray) -> np.ndarray | None:
    """The photo's own gain per channel: the 75th percentile of the local gain where the data determine it.

    (A percentile above the median: shading only lowers the gain of a lit film, and a
    decoration painted over on most of the photo must not set it.)

    Parameters
    ----------
    gain : (H, W, 3) float32
    determined : (H, W, 3) bool
        Where each channel's window has the contrast to determine its gain.
    fitted : (H, W) bool

    Returns
    -------
    (3,) float or None
        None when no pixel determines any channel.
    """
    out = np.ones(3)
    for c in range(3):
        m = fitted & determined[..., c]
        if not m.any():
            return None
        out[c] = max(float(np.percentile(gain[..., c][m], 75)), 1e-3)
    return out


def film_colour(white: np.ndarray, design: np.ndarray, fitted: np.ndarray, at: np.ndarray | None = None) -> np.ndarray:
    """The bare film's colour as the photo shows it: one colour of light, at each pixel's brightness.

    The exposure fit's white (``gain · 255 + offset``) extrapolates each channel from the
    ink's level to the film's: over dark ink that multiplies the gain's error several times,
    a different error per channel (over the cow's dark green ink the film came out yellow,
    188, 174, 137, where the photo of ink gone showed it grey, 166, 167, 165). One lamp
    lights the whole film, so its colour (the film's chromaticity, the camera's white
    balance included) is one: the median of the fitted white's chromaticity where the
    design is near the film's own colour (every channel at least FILM_NEAR of full scale:
    a short extrapolation; up to 4 MAX_FILM_SAMPLES pixels, evenly spread, are looked at). The
    brightness stays local (shading, vignetting): the scalar b of ``white ≈ b · colour`` by
    least squares, each channel weighted by the square of the design's level there (a
    channel's gain is determined in proportion to its signal).

    Parameters
    ----------
    white : (H, W, 3) float32
        The exposure fit's film white, grey levels.
    design : (H, W, 3) float32
        The design as the fit saw it (moved and blurred like the photo), grey levels.
    fitted : (H, W) bool
        Pixels the exposure fit used.
    at : (H, W) bool, optional
        The pixels whose film colour is asked (default all); ``white`` is kept elsewhere.

    Returns
    -------
    (H, W, 3) float32
        The film's colour, grey levels; ``white`` itself where fewer than MIN_FILM_PX pixels
        show the design near the film's colour (the light's colour is then not known better).
    """
    # (every k-th pixel, for at most 4 MAX_FILM_SAMPLES looked at: the film's colour is one number)
    k = max(1, fitted.size // (4 * MAX_FILM_SAMPLES))
    d = design.reshape(-1, 3)[::k]
    near = np.flatnonzero(fitted.reshape(-1)[::k] & (_cmin(d) >= FILM_NEAR * 255.0))
    if len(near) < MIN_FILM_PX:
        return white
    w_near = white.reshape(-1, 3)[::k][near]
    colour = np.median(w_near / np.maximum(_cmax(w_near), 1e-3)[:, None], axis=0).astype(np.float32)
    colour /= max(float(colour.max()), 1e-3)
    sel = np.ones(white.shape[:2], bool) if at is None else at
    w = design[sel] ** 2
    b = _csum(w * white[sel] * colour) / np.maximum(_csum(w * colour * colour), 1e-6)
    out = white.copy()
    out[sel] = b[:, None] * colour
    return out


def texture_lost(
    gain: np.ndarray,
    determined: np.ndarray,
    fitted: np.ndarray,
    g0: np.ndarray | None,
    brightness: np.ndarray | None = None,
) -> np.ndarray:
    """Where the photo has lost the design's texture: the local gain collapsed where it is determined.

    Parameters
    ----------
    gain : (H, W, 3) float32
        The exposure fit's local gain (:func:`exposure_fit`).
    determined : (H, W, 3) bool
        Where each channel's window holds at least LOST_MIN_CONTRAST of the design's contrast.
    fitted : (H, W) bool
        The pixels the photo shows and the fit may use.
    g0 : (3,) float or None
        The photo's own gain (:func:`photo_gain`); None: nothing determines it.
    brightness : (H, W, 3) float32, optional
        The light that is there: the photo's local mean over the design's, per channel, in the
        exposure fit's window.

    Returns
    -------
    (H, W) bool
        Pixels where every determined channel has a gain below LOST_GAIN of ``g0`` (and of
        ``brightness``: not a shadow).
    """
    if g0 is None:
        return np.zeros(fitted.shape, bool)
    # (channel by channel: numpy's all() and any() along a short last axis are slow, and the
    # whole image's ratio in float64 was a third of a gigabyte of traffic)
    low = fitted.copy()
    for c in range(3):
        collapsed = gain[..., c] / g0[c] < LOST_GAIN
        if brightness is not None:
            collapsed &= gain[..., c] < LOST_GAIN * brightness[..., c]
        low &= ~determined[..., c] | collapsed
    return low & (determined[..., 0] | determined[..., 1] | determined[..., 2])


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


def shift_explained(
    ref_n: np.ndarray, pho_n: np.ndarray, flow: np.ndarray, region: np.ndarray, factor: int = 1
) -> float | None:
    """Share of the residual over a region that moving the print by the flow takes away.

    Judged at the flow's own resolution: where the photo is coarser than the grid, the
    print's detail finer than the photo's pixel is a residual no shift explains (a 12 mm
    bubble's flow explained 0.37 of the full grid's residual and 0.96 of the flow grid's).

    Parameters
    ----------
    ref_n, pho_n : (h, w) float32
        The print and the photo on it, locally normalised, as the flow compared them
        (:func:`dense_flow`: on the grid reduced by ``factor``).
    flow : (H, W, 2) float32
        The dense flow, grid px.
    region : (H, W) bool
        The pixels of the region.
    factor : int
        The flow's reduction of the grid (:func:`flow_factor`).

    Returns
    -------
    float or None
        1 - |r1|² / |r0|², with r0 the residual of the print where it is and r1 that of the
        print moved by the flow; None for an empty region.
    """
    if factor > 1:
        h, w = ref_n.shape
        flow = cv2.resize(flow, (w, h), interpolation=cv2.INTER_AREA)
        flow[..., 0] *= w / region.shape[1]
        flow[..., 1] *= h / region.shape[0]
        region = cv2.resize(region.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) > 0.5
    ii, jj = np.nonzero(region)
    if len(ii) == 0:
        return None
    # (in floats: the normalised images are uint8, whose differences and squares wrap)
    ref_n, pho_n = ref_n.astype(np.float32), pho_n.astype(np.float32)
    y0, y1, x0, x1 = ii.min(), ii.max() + 1, jj.min(), jj.max() + 1
    box = (slice(y0, y1), slice(x0, x1))
    gx, gy = np.meshgrid(np.arange(x0, x1, dtype=np.float32), np.arange(y0, y1, dtype=np.float32))
    moved = cv2.remap(
        ref_n, gx - flow[box][..., 0], gy - flow[box][..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    inside = region[box]
    r0 = (pho_n[box] - ref_n[box])[inside]
    r1 = (pho_n[box] - moved)[inside]
    e0 = float((r0 * r0).sum())
    return 1.0 - float((r1 * r1).sum()) / e0 if e0 > 0 else 0.0


def _cmax(a: np.ndarray) -> np.ndarray:
    """Largest of the three channels (numpy's reduction along a short last axis is several times slower)."""
    return np.maximum(np.maximum(a[..., 0], a[..., 1]), a[..., 2])


def _cmin(a: np.ndarray) -> np.ndarray:
    """Smallest of the three channels."""
    return np.minimum(np.minimum(a[..., 0], a[..., 1]), a[..., 2])


SCRATCH_MM = 1.5  # ink gone along a line narrower than about half this is a scratch (thin_ink_loss)
# a scratch's line is judged without the broad colour tolerance only where the film is stretched
# less than this (surface mm per print mm): beyond, a thin line of print is broad on the part
THIN_MAX_STRETCH = 2.0


def thin_ink_loss(
    photo: np.ndarray, pred: np.ndarray, film: np.ndarray, scored: np.ndarray, px_per_mm: float, limit: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a line thinner than a scratch's width steps the photo towards the bare film, over any ink.

    t = (photo - pred) · u, u the unit step from the design's colour to the film's: how far
    the photo moved towards the film, grey levels. Shading, a highlight or an exposure error
    change t over areas much broader than a scratch; a white top-hat of t (t less its
    opening by a disc of SCRATCH_MM) keeps what is thinner than about half the disc. A pixel
    has lost its ink where that reaches half the step to the film and exceeds ``limit`` (the
    noise, and half a pixel's placement at the design's edges) and t itself exceeds
    ``limit`` (beside ink the photo shows darker than the model, the opening sinks): over
    pale ink too, where a broad step of that size is shading or light. (The colour test's fixed tolerance is for
    what is broad; a thin line of film over a light grey square is what a scratch across a
    checker shows.)

    Parameters
    ----------
    photo, pred, film : (H, W, 3) float32
        The photo on the print, the model, and the bare film's colour as the photo would show it.
    scored : (H, W) bool
    px_per_mm : float
    limit : (H, W) float32
        Grey levels.

    Returns
    -------
    found : (H, W) bool
        Ink gone along a thin line.
    findable : (H, W) bool
        Where a scratch is found (the step to the film at least twice ``limit`` and twice
        LOST_MIN_CONTRAST): the detection limit's scratch map.
    alpha : (H, W) float32
        Where findable, the share of the step to the film the line takes against its
        surroundings (0 to 1); 0 elsewhere.
    """
    step = film - pred
    size = _length(step)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = _csum((photo - pred) * step) / np.maximum(size, 1e-3)
    t = np.where(scored, t, 0.0).astype(np.float32)
    r = max(1, int(round(0.5 * SCRATCH_MM * px_per_mm)))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    hat = cv2.morphologyEx(t, cv2.MORPH_TOPHAT, disc)
    # (a step to the film under LOST_MIN_CONTRAST twice over is pale ink a line of film barely
    # changes: a perfect render's antialiased edges reach half of it, measured 6 grey levels)
    findable = scored & (size >= 2.0 * np.maximum(limit, LOST_MIN_CONTRAST))
    with np.errstate(invalid="ignore", divide="ignore"):
        alpha = np.where(findable, np.clip(hat / np.maximum(size, 1e-3), 0.0, 1.0), 0.0).astype(np.float32)
    # (and the line itself beyond the limit: beside ink the photo shows darker than the model,
    # the opening sinks and a pale gap that matches the model stands 20 grey levels above it)
    # (and beyond what the top-hat makes of the photo's own noise: the opening follows the noise's
    # troughs, so the hat of a sound photo sits a few noise levels up, and a path tracer's
    # correlated noise over pale ink passed the pixel's limit in 55 places of one perfect part;
    # the hat's median and spread over the scored print, where lines are a minute share, are
    # that noise's own)
    ref = hat[scored]
    med, spread = 0.0, 1.0
    if ref.size:
        med = float(np.median(ref))
        spread = max(1.4826 * float(np.median(np.abs(ref - med))), NOISE_FLOOR)
    floor = med + SIGNIFICANCE_Z * spread
    excess = np.where(
        findable, np.minimum(np.minimum(hat - np.maximum(0.5 * size, limit), t - limit), hat - floor), np.nan
    )
    excess = excess.astype(np.float32)
    # a line, not speckles: a component at least SCRATCH_MM long (a path tracer's noise in a
    # glossy highlight sparkles in single pixels, which the bridging of ink gone would join)
    found = findable & (excess > 0)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(found.astype(np.uint8), connectivity=8)
    span = np.hypot(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    keep = span >= SCRATCH_MM * px_per_mm
    keep[0] = False
    return keep[lab], findable, alpha


def thin_told(
    thin: np.ndarray, photo: np.ndarray, pred: np.ndarray, core: np.ndarray | None = None, gap_px: int = 0
) -> np.ndarray:
    """Each thin line of film-ward step told as light or as ink gone, where the ink under it varies.

    Light added to the ink (a glint along a ridge) keeps the ink's variation along the line:
    the photo follows the design there (correlation KEPT_TEXTURE at least, at a gain of
    KEPT_CONTRAST at least), as a highlight over a checker does. Ink that is gone shows the
    film all along it, whatever ink it crosses. Where the ink under the line is uniform (its
    grey levels' spread below LOST_MIN_CONTRAST) nothing tells them apart in one photo.
    Judged on the line's ``core`` where it holds MIN_CORE_PX: a scratch two photo pixels wide
    is blurred into its flanks, where the photo keeps most of the ink's variation (a gain of
    0.4 to 0.6 over a line whose core keeps a quarter), while added light keeps it in its core
    too.

    Parameters
    ----------
    thin : (H, W) bool
        :func:`thin_ink_loss`'s lines.
    photo, pred : (H, W, 3) float32
    core : (H, W) bool, optional
        The lines' pixels that take at least half the step to the film.
    gap_px : int
        Pieces of line this close are one line (a scratch across a checker is found in pieces,
        over the dark squares, each over uniform ink; as one it crosses the checker).

    Returns
    -------
    (H, W) uint8
        Per pixel of a line: 1 light, 2 ink gone, 3 not told (uniform ink); 0 off the lines.
    """
    out = np.zeros(thin.shape, np.uint8)
    joined = thin.astype(np.uint8)
    if gap_px > 0:
        joined = cv2.dilate(joined, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * gap_px + 1,) * 2))
    n, lab = cv2.connectedComponents(joined, connectivity=8)
    if n <= 1:
        return out
    use = thin
    if core is not None:
        # (a line's core where it has one: MIN_CORE_PX of its pixels; its whole elsewhere)
        n_core = np.bincount(lab[thin & core], minlength=n)
        use = thin & (core | (n_core[lab] < MIN_CORE_PX))
    g_ph = cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY)[use].astype(np.float64)
    g_pr = cv2.cvtColor(pred, cv2.COLOR_RGB2GRAY)[use].astype(np.float64)
    k = lab[use]

    def per(v):
        return np.bincount(k, v, n)

    cnt = np.maximum(per(np.ones_like(g_ph)), 1.0)
    mx, my = per(g_pr) / cnt, per(g_ph) / cnt
    vx = per(g_pr * g_pr) / cnt - mx * mx
    vy = per(g_ph * g_ph) / cnt - my * my
    cxy = per(g_pr * g_ph) / cnt - mx * my
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cxy / np.sqrt(vx * vy)
        gain = cxy / vx
    varied = np.sqrt(np.maximum(vx, 0.0)) >= LOST_MIN_CONTRAST
    light = varied & (corr >= KEPT_TEXTURE) & (gain >= KEPT_CONTRAST)
    verdict = np.where(varied, np.where(light, 1, 2), 3).astype(np.uint8)
    verdict[0] = 0
    out[thin] = verdict[lab[thin]]
    return out


def _residual(photo: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Largest channel residual, grey levels; a channel clipped in the photo where the model is bright too
    says nothing (yellow ink's red channel reaches 255 on a well exposed photo)."""
    r = photo - pred
    np.abs(r, out=r)
    np.copyto(r, 0.0, where=(photo >= SATURATED) & (pred >= SATURATED - 15))
    return _cmax(r)


def _hull_box(ii: np.ndarray, jj: np.ndarray, reach_px: int, shape) -> tuple[tuple[slice, slice], np.ndarray]:
    """The convex hull of pixels (rows ``ii``, columns ``jj``), grown by ``reach_px``, in its box.

    Returns
    -------
    box : (slice, slice)
        The hull's box plus the reach, within ``shape`` (the dilation need not sweep the whole grid).
    hull : bool array of the box's shape
    """
    pts = np.stack([jj, ii], axis=1).astype(np.int32)
    hull = cv2.convexHull(pts)
    x0, y0 = max(int(jj.min()) - reach_px, 0), max(int(ii.min()) - reach_px, 0)
    x1, y1 = min(int(jj.max()) + reach_px + 1, shape[1]), min(int(ii.max()) + reach_px + 1, shape[0])
    sub = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillConvexPoly(sub, hull - np.array([x0, y0], np.int32), 1)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach_px + 1, 2 * reach_px + 1))
    return (slice(y0, y1), slice(x0, x1)), cv2.dilate(sub, disc).astype(bool)


def _full(shape, mask) -> np.ndarray:
    """A mask as a whole image: ``mask`` itself, or a ``(box, pixels)`` pair made whole (a new array)."""
    if isinstance(mask, np.ndarray):
        return mask
    box, pixels = mask
    out = np.zeros(shape, bool)
    out[box] = pixels
    return out


def _count(mask) -> int:
    """Pixels of a mask, whole or ``(box, pixels)``."""
    return np.count_nonzero(mask if isinstance(mask, np.ndarray) else mask[1])


def _filled(region: np.ndarray) -> np.ndarray:
    """The region with its holes filled (a bubble's plain squares are inside it, not around it)."""
    cs, _ = cv2.findContours(region.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = np.zeros(region.shape, np.uint8)
    cv2.drawContours(out, cs, -1, 1, thickness=cv2.FILLED)
    return out.astype(bool) | region


def find_defects(
    shift_bad,
    colour_bad,
    missing,
    shift_mm,
    colour_res,
    grid: PrintGrid,
    alpha=None,
    evidence=None,
    z_shift=None,
    z_colour=None,
    window_px: float = TENSOR_SIGMA_PX,
    extent=None,
    measured=None,
    core=None,
):
    """Connected regions of excess misregistration or colour residual, sized on the print.

    Parameters
    ----------
    shift_bad, colour_bad, missing : (H, W) bool
        Pixels beyond the misregistration tolerance, beyond the colour tolerance, and
        showing bare film.
    shift_mm, colour_res : (H, W) float
        Misregistration (mm on the surface) and colour residual (grey levels).
    grid : PrintGrid
    alpha : (H, W) float, optional
        Share of the ink gone per pixel (0 to 1). A region of missing ink is sized by its
        sum (sub-pixel, and independent of the blur, which only spreads it) and located at
        its weighted centre; a threshold would size a thin scratch by the blur's width.
    evidence : (H, W) bool, optional
        Where the misregistration actually measured (full vector, or the component across
        an edge) exceeds the tolerance; a shift region needs a quarter of its pixels there.
    z_shift, z_colour : (H, W) float, optional
        Per pixel, by how many standard uncertainties the misregistration and the colour
        residual exceed their tolerances.
    window_px : float
        The flow's window (Gaussian sigma, grid px): pixels closer than about its size share
        their evidence, so a region of n pixels holds n / (4π window²) independent ones.
    extent, measured : (H, W) float and bool, optional
        The misregistration that sizes a shift region (mm; the flow's own vector, which DIS
        spreads evenly over plain patches and across the region's edge) and where the photo
        is scored: a region extends over the scored pixels around it where ``extent`` is at
        least half its upper quartile.
    core : (H, W) bool, optional
        The part of ``evidence`` that pixels measure on their own (not a window of about a
        millimetre around them, which reaches past a slid region's rim): where it holds two
        windows of a region, it alone places and sizes the region.

    Returns
    -------
    labels : (H, W) int32
        Defect number + 1 per pixel, 0 elsewhere.
    defects : list of dict
        In decreasing order of area.
    """
    k3 = np.ones((3, 3), np.uint8)
    # an opening drops isolated pixels (noise, JPEG), a closing joins a region's parts
    sb = cv2.morphologyEx(shift_bad.astype(np.uint8), cv2.MORPH_OPEN, k3)
    # (not ink that is gone: a scratch on a coarse grid is two pixels wide, and the opening would
    # take it; its specks are what MIN_DEFECT_MM2 drops)
    cb = cv2.morphologyEx(colour_bad.astype(np.uint8), cv2.MORPH_OPEN, k3) | (colour_bad & missing).astype(np.uint8)
    both = cv2.morphologyEx(sb | cb, cv2.MORPH_CLOSE, k3)
    # ink gone in pieces a short gap apart is one defect: a scratch across a checker loses its
    # ink on the dark squares, and over the light ones the step to the film is too small to see
    # (the gap's pixels join the region's connection, not its area; and a scratch's thin
    # stretches, which the opening drops, connect its pieces too)
    r = max(1, int(round(0.5 * MISSING_GAP_MM * grid.px_per_mm)))
    gone = colour_bad & missing
    bridge = cv2.dilate(gone.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    # (each region's bounding box with it: the bridge's pixels only widen a box, which holds all of
    # the region's pixels still)
    n, lab, boxes, _ = cv2.connectedComponentsWithStats(both | bridge, connectivity=8)
    lab[both == 0] = 0
    px_mm2 = 1.0 / grid.px_per_mm**2
    two_windows = MIN_SHIFT_WINDOWS * 4 * np.pi * window_px**2
    reach = int(math.ceil(3 * window_px))
    if extent is not None:
        # where a shift region may grow: the measured pixels' extent (-inf elsewhere), once (the
        # same pixels as extent >= level where measured: a level is half a length, never -inf)
        grow = np.where(measured, extent, -np.inf).astype(extent.dtype, copy=False)

    # each region's kind and pixels; a shift region grown to where the flow reaches half its
    # shift, and shift regions that grow into one another merged (one bubble, one defect)
    def one(k: int):
        # the region's own pixels from its bounding box (a photo with the film off has some 60
        # regions: full-size comparisons for each took a second); its masks stay in boxes until
        # merged (full-size masks of every region took a quarter gigabyte)
        x0, y0, w, h = boxes[k, :4]
        box = (slice(y0, y0 + h), slice(x0, x0 + w))
        in_box = lab[box] == k
        s_in, c_in = in_box & (sb[box] > 0), in_box & (cb[box] > 0)
        if evidence is not None and (s_in & evidence[box]).sum() < 0.25 * s_in.sum():
            s_in &= evidence[box]  # the rest is the flow's guess along an edge
        ns, nc = int(s_in.sum()), int(c_in.sum())
        if (ns + nc) == 0:
            return None
        s_px = (box, s_in)
        # a bubble's flow edges leave a little colour residual (under 1 % of its area in
        # tests); ink that is gone leaves a lot, and drags the flow around it too
        if nc >= 0.2 * ns:
            kind = "missing" if (in_box & missing[box]).sum() > 0.5 * nc else "colour"
        else:
            kind = "shift"
            if extent is not None:
                # found by significance, sized at half its height: the flow ramps from the slid
                # region's shift to 0 over the flow's window, and crosses half of it at the
                # region's edge whatever the tolerance (the tolerance's threshold would size a
                # large slide too large and a slide just above the tolerance too small)
                # (from the pixels' own evidence where it holds two windows: a millimetre
                # window's reaches past the rim, where the flow is already down; and the upper
                # quartile's half, which that reach does not lower as it would a median's)
                seeds = s_in
                if core is not None and (s_in & core[box]).sum() >= two_windows:
                    seeds = s_in & core[box]
                level = 0.5 * float(np.percentile(extent[box][seeds], 75))
                n_h, lab_h = cv2.connectedComponents((grow >= level).view(np.uint8), connectivity=8)
                hit = np.unique(lab_h[box][seeds])
                # (within the hull of its evidence and the flow's reach around it: a slid
                # region's plain patches lie between its textured edges, and beyond them the
                # flow ramps down over its window; a weak region's half height is the flow's
                # noise, which would otherwise grow it over the print: 53,000 mm² on a face)
                ii, jj = np.nonzero(seeds)
                hull_box, hull = _hull_box(ii + y0, jj + x0, reach, lab.shape)
                taken = np.zeros(n_h, bool)
                taken[hit[hit > 0]] = True
                # (the grown region lies in the hull's box; the seeds in the region's: both boxes)
                (hy0, hx0), (hy1, hx1) = ((b.start for b in hull_box), (b.stop for b in hull_box))
                gy0, gx0, gy1, gx1 = min(hy0, y0), min(hx0, x0), max(hy1, y0 + h), max(hx1, x0 + w)
                grown = np.zeros((gy1 - gy0, gx1 - gx0), bool)
                grown[hy0 - gy0 : hy1 - gy0, hx0 - gx0 : hx1 - gx0] = taken[lab_h[hull_box]] & hull
                grown[y0 - gy0 : y0 - gy0 + h, x0 - gx0 : x0 - gx0 + w] |= seeds
                s_px = ((slice(gy0, gy1), slice(gx0, gx1)), grown)
        return [kind, (box, in_box), s_px, (box, c_in), ns, nc]

    if n > 8:
        # (the regions one by one on two threads: most of a region's time is its components,
        # which release the GIL)
        with ThreadPoolExecutor(max_workers=2) as pool:
            regions = [r for r in pool.map(one, range(1, n)) if r is not None]
    else:
        regions = [r for r in map(one, range(1, n)) if r is not None]
    merged: list = []
    for r in sorted(regions, key=lambda r: -_count(r[2])):
        if r[0] == "shift":
            into = next((m for m in merged if m[0] == "shift" and (m[2] & _full(lab.shape, r[2])).any()), None)
            if into is not None:
                into[1] |= _full(lab.shape, r[1])
                into[2] |= _full(lab.shape, r[2])
                into[4] += r[4]
                continue
        merged.append([r[0], _full(lab.shape, r[1]), _full(lab.shape, r[2]), _full(lab.shape, r[3]), r[4], r[5]])
    found = []
    for kind, region, s_px, c_px, ns, nc in merged:
        if kind != "shift":
            sized = c_px
        elif evidence is not None and (s_px & evidence).sum() < MIN_SHIFT_WINDOWS * 4 * np.pi * window_px**2:
            # evidence within a single flow window is one measurement: DIS's errors have tails
            # its uncertainty does not describe (it drifted 13 px over a photograph's soft
            # background, 12 pixels beyond 3 sigma), so a slid region needs two windows of it
            continue
        else:
            # a shift shows only where there is texture: the slid region's plain patches between
            # its edges belong to it too (a closing of SHIFT_CLOSE_MM: 1.5 mm made a 12 mm bubble
            # 10 % too large, none left a 6 mm one 15 % too small; 1 mm: -1 % and -12 %)
            r = max(1, int(round(SHIFT_CLOSE_MM * grid.px_per_mm / 2)))
            disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
            sized = cv2.morphologyEx(s_px.astype(np.uint8), cv2.MORPH_CLOSE, disc).astype(bool) | s_px
        ii, jj = np.nonzero(sized)
        wts = np.ones(len(ii))
        if kind == "missing" and alpha is not None:
            # the blur's tails reach a few pixels beyond the thresholded region
            grown = cv2.dilate(region.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
            ii, jj = np.nonzero(grown)
            wts = alpha[ii, jj].astype(np.float64)
        area = float(wts.sum()) * px_mm2
        if area < MIN_DEFECT_MM2:
            continue
        centre = [
            float(((jj + 0.5) * wts).sum() / wts.sum() / grid.px_per_mm),
            float(((ii + 0.5) * wts).sum() / wts.sum() / grid.px_per_mm),
        ]
        sm = shift_mm[region & np.isfinite(shift_mm)]
        # the region's significance: its mean excess in standard uncertainties, times the
        # square root of its independent measurements; the confidence is the one-sided
        # normal probability that the excess is not chance
        zmap = z_colour if kind != "shift" else z_shift
        zs = zmap[sized & np.isfinite(zmap)] if zmap is not None else np.zeros(0)
        n_ind = max(1.0, len(zs) / (4 * np.pi * window_px * window_px))
        z = float(np.clip(np.mean(zs), 0, None) * np.sqrt(n_ind)) if len(zs) else None
        found.append(
            {
                "kind": kind,
                "centre_mm": centre,
                "area_mm2": area,
                "area_surface_mm2": float((grid.surface_per_print[ii, jj] ** 2 * wts).sum() * px_mm2),
                "bbox_mm": [
                    float(jj.min() / grid.px_per_mm),
                    float(ii.min() / grid.px_per_mm),
                    float((jj.max() + 1) / grid.px_per_mm),
                    float((ii.max() + 1) / grid.px_per_mm),
                ],
                "peak_mm": float(sm.max()) if len(sm) else None,
                "mean_mm": float(sm.mean()) if len(sm) else None,
                "colour_peak": float(np.nanmax(colour_res[region])) if nc else 0.0,
                "significance_z": z,
                "confidence": (float(0.5 * math.erfc(-z / math.sqrt(2))) if z is not None else None),
                "shift_area_mm2": ns * px_mm2,
                "colour_area_mm2": nc * px_mm2,
                "_mask": _filled(region),
            }
        )
    found.sort(key=lambda d: (-d["area_mm2"], d["centre_mm"]))
    labels = np.zeros(lab.shape, np.int32)
    for i, d in enumerate(found):
        labels[d.pop("_mask")] = i + 1
    return labels, found


def coverage_by_view(state: np.ndarray, owner: np.ndarray, names: list[str]) -> dict:
    """Per view, the shares of its own region on the print: measured (colour, shift) and unmeasured by reason."""
    out = {}
    for vi, name in enumerate(names):
        own = state[owner == vi]
        n = max(len(own), 1)
        out[name] = {
            "measured": float(np.isin(own, MEASURED).sum() / n),
            "shift_measured": float(np.isin(own, (NORMAL, FULL, DEFECT)).sum() / n),
            "shift_full_vector": float(np.isin(own, (FULL, DEFECT)).sum() / n),
            "defective": float((own == DEFECT).sum() / n),
            "unmeasured": {
                STATE_NAMES[k]: float((own == k).sum() / n)
                for k in range(COLOUR_ONLY)
                if k != OFF_PART and (own == k).any()
            },
        }
    return out
