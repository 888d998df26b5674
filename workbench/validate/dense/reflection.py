"""What a glossy film can mirror of the room towards the camera: Fresnel's share of the brightest white.

A glossy film is a dielectric: besides the ink it shows, its surface mirrors whatever lies in
the mirror direction, by Fresnel's reflectance at the angle it is seen under (4 to 5 % face on,
18 % at 70°, 40 % at 80°). A lamp mirrored so is a highlight, and the photometric model takes
it for light where the photo shows it (:mod:`workbench.validate.dense.light`). The rest of what
surrounds the part (the fixture's plate with its white squares, the table, the room's walls, a
soft sky) is mirrored too, and on dark ink near the part's silhouette its reflection of white
paper brightens the ink with the sharp edges of the plate's squares: as ink that is gone does.
The photo does not say how glossy the film is, nor what lies in each mirror direction; it says
how bright a white surface is under its light (the bare film the ink around shows). A
reflection of the room, the lamps apart, is no brighter than that white; a film no glossier
than a bare dielectric surface. So at each pixel the light the room can add is at most
``fresnel_reflectance(cos_i) * white``: a brightening within it is explained by a reflection
as well as by ink gone, and is not counted as either; where ink that is gone would brighten
the ink by no more than that, ink gone is not found there.
"""

from __future__ import annotations

import numpy as np

from workbench.validate.photometric import linear, linear_slope

# the film's refractive index, at the high end of the films a part is decorated with (PMMA 1.49,
# polycarbonate 1.58, PET 1.57 to 1.65): a higher index reflects more, so the bound holds for all
FILM_INDEX = 1.65
# linear-light luminance of a linear sRGB colour (Rec. 709 primaries, as sRGB's)
LUMINANCE = np.array([0.2126, 0.7152, 0.0722], np.float32)


def fresnel_reflectance(cos_i: np.ndarray, n: float = FILM_INDEX) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a dielectric surface seen at incidence ``arccos(cos_i)`` from air.

    Snell's law gives the refracted angle, sin_t = sin_i / n; the two polarisations reflect
    r_s = ((cos_i - n cos_t) / (cos_i + n cos_t))^2 and r_p = ((cos_t - n cos_i) / (cos_t + n cos_i))^2,
    and unpolarised light their mean (((n - 1) / (n + 1))^2 face on, 1 at grazing incidence).

    Parameters
    ----------
    cos_i : array of float
        Cosine of the angle between the surface normal and the direction to the camera, 0 to 1.
    n : float
        Refractive index of the film.

    Returns
    -------
    array of float32, the same shape
        Share of the incident light the surface mirrors, 0 to 1.
    """
    c = np.clip(np.asarray(cos_i, np.float32), np.float32(0.0), np.float32(1.0))
    sin_t = np.sqrt(np.float32(1.0) - c * c) / np.float32(n)
    cos_t = np.sqrt(np.float32(1.0) - sin_t * sin_t)
    rs = ((c - n * cos_t) / (c + n * cos_t)) ** 2
    rp = ((cos_t - n * c) / (cos_t + n * c)) ** 2
    return (0.5 * (rs + rp)).astype(np.float32)


def room_reflection(X: np.ndarray, normal: np.ndarray, camera_center: np.ndarray, white: float) -> np.ndarray:
    """The most light a glossy film adds at each grid pixel by mirroring the room (its lamps apart).

    Parameters
    ----------
    X : (H, W, 3) float
        Surface point under each grid pixel, mm (NaN off the part).
    normal : (H, W, 3) float
        Unit surface normal there (NaN off the part).
    camera_center : (3,) float
        The photo's camera centre, mm, in the frame of ``X``.
    white : float
        Luminance of the brightest white the photo shows (the bare film under its light), linear light 0 to 1.

    Returns
    -------
    (H, W) float32
        Linear-light luminance: ``fresnel_reflectance(|n · v|) * white`` (v the unit vector to the
        camera); NaN off the part.
    """
    v = np.asarray(camera_center, np.float32)[None, None, :] - X.astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        v /= np.sqrt(np.sum(v * v, axis=-1, keepdims=True))
        cos_i = np.abs(np.sum(v * normal.astype(np.float32), axis=-1))
    out = fresnel_reflectance(np.nan_to_num(cos_i, nan=1.0)) * np.float32(white)
    out[~np.isfinite(cos_i)] = np.nan
    return out


def luminance(lin: np.ndarray) -> np.ndarray:
    """Linear-light luminance of (..., 3) linear sRGB colours; float32 (...)."""
    lin = np.asarray(lin, np.float32)
    return lin[..., 0] * LUMINANCE[0] + lin[..., 1] * LUMINANCE[1] + lin[..., 2] * LUMINANCE[2]


def within_room_reflection(
    photo: np.ndarray,
    pred: np.ndarray,
    film: np.ndarray,
    seen: np.ndarray,
    X: np.ndarray,
    normal: np.ndarray,
    camera_center: np.ndarray,
    noise: float,
    z: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Where the photo's brightening over the design, and where ink gone, lie within the room's reflection.

    The room's reflection is bounded (:func:`room_reflection`) by the brightest white the photo
    shows: the bare film under its light, its 99th percentile over the photo (the part's best-lit
    film). Both tests allow ``z`` times the photo's noise, taken to linear light at the design's
    level through the sRGB curve's slope.

    Parameters
    ----------
    photo, pred, film : (H, W, 3) float32
        The photo on the print, the design as the photo's model shows it, and the bare film
        under its light; grey levels (sRGB-encoded).
    seen : (H, W) bool
        Pixels of the part the photo sees.
    X, normal : (H, W, 3) float
        Surface point (mm) and unit normal under each pixel (NaN off the part).
    camera_center : (3,) float
        The photo's camera centre, mm, in the frame of ``X``.
    noise : float
        The photo's noise per channel, grey levels.
    z : float
        Significance, standard deviations.

    Returns
    -------
    explained : (H, W) bool
        The photo is no brighter than the design by more than the room's reflection there.
    mimics : (H, W) bool
        Ink that is gone (the bare film in the ink's place) would be no brighter than that.
    """
    lum_pred = luminance(linear(pred))
    films = luminance(linear(film[seen][::97])) if seen.any() else np.ones(1, np.float32)
    white = float(np.percentile(films, 99))
    room = room_reflection(X, normal, camera_center, white)
    allow = np.float32(z * noise) * luminance(linear_slope(pred))
    with np.errstate(invalid="ignore"):
        explained = luminance(linear(photo)) - lum_pred <= room + allow
        mimics = luminance(linear(film)) - lum_pred <= room + allow
    return explained, mimics
