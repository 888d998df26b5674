"""What the flow can know: its uncertainty, its floor, the flow back and the stated slide limit."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.validate import detection
from workbench.validate.dense.flow import (
    _enlarge_flow,
    dis_flow,
    structure_tensor,
    tensor_components,
    two_directions,
    window_gain,
    window_two_way,
)
from workbench.validate.dense.options import (
    DETECT_Z,
    FLOW_FLOOR_PX,
    NOISE_FLOOR,
    PHOTO_FLOOR_PX,
    SIGNIFICANCE_Z,
)

# the median of χ² of one and of two degrees of freedom: 0.4549 and 2 ln 2
CHI2_MEDIAN = {1: 0.454936, 2: 2.0 * float(np.log(2.0))}


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


def window_mismatch(
    slide_px: np.ndarray, gray: np.ndarray, window_px: float, where: np.ndarray, noise: float, n_eff: float
) -> float:
    """What a window's slide errs by in this photo beyond its noise, κ² (grey levels²): the wide window's model term.

    A window's slide v is the least-squares vector its pixels' flows support through the
    window's structure tensor T (:func:`workbench.validate.dense.flow.tensor_weighted_flow`).
    With errors of covariance s² T⁻¹ (the photo's noise alone: s² = σ_n² / N, N the window's
    independent samples) the form vᵀ T v / s² is χ² of two degrees of freedom on a sound part,
    of one where the window's texture has one direction (its slide is the component across the
    edge, and vᵀ T v is λ1 times its square). What the model of the photo does not explain (its
    blur, shading and compression against the print's faint texture, or stripes the design
    stretched) adds to s² a κ² of its own, which makes the window's slide err more where its
    texture is fainter: its variance κ² / λ along an eigenvector of eigenvalue λ, as a pixel's
    own flow has its mismatch (:func:`flow_uncertainty`). The slide the placement leaves every
    window (``slide_px`` less it) is no error of any one window.

    Estimated over the photo's windows by the median of vᵀ T v, each over the median of χ² of
    its degrees of freedom (2 ln 2 for two, 0.455 for one), less the noise's share: a defect, a
    minority of the windows, moves a median as a median moves (a tenth of the windows slid by
    2 px raise s² by 17 %), so it does not hide itself; past half of the windows it would, and
    a slide over most of the film is the placement's, measured as such. On a --realistic photo
    of the lily's top, its artwork stretched into faint streaks, the windows' slides were 3.5
    times their noise's uncertainty on the median (14 % of them 3 uncertainties past the 0.2 mm
    tolerance, and one region failed the perfect part); with κ², 0.4 to 0.5 times, and none of
    the windows that measure a slide is 3 past the tolerance.

    Parameters
    ----------
    slide_px : (H, W, 2) float32
        The windows' slides less the placement the flow holds, grid px.
    gray : (H, W) float32
        The print as the windows weighed it (the flow's smoothed print).
    window_px : float
        The window, Gaussian sigma, grid px.
    where : (H, W) bool
        The windows to take (scored, resolved, away from light).
    noise : float
        σ_n, the photo's noise at the flow's scale, grey levels.
    n_eff : float
        Independent noise samples in a window (:func:`effective_samples`).

    Returns
    -------
    float
        κ², grey levels² (0 where the windows err by no more than the noise).
    """
    if not where.any():
        return 0.0
    a, b, c = tensor_components(gray, window_px)
    a, b, c = a[where], b[where], c[where]
    vx, vy = slide_px[..., 0][where], slide_px[..., 1][where]
    # vᵀ T v, the slide weighed by the texture that measures it, over the median of χ² of its
    # degrees of freedom: s² on the median, whichever the window
    form = a * vx * vx + 2.0 * b * vx * vy + c * vy * vy
    form = form / np.where(two_directions(a, b, c), np.float32(CHI2_MEDIAN[2]), np.float32(CHI2_MEDIAN[1]))
    form = form[np.isfinite(form)]
    if not len(form):
        return 0.0
    return max(float(np.median(form)) - noise * noise / max(n_eff, 1.0), 0.0)


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


def stated_shift_limit(
    tolerance_mm, noise, l1, l2, n_eff, floor, mm_per_px, wide_sigma, two_way, measurable, usable, l1_wide, l2_wide
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The detection limit's smallest slide found at each pixel, stated for a sound part (:func:`analyse`).

    The photo's noise through the texture it resolves (the mismatch and the flow back, which a
    defect itself raises, left out: :func:`workbench.validate.detection.expected_flow_sigma`),
    and the window's slide's uncertainty ``wide_sigma``, of which the window answers
    :func:`window_gain` of its eigenvalues ``l1_wide``, ``l2_wide`` where its texture has two
    directions (elsewhere it states nothing: the defect search takes no evidence from it);
    :func:`workbench.validate.detection.shift_limit` at SIGNIFICANCE_Z + DETECT_Z.

    Returns
    -------
    limit : (H, W) float32
        mm on the surface; NaN where no slide is found.
    sigma : (H, W) float32
        The stated uncertainty of the pixel's own full vector, mm on the surface, where the
        pixel measures it (``two_way``, within ``usable``); NaN elsewhere. The part fuses it
        over its photos (:func:`workbench.validate.detection.fused_shift_limit`).
    window_sigma : (H, W) float32
        The window's slide's uncertainty ``wide_sigma`` where the window measures it (within
        ``usable``) and its texture has two directions (it answers WINDOW_GAIN of a slide); NaN
        elsewhere. The part fuses it too.
    """
    weak_e, _ = detection.expected_flow_sigma(noise, l1, l2, n_eff, floor)
    weak_mm = weak_e * mm_per_px
    gain = window_gain(l1_wide, l2_wide)
    two_way_window = window_two_way(l1_wide, l2_wide)
    # (a window along an edge that barely turns is no evidence of a slide (the defect search
    # takes a window's only where its texture has two directions: it answers a twentieth of a
    # slide along the edge, WINDOW_GAIN_ALONG_EDGE), so the limit is not stated from it either)
    limit = detection.shift_limit(
        tolerance_mm, SIGNIFICANCE_Z + DETECT_Z, weak_mm, wide_sigma, two_way,
        measurable & two_way_window, usable, gain,
    )  # fmt: skip
    own = np.where(two_way & (weak_mm <= usable), weak_mm, np.nan).astype(np.float32)
    window = measurable & (wide_sigma <= usable) & two_way_window
    return limit, own, np.where(window, wide_sigma, np.nan).astype(np.float32)
