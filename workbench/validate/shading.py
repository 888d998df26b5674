"""The light a surface receives in one photo, as a function of its normal, fitted over the whole part."""

from __future__ import annotations

import numpy as np

from workbench.validate.photometric import grey_levels, linear

# A matte surface under distant light receives E(n) = ∫ L(ω) max(0, n · ω) dω, whose spherical-
# harmonic expansion is 99 % in its first nine terms (Ramamoorthi & Hanrahan 2001: the clamped
# cosine kernel's coefficients fall as l^-5/2 and vanish for odd l > 1): second order describes
# the shading of a photo's lamps, ambient and sky alike by nine numbers per channel. (A lamp's
# clamped cosine added as a tenth term, its direction fitted, explained the lamp's terminator
# better in relative terms but made perfect renders of the cow worse: 2 false defects against 0.)
SH_TERMS = 9
# The fit's sample: every SAMPLE_STEP-th scored grid pixel, at most MAX_SAMPLES of them (a grid
# holds up to 4 million; nine unknowns per channel need thousands, not millions, of samples: a
# 12 Mpx photo's 300,000 took 0.3 s over the three channels)
SAMPLE_STEP = 7
MAX_SAMPLES = 100_000
SHADE_CHUNK = 262_144  # normals evaluated at once (:func:`shading_factor`)
# Tukey's biweight, with the residuals' scale from their median absolute deviation: a
# constant at 95 % efficiency for Gaussian noise. Cast shadows, glints and defects, which no
# function of the normal explains, weigh nothing once beyond it.
TUKEY_C = 4.685
IRLS_ROUNDS = 8
# The scale is at least SCALE_FLOOR of the photo's level (below an 8-bit photo's quantisation: a
# fit that leaves almost nothing does not cast out all but its closest samples) and at most
# SCALE_CAP of it: a light that is right leaves the photo's noise and its own error, |ln| 0.017 to
# 0.047 (the mean of the better 80 %, on samples it was not fitted to) on perfect photos of the
# lily and the face by both renderers, Mitsuba's 8 samples a pixel included; a scale drawn from a
# part half painted over called the paint explained.
SCALE_FLOOR = 1e-3
SCALE_CAP = 0.1
# A light that explains less than this share of the part's samples is not the light: an
# M-estimator breaks down well before half of its data are wrong (half of a part painted over
# bent the harmonics to explain the paint, and the decoration's loss was explained away). Then
# the local fit works alone, as without a model of the light.
MIN_INLIER_SHARE = 2.0 / 3.0
# A design darker than this (linear light) says nothing of the light on it: ink near black
# shows the photo's black level and flare, not the shading.
MIN_ALBEDO = 0.02
# The ridge on the eight directional terms, relative to the mean squared albedo: where the
# part's normals span little of the sphere (a flat part) they are not determined and stay near
# zero (constant shading, as the local exposure fit then models it alone). Over a hemisphere the
# harmonics are nearly dependent and a ridge bends the light along what the normals do not tell
# apart: at 1e-3 the fitted light erred by up to 70 % at the hemisphere's rim, at 1e-6 by 0.015 %
# there and by 0.08 % over a flat part (tests/test_shading.py's cases, without noise).
RIDGE = 1e-6


def sh_basis(normal: np.ndarray, dtype=np.float64) -> np.ndarray:
    """The nine real spherical harmonics up to second order at unit normals (unnormalised).

    Parameters
    ----------
    normal : (..., 3) float
        Unit normals.
    dtype : numpy dtype
        Of the result (float64 for the fit; float32 where the light is only evaluated).

    Returns
    -------
    (..., 9) ``dtype``
        1, x, y, z, xy, xz, yz, x² − y², 3z² − 1 (the constant factors of the orthonormal basis
        are absorbed by the coefficients).
    """
    x, y, z = (np.asarray(normal[..., k], dtype) for k in range(3))
    return np.stack([np.ones_like(x), x, y, z, x * y, x * z, y * z, x * x - y * y, 3 * z * z - 1], axis=-1)


