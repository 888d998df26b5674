"""The photo as light on ink: the bare film as the ink around shows it, and light added against ink gone.

One model of image formation replaces the rules that told light from ink. In linear light a
photo pixel is the ink's colour times the light that falls on it there, plus light the glossy
film adds:

    P = A ⊙ F + s · L,

with A the design's colour (linear sRGB, the film's white 1), F the bare film's colour as the
photo shows it there (the lamp's colour and the shading, vignetting and exposure of the photo:
:func:`film_level`), s ≥ 0 the light added and L its colour. Ink that is gone shows F itself.
A matte film adds no light of its own (s = 0): what light reaches its ink beyond the model's
(the part's own interreflection, a shading the model misses) scales the ink, ``P = k A ⊙ F``.

A region of the colour residual is judged by which hypothesis explains its photo better, as a
log-likelihood ratio with the photo's own noise (:func:`judge_region`):

- **ink gone**: ``P = α b F + (1 - α) D`` (D the design as the local exposure fit shows it,
  α in [0, 1] one share for the region, b the film's brightness within its uncertainty);
- **light added**: ``P = k D + s L`` (k within the colour test's shading allowance, s ≥ 0); on a
  matte film ``P = k D``, k smooth over the region, within the same allowance.

Ink gone cannot exceed the bare film and takes the design's texture with it; light keeps the
texture and may go on beyond the film. Over uniform neutral ink the two predict the same photo
and the ratio is near 0: one photo cannot tell them apart there, and the command decides by
where the photo's lamp is mirrored (a glint can only be there). A clipped channel says only that
the photo is at least the clipping level (a censored sample).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

SATURATED = 250  # a channel this bright is clipped (the photo says only "at least this")
SATURATED_LIN = float(((SATURATED / 255.0 + 0.055) / 1.055) ** 2.4)  # the clipping level in linear light
SHADING = 1.6  # the light hypothesis' gain per region is within [1 / SHADING, SHADING] (as the colour test's)
# the film's level as pale ink shows it errs by this much (log units, one standard deviation) beyond
# its noise: measured against renders of the bare film from the same pose (a dark photograph printed
# on the cow's part, both renderers, matte): the photo over ink above 0.3 (linear) was 0.87 to 1.02
# times the design times the film (10th to 90th percentile). Over dark ink an additive error (flare,
# the blur's mixing, a black level, a glossy film's sheen) adds O / (A F) (see film_level): over ink
# of 0.01 to 0.03 the photo was 1.0 to 1.6 times it, and the film's level there erred by 8 to 9 %
# (MAD), up to 25 % (5th and 95th percentiles); a spherical-harmonic shading of the surface's normal,
# fitted over the whole part, and a local affine fit of photo to design erred as much
FILM_ERR_PALE = 0.05
FILM_PRIOR_DOF = 3.0  # the film brightness prior's degrees of freedom (a heavy tail: see judge_region)
MAX_REL_NOISE = 0.5  # a pixel whose photo has more relative noise than this says nothing of the film's level
UNKNOWN = 1.0  # the film's uncertainty (log units) where no ink around says anything of it


def linear(grey: np.ndarray) -> np.ndarray:
    """Grey levels (0 to 255, sRGB-encoded) to linear light (0 to 1); float32, same shape.

    The sRGB curve (:func:`workbench.validate.colour.srgb_decode`) in float32: a whole grid's
    three channels in float64 took a third of a second.
    """
    v = np.maximum(np.asarray(grey, np.float32), np.float32(0.0)) / np.float32(255.0)
    return np.where(v <= 0.04045, v / np.float32(12.92), ((v + np.float32(0.055)) / np.float32(1.055)) ** 2.4).astype(
        np.float32
    )


def grey_levels(lin: np.ndarray) -> np.ndarray:
    """Linear light (0 to 1) to grey levels (0 to 255, sRGB-encoded, not clipped); float32 (:func:`linear` inverted)."""
    a = np.abs(np.asarray(lin, np.float32))
    v = np.where(a <= 0.0031308, a * np.float32(12.92), np.float32(1.055) * a ** np.float32(1 / 2.4) - 0.055)
    return (np.float32(255.0) * np.sign(lin) * v).astype(np.float32)


def linear_slope(grey: np.ndarray) -> np.ndarray:
    """d lin / d grey of the sRGB curve at each grey level (linear light per grey level); float32.

    lin = v / 12.92 below v = 0.04045, ((v + 0.055) / 1.055)^2.4 above (v = grey / 255), so the
    slope is 1 / (12.92 · 255) there and 2.4 / 1.055 · ((v + 0.055) / 1.055)^1.4 / 255 here.
    """
    v = np.clip(grey, 1.0, 255.0) / 255.0
    return (np.where(v <= 0.04045, 1.0 / 12.92, 2.4 / 1.055 * ((v + 0.055) / 1.055) ** 1.4) / 255.0).astype(np.float32)


@dataclass(frozen=True)
class FilmLevel:
    """The bare film as the photo shows it, per grid pixel.

    Attributes
    ----------
    film : (H, W, 3) float32
        Its colour, grey levels (sRGB-encoded, may exceed 255 where the photo would clip).
    sigma : (H, W) float32
        Its relative standard uncertainty, log units (UNKNOWN where no ink around tells it).
    """

    film: np.ndarray
    sigma: np.ndarray


def film_level(
    photo: np.ndarray,
    design: np.ndarray,
    fitted: np.ndarray,
    noise: float,
    window_px: float,
    fallback: np.ndarray,
    added: np.ndarray | None = None,
    window_share: np.ndarray | None = None,
) -> FilmLevel:
    """The bare film's colour as the photo shows it, from the ink around each pixel.

    Every ink is lit alike: ``P = A ⊙ F`` in linear light, so each inked pixel measures the film,
    ``log F = log P - log A``, with relative noise σ_rel = σ · (d lin / d grey) / P. The film's
    level at a pixel is the precision-weighted (1 / σ_rel²) Gaussian mean of those over
    ``window_px``, common to the three channels (one lamp) times each channel's own gain (the
    light's colour: the precision-weighted mean over the photo); pixels beyond three standard
    deviations of a first estimate (defects, glints, wrong ink) are left out of the second.
    Light added over the ink (a glossy film's sheen, flare, the blur's mixing) raises P by O
    whatever the ink, so a pixel of ink A misleads by about O / (A F) in log F: in the second
    pass each pixel's variance holds that term too, O the larger of the photo's own additive
    scatter (the robust spread of P - A F over the first pass) and the light the exposure fit adds
    there (``added``); pale ink then tells the film, dark ink does not. That error is common to
    the window's pixels (it does not average out), so the film's uncertainty is the mean's own
    (1 / √Σw) and FILM_ERR_PALE in quadrature, plus the window's weighted mean of O / (A F). Unlike an
    exposure fit's gain and offset extrapolated from dark ink to the film's white, nothing is
    extrapolated: over ink of 0.01 (linear) the photo still measures the film, noisily.

    Parameters
    ----------
    photo, design : (H, W, 3) float32
        The photo on the print and the design as the photo would show it (moved by the flow,
        blurred like the photo), grey levels.
    fitted : (H, W) bool
        Pixels that may measure the film (scored, not clipped).
    noise : float
        The photo's noise per channel, grey levels.
    window_px : float
        The window's Gaussian sigma, grid px.
    fallback : (H, W, 3) float32
        The film's colour where no ink around measures it (grey levels).
    added : (H, W) float32, optional
        Light added over the ink, linear light (the exposure fit's offset).
    window_share : (H, W) float32, optional
        The window's share of ``window_px`` at each pixel, in (0, 1] (:func:`window_shares`):
        where the print is squeezed, so that the window covers no more of the surface than it
        does where the print is typical. Rounded to halvings.

    Returns
    -------
    FilmLevel
    """
    # the film's level varies over the window, not from pixel to pixel: measured on the grid reduced
    # by a whole factor (each reduced pixel the mean of k² pixels, its noise 1 / k of theirs), then
    # brought back; a 12 Mpx photo's grid took 1.5 s at its own size
    H, W = fitted.shape
    k = max(1, int(window_px // 8))
    if k > 1:
        size = (max(1, W // k), max(1, H // k))
        photo = cv2.resize(photo, size, interpolation=cv2.INTER_AREA)
        design = cv2.resize(design, size, interpolation=cv2.INTER_AREA)
        fitted = cv2.resize(fitted.astype(np.float32), size, interpolation=cv2.INTER_AREA) >= 1.0
        added = None if added is None else cv2.resize(added, size, interpolation=cv2.INTER_AREA)
        noise, window_px = noise / k, window_px / k
    P, A = linear(photo), linear(design)
    srel = np.float32(max(noise, 0.5 / k)) * linear_slope(photo) / np.maximum(P, 1e-6)
    ok = fitted[..., None] & (A > 1e-4) & (P > 0) & (srel < MAX_REL_NOISE)
    r = np.log(np.maximum(P, 1e-6)) - np.log(np.maximum(A, 1e-6))
    w = np.where(ok, 1.0 / (srel * srel), 0.0).astype(np.float32)
    if not (w > 0).any():
        return FilmLevel(fallback.astype(np.float32), np.full((H, W), UNKNOWN, np.float32))
    # each channel's gain: the light's colour (and the camera's white balance), one for the photo
    gains = np.zeros(3, np.float32)
    for c in range(3):
        wc = w[..., c]
        gains[c] = float((wc * np.nan_to_num(r[..., c])).sum() / max(float(wc.sum()), 1e-12)) if wc.any() else 0.0
    # the level common to the channels, per pixel, and its precision
    ws = w.sum(axis=2)
    rs = (w * np.nan_to_num(r - gains)).sum(axis=2) / np.maximum(ws, 1e-12)
    # the additive error O per pixel: the photo's own (the robust spread of P - A F about the
    # film of the whole window), or the light the exposure fit adds over the ink where more
    first = _window_mean(ws, rs, window_px)
    f1 = (np.exp(first)[..., None] * np.exp(gains)).astype(np.float32)
    d = (P - A * f1)[ok]
    o_own = 1.4826 * float(np.median(np.abs(d - np.median(d)))) if d.size else 0.0
    O = np.full(fitted.shape, o_own, np.float32) if added is None else np.maximum(added, o_own).astype(np.float32)
    halvings = np.zeros(fitted.shape, np.int32)
    if window_share is not None:
        share = window_share if k == 1 else cv2.resize(window_share, fitted.shape[::-1], interpolation=cv2.INTER_AREA)
        # (halvings down to a window of one grid pixel)
        most = max(0, int(np.floor(np.log2(max(window_px * k, 1.0)))))
        halvings = np.clip(np.rint(-np.log2(np.clip(share, 1e-6, 1.0))), 0, most).astype(np.int32)
    level = np.zeros(fitted.shape, np.float32)
    sigma = np.full(fitted.shape, UNKNOWN, np.float32)
    for m in np.unique(halvings):
        at = halvings == m
        lv, sg = _film_in_window(ws, rs, A, srel, ok, r, gains, O, window_px / 2.0**m)
        level[at], sigma[at] = lv[at], sg[at]
    known = sigma < UNKNOWN
    if k > 1:
        level = cv2.resize(level, (W, H), interpolation=cv2.INTER_LINEAR)
        sigma = cv2.resize(sigma, (W, H), interpolation=cv2.INTER_LINEAR)
        known = sigma < UNKNOWN
    film = grey_levels(np.exp(level[..., None] + gains[None, None, :]).astype(np.float32))
    film = np.where(known[..., None], film, fallback).astype(np.float32)
    return FilmLevel(film, sigma)


def window_shares(X: np.ndarray) -> np.ndarray:
    """How much of a window of grid pixels a local model may use, so that it covers the surface it covers typically.

    A model of the light (the film's level, the shading) holds over a patch of the *surface*: the
    shading follows the surface's normal. A window of so many grid pixels covers the surface at
    the print's local scale, s = max(|∂X/∂i|, |∂X/∂j|) mm of surface per grid pixel (the longer
    of the two axes' steps: the window must reach no further along either). Where the design
    squeezed the print (a dome's cap mapped to a small disc: 8 to 28 times the typical scale on
    the scanned face's crown) one window spans tens of millimetres of a surface turning through
    the lamp's light. Its share there is s_typical / s (the median scale over the grid), at most
    1: the window keeps the surface size it has over most of the part.

    Parameters
    ----------
    X : (H, W, 3) float
        Surface point under each grid pixel, mm (NaN off the part).

    Returns
    -------
    (H, W) float32
        In (0, 1]; 1 off the part and where the print is not squeezed.
    """
    H, W = X.shape[:2]
    share = np.ones((H, W), np.float32)
    if H < 2 or W < 2:
        return share
    # (the steps between neighbours, each set on the pixel before it: a one-pixel shift is nothing
    # against a window of many)
    di = np.linalg.norm(np.diff(X, axis=0), axis=2)[:, :-1]
    dj = np.linalg.norm(np.diff(X, axis=1), axis=2)[:-1, :]
    s = np.maximum(di, dj)
    ok = np.isfinite(s) & (s > 0)
    if not ok.any():
        return share
    typical = float(np.median(s[ok]))
    share[:-1, :-1] = np.where(ok, np.minimum(1.0, typical / np.where(ok, s, 1.0)), 1.0)
    return share


def _window_mean(ws: np.ndarray, rs: np.ndarray, window_px: float) -> np.ndarray:
    """The ``ws``-weighted Gaussian mean of ``rs`` over ``window_px`` (grid px)."""
    num = cv2.GaussianBlur(ws * rs, (0, 0), window_px)
    den = cv2.GaussianBlur(ws, (0, 0), window_px)
    return num / np.maximum(den, 1e-12)


def _film_in_window(ws, rs, A, srel, ok, r, gains, O, window_px: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`film_level`'s estimate over one window: the log level common to the channels and its sigma.

    ``ws``, ``rs`` (H, W) each pixel's precision and log level from its noise alone, ``A``,
    ``srel``, ``ok``, ``r`` (H, W, 3) and ``O`` (H, W) as :func:`film_level` computes them (on its
    reduced grid); ``gains`` (3,) the channels' log gains. Returns the level (H, W, log units, 0
    where unknown) and its uncertainty (H, W, UNKNOWN where unknown).
    """
    first = _window_mean(ws, rs, window_px)
    f1 = (np.exp(first)[..., None] * np.exp(gains)).astype(np.float32)
    # (a second pass with each pixel's share of the additive error, O / (A F) in log F, and without
    # what the ink around does not explain: a defect, a glint, wrong ink)
    extra = (O[..., None] / np.maximum(A * f1, 1e-6)) ** 2
    w = np.where(ok, 1.0 / (srel * srel + extra), 0.0).astype(np.float32)
    ws = w.sum(axis=2)
    rs = (w * np.nan_to_num(r - gains)).sum(axis=2) / np.maximum(ws, 1e-12)
    far = np.abs(rs - first) > 3.0 * np.hypot(1.0 / np.sqrt(np.maximum(ws, 1e-12)), FILM_ERR_PALE)
    ws = np.where(far, 0.0, ws).astype(np.float32)
    num = cv2.GaussianBlur(ws * rs, (0, 0), window_px)
    den = cv2.GaussianBlur(ws, (0, 0), window_px)
    level = num / np.maximum(den, 1e-12)
    # the additive error's bias, common to the window: its pixels' O / (A F), as the weights average it
    bias_px = (w * np.sqrt(extra)).sum(axis=2) / np.maximum(w.sum(axis=2), 1e-12)
    bias = cv2.GaussianBlur(ws * bias_px, (0, 0), window_px) / np.maximum(den, 1e-12)
    # Σw over the window: the Gaussian's normalised blur of ws times its area 2π s² (its weights sum to 1)
    total = den * np.float32(2.0 * np.pi * window_px * window_px)
    sigma = (np.hypot(1.0 / np.sqrt(np.maximum(total, 1e-12)), FILM_ERR_PALE) + bias).astype(np.float32)
    known = (den > 0) & (sigma < UNKNOWN)
    sigma = np.where(known, sigma, UNKNOWN).astype(np.float32)
    return np.where(known, level, 0.0).astype(np.float32), sigma


def beyond_film(photo: np.ndarray, film: FilmLevel, noise: float, z: float) -> np.ndarray:
    """Pixels brighter than the bare film could show there: light added, whatever the ink.

    Every channel exceeds the film's raised by ``z`` of its uncertainty (:attr:`FilmLevel.sigma`)
    and by ``z`` of the photo's noise; a clipped channel (at least SATURATED) counts as beyond where
    the film so raised stays below SATURATED. Where the film is unknown nothing is beyond it.

    Parameters
    ----------
    photo : (H, W, 3) float32
        Grey levels.
    film : FilmLevel
    noise : float
        The photo's noise, grey levels.
    z : float
        Significance.

    Returns
    -------
    (H, W) bool
    """
    top = grey_levels(linear(film.film) * np.exp(z * film.sigma)[..., None])
    clipped = photo >= SATURATED
    over = (photo > top + z * noise) | (clipped & (top < SATURATED))
    return over[..., 0] & over[..., 1] & over[..., 2] & (film.sigma < UNKNOWN)


@dataclass(frozen=True)
class Judgement:
    """What explains one region of the colour residual, and by how much.

    Attributes
    ----------
    hypothesis : str
        ``"ink gone"``, ``"light"`` or ``"not told"`` (neither explains it significantly better).
    log_lr : float
        log-likelihood of light added over that of ink gone, in effective independent samples
        (positive: light explains the photo better).
    share : float
        The ink gone hypothesis' share of the step to the film (α).
    added : float
        The light hypothesis' light added, grey levels of its largest channel at the region's level.
    pixels : int
        Pixels judged (the region's core).
    separation : float
        How far apart the two hypotheses' photos are, RMS in standard deviations per pixel and
        channel: below 1 the photo cannot tell them, whatever the ratio.
    gain : float
        The light hypothesis' gain of the ink (k; its median over the region on a matte film).
    """

    hypothesis: str
    log_lr: float
    share: float
    added: float
    pixels: int
    separation: float = 0.0
    gain: float = 1.0

    def as_dict(self) -> dict:
        return {
            "hypothesis": self.hypothesis,
            "log_likelihood_ratio_light_vs_ink_gone": round(self.log_lr, 2),
            "ink_gone_share": round(self.share, 3),
            "light_added_grey_levels": round(self.added, 1),
            "pixels": self.pixels,
            "separation_sigma": round(self.separation, 2),
            "light_gain": round(self.gain, 3),
        }


def _chi2(P: np.ndarray, M: np.ndarray, var: np.ndarray, clipped: np.ndarray) -> float:
    """Σ (P - M)² / var over pixels and channels; a clipped channel fits any model at or above it."""
    r = P - M
    r = np.where(clipped & (r < 0), 0.0, r)
    return float((r * r / var).sum())


def smooth_scale(P: np.ndarray, X: np.ndarray, var: np.ndarray, Q: np.ndarray | None) -> np.ndarray:
    """The scale of ``X`` that fits ``P`` at each pixel, smooth over the pixels (one scale without ``Q``).

    Per pixel by least squares over the channels, ŝ = Σ_c P X / var / Σ_c X² / var, of weight
    Σ_c X² / var; then the weighted least-squares surface ``Q`` coef through them, or their
    weighted mean.

    Parameters
    ----------
    P, X, var : (n, 3) float
        The photo, what is scaled, and each value's variance (linear light).
    Q : (n, k) float or None
        The surface's terms at each pixel (a second-order surface of position: 1, x, y, x², xy, y²).

    Returns
    -------
    (n,) float
        The scale at each pixel.
    """
    w = (X * X / var).sum(axis=1)
    s = (P * X / var).sum(axis=1) / np.maximum(w, 1e-12)
    if Q is not None:
        return Q @ np.linalg.lstsq(Q * np.sqrt(w)[:, None], s * np.sqrt(w), rcond=None)[0]
    return np.full(len(P), float((s * w).sum() / max(float(w.sum()), 1e-12)))


def judge_region(
    photo: np.ndarray,
    design: np.ndarray,
    film: np.ndarray,
    light: np.ndarray,
    noise: float,
    model_err: float,
    film_sigma: float,
    n_eff: float,
    z: float,
    xy: np.ndarray | None = None,
    additive: bool = True,
) -> Judgement:
    """Light added against ink gone over one region's pixels, as a log-likelihood ratio.

    Both hypotheses are fitted in linear light, each pixel's variance the photo's noise carried
    through the sRGB curve (σ_lin = σ · d lin / d grey at the photo's level) and what the design's
    model misses around the region (``model_err`` of the photo's level):

    - ink gone: ``P = α b F + (1 - α) D``, b = exp(u) with u ~ N(0, film_sigma²) (the film's
      brightness as the ink around tells it: its prior adds u² / film_sigma² once), and α = 1 on a
      region's core (``whole``: there the photo shows the bare film alone; a region stepped only a
      part of the way there, as a sheen steps it, is no ink gone), in [0, 1] on a region narrower
      than the photo's blur (a thin scratch never reaches the film's colour);
    - light: ``P = k D + s L``, k in [1 / SHADING, SHADING], s ≥ 0, on a film that adds light
      of its own (``additive``: a glossy film mirrors the lamp and the room); on one that adds
      none (a matte film) ``P = k D``: whatever light reaches the ink (the lamp's shading, the
      part's own interreflection) is scattered back in the ink's colour, so it scales the ink and
      its texture, k in [1 / SHADING, SHADING] varying smoothly over a region's core, one k over
      a region narrower than the blur (a gain follows no blurred step's profile: a scratch's does).

    log LR = (χ²_gone - χ²_light) / 2, the pixels' terms scaled by the region's independent
    samples over its pixels (the photo's noise is correlated over its blur). The region is light
    when that exceeds z² / 2 (the significance of a z-score), ink gone when it is below -z² / 2,
    and not told between.

    Parameters
    ----------
    photo, design, film : (n, 3) float32
        The photo, the design as the exposure fit shows it, and the bare film under the shading,
        at the region's pixels, grey levels.
    light : (3,) float
        The colour of light added (largest channel 1).
    noise : float
        The photo's noise, grey levels (per channel).
    model_err : float
        The design's model's relative error around the region (log units).
    film_sigma : float
        The film's relative uncertainty there (:attr:`FilmLevel.sigma`, log units).
    n_eff : float
        Independent noise samples among the region's pixels.
    z : float
        Significance.
    xy : (n, 2) float, optional
        The pixels' positions (grid px) where they are a region's core, clear of its blurred rim:
        there ink gone shows the film alone (α = 1) and light added varies smoothly; without it
        (a region narrower than the blur) each pixel has its own α and light.
    additive : bool
        The film adds light of its own (glossy), or only scatters what reaches its ink (matte).

    Returns
    -------
    Judgement
    """
    n = len(photo)
    if n == 0:
        return Judgement("not told", 0.0, 0.0, 0.0, 0)
    whole = xy is not None
    P, D, F = linear(photo), linear(design), linear(film)
    clipped = photo >= SATURATED
    # σ in linear light: the noise through the sRGB curve's slope, and the model's relative error
    var = (np.float32(max(noise, 0.5)) * linear_slope(photo)) ** 2 + (model_err * P) ** 2 + 1e-10
    scale = min(1.0, n_eff / n)
    # the film's brightness b has a prior: a Student t of FILM_PRIOR_DOF degrees of freedom on
    # u = log b with scale film_sigma (the film's level is off by more than 3 of its sigmas in a few
    # per cent of places: a Gaussian's tail would call every dropout there light),
    # -2 log p = (ν + 1) log(1 + (u / σ)² / ν)
    fs = max(film_sigma, 1e-3)

    def prior(u: float) -> float:
        return float((FILM_PRIOR_DOF + 1.0) * np.log1p((u / fs) ** 2 / FILM_PRIOR_DOF))

    # over a region's core both hypotheses vary smoothly with the pixel's position, the same way (a
    # second-order surface: the film's brightness for ink gone, as shading and a fold of the
    # surface under it vary; the light added for light, as a glint peaks where the surface mirrors
    # the lamp), so neither wins by following the photo's light across the region better; what
    # tells them is the ink's texture (light keeps it), the film's level (ink gone does not go past
    # it) and the colour (ink gone shows the film's)
    Q = None
    if whole and n >= 12:
        c = (xy - xy.mean(axis=0)) / max(float(np.ptp(xy)), 1.0)
        Q = np.stack([np.ones(n), c[:, 0], c[:, 1], c[:, 0] ** 2, c[:, 0] * c[:, 1], c[:, 1] ** 2], axis=1)
    best_g, share = np.inf, 1.0
    plausible = D  # the best ink gone within the prior's ±3 sigma: what the photo is told from
    if whole:
        # ink gone on the core: the bare film alone, P = b(x) F; b per pixel by least squares
        # (b̂ = Σ_c P F / var / Σ_c F² / var, weight Σ_c F² / var), then the smooth b(x) through them;
        # that, and the same scaled to the prior's bounds (±3 sigma), weighed with the prior
        b_px = smooth_scale(P, F, var, Q)
        mean_b = max(float(np.mean(b_px)), 1e-6)
        u_ls = float(np.log(mean_b))
        u_in = float(np.clip(u_ls, -3.0 * fs, 3.0 * fs))
        plausible = F * (b_px * np.exp(u_in) / mean_b)[:, None]
        for u in (u_ls, u_in):
            model = F * (b_px * np.exp(u) / mean_b)[:, None]
            chi = _chi2(P, model, var, clipped) * scale + prior(u)
            if chi < best_g:
                best_g = chi
    else:
        # a region narrower than the blur: each pixel's share of the step to the film, in [0, 1]
        # (blur mixes its pixels), for each film brightness on a grid over ±6 film_sigma
        best_in = np.inf
        for u in np.linspace(-6.0, 6.0, 49) * fs:
            step = np.exp(u) * F - D
            den = (step * step / var).sum(axis=1)
            a = np.clip(((P - D) * step / var).sum(axis=1) / np.maximum(den, 1e-12), 0.0, 1.0)
            model = D + a[:, None] * step
            data = _chi2(P, model, var, clipped) * scale
            chi = data + prior(u)
            if chi < best_g:
                best_g, share = chi, float(a.mean())
            if abs(u) <= 3.0 * fs + 1e-9 and data < best_in:
                best_in, plausible = data, model
    # light added: for each gain on a grid over the allowance, the light added in closed form:
    # per pixel on a thin region (only its direction and the film's level tell it from ink gone),
    # the smooth surface over a region's core (a glint varies smoothly; the ink's texture does not,
    # and light keeps it), from each pixel's own estimate ŝ = Σ_c (P - kD) L / var / Σ_c L² / var
    # weighted by Σ_c L² / var
    Lc = linear(255.0 * np.asarray(light, np.float32))[None, :]
    best_l, added, gain = np.inf, 0.0, 1.0
    if not additive:
        # a matte film: P = k D. k per pixel by least squares (k̂ = Σ_c P D / var / Σ_c D² / var,
        # weight Σ_c D² / var), then the smooth k(x) through them over a core; no light of its own,
        # so a region stepped to the film over textured ink needs the texture scaled with it, which
        # the film's flat colour does not show
        k_px = smooth_scale(P, D, var, Q)
        # (within the colour test's shading allowance, as light added's k: more light than that on
        # a region's ink, sharp-edged, is another ink, not light)
        k_px = np.clip(k_px, 1.0 / SHADING, SHADING)
        model_l = D * k_px[:, None]
        best_l = _chi2(P, model_l, var, clipped) * scale
        added, gain = max(float(np.median(np.max(model_l - D, axis=1))), 0.0), float(np.median(k_px))
    wl = (Lc * Lc / var).sum(axis=1)
    if Q is not None:
        Qw = Q * np.sqrt(wl)[:, None]
    # (the gain k is shading: a region's own, within SHADING; a line narrower than the blur has its
    # surroundings' shading, which the model already holds, k = 1: with a gain of its own, white
    # light over ink dimmed by k mimics a blurred scratch's partial step to the film)
    gains = np.exp(np.linspace(-np.log(SHADING), np.log(SHADING), 21)) if whole else np.ones(1)
    for k in gains if additive else ():
        s_px = ((P - k * D) * Lc / var).sum(axis=1) / np.maximum(wl, 1e-12)
        if Q is not None:
            coef = np.linalg.lstsq(Qw, s_px * np.sqrt(wl), rcond=None)[0]
            s_px = Q @ coef
        s_px = np.maximum(s_px, 0.0)
        model = k * D + s_px[:, None] * Lc
        chi = _chi2(P, model, var, clipped) * scale
        if chi < best_l:
            best_l, added, model_l, gain = chi, float(np.median(s_px)), model, float(k)
    log_lr = 0.5 * (best_g - best_l)
    added_grey = float(grey_levels(np.float32(added)))
    # the two explanations must predict photos that differ: by at least one standard deviation per
    # independent sample on average (where a clipped channel hides both, they do not differ);
    # otherwise however the ratio falls, it falls on the models' errors, not on the photo
    d = np.where(clipped & (plausible >= SATURATED_LIN) & (model_l >= SATURATED_LIN), 0.0, plausible - model_l)
    separation = float(np.sqrt((d * d / var).sum() / max(3 * n, 1)))
    cut = 0.5 * z * z
    if separation < 1.0:
        hypothesis = "not told"
    else:
        hypothesis = "light" if log_lr > cut else ("ink gone" if log_lr < -cut else "not told")
    return Judgement(hypothesis, float(log_lr), share, added_grey, n, separation, gain)


INNER_SHARE = 0.4  # a broad region is judged on its pixels at least this share of its largest depth inside
MIN_CORE_PX = 12  # ... where that leaves this many
RING_PX = 8  # the ring around a region whose model error is its allowance, grid px wide


def model_error(
    photo: np.ndarray, pred: np.ndarray, measured: np.ndarray, region: np.ndarray, box: tuple, noise: float
) -> float:
    """How far the design's model misses the photo around a region, beyond the noise (relative, log units).

    The robust variance of log(P / D) over the ring of RING_PX around the region, less the
    noise's share of it (its median relative variance there); 0 where the ring is empty.

    Parameters
    ----------
    photo, pred : (H, W, 3) float32
        Grey levels.
    measured : (H, W) bool
        Pixels the model is judged on.
    region : (h, w) bool
        The region, in ``box``.
    box : tuple of slice
        The region's bounding box in the grid.
    noise : float
        The photo's noise, grey levels.

    Returns
    -------
    float
    """
    H, W = measured.shape
    y0, x0 = max(0, box[0].start - RING_PX), max(0, box[1].start - RING_PX)
    y1, x1 = min(H, box[0].stop + RING_PX), min(W, box[1].stop + RING_PX)
    inside = np.zeros((y1 - y0, x1 - x0), np.uint8)
    inside[box[0].start - y0 : box[0].stop - y0, box[1].start - x0 : box[1].stop - x0] = region
    grown = cv2.dilate(inside, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * RING_PX + 1,) * 2))
    ring = (grown > 0) & (inside == 0) & measured[y0:y1, x0:x1]
    if ring.sum() < 10:
        return 0.0
    ph, pr = photo[y0:y1, x0:x1][ring], pred[y0:y1, x0:x1][ring]
    P, D = linear(ph), linear(pr)
    r = np.log(np.maximum(P, 1e-6) / np.maximum(D, 1e-6))
    srel = np.float32(max(noise, 0.5)) * linear_slope(ph) / np.maximum(P, 1e-6)
    ok = (srel < MAX_REL_NOISE) & (D > 1e-4)
    if ok.sum() < 10:
        return 0.0
    spread = 1.4826 * float(np.median(np.abs(r[ok] - np.median(r[ok]))))
    return float(np.sqrt(max(spread * spread - float(np.median(srel[ok] ** 2)), 0.0)))


def region_core(region: np.ndarray, blur_px: float) -> np.ndarray:
    """The region's pixels farther than twice the photo's blur and a pixel from its rim (all of it where none are).

    At the rim the photo mixes the region with its surroundings over about twice the blur's
    sigma; the core shows the region alone.

    Parameters
    ----------
    region : (h, w) bool
    blur_px : float
        The photo's blur on the grid (Gaussian sigma, grid px).

    Returns
    -------
    (h, w) bool
    """
    # (the closing of the colour test's pixels and the pixel's own extent add a pixel to the rim)
    d = cv2.distanceTransform(np.pad(region, 1).astype(np.uint8), cv2.DIST_L2, 3)[1:-1, 1:-1]
    # a line of half-width h blurred by σ reaches 99 % of its contrast at its middle where
    # erf(h / (√2 σ)) ≥ 0.99, h ≥ 2.6 σ; σ the photo's blur and a grid pixel's own (the warp's
    # interpolation), in quadrature (at 2 σ of the blur alone a 0.5 mm scratch kept a core, was
    # asked to show the film alone, which its blurred middle never does, and was taken for light)
    core = d > 2.6 * float(np.hypot(blur_px, 1.0)) + 1.0
    # (and the inner part of a broad region: the rim's ramp spans the photo's own blur, the render's
    # and the warp's interpolation, wider than the blur the flow measured; a dropout of 20 px radius
    # kept 18 grey levels of spread in its core at 2 blur, 7 (its noise) within 0.4 of its radius)
    inner = core & (d >= INNER_SHARE * float(d.max()))
    if inner.sum() >= MIN_CORE_PX:
        return inner
    return core if core.sum() >= 4 else region


EXPLAINS = 0.9  # share of a region's pixels the light hypothesis must bring within the colour limit to explain it


@dataclass(frozen=True)
class RegionVerdicts:
    """Each region of the colour residual judged (:func:`judge_regions`).

    Attributes
    ----------
    labels : (H, W) int32
        Region number per pixel (0: none).
    light : (H, W) bool
        Pixels of regions light explains significantly better than ink gone: not defects.
    not_told : (H, W) bool
        Pixels of regions of ink gone or light that the photo cannot tell apart.
    judgements : dict of int to dict
        Per region number, :meth:`Judgement.as_dict` and ``explained`` (the share of its pixels
        the light hypothesis brings within the colour limit) and ``had_ink_gone``.
    """

    labels: np.ndarray
    light: np.ndarray
    not_told: np.ndarray
    judgements: dict


def judge_regions(
    colour_bad: np.ndarray,
    gone: np.ndarray,
    photo: np.ndarray,
    pred: np.ndarray,
    film: np.ndarray,
    light: np.ndarray,
    colour_limit: np.ndarray,
    noise: float,
    film_sigma: np.ndarray,
    measured: np.ndarray,
    blur_px: np.ndarray,
    samples_per_px: np.ndarray | float,
    z: float,
    additive: bool = True,
) -> RegionVerdicts:
    """Every region of the colour residual judged by the photometric model (:func:`judge_region`).

    A region with pixels stepped towards the bare film (``gone``) is ink gone, light, or not told
    by the likelihood ratio on its core (:func:`region_core`). A region with none is light only
    where light added explains it (EXPLAINS of its pixels within the colour limit) and the ratio
    favours light; it stays a colour defect otherwise.

    Parameters
    ----------
    colour_bad, gone : (H, W) bool
        Pixels beyond the colour test, and those stepped towards the bare film's colour.
    photo, pred : (H, W, 3) float32
        The photo on the print and the design as the exposure fit shows it, grey levels.
    film : (H, W, 3) float32
        The bare film under the shading, grey levels (:func:`grey_levels` of :attr:`Shading.film`).
    light : (3,) float
        The colour of light added (largest channel 1).
    colour_limit : (H, W) float32
        The colour test's limit, grey levels.
    noise : float
        The photo's noise per channel, grey levels.
    film_sigma : (H, W) float32
        :attr:`FilmLevel.sigma`.
    measured : (H, W) bool
        Pixels whose photo the design's model is judged on around a region (scored, within the
        colour limit): the model's own error there is each region's allowance.
    blur_px : (H, W) float32
        The photo's blur on the grid (Gaussian sigma, grid px).
    samples_per_px : float or (H, W) float
        Independent noise samples per grid pixel (1 / the area the noise is correlated over).
    z : float
        Significance.
    additive : bool
        The film adds light of its own (glossy) or only scatters what reaches its ink (matte):
        :func:`judge_region`.

    Returns
    -------
    RegionVerdicts
    """
    H, W = colour_bad.shape
    light_px = np.zeros((H, W), bool)
    not_told = np.zeros((H, W), bool)
    bad = cv2.morphologyEx(colour_bad.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    n, lab, st, _ = cv2.connectedComponentsWithStats(bad, connectivity=8)
    judgements: dict = {}
    spp = np.broadcast_to(np.asarray(samples_per_px, np.float32), (H, W))
    Lc = np.asarray(light, np.float32)
    Lg = np.broadcast_to(Lc, (1, 3))
    for r in range(1, n):
        x0, y0, w, h, _ = st[r]
        box = (slice(y0, y0 + h), slice(x0, x0 + w))
        region = lab[box] == r
        core = region_core(region, float(np.median(blur_px[box][region])))
        P, D, F = photo[box][core], pred[box][core], film[box][core]
        j = judge_region(
            P, D, F, Lc, noise, model_error(photo, pred, measured, region, box, noise),
            float(np.median(film_sigma[box][core])), float(spp[box][core].sum()), z,
            np.argwhere(core).astype(np.float64) if (core != region).any() else None, additive,
        )  # fmt: skip
        # how much of the region light brings within the colour limit (its own fit per pixel: light
        # added, or on a matte film the gain)
        Pl, Dl = linear(photo[box][region]), linear(pred[box][region])
        if additive:
            Ll = linear(255.0 * Lg)
            s = np.maximum(((Pl - Dl) * Ll).sum(axis=1) / max(float((Ll * Ll).sum()), 1e-9), 0.0)
            fit = grey_levels(Dl + s[:, None] * Ll)
        else:
            k = (Pl * Dl).sum(axis=1) / np.maximum((Dl * Dl).sum(axis=1), 1e-12)
            fit = grey_levels(Dl * np.clip(k, 1.0 / SHADING, SHADING)[:, None])
        ph = photo[box][region]
        res = np.abs(np.where((ph >= SATURATED) & (fit >= ph), 0.0, ph - fit)).max(axis=1)
        explained = float(np.mean(res <= colour_limit[box][region]))
        stepped = bool(gone[box][region].any())
        record = {**j.as_dict(), "explained": round(explained, 3), "had_ink_gone": stepped}
        if stepped:
            if j.hypothesis == "light":
                light_px[box] |= region
            elif j.hypothesis == "not told":
                not_told[box] |= region
        elif j.hypothesis == "light" and explained >= EXPLAINS:
            light_px[box] |= region
        elif j.hypothesis == "not told" and explained >= EXPLAINS:
            not_told[box] |= region
        else:
            record["hypothesis"] = "colour" if j.hypothesis != "light" else "colour (light does not explain it)"
        judgements[r] = record
    return RegionVerdicts(lab.astype(np.int32), light_px, not_told, judgements)


MAX_LISTED = 50  # regions not counted that validation.json lists (the largest); the rest are in the maps


def judgement_at(region: np.ndarray, verdicts: RegionVerdicts) -> dict | None:
    """The judgement of the judged region that covers most of ``region`` ((H, W) bool); None: none does."""
    k = verdicts.labels[region]
    k = k[k > 0]
    if not len(k):
        return None
    return verdicts.judgements.get(int(np.bincount(k).argmax()))


def not_counted_regions(causes: dict, verdicts: RegionVerdicts, px_per_mm: float, min_mm2: float) -> list[dict]:
    """The regions left out of the defects, each with what decided it.

    Parameters
    ----------
    causes : dict of str to (H, W) bool
        Why a pixel is not counted, in words (``"light: brighter than the bare film could be"``,
        ...); a region takes the cause that covers most of it.
    verdicts : RegionVerdicts
        The photometric judgements, attached where a judged region lies under the region.
    px_per_mm : float
        The grid's resolution.
    min_mm2 : float
        Smaller regions are not listed.

    Returns
    -------
    list of dict
        At most MAX_LISTED, largest first: ``centre_mm`` (print, x right, y down), ``area_mm2``
        and ``decided_by`` (``cause`` and, where judged, the judgement).
    """
    names = list(causes)
    if not names:
        return []
    H, W = verdicts.labels.shape
    which = np.zeros((H, W), np.uint8)
    for i, name in enumerate(names):
        which[(which == 0) & causes[name]] = i + 1
    n, lab, st, cen = cv2.connectedComponentsWithStats((which > 0).astype(np.uint8), connectivity=8)
    mm2 = 1.0 / (px_per_mm * px_per_mm)
    out = []
    for r in np.argsort(-st[1:, cv2.CC_STAT_AREA]) + 1:
        area = float(st[r, cv2.CC_STAT_AREA]) * mm2
        if area < min_mm2 or len(out) >= MAX_LISTED:
            break
        x0, y0, w, h, _ = st[r]
        box = (slice(y0, y0 + h), slice(x0, x0 + w))
        region = lab[box] == r
        cause = names[int(np.bincount(which[box][region], minlength=len(names) + 1)[1:].argmax())]
        decided = {"cause": cause}
        full = np.zeros((H, W), bool)
        full[box] = region
        j = judgement_at(full, verdicts)
        if j is not None:
            decided["judgement"] = j
        cx, cy = cen[r]
        out.append(
            {
                "centre_mm": [round((cx + 0.5) / px_per_mm, 2), round((cy + 0.5) / px_per_mm, 2)],
                "area_mm2": round(area, 2),
                "decided_by": decided,
            }
        )
    return out
