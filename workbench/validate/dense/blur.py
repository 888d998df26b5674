"""The photo's blur on the print grid: its estimate, its local PSF and the detail it cannot resolve."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workbench.validate.dense.options import BLUR_LEVELS, PRINT_BLUR_PX, TENSOR_SIGMA_PX, UNRESOLVED_KEEP

# the camera's blur (photo px) tried, and the print's own (grid px): a photo's pixel alone is a box
# of 0.29 px; lens, demosaicing, the renderer's or the camera's filter and the warp add to it
CAMERA_BLURS_PX = (0.0, 0.35, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0)
PRINT_BLURS_PX = (0.0, PRINT_BLUR_PX)
# the detail the blur is judged on: what a Gaussian of this sigma (grid px) leaves out, so that the
# design's broad shading and the exposure's slow changes, which no blur alters, do not weigh in
DETAIL_SIGMA_PX = 1.5
BLUR_SAMPLES = 500_000  # grid pixels the candidates are scored on, at most
# the blur is measured where the photo samples the print's two axes alike, within this ratio: a
# round candidate there is the blur the model applies along each axis (:func:`blur_locally_axes`)
# to within 12 % of its sigma
ROUND_FOOTPRINT = 1.25
ROUND_MIN_SHARE = 0.1  # ... where that is at least this share of the compared pixels


@dataclass(frozen=True)
class PhotoBlur:
    """The photo's blur in two parts: the print's own, fixed on the print, and the camera's, fixed in photo pixels.

    The print's own: a print pixel is a box (sigma 0.29 px) that the film shows interpolated
    (a triangle, 0.41 px) and the ink spreads a little, PRINT_BLUR_PX in all (never more than
    was measured). The camera's (lens, sensor, demosaicing, the warp's anti-aliasing) is
    fixed in photo pixels, so on the grid it is ``1 / footprint`` times it where the photo
    samples the print at ``footprint`` photo px per grid px. (Where a deep part is seen partly
    from far and partly from near, the photo can be three times finer than its median on the
    print: the near surface's blur is then a third, and the print's detail there is resolved.
    Holding it to the median's blur made the model blurrier than the photo, and the print's
    sharp checker there "ink gone".)

    Attributes
    ----------
    print_px : float
        Gaussian sigma, grid px.
    camera_px : float
        Gaussian sigma, photo px.
    """

    print_px: float
    camera_px: float

    def on_grid(self, footprint, scale: float) -> np.ndarray:
        """Gaussian sigma on the grid, grid px: ``b² = print_px² + (camera_px / footprint)²`` (variances add).

        Parameters
        ----------
        footprint : (H, W) or (n,) float
            Photo px per grid px; ``scale`` is taken where it is 0 (not seen).
        scale : float
            The photo's median footprint.

        Returns
        -------
        Same shape as ``footprint``, float32, at most BLUR_LEVELS[-1].
        """
        fp = np.asarray(footprint, np.float32)
        fp = np.where(fp > 0, fp, np.float32(max(scale, 1e-3)))
        b = np.sqrt(self.print_px**2 + (self.camera_px / fp) ** 2)
        return np.clip(b, 0.0, BLUR_LEVELS[-1]).astype(np.float32)


def estimate_blur(
    ref_gray: np.ndarray,
    warped_gray: np.ndarray,
    mask: np.ndarray,
    footprint: np.ndarray,
    scale: float,
    footprint_axes: np.ndarray | None = None,
) -> PhotoBlur:
    """The print's and the camera's blur that make the print look most like the warped photo.

    Each candidate pair blurs the print by its sigma at every grid pixel
    (:meth:`PhotoBlur.on_grid`, rounded to BLUR_LEVELS as :func:`blur_locally` does) and is
    scored by the normalised correlation of the two images' detail (each less its Gaussian of
    DETAIL_SIGMA_PX) over ``mask``; the best pair is the photo's blur. (One sigma on the grid
    for the whole photo is set by the design's sharpest, highest-contrast detail wherever the
    photo sees it best, and was then scaled to the rest as if measured at the median: a face
    mask's photo at a median 0.58 photo px per grid px came out at 0, where a 0.5 mm scratch
    seen at 0.76 showed a sigma of 1.6 grid px, 1.25 photo px, and was stated found where it
    steps the photo 46 % of the way to the film. This model finds 1.25 photo px there.)

    Parameters
    ----------
    ref_gray, warped_gray : (H, W) float32
        The print (moved by the flow) and the photo on the grid, grey levels.
    mask : (H, W) bool
        Where they are compared.
    footprint : (H, W) float32
        Photo px per grid px (0: not seen).
    scale : float
        The median footprint, photo px per grid px.
    footprint_axes : (H, W, 2) float32, optional
        Photo px per grid px that the camera's blur sees along x and y
        (:func:`workbench.validate.print_warp.footprint_axes`): the blur is measured where the
        two agree within ROUND_FOOTPRINT, at their geometric mean (a round candidate there is
        the model's blur along each axis), where that is at least ROUND_MIN_SHARE of ``mask``;
        over all of it, at ``footprint``, otherwise.

    Returns
    -------
    PhotoBlur
    """
    geometric = False
    if footprint_axes is not None:
        fx, fy = footprint_axes[..., 0], footprint_axes[..., 1]
        round_ = mask & (np.maximum(fx, fy) <= ROUND_FOOTPRINT * np.minimum(fx, fy))
        if round_.sum() >= ROUND_MIN_SHARE * mask.sum():
            # (and the candidates there at the two axes' geometric mean: the spread the model then
            # applies along each, to within the ratio's square root; taken at the sampled pixels)
            mask, geometric = round_, True
    at = np.flatnonzero(mask)  # (the masked pixels once: a boolean index finds them again each time)
    if len(at) < 100:
        return PhotoBlur(0.0, 0.0)
    # (evenly thinned to BLUR_SAMPLES: a correlation over that many pixels is settled to the
    # third decimal, and the 20 candidates each index the whole stack)
    at = at[:: -(-len(at) // BLUR_SAMPLES)]

    photo = warped_gray.astype(np.float32)
    w = (photo - cv2.GaussianBlur(photo, (0, 0), DETAIL_SIGMA_PX)).ravel()[at]
    w = w - w.mean()
    ww = float((w * w).sum())
    # (the print's detail at every level of blur once; a candidate takes each pixel's level. The
    # detail of the blurred print is the blurred detail: both are convolutions)
    ref = ref_gray.astype(np.float32)
    ref_detail = ref - cv2.GaussianBlur(ref, (0, 0), DETAIL_SIGMA_PX)
    stack = np.stack(
        [(cv2.GaussianBlur(ref_detail, (0, 0), s) if s > 0 else ref_detail).ravel()[at] for s in BLUR_LEVELS]
    )
    if geometric:
        fp = np.sqrt(footprint_axes[..., 0].ravel()[at] * footprint_axes[..., 1].ravel()[at])
    else:
        fp = footprint.ravel()[at]
    best, best_blur = -2.0, PhotoBlur(0.0, 0.0)
    for b0 in PRINT_BLURS_PX:
        for c in CAMERA_BLURS_PX:
            blur = PhotoBlur(b0, c)
            k = blur_levels(blur.on_grid(fp, scale)).astype(np.intp)
            g = np.take_along_axis(stack, k[None], axis=0)[0]
            g = g - g.mean()
            ncc = float((g * w).sum() / np.sqrt(float((g * g).sum()) * ww + 1e-12))
            if ncc > best:
                best, best_blur = ncc, blur
    return best_blur


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


def blur_locally_axes(img: np.ndarray, sigma_x: np.ndarray, sigma_y: np.ndarray) -> np.ndarray:
    """An image blurred by an axis-aligned Gaussian whose two sigmas vary over it (each rounded to BLUR_LEVELS).

    A Gaussian of sigmas (sx, sy) is a blur along x by sx and then along y by sy; each pass
    takes each pixel's level (where the levels do not change within a kernel's reach, the same
    image as the two-dimensional Gaussian).

    Parameters
    ----------
    img : (H, W) or (H, W, C) float32
    sigma_x, sigma_y : (H, W) float
        Per pixel, along x (axis 1) and y (axis 0), grid px.

    Returns
    -------
    Same shape as ``img``.
    """
    return _blur_along(_blur_along(img, sigma_x, 1), sigma_y, 0)


def _blur_along(img: np.ndarray, sigma: np.ndarray, axis: int) -> np.ndarray:
    """``img`` blurred along one axis (1: x, 0: y) by a Gaussian of each pixel's level (:func:`blur_levels`)."""
    k = blur_levels(sigma)
    present = np.flatnonzero(np.bincount(k.ravel().view(np.uint8), minlength=len(BLUR_LEVELS)))
    one = np.ones((1, 1), np.float32)
    out = None
    for i in present:
        s = float(BLUR_LEVELS[i])
        if s > 0:
            # (the kernel OpenCV's GaussianBlur takes for floats: 4 sigma each side)
            g = cv2.getGaussianKernel(int(round(s * 8 + 1)) | 1, s, cv2.CV_32F)
            b = cv2.sepFilter2D(img, -1, g if axis == 1 else one, one if axis == 1 else g)
        else:
            b = img
        if out is None:
            out = b.copy() if len(present) > 1 or b is img else b
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
        The photo's blur on the grid at each pixel (:meth:`PhotoBlur.on_grid`), Gaussian sigma, grid px.
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
