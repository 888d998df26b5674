"""The dense flow: the images it compares, the flow itself and the print's texture that gates it."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workbench.validate.dense._channels import _cmin
from workbench.validate.dense.options import (
    FLOW_RESOLUTION,
    MEDIAN_FLOW_MM,
    NORM_SIGMA_PX,
    REGISTRATION_BLUR_PX,
    SATURATED,
    TENSOR_SIGMA_PX,
    WINDOW_GAIN,
    WINDOW_GAIN_ALONG_EDGE,
    WINDOW_TWO_WAY_STATED,
)
from workbench.validate.print_warp import FULL


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


# a window's texture has two directions where its tensor's determinant is more than this share
# of its trace squared (λ2 / λ1 above about 1e-3): there its slide is the whole vector, elsewhere
# the component across the edge (:func:`tensor_weighted_flow`)
TWO_DIRECTIONS = 1e-3


def two_directions(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Where a window's structure tensor [[a, b], [b, c]] (:func:`tensor_components`) has two directions; bool."""
    tr = a + c
    return a * c - b * b > TWO_DIRECTIONS * tr * tr


def tensor_components(gray: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The smoothed structure tensor's components <gx²>, <gx gy>, <gy²>.

    Parameters
    ----------
    gray : (H, W) float32
        Grey levels.
    sigma : float
        Gaussian window, pixels.

    Returns
    -------
    a, b, c : (H, W) float32
        <gx²>, <gx gy>, <gy²> under the window, grey levels² per px² (Sobel gradients over 8).
    """
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3) / 8
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3) / 8
    return window_mean(gx * gx, sigma), window_mean(gx * gy, sigma), window_mean(gy * gy, sigma)


def window_mean(p: np.ndarray, sigma: float) -> np.ndarray:
    """An image under a Gaussian window.

    Parameters
    ----------
    p : (H, W) float32
    sigma : float
        The window's sigma, px. A wide one (8 px or more) is summed at a quarter of the
        resolution (a sixteenth of the pixels) and interpolated back.

    Returns
    -------
    (H, W) float32
    """
    H, W = p.shape[:2]
    if sigma < 8:
        return cv2.GaussianBlur(p, (0, 0), sigma)
    q = 4
    small = cv2.GaussianBlur(cv2.resize(p, (W // q, H // q), interpolation=cv2.INTER_AREA), (0, 0), sigma / q)
    return cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)


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
    a, b, c = tensor_components(gray, sigma)
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
    a, b, c = window_mean(xx, sigma), window_mean(xy, sigma), window_mean(yy, sigma)
    nx, ny = window_mean(xx * mx + xy * my, sigma), window_mean(xy * mx + yy * my, sigma)
    det = a * c - b * b
    tr = a + c
    two_way = two_directions(a, b, c)
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


def window_two_way(l1_wide: np.ndarray, l2_wide: np.ndarray) -> np.ndarray:
    """Where the wide window's texture has two directions: weaker eigenvalue > 0, ≥ WINDOW_TWO_WAY_STATED of the other.

    Parameters
    ----------
    l1_wide, l2_wide : (H, W) float32
        The wide window's structure tensor eigenvalues (:func:`print_texture`).

    Returns
    -------
    (H, W) bool
        There its slide is measured in any direction: it is evidence of a slide, and the
        detection limit is stated from it.
    """
    return (l2_wide > 0) & (l2_wide >= WINDOW_TWO_WAY_STATED * l1_wide)


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
    return np.where(window_two_way(l1_wide, l2_wide), WINDOW_GAIN, WINDOW_GAIN_ALONG_EDGE).astype(np.float32)


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
