"""What can go wrong between the design and a photo of the real part, each off by default."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np


@dataclass(frozen=True)
class Imperfections:
    """Imperfections of the decoration and of the photo.

    Film and print (print coordinates: mm from the trim's top-left corner, x right,
    y down, as the print is seen from its printed side):

    Attributes
    ----------
    film_offset_mm : (2,) float
        Where the film sits relative to where it should: the print moves by this on the part.
    film_offsets_mm : tuple of (film, dx, dy)
        With several films, each listed film (1-based) moved on its own, mm.
    film_rotation_deg : float
        Film rotated about the print's centre, counter-clockwise seen on the print.
    film_scale_pct : float
        Film uniformly larger by this percentage (about the print's centre).
    print_scale_pct : (2,) float
        Printer scale error in x and y, percent (about the print's centre).

    Photo:

    distortion : (5,) float
        Lens distortion (k1, k2, p1, p2, k3) of the camera taking the photo.
    blur_px : float
        Gaussian blur sigma, photo pixels.
    noise : float
        Gaussian noise sigma, grey levels (0 to 255).
    exposure : float
        Multiplies linear intensity.
    gamma : float
        Output = input ** (1 / gamma).
    shading : bool
        Lambertian shading from ``light`` plus ``ambient``.
    light : (3,) float
        Direction towards the light, world frame.
    ambient : float
        Share of light that does not depend on the surface's direction.
    gloss : float
        Specular reflection of the film (0: matte): a white highlight of this strength
        (share of full scale) where the surface mirrors the light towards the camera
        (Blinn-Phong), added on the part only, not on the fixture's paper.
    shininess : float
        Blinn-Phong exponent: larger is a smaller, sharper highlight.
    vignetting : float
        Brightness falls by this share at the image corners (quadratic in radius).
    jpeg_quality : int or None
        JPEG round trip at this quality.
    seed : int
        Seed of the noise.
    defects : tuple of str
        Local film defects (:mod:`workbench.render.defects` specification strings).
    colour_shift_lab : (3,) float
        Every colour of the print shifted by (ΔL*, Δa*, Δb*) in CIELAB D50 (a wrong ink,
        profile or press): the truth for colour QA.
    white_balance : (3,) float
        Linear gains per channel on the whole scene (part and fixture alike): a coloured light.

    The part on its plate (:mod:`workbench.validate.seating` defines the motion):

    part_offset_mm : (3,) float
        The part's centre (its bounding box's centre) moved by this, mesh frame, mm.
    part_rotation_deg : (3,) float
        The part turned about its centre by (rx, ry, rz): ``R = Rz Ry Rx``, about the mesh
        frame's axes. A design point X is then at ``R X + t``.
    """

    film_offset_mm: tuple[float, float] = (0.0, 0.0)
    film_offsets_mm: tuple[tuple[int, float, float], ...] = ()
    film_rotation_deg: float = 0.0
    film_scale_pct: float = 0.0
    print_scale_pct: tuple[float, float] = (0.0, 0.0)
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    blur_px: float = 0.0
    noise: float = 0.0
    exposure: float = 1.0
    gamma: float = 1.0
    shading: bool = False
    light: tuple[float, float, float] = (0.3, -0.5, 1.0)
    ambient: float = 0.35
    gloss: float = 0.0
    shininess: float = 80.0
    vignetting: float = 0.0
    jpeg_quality: int | None = None
    seed: int = 0
    defects: tuple = ()
    colour_shift_lab: tuple[float, float, float] = (0.0, 0.0, 0.0)
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    part_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    part_rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "defects", tuple(self.defects))  # a list from a truth file, hashable again

    def to_dict(self) -> dict:
        d = asdict(self)
        d.pop("extra")
        d["defects"] = list(self.defects)
        return d


REALISTIC = {"blur_px": 1.0, "noise": 3.0, "jpeg_quality": 90, "shading": True, "vignetting": 0.15}


def film_transform(imp: Imperfections, print_size_mm: tuple[float, float]) -> np.ndarray:
    """The print point a surface point shows, as an affine map of the point it should show.

    The printer scales the print about its centre c by S; the film is then scaled by
    the film scale, rotated by θ about c and moved by d. A surface point that should
    show print point p shows q with p = c + R(θ) s S (q - c) + d, so
    q = c + (s S)⁻¹ R(θ)⁻¹ (p - c - d).

    Parameters
    ----------
    imp : Imperfections
        Film and print imperfections.
    print_size_mm : (2,) float
        Width and height of the print, mm.

    Returns
    -------
    A : (2, 3) float
        ``q = A [p, 1]``, print mm (x right, y down).
    """
    c = 0.5 * np.asarray(print_size_mm, dtype=np.float64)
    t = np.radians(imp.film_rotation_deg)
    # counter-clockwise as seen on the print, whose y axis points down
    R = np.array([[np.cos(t), np.sin(t)], [-np.sin(t), np.cos(t)]])
    S = np.diag([1 + imp.print_scale_pct[0] / 100, 1 + imp.print_scale_pct[1] / 100]) * (1 + imp.film_scale_pct / 100)
    M = np.linalg.inv(R @ S)
    d = np.asarray(imp.film_offset_mm, dtype=np.float64)
    return np.column_stack([M, c - M @ (c + d)])
