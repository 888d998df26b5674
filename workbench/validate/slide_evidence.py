"""A slide of the film is one field on the print: what each photo measured of it, and where two photos disagree.

A film that slid moves the print's texture by the same vector s(p) at each print point p, in
every photo of the part; a glint or a reflection that the flow follows moves with the camera.
Each photo measures a projection of the film's whole displacement there (its placement plus
the slide): the full vector where the print's texture has two directions, the component across
the edge (along the edge's unit normal n) where it has one, each with its standard uncertainty.
Where photo A found a slide and photo B measured the same component at the same print pixels,
the two measure one number. A's slide is not the film's where B measured that component

- smaller than A by more than SIGNIFICANCE_Z of the two uncertainties combined, the whole
  displacements compared (each photo's own fitted placement, which validate rounds to none when
  it is within the tolerance's share, differs between photos by up to that share), and
- in place: B's own slide there (after its placement) within the tolerance by that significance.

Like is compared with like: a pixel's own measure with another's own, a window's slide (where
the pixel has no measure of its own) with another's window. A window of about a millimetre
answers a small bubble's slide at a fraction of it (a 0.5 mm slide over a disc of 1.3 mm radius:
0.24 mm), in every photo alike, so against a pixel's own measure it would state a small bubble
in place. This compares what the photos
*measured*, not what they state they could find (the detection limits of
:mod:`workbench.validate.detection`): a photo that measured the slide too, even one whose own
test set it aside (as light, or as a flow that explains little), measured it moved, and never
overrules it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# two edge normals are one edge's (the print's, seen by two photos) when they are within this
# angle: the structure tensor's direction over a window of TENSOR_SIGMA_PX errs by a few degrees on
# a soft edge, and the component each measures then differs by 1 - cos 20° = 6 % of the slide
SAME_EDGE_DEG = 20.0


@dataclass(frozen=True)
class SlideMeasure:
    """What one photo's flow measured of the film, per pixel of the print's analysis grid.

    Attributes
    ----------
    slide_mm : (H, W, 2) float16
        The slide the pixel's own measure gives, after the photo's fitted placement, mm on the
        surface (x, y on the print): the full vector where ``normal`` is 0, the component across
        the edge (a multiple of ``normal``) where it is not; NaN where the photo measured none
        (not scored, no texture, under light).
    placement_mm : (H, W, 2) float16
        The photo's fitted placement of the film there, mm (0 where it fitted none): the film's
        whole displacement is ``slide_mm + placement_mm``.
    sigma_mm : (H, W) float16
        The measure's standard uncertainty, mm (of the full vector along its weakest direction,
        or of the component across the edge); NaN where none.
    normal : (H, W, 2) float16
        The edge's unit normal where only the component across it is known, 0 elsewhere.
    window : (H, W) bool
        The measure is a window's slide (about a millimetre's, where the pixel has none of its own).
    claim : (H, W) int16
        The photo's defect ``id`` at the pixels of the slides it kept as defects where its own
        measure there is beyond the tolerance significantly (what the photo claims moved), 0
        elsewhere.
    tolerance_mm : float
        The misregistration tolerance the photo was judged by, mm.
    wide_mm : (H, W, 2) float16 or None
        The window's slide (about a millimetre's, :func:`workbench.validate.dense.tensor_weighted_flow`)
        after the photo's placement, mm, wherever the window's measure is usable (whether or not
        the pixel has its own); NaN elsewhere. The part fuses it over its photos
        (:mod:`workbench.validate.slide_fusion`).
    wide_sigma_mm : (H, W) float16 or None
        Its standard uncertainty along the window's weaker direction, mm; NaN where none.
    window_px : float or None
        The flow's window, Gaussian sigma, grid px: the wide window's is four times it (None:
        ``dense.TENSOR_SIGMA_PX``).
    set_aside : (H, W) bool or None
        The slid regions the photo's own tests took for light (a flow that follows light,
        shading or blur, not the film: ``shift_not_explained``, ``shift_as_light``), with the
        flow's reach around them: the photo measured the print moved there, but not the film.
    """

    slide_mm: np.ndarray
    placement_mm: np.ndarray
    sigma_mm: np.ndarray
    normal: np.ndarray
    window: np.ndarray
    claim: np.ndarray
    tolerance_mm: float
    wide_mm: np.ndarray | None = None
    wide_sigma_mm: np.ndarray | None = None
    window_px: float | None = None
    set_aside: np.ndarray | None = None


def seen_in_place(a: SlideMeasure, b: SlideMeasure, box: tuple, z: float) -> np.ndarray:
    """Where photo ``b`` measured in place, and significantly short of photo ``a``, the slide ``a`` found.

    The component compared, u: across ``b``'s edge where ``b`` knows only that one, else across
    ``a``'s where ``a`` does, else along ``a``'s slide; turned so that ``a``'s slide along it is
    positive. Where both know only a component, their edges must be one (normals within
    SAME_EDGE_DEG, either sign); and both must be a pixel's own measure, or both a window's.
    Then, with d = slide + placement each photo's whole displacement:

    - (d_a - d_b) · u > z sqrt(σa² + σb²): ``b`` sees the print moved less than ``a`` does, and
    - |slide_b · u| <= tolerance + z σb: ``b``'s own slide there is within the tolerance.

    Parameters
    ----------
    a, b : SlideMeasure
        The photo whose slide is in question, and another photo of the part.
    box : tuple of slice
        The pixels to compare: rows and columns of the grid (around ``a``'s defect).
    z : float
        The significance, standard uncertainties.

    Returns
    -------
    (h, w) bool
        Over ``box``: True where both measured and both conditions hold.
    """

    def f64(x):
        return np.asarray(x[box], np.float64)

    sa, sb = f64(a.slide_mm), f64(b.slide_mm)
    da, db = sa + f64(a.placement_mm), sb + f64(b.placement_mm)
    ga, gb = f64(a.sigma_mm), f64(b.sigma_mm)
    na, nb = f64(a.normal), f64(b.normal)
    acr_a, acr_b = np.any(na != 0, axis=-1), np.any(nb != 0, axis=-1)
    length = np.linalg.norm(sa, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(length > 0, sa / length, 0.0)
    u = np.where(acr_a[..., None], na, u)
    u = np.where(acr_b[..., None], nb, u)
    # (turned so that a's slide along u is positive: a's claim is a move along +u)
    u = np.where(((sa * u).sum(-1) < 0)[..., None], -u, u)
    same_edge = ~(acr_a & acr_b) | (np.abs((na * nb).sum(-1)) >= np.cos(np.radians(SAME_EDGE_DEG)))
    with np.errstate(invalid="ignore"):
        shorter = ((da - db) * u).sum(-1) > z * np.hypot(ga, gb)
        in_place = np.abs((sb * u).sum(-1)) <= b.tolerance_mm + z * gb
    both = np.isfinite(sa).all(-1) & np.isfinite(sb).all(-1) & np.isfinite(ga) & np.isfinite(gb)
    alike = a.window[box] == b.window[box]
    return both & alike & same_edge & shorter & in_place


def claim_seen_in_place(
    a: SlideMeasure, b: SlideMeasure, defect_id: int, z: float, box: tuple, clean: np.ndarray
) -> tuple[float, float | None]:
    """The share of a defect's claim that photo ``b`` measured in place (:func:`seen_in_place`), and b's median there.

    Parameters
    ----------
    a, b : SlideMeasure
        The photo whose defect is in question, and another photo of the part.
    defect_id : int
        The defect's ``id`` in photo ``a``.
    z : float
        The significance (:func:`seen_in_place`).
    box : tuple of slice
        The defect's box on the grid (rows, cols): its claim lies within it.
    clean : (h, w) bool
        Over ``box``: where ``b`` measured and found no defect; only there does its measure count.

    Returns
    -------
    share : float
        Of the defect's claim pixels (0 when it has none).
    b_median_mm : float or None
        The length of b's own slide, median over the pixels where it is in place (None: none).
    """
    where = a.claim[box] == defect_id
    n = int(where.sum())
    if n == 0:
        return 0.0, None
    seen = seen_in_place(a, b, box, z) & where & clean
    k = int(seen.sum())
    if k == 0:
        return 0.0, None
    vb = np.asarray(b.slide_mm[box][seen], np.float64)
    return k / n, float(np.median(np.hypot(vb[:, 0], vb[:, 1])))
