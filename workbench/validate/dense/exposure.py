"""The colour model: the exposure fit, the colour residuals and tests, the film's colour, lost texture."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.validate.dense._channels import _cmax, _cmin
from workbench.validate.dense.lines import thin_ink_loss
from workbench.validate.dense.options import (
    COLOUR_TOL,
    DETECT_Z,
    FILM_NEAR,
    LOST_GAIN,
    MAX_FILM_SAMPLES,
    MIN_FILM_PX,
    NOISE_FLOOR,
    SATURATED,
    SHADING,
    SIGNIFICANCE_Z,
)
from workbench.validate.print_warp import _csum


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


def window_ratio(num: np.ndarray, den: np.ndarray, weight: np.ndarray, sigma: float) -> np.ndarray:
    """The ratio of two images' weighted means over a Gaussian window: the light a photo holds over a design.

    Σ w num / Σ w den in each window (where the window's weights are nearly all 0, the mean of
    ``den`` is floored at the weights' own sum). The fields are smooth on the window's scale:
    with a window of 16 px or more the sums are taken at a quarter of the resolution and the
    ratio interpolated back (as :func:`exposure_fit`; a 12 Mpx photo's took 1.9 s at full).

    Parameters
    ----------
    num, den : (H, W, C) float32
        Grey levels.
    weight : (H, W) bool or float32
        Which pixels the windows take.
    sigma : float
        Window, Gaussian sigma, px.

    Returns
    -------
    (H, W, C) float32
    """
    H, W = weight.shape
    q = 4 if sigma >= 16 else 1
    small = (max(W // q, 1), max(H // q, 1))

    def down(a):
        return cv2.resize(a, small, interpolation=cv2.INTER_AREA) if q > 1 else a

    fw = weight.astype(np.float32)
    sw = cv2.GaussianBlur(down(fw), (0, 0), sigma / q)[..., None]
    fw = fw[..., None]
    top = cv2.GaussianBlur(down(num * fw), (0, 0), sigma / q)
    bottom = cv2.GaussianBlur(down(den * fw), (0, 0), sigma / q)
    ratio = top.reshape(sw.shape[:2] + (-1,)) / np.maximum(bottom.reshape(sw.shape[:2] + (-1,)), sw + 1e-6)
    return (cv2.resize(ratio, (W, H), interpolation=cv2.INTER_LINEAR) if q > 1 else ratio).reshape(H, W, -1)


def colour_residuals(pho, pred, film, res, weight, scored, fp, px_per_mm, blur, design):
    """The colour test of :func:`analyse` before highlights are told from ink: residuals, limits, ink gone.

    Apart so that it can run beside the flow's uncertainty (it needs none of it).

    Parameters
    ----------
    pho, pred : (H, W, 3) float32
        The photo on the print and the model (the print moved, blurred like the photo, in its exposure).
    film : (H, W, 3) float32
        The bare film as the photo shows it, grey levels (:func:`workbench.validate.photometric.film_level`).
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
    blur : (H, W) float32
        The photo's blur at each pixel, Gaussian sigma, grid px (what a scratch keeps of its step).
    design : (H, W, 3) float32
        The print moved by the flow and blurred like the photo, before its exposure, grey levels
        (255: no ink, the bare film).

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
        Scored pixels where both the design's own step to the film's white and the model's
        step to the bare film exceed twice COLOUR_TOL: where broad ink loss is sought.
    dropout_found : (H, W) bool
        Where ink that is gone would be found (the detection limit's map).
    thin, thin_found : (H, W) bool
        A scratch's ink gone, and where a scratch would be found (:func:`thin_ink_loss`),
        both only where the design's step to the film exceeds the scratch test's limit.
    """
    colour_scored = scored
    # ink missing: the photo matches the bare film's colour, the design does not. The film as the
    # ink around shows it, in linear light (the exposure fit's gain and offset extrapolated from
    # dark ink to the film's white erred by -90 to +30 grey levels along a face mask's scratch,
    # 143 to 210 against the 235 four photos agree on: a scratch "found" by the error, or lost);
    # the photo shows no more than its top. Ink only absorbs: the film is at least as bright as
    # the ink under the same light, and where the film the ink around tells comes out darker
    # than the model of the ink itself, the two accounts of the light disagree (near-white ink at
    # a shadow's edge on a bunny: the film 150, the ink's model 180, the photo 100), and a darker
    # photo is no step towards the film: there is no step to seek
    film_pred = np.clip(film, pred, np.float32(255.0))
    # how much of the ink is gone, per pixel: the photo's step from the design's colour towards
    # the bare film's, as a share of the whole step (0 to 1; blur spreads it, its sum keeps the area)
    step = film_pred - pred
    step2 = _csum(step * step)
    # ink can be gone only where the design lays some down, by its own step to the bare film (the
    # print's white): a pixel the design leaves white is the film already, whatever the model's
    # exposure makes of it (where a flat render's white was clipped, the fit's gain came from the
    # ink beside it and put the design's white at 225 against the film's 254: a line of "ink gone"
    # of 7.2 mm² over no ink at all on a perfect face). Broad ink loss is sought where that step
    # exceeds twice the colour test's tolerance, as the part's coverage counts it
    # (:func:`workbench.validate.coverage.where_defects_show`)
    ink_step = _cmax(np.float32(255.0) - design)
    inked = colour_scored & (ink_step > 2 * COLOUR_TOL) & (_cmax(np.abs(step)) > 2 * COLOUR_TOL)
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
    thin, thin_found, thin_alpha = thin_ink_loss(
        pho, pred, film_pred, colour_scored, px_per_mm, thin_limit, blur, colour_noise
    )
    # (a scratch, where the design's own step to the film is more than the scratch test asks of
    # the photo's)
    ink = ink_step > thin_limit
    thin &= ink
    thin_found &= ink
    gone |= thin
    # (its share of the ink gone, against its surroundings: over pale ink the plain share is not taken)
    alpha = np.maximum(alpha, np.where(ink, thin_alpha, np.float32(0.0)))
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


def _residual(photo: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """Largest channel residual, grey levels; a channel clipped in the photo where the model is bright too
    says nothing (yellow ink's red channel reaches 255 on a well exposed photo)."""
    r = photo - pred
    np.abs(r, out=r)
    np.copyto(r, 0.0, where=(photo >= SATURATED) & (pred >= SATURATED - 15))
    return _cmax(r)
