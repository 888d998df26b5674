"""A slide of the film is one field on the print: what each photo measured of it, and where two photos disagree.

A film that slid moves the print's texture by the same vector s(p) at each print point p, in
every photo of the part; a glint or a reflection that the flow follows moves with the camera.
Each photo measures a projection of s: the full vector where the print's texture has two
directions, the component across the edge (along the edge's unit normal n) where it has one,
each with its standard uncertainty. Where one photo found a slide and another photo measured
the same component at the same print pixels, the two measure one number: if the second sees
it significantly smaller (|a·u| - |b·u| beyond SIGNIFICANCE_Z of the two uncertainties
combined, u the component both know), the first photo's slide is not the film's.

This compares what the photos *measured*, not what they state they could find (the detection
limits of :mod:`workbench.validate.detection`): a slide is never contradicted by a photo that
measured it too, even one whose own test dismissed it (as light, or as a flow that explains
little), because that photo's measurement moves with the film as well.
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
    """What one photo's flow measured of the film's slide, per pixel of the print's analysis grid.

    Attributes
    ----------
    slide_mm : (H, W, 2) float32
        The slide measured without the films' fitted placement, mm on the surface (x, y on the
        print): the full vector where ``across`` is False, the component across the edge (a
        multiple of ``normal``) where it is True; NaN where the photo measured none (not scored,
        no texture, under light).
    sigma_mm : (H, W) float32
        Its standard uncertainty, mm (of the full vector along its weakest direction, or of the
        component across the edge); NaN where none.
    across : (H, W) bool
        Only the component across the edge is known.
    normal : (H, W, 2) float32
        The edge's unit normal where ``across`` (0 elsewhere).
    claim : (H, W) bool
        Pixels of the slides the photo kept as defects where its own measure there is beyond the
        tolerance significantly: what the photo claims moved.
    labels : (H, W) int32
        The photo's defect number + 1 per pixel (0: none), as its ``defects`` list them.
    """

    slide_mm: np.ndarray
    sigma_mm: np.ndarray
    across: np.ndarray
    normal: np.ndarray
    claim: np.ndarray
    labels: np.ndarray


def seen_smaller(a: SlideMeasure, b: SlideMeasure, where: np.ndarray, z: float) -> np.ndarray:
    """Where photo ``b`` measured a slide significantly smaller than photo ``a``'s, along a component both know.

    The component: across ``a``'s edge where ``a`` knows only that one (u its normal), else
    across ``b``'s where ``b`` does, else the direction of the difference of the two full
    vectors (the most the two disagree). Where both know only a component, their edges must
    be one (normals within SAME_EDGE_DEG, either sign).

    Parameters
    ----------
    a, b : SlideMeasure
        The photo whose slide is in question, and another photo of the part.
    where : (H, W) bool
        The pixels to compare (a's claim over one of its defects).
    z : float
        The significance, standard uncertainties of the difference.

    Returns
    -------
    (H, W) bool
        True where both measured and |a·u| - |b·u| > z sqrt(σa² + σb²).
    """
    ii, jj = np.nonzero(where)
    out = np.zeros(where.shape, bool)
    va, vb = a.slide_mm[ii, jj].astype(np.float64), b.slide_mm[ii, jj].astype(np.float64)
    sa, sb = a.sigma_mm[ii, jj].astype(np.float64), b.sigma_mm[ii, jj].astype(np.float64)
    both = np.isfinite(va).all(1) & np.isfinite(vb).all(1) & np.isfinite(sa) & np.isfinite(sb)
    acr_a, acr_b = a.across[ii, jj], b.across[ii, jj]
    na, nb = a.normal[ii, jj].astype(np.float64), b.normal[ii, jj].astype(np.float64)
    diff = va - vb
    length = np.linalg.norm(diff, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(length > 0, diff / length, np.array([[1.0, 0.0]]))
    u = np.where(acr_b[:, None], nb, u)
    u = np.where(acr_a[:, None], na, u)
    same_edge = ~(acr_a & acr_b) | (np.abs((na * nb).sum(1)) >= np.cos(np.radians(SAME_EDGE_DEG)))
    ca, cb = np.abs((va * u).sum(1)), np.abs((vb * u).sum(1))
    with np.errstate(invalid="ignore"):
        smaller = both & same_edge & (ca - cb > z * np.hypot(sa, sb))
    out[ii[smaller], jj[smaller]] = True
    return out


def claim_seen_smaller(
    a: SlideMeasure, b: SlideMeasure, defect_id: int, z: float, clean: np.ndarray | None = None
) -> tuple[float, float | None]:
    """The share of a defect's claim that photo ``b`` measured significantly smaller, and b's median there.

    Parameters
    ----------
    a, b : SlideMeasure
    defect_id : int
        The defect's ``id`` in photo ``a`` (its label).
    z : float
        The significance (:func:`seen_smaller`).
    clean : (H, W) bool, optional
        Where ``b`` measured and found no defect: only there does its measure count.

    Returns
    -------
    share : float
        Of the defect's claim pixels (0 when it has none).
    b_median_mm : float or None
        The length of b's measure, median over the pixels where it is smaller (None: none).
    """
    where = a.claim & (a.labels == defect_id)
    n = int(where.sum())
    if n == 0:
        return 0.0, None
    smaller = seen_smaller(a, b, where if clean is None else where & clean, z)
    k = int(smaller.sum())
    if k == 0:
        return 0.0, None
    vb = b.slide_mm[smaller]
    return k / n, float(np.median(np.hypot(vb[:, 0], vb[:, 1])))
