"""The photo's blur on the print grid: its estimate, its local PSF and the detail it cannot resolve."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.validate.dense.options import BLUR_LEVELS, PRINT_BLUR_PX, TENSOR_SIGMA_PX, UNRESOLVED_KEEP


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