def fit_irradiance(
    albedo: np.ndarray, observed: np.ndarray, normal: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """The weights of :func:`sh_basis` that make ``observed ≈ albedo · E(n)``, robustly, and the samples they explain.

    Iteratively reweighted least squares with Tukey's biweight (the residuals' scale from the
    kept samples' median absolute deviation), a small ridge on the eight directional harmonics.

    Parameters
    ----------
    albedo, observed : (n,) float
        The surface's colour as designed and as seen, in linear light (one channel, or Y).
    normal : (n, 3) float
        Unit surface normals.

    Returns
    -------
    coef : (9,) float64
    inlier : (n,) bool
        The samples the fit explains (Tukey weight above zero in its last round).
    None when fewer than 10 samples per unknown have an albedo of at least MIN_ALBEDO.
    """
    keep = np.asarray(albedo) >= MIN_ALBEDO
    if keep.sum() < 10 * SH_TERMS:
        return None
    a = np.asarray(albedo, np.float64)[keep]
    M = sh_basis(np.asarray(normal)[keep]) * a[:, None]  # albedo · (c · basis(n)): linear in c
    y = np.asarray(observed, np.float64)[keep]
    ridge = RIDGE * float(np.mean(a * a)) * len(y) * np.eye(SH_TERMS)
    ridge[0, 0] = 0.0  # (the constant term, the exposure, is free)
    # the start: one light for every normal, its level the median ratio. An M-estimator keeps the
    # solution it starts near; from least squares over everything, half of a part painted over
    # bent the harmonics to explain the paint (from 0.4 to 1.6 of the median across a shallow
    # dome), and then explained it away. From an even light, what no light explains weighs
    # nothing from the first round.
    coef = np.zeros(SH_TERMS)
    coef[0] = float(np.median(y / a))
    level = float(np.median(np.abs(y)))
    r = y - M @ coef
    w = _tukey_weights(r, r, level)
    for _ in range(IRLS_ROUNDS):
        Mw = M * w[:, None]
        coef = np.linalg.lstsq(Mw.T @ M + ridge, Mw.T @ y, rcond=1e-12)[0]
        r = y - M @ coef
        # (the scale from the samples the last round kept: the outliers do not inflate it)
        w = _tukey_weights(r, r[w > 0], level)
    inlier = np.zeros(len(keep), bool)
    inlier[np.flatnonzero(keep)] = w > 0
    return coef, inlier


def _tukey_weights(r: np.ndarray, kept: np.ndarray, level: float) -> np.ndarray:
    """Tukey's biweight of residuals ``r``, its scale from the residuals ``kept`` (MAD) within
    SCALE_FLOOR and SCALE_CAP of the photo's ``level``; (n,) float64."""
    s = min(max(1.4826 * float(np.median(np.abs(kept))), SCALE_FLOOR * level, 1e-12), SCALE_CAP * level)
    u = r / (TUKEY_C * s)
    return np.where(np.abs(u) < 1.0, (1.0 - u * u) ** 2, 0.0)


def fit_shading(photo: np.ndarray, design: np.ndarray, normal: np.ndarray, weight: np.ndarray) -> np.ndarray | None:
    """The light of a photo on the print's grid: photo ≈ design · E(n) per channel, in linear light.

    The photo of a matte film in linear light is its albedo (the design, as printed) times the
    irradiance E at the surface normal, E(n) = c · Y(n) per channel (:func:`sh_basis`), fitted
    by :func:`fit_irradiance` over a sample of the pixels that may inform it.

    Parameters
    ----------
    photo, design : (H, W, 3) float32
        Photo and design on the print's grid, grey levels.
    normal : (H, W, 3) float32
        Unit surface normal per pixel (NaN off the part).
    weight : (H, W) bool or float
        Where the pixel may inform the fit (scored, not clipped).

    Returns
    -------
    (3, 9) float64 or None
        Coefficients per channel (a channel without enough samples: constant light); None when
        no channel has enough samples, or when the light explains less than MIN_INLIER_SHARE of
        them.
    """
    ok = (np.asarray(weight) > 0) & np.isfinite(normal).all(axis=-1)
    idx = np.flatnonzero(ok.ravel())
    idx = idx[:: max(SAMPLE_STEP, -(-len(idx) // MAX_SAMPLES))]
    n = normal.reshape(-1, 3)[idx]
    A = linear(design.reshape(-1, 3)[idx])
    P = linear(photo.reshape(-1, 3)[idx])
    fits = [fit_irradiance(A[:, c], P[:, c], n) for c in range(3)]
    if all(f is None for f in fits):
        return None
    one = np.zeros(SH_TERMS)
    one[0] = 1.0
    coef = np.stack([one if f is None else f[0] for f in fits])
    # (a sample supports the light where every channel the fit used explains it)
    inlier = np.logical_and.reduce([f[1] for f in fits if f is not None])
    # (of the samples every such channel could use: dark ink tells nothing, and is no outlier)
    usable = np.logical_and.reduce([A[:, c] >= MIN_ALBEDO for c in range(3) if fits[c] is not None])
    if inlier.sum() < MIN_INLIER_SHARE * max(int(usable.sum()), 1):
        return None
    return coef


def shading_factor(normal: np.ndarray, coef: np.ndarray | None) -> np.ndarray:
    """The irradiance E(n) at every pixel relative to its median, linear light.

    Parameters
    ----------
    normal : (H, W, 3) float32
        Unit surface normals (NaN off the part).
    coef : (3, 9) float or None
        :func:`fit_shading`'s coefficients (None: no model of the light, 1 everywhere).

    Returns
    -------
    (H, W, 3) float32
        E(n) / median E over the part, at least 1/100 (1 off the part): the photo's exposure stays
        with the local fit, which this factor only relieves of the shading.
    """
    H, W = normal.shape[:2]
    if coef is None:
        return np.ones((H, W, 3), np.float32)
    # the basis times the coefficients in chunks, over the whole grid (off the part a NaN normal
    # gives a NaN light, replaced at the end): a 4 Mpx grid's (n, 9) basis in float64 would hold
    # 290 MB, and gathering the part's pixels and scattering them back took 0.4 s of 0.55
    flat = normal.reshape(-1, 3)
    E = np.empty((len(flat), 3), np.float32)
    for start in range(0, len(flat), SHADE_CHUNK):
        E[start : start + SHADE_CHUNK] = irradiance(flat[start : start + SHADE_CHUNK], coef)
    # (the median over an evenly thinned sample of the part: a normalisation the local exposure
    # fit takes over)
    sample = E[:: max(1, len(E) // MAX_SAMPLES)]
    sample = sample[np.isfinite(sample).all(axis=1)]
    med = np.median(sample, axis=0) if len(sample) else np.ones(3, np.float32)
    E /= np.where(med > 0, med, 1.0).astype(np.float32)
    # (NaN compares false: off the part the factor is 1)
    return np.where(E >= 0.01, E, np.where(np.isnan(E), np.float32(1.0), np.float32(0.01))).reshape(H, W, 3)


def irradiance(normal: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """The light E(n) per channel at unit normals, as :func:`fit_shading` fitted it (not relative to a median).

    Parameters
    ----------
    normal : (n, 3) float
        Unit normals.
    coef : (3, 9) float
        :func:`fit_shading`'s coefficients.

    Returns
    -------
    (n, 3) float32
        Linear light, in the photo's units over the design's albedo.
    """
    return sh_basis(np.asarray(normal), np.float32) @ np.asarray(coef, np.float32).T


def shaded(design: np.ndarray, factor: np.ndarray) -> np.ndarray:
    """The design as the shading shows it: its linear light times the factor, back in grey levels.

    Parameters
    ----------
    design : (H, W, 3) float32
        Grey levels.
    factor : (H, W, 3) float32
        :func:`shading_factor`.

    Returns
    -------
    (H, W, 3) float32
        Grey levels (not clipped: a shading above the median brightens the film's white past 255).
    """
    return grey_levels(linear(design) * factor)
