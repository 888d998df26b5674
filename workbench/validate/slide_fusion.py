"""A slide of the film fused over the part's photos: one field on the print, each photo's measure a projection of it.

A film that slid moves the print by the same vector s(p) at each print point p in every photo
of the part (:mod:`workbench.validate.slide_evidence`). Each photo measures, where its own flow
has a measure (not a window's), either the whole vector (the print's texture has two
directions there) or its component across an edge, c = n·s, each with its standard
uncertainty σ_k after the photo's own placement of the film. Independent measures of one
vector fuse by least squares: with P_k the projection a photo measures (the identity for the
whole vector, n nᵀ for a component) and w_k = σ_k⁻²,

    A = Σ w_k P_k,    b = Σ w_k P_k s_k,    ŝ = A⁻¹ b,

and ŝ's uncertainty along its least known direction is λ_min(A)^-½. The photos' errors are
independent: each photo's noise and its own sampling of the print (the photo's floor, which no
window averages away, is its own); what all photos share, DIS's floor on the print's texture
(FLOW_FLOOR_PX, 0.04 grid px: 0.005 mm at the cow's 8.8 grid px per mm), is below what fusing
lifts. Two photos that each know half as much know the slide to 1/√2 of either. Components
alone fix no vector: the edge's normal is the print's (each photo takes it from the print
blurred as it sees it), so every photo measures the same component there, and two estimates
of one edge a few degrees apart would make DIS's drift along it a slide (A's eigenvalues for
two equal measures θ apart are w (1 ± cos θ), in the ratio tan²(θ / 2): edges within
SAME_EDGE_DEG are one edge). The pixels' own measures are fused where a photo measures the
whole vector, with the others' components there. The measures agree with one vector when their weighted misfit

    χ² = Σ w_k |P_k s_k - P_k ŝ|² = Σ w_k c_k² - bᵀ ŝ

(c_k the measured component, or |s_k| for a whole vector) is within the χ² law's quantile at
the significance's two-sided tail for Σ rank(P_k) - 2 degrees of freedom; where they disagree a
light moved with one camera (:func:`workbench.validate.part.light_in_one_photo` decides those)
and the fused vector is no measure.

What a photo's own tests took for light, a slid region whose flow moving the print does not
explain the photo (:func:`workbench.validate.dense.shift_explained`: the flow followed light,
shading or blur), takes no part: the photo measured the print moved there, not the film, and
two photos whose flow follows one sheen agree with each other as well as two that see a slide
(a perfect glossy cow, Mitsuba, and a perfect matte lily, the workbench's: 18 mm² fused at
z 12 and 9 from two photos that had each set the region aside).

The windows' slides (about a millimetre's least-squares vector, where most of a print's
stated limit comes from: a pixel's own full vector is rare on artwork) fuse alike, window
with window: a window answers a small bubble's slide at a fraction of it in every photo
alike, so it is never mixed with a pixel's own measure.

The part finds a slide where a fused vector, from at least two photos that agree, exceeds the
tolerance by SIGNIFICANCE_Z of its uncertainty (which must be within the tolerance over
SIGNIFICANCE_Z, as a photo's own measure's must), with two flow windows of such evidence,
sized as a photo sizes its slides, over more than the verdict's area, and measured by two
photos that see it from directions no one lamp serves both (a glint pulls the flow of photos
from one direction alike). The stated limit that goes with it (:func:`fused_part_limit`) is
claimed only where two such photos measure.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from scipy import ndimage
from scipy.special import chdtri

from workbench.validate import detection, print_warp
from workbench.validate.dense.options import (
    APART_DEG,
    DETECT_Z,
    MIN_SHIFT_WINDOWS,
    SHIFT_CLOSE_MM,
    SIGNIFICANCE_Z,
    TENSOR_SIGMA_PX,
    WINDOW_GAIN,
)
from workbench.validate.rule import significant
from workbench.validate.slide_evidence import SAME_EDGE_DEG

APART_STEP = 8  # grid pixels between the points the stated limit's camera angles are taken at


@dataclass(frozen=True)
class FusedSlide:
    """The photos' measures of the film's slide fused, per pixel of the print's analysis grid.

    Attributes
    ----------
    slide_mm : (H, W, 2) float32
        The fused slide (x, y on the print), mm on the surface; NaN where fewer than two photos
        measure it, the measures do not fix both components within the usable uncertainty, or
        they disagree.
    sigma_mm : (H, W) float32
        Its standard uncertainty along its least known direction, mm; NaN where ``slide_mm`` is.
    photos : (K, H, W) bool
        Where photo k's measure took part (nowhere where fewer than two photos measure), K the
        number of photos given (None ones included).
    chi2 : (H, W) float32
        The measures' weighted misfit to one vector (NaN where not fused).
    """

    slide_mm: np.ndarray
    sigma_mm: np.ndarray
    photos: np.ndarray
    chi2: np.ndarray


def _usable(vector_mm: np.ndarray, sigma_mm: np.ndarray, use: np.ndarray | None) -> np.ndarray:
    """Where a photo has a measure of this kind: a finite vector and a positive finite σ (and ``use``).

    On float16's bits (numpy's float16 arithmetic is emulated, slow): finite where the exponent
    is not all ones (0x7C00), σ positive where the sign bit is clear and the bits are not 0.
    """
    v = np.ascontiguousarray(vector_mm, np.float16).view(np.uint16) & 0x7C00
    u = np.ascontiguousarray(sigma_mm, np.float16).view(np.uint16)
    ok = (u > 0) & (u < 0x7C00) & (v[..., 0] != 0x7C00) & (v[..., 1] != 0x7C00)
    return ok if use is None else ok & use


def _taken(m, use: np.ndarray | None) -> np.ndarray | None:
    """``use`` less what the photo's own tests set aside as light (:attr:`SlideMeasure.set_aside`):
    there its flow followed light, shading or blur, and its measure is not the film's."""
    if m.set_aside is None:
        return use
    return ~m.set_aside if use is None else use & ~m.set_aside


def fuse_slides(slides: list, z: float, usable_mm: float) -> FusedSlide:
    """The photos' own measures of the film's slide (the whole vector, or across an edge), fused per print pixel.

    Parameters
    ----------
    slides : list of SlideMeasure or None
        Each photo's measure (``DenseResult.slide``), on one grid; None: the photo has none.
        What a photo set aside as light (``set_aside``) takes no part.
    z : float
        The significance, standard uncertainties: measures disagree where their misfit exceeds
        the χ² quantile of the normal law's two-sided tail beyond ``z``.
    usable_mm : float
        The largest uncertainty a fused measure may have, mm (a photo's own measures are gated
        so: the tolerance over the significance).

    Returns
    -------
    FusedSlide
    """
    own = [None if m is None else (m.slide_mm, m.sigma_mm, _taken(m, ~m.window), m.normal) for m in slides]
    return _fuse(own, z, next(m.sigma_mm.shape for m in slides if m is not None), usable_mm)


def fuse_windows(slides: list, z: float, usable_mm: float) -> FusedSlide:
    """The photos' windows' slides (about a millimetre's, whole vectors), fused per print pixel.

    Like is fused with like: a window answers a small bubble's slide at a fraction of it, in
    every photo alike (:mod:`workbench.validate.slide_evidence`).

    Parameters
    ----------
    slides : list of SlideMeasure or None
        As :func:`fuse_slides`; a photo without windows' slides (``wide_mm`` None) takes no part.
    z, usable_mm : float
        As :func:`fuse_slides`.

    Returns
    -------
    FusedSlide
    """
    wide = [
        None if m is None or m.wide_mm is None else (m.wide_mm, m.wide_sigma_mm, _taken(m, None), None) for m in slides
    ]
    return _fuse(wide, z, next(m.sigma_mm.shape for m in slides if m is not None), usable_mm)


def _fuse(measures: list, z: float, shape: tuple, usable_mm: float) -> FusedSlide:
    """Least squares over the photos' measures ``(vector, sigma, use or None, normal or None)`` on a grid.

    The sums run in float32 (the misfit q - bᵀ ŝ loses 1e-7 of q, some 1e-5 of a unit of χ², to
    the cancellation), a photo's weight 0 where it has no measure, over the pixels two photos or
    more measure. Where the measures carry normals (the pixels' own), only where some photo
    measures the whole vector: one print edge has one normal in every photo (each takes it from
    the print), so components alone fix no vector; those pixels are few (a print's two-way
    texture is a few % of it) and are gathered. The windows' measures are whole vectors over
    most of the grid, which is summed as it is (a gather would only slow it).

    Returns
    -------
    FusedSlide
    """
    f32 = np.float32
    photos = np.zeros((len(measures), *shape), bool)
    whole = np.zeros(shape, bool)
    with_normals = False
    for k, got in enumerate(measures):
        if got is not None:
            photos[k] = _usable(got[0], got[1], got[2])
            if got[3] is not None:
                with_normals = True
                whole |= photos[k] & ~np.any(got[3].view(np.uint16) & 0x7FFF, axis=-1)
    if with_normals:
        photos &= whole
    count = photos.sum(axis=0)
    photos[:, count < 2] = False
    at = np.flatnonzero(count >= 2) if with_normals else None

    def flat(a: np.ndarray, per: int = 1) -> np.ndarray:
        # the grid's pixels as a column (``per`` numbers each), those fused only
        a = a.reshape(-1, per) if per > 1 else a.reshape(-1)
        return (a if at is None else a[at]).astype(f32)

    n_px = count.size if at is None else len(at)
    axx, axy, ayy, bx, by, q = (np.zeros(n_px, f32) for _ in range(6))
    rank = np.zeros(n_px, np.int16)
    for k, got in enumerate(measures):
        if got is None:
            continue
        ok = photos[k].reshape(-1) if at is None else photos[k].reshape(-1)[at]
        v = flat(got[0], 2)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            w = np.where(ok, f32(1.0) / np.square(flat(got[1])), f32(0.0))
        sx = np.where(ok, v[:, 0], f32(0.0))
        sy = np.where(ok, v[:, 1], f32(0.0))
        full, wf = ok, w
        if got[3] is not None:
            n = flat(got[3], 2)
            length = np.sqrt(n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1])
            edge = ok & (length > 0)
            full = ok & ~edge
            wf = np.where(full, w, f32(0.0))
            # a component across the edge: P = n nᵀ with n of unit length (stored in half
            # precision, renormalised), the measure c = n·s (s stored as c n: P s = s to half
            # precision's rounding, which q - bᵀ ŝ would magnify)
            with np.errstate(invalid="ignore", divide="ignore"):
                nx = np.where(edge, n[:, 0] / length, f32(0.0))
                ny = np.where(edge, n[:, 1] / length, f32(0.0))
            c = nx * sx + ny * sy
            we = np.where(edge, w, f32(0.0))
            axx += we * nx * nx
            ayy += we * ny * ny
            axy += we * nx * ny
            bx += we * c * nx
            by += we * c * ny
            q += we * c * c
            rank += edge
        # the whole vector: P = I
        axx += wf
        ayy += wf
        bx += wf * sx
        by += wf * sy
        q += wf * (sx * sx + sy * sy)
        rank += 2 * full
    det = axx * ayy - axy * axy
    # A's eigenvalues: half its trace less and plus the root of its discriminant
    root = np.sqrt(0.25 * (axx - ayy) ** 2 + axy * axy)
    lam, big = 0.5 * (axx + ayy) - root, 0.5 * (axx + ayy) + root
    # both components fixed: by edges more than SAME_EDGE_DEG apart (or a whole vector), and to
    # within the usable uncertainty
    two = count.reshape(-1) >= 2 if at is None else np.ones(n_px, bool)
    fixed = two & (lam >= f32(math.tan(math.radians(SAME_EDGE_DEG) / 2.0) ** 2) * big)
    fixed &= lam * f32(usable_mm**2) >= 1.0
    with np.errstate(invalid="ignore", divide="ignore"):
        sx = (ayy * bx - axy * by) / det
        sy = (axx * by - axy * bx) / det
        misfit = np.maximum(q - (bx * sx + by * sy), f32(0.0))
        sigma = f32(1.0) / np.sqrt(lam)
    dof = rank - 2
    # the misfit's quantile at the two-sided tail beyond z (the normal law's), per number of
    # degrees of freedom; exactly determined measures (none left) always agree
    alpha = math.erfc(z / math.sqrt(2.0))
    agree = fixed & (dof <= 0)
    for d in np.unique(dof[fixed & (dof > 0)]):
        agree |= fixed & (dof == d) & (misfit <= f32(chdtri(int(d), alpha)))
    out = np.full((count.size, 4), np.nan, f32)  # slide x, y, its sigma, the misfit
    rows = np.arange(count.size) if at is None else at
    out[rows[agree], 0] = sx[agree]
    out[rows[agree], 1] = sy[agree]
    out[rows[agree], 2] = sigma[agree]
    out[rows[fixed], 3] = misfit[fixed]
    out = out.reshape(*shape, 4)
    return FusedSlide(out[..., :2], out[..., 2], photos, out[..., 3])


def slid_pixels(fused: FusedSlide, tolerance_mm: float, z: float, erode_px: int = 0) -> np.ndarray:
    """Where the fused slide exceeds the tolerance by more than ``z`` of its uncertainty.

    Parameters
    ----------
    fused : FusedSlide
        The fused measure.
    tolerance_mm, z : float
        The tolerance (mm on the surface) and the significance (standard uncertainties).
    erode_px : int
        A window's slide spreads past a slid region's rim by about its own radius: eroded by
        half the window's width (``erode_px``, grid px), its evidence stays inside the region it
        measured, as a photo's own window evidence does. 0 for the pixels' own measures.

    Returns
    -------
    (H, W) bool
    """
    mag = np.hypot(fused.slide_mm[..., 0], fused.slide_mm[..., 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        slid = np.nan_to_num((mag - tolerance_mm) / fused.sigma_mm, nan=-np.inf) > z
    if erode_px > 0:
        disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * erode_px + 1,) * 2)
        slid = cv2.erode(slid.astype(np.uint8), disc).astype(bool)
    return slid


def slid_regions(
    seeds: np.ndarray, slide_mm: np.ndarray, px_per_mm: float, window_px: float, min_area_mm2: float
) -> tuple[np.ndarray, int]:
    """The slid regions the seeds found, sized as a photo sizes its slides, larger than the verdict's area.

    As :func:`workbench.validate.dense.find_defects` takes a photo's: the seeds opened by a 3 x 3
    square (chance exceedances are single pixels); a group of them needs MIN_SHIFT_WINDOWS flow
    windows of evidence (DIS's errors have tails its uncertainty does not describe); it grows to
    where the slide reaches half its height (half the upper quartile over the seeds), within
    the flow's reach of them (three windows), the flow ramping from the slide to 0 across the
    rim; and the plain patches between its textured parts, SHIFT_CLOSE_MM across, are closed.

    Parameters
    ----------
    seeds : (H, W) bool
        The slid pixels (:func:`slid_pixels`).
    slide_mm : (H, W, 2) float
        The fused slide there and around, mm (NaN: none).
    px_per_mm : float
        The grid's resolution, px per print mm.
    window_px : float
        The flow's window, Gaussian sigma, grid px.
    min_area_mm2 : float
        The verdict's area, print mm²: regions no larger are left out.

    Returns
    -------
    labels : (H, W) int32
        Region number (1 to n) per pixel, 0 elsewhere.
    n : int
        The number of regions.
    """
    H, W = seeds.shape
    mag = np.nan_to_num(np.hypot(slide_mm[..., 0], slide_mm[..., 1]), nan=0.0)
    opened = cv2.morphologyEx(seeds.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, lab, box, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
    two_windows = MIN_SHIFT_WINDOWS * 4.0 * np.pi * window_px**2
    reach = int(math.ceil(3.0 * window_px))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2)
    grown = np.zeros((H, W), np.uint8)
    for i in range(1, n):
        if box[i, cv2.CC_STAT_AREA] < two_windows:
            continue
        x, y, w, h = (
            int(box[i, c]) for c in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT)
        )
        sub = (slice(max(y - reach, 0), min(y + h + reach, H)), slice(max(x - reach, 0), min(x + w + reach, W)))
        seed = lab[sub] == i
        level = 0.5 * float(np.percentile(mag[sub][seed], 75))
        near = cv2.dilate(seed.astype(np.uint8), disc).astype(bool)
        k, parts = cv2.connectedComponents(((mag[sub] >= level) & near).view(np.uint8), connectivity=8)
        hit = np.zeros(k, bool)
        hit[np.unique(parts[seed])] = True
        hit[0] = False
        grown[sub] |= (hit[parts] | seed).astype(np.uint8)
    r = max(1, int(round(SHIFT_CLOSE_MM * px_per_mm / 2)))
    closed = cv2.morphologyEx(grown, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
    n, lab, stats, _ = cv2.connectedComponentsWithStats(closed, connectivity=8)
    keep = np.zeros(n, np.int32)
    m = 0
    for i in range(1, n):
        if stats[i, cv2.CC_STAT_AREA] / (px_per_mm * px_per_mm) > min_area_mm2:
            m += 1
            keep[i] = m
    return keep[lab], m


def camera_rays(X: np.ndarray, centre, dtype=np.float32) -> np.ndarray | None:
    """Unit vectors from surface points towards a camera; None where the camera is not known.

    Parameters
    ----------
    X : (..., 3) float
        Surface points, mm (NaN: none).
    centre : (3,) float or None
        The camera's centre, mm.
    dtype : numpy dtype
        The rays' (float32 for a grid of them, float64 for one point's).

    Returns
    -------
    (..., 3) array of ``dtype``, or None
    """
    if centre is None or not np.isfinite(np.asarray(centre, np.float64)).all():
        return None
    v = np.asarray(centre, dtype) - np.asarray(X, dtype)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.sqrt((v * v).sum(axis=-1, keepdims=True))


def angle_deg(u: np.ndarray, v: np.ndarray) -> float:
    """The angle between two unit vectors ((3,) float each), degrees."""
    return float(np.degrees(np.arccos(np.clip(float((u * v).sum()), -1.0, 1.0))))


def seen_apart(rays: list, k: int, j: int) -> np.ndarray | None:
    """Where photos ``k`` and ``j`` see the surface from more than APART_DEG apart; None where either is unknown.

    Parameters
    ----------
    rays : list of (..., 3) float or None
        Each photo's :func:`camera_rays`.
    k, j : int
        The two photos.

    Returns
    -------
    (...) bool or None
    """
    if rays[k] is None or rays[j] is None:
        return None
    return (rays[k] * rays[j]).sum(axis=-1) < np.float32(math.cos(math.radians(APART_DEG)))


def fused_part_limit(maps: dict, X: np.ndarray, centres: list, tolerance_mm: float) -> np.ndarray:
    """The part's smallest slide found, stored: each photo's and, where two photos apart measure, theirs fused.

    The photos' own full vectors and their windows' slides fuse apart
    (:func:`workbench.validate.detection.fused_shift_limit`, at SIGNIFICANCE_Z + DETECT_Z; a
    window answers WINDOW_GAIN of a slide), and the fused limit is claimed only where two of the
    photos that measure see the point from more than APART_DEG apart: the detector
    (:func:`slides_found_together`) counts nothing else.

    Parameters
    ----------
    maps : dict
        The detection maps (:func:`workbench.validate.detection.part_maps`): ``part_shift_limit_um``
        and per photo K ``photoK_slide_sigma_um`` and ``photoK_window_sigma_um``.
    X : (H, W, 3) float
        The surface point under each grid pixel, mm (NaN: none).
    centres : list of (3,) float or None
        Each photo's camera centre, mm, by entry index K.
    tolerance_mm : float
        The tolerance, mm.

    Returns
    -------
    (H, W) uint16
        µm (detection.NONE_UM where none is found).
    """
    best = maps["part_shift_limit_um"]
    H, W = best.shape
    # (the angle between two cameras seen from the surface turns slowly over it: taken every
    # APART_STEP grid pixels and spread to the rest)
    coarse = X[::APART_STEP, ::APART_STEP]
    rays = [camera_rays(coarse, c) if f"photo{k}_shift_limit_um" in maps else None for k, c in enumerate(centres)]
    apart: dict = {}
    for k in range(len(rays)):
        for j in range(k + 1, len(rays)):
            got = seen_apart(rays, k, j)
            if got is not None and got.any():
                apart[k, j] = cv2.resize(got.view(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST).view(bool)
    for kind, gain in (("slide_sigma_um", 1.0), ("window_sigma_um", WINDOW_GAIN)):
        have = [k for k in range(len(centres)) if f"photo{k}_{kind}" in maps]
        if len(have) < 2:
            continue
        measured = {k: maps[f"photo{k}_{kind}"] != detection.NONE_UM for k in have}
        claimed = np.zeros((H, W), bool)
        for (k, j), mask in apart.items():
            if k in measured and j in measured:
                claimed |= mask & measured[k] & measured[j]
        if not claimed.any():
            continue
        limit = detection.fused_shift_limit([maps[f"photo{k}_{kind}"] for k in have], tolerance_mm,
                                            SIGNIFICANCE_Z + DETECT_Z, gain)  # fmt: skip
        best = np.minimum(best, np.where(claimed, detection.to_stored(limit), detection.NONE_UM).astype(np.uint16))
    return best


def claimed_by_photos(entries: list[dict], dismissed: list, shape: tuple, px_per_mm: float, max_defect_mm2: float):
    """Where the photos' own defects already decide the part: those that fail it, and those dismissed as light.

    A fused region's pixels there are theirs: a slide a photo found significant over more than
    the verdict's area fails the part already (unless it is open: the photo could not tell it
    from light), and one another photo showed to be light stays light. A photo at fault
    (``photo_quality.problems``) decides nothing.

    Parameters
    ----------
    entries : list of dict
        The photos' entries (``defects`` with ``bbox_mm``, ``area_mm2``, ``significance_z``).
    dismissed : list of dict
        The defects taken for light (``photo_index``, ``id``).
    shape : tuple
        The grid's (H, W).
    px_per_mm : float
        The grid's resolution.
    max_defect_mm2 : float
        The verdict's area, print mm².

    Returns
    -------
    (H, W) bool
        The defects' boxes.
    """
    gone = {(x["photo_index"], x["id"]) for x in dismissed or []}
    out = np.zeros(shape, bool)
    for k, e in enumerate(entries):
        if (e.get("photo_quality") or {}).get("problems"):
            continue
        for d in e.get("defects", []):
            # (an open region, which the photo could not tell from light, decides nothing)
            counted = d["area_mm2"] > max_defect_mm2 and significant(d) and not d.get("unresolved")
            if counted or (k, d.get("id")) in gone:
                out[print_warp.box_slices(d["bbox_mm"], px_per_mm)] = True
    return out


@dataclass(frozen=True)
class FusionOptions:
    """What the part's fused slide is judged by.

    Attributes
    ----------
    tolerance_mm : float
        The misregistration tolerance, mm on the surface (``--tolerance-mm``).
    max_defect_mm2 : float
        The verdict's area, print mm² (``--max-defect-mm2``): larger slid regions fail the part.
    """

    tolerance_mm: float
    max_defect_mm2: float


def slides_found_together(
    slides: list, entries: list[dict], dismissed: list, grid, opts: FusionOptions, views: list
) -> tuple[list[dict], list[dict]]:
    """The part's slides that only its photos together find, and those its photos' directions leave undecided.

    The photos' own measures and their windows' slides are fused (:func:`fuse_slides`,
    :func:`fuse_windows`; the windows' evidence eroded by half their width); the slid pixels
    seed regions (:func:`slid_regions`); a region's pixels where a photo's own defect already
    decides (:func:`claimed_by_photos`) are its (a region whose slid pixels lie mostly there is
    that defect, or that light), and what remains must still be larger than the verdict's area.
    A region is the film's only where two photos that took part see it from more than
    APART_DEG apart, over two flow windows of its slid pixels at least: a glint at
    one print position in two photos needs one lamp mirrored into both cameras, and reflection
    keeps the angle between two rays (as :func:`workbench.validate.part.light_in_one_photo`
    takes ink gone two photos found). Otherwise it is not counted, and says why.

    Parameters
    ----------
    slides : list of SlideMeasure or None
        Each photo's measure, by entry.
    entries : list of dict
        The photos' entries (``photo``, ``defects``, ``pose.camera_center_mm``).
    dismissed : list of dict
        The defects the part took for light (:func:`workbench.validate.part.light_in_one_photo`).
    grid : PrintGrid
        The print's analysis grid (``px_per_mm``, ``owner``, ``X``).
    opts : FusionOptions
    views : list of str
        The design's view names, by owner index.

    Returns
    -------
    found : list of dict
        ``kind`` (``shift``), ``centre_mm``, ``area_mm2``, ``bbox_mm`` (print mm), ``peak_mm``
        and ``median_mm`` (the slide over its slid pixels, mm on the surface), ``photos`` (those
        whose measures took part over at least half of them), ``view`` (the one owning its
        centre), ``apart_deg`` (the widest angle between two of its photos' cameras, seen from
        it) and ``decided_by`` (``hypothesis`` slide, ``z`` the median significance, ``words``);
        empty when fewer than two photos measured.
    light : list of dict
        The regions not counted (``photo``: the photos, ``id`` None, ``kind``, ``area_mm2``,
        ``centre_mm``, ``decided_by``), as :func:`workbench.validate.part.light_in_one_photo`
        lists its own.
    """
    if sum(m is not None for m in slides) < 2:
        return [], []
    usable = opts.tolerance_mm / SIGNIFICANCE_Z
    # (the two on two threads: their whole-grid sums release the GIL)
    with ThreadPoolExecutor(max_workers=2) as pool:
        own_job = pool.submit(fuse_slides, slides, SIGNIFICANCE_Z, usable)
        wide = fuse_windows(slides, SIGNIFICANCE_Z, usable)
        own = own_job.result()
    win = max((m.window_px or TENSOR_SIGMA_PX) for m in slides if m is not None)
    slid_own = slid_pixels(own, opts.tolerance_mm, SIGNIFICANCE_Z)
    slid_wide = slid_pixels(wide, opts.tolerance_mm, SIGNIFICANCE_Z, max(1, int(round(2 * win))))
    # (a pixel's slide as what found it measured it: the pixels' own where their own fused
    # measures found it or where no window's did, the windows' where only theirs did)
    pick = slid_own | ~np.isfinite(wide.sigma_mm) | (~slid_wide & np.isfinite(own.sigma_mm))
    slide_mm = np.where(pick[..., None], own.slide_mm, wide.slide_mm)
    sigma_mm = np.where(pick, own.sigma_mm, wide.sigma_mm)
    seeds = slid_own | slid_wide
    px_mm2 = 1.0 / (grid.px_per_mm * grid.px_per_mm)
    labels, n = slid_regions(seeds, slide_mm, grid.px_per_mm, win, opts.max_defect_mm2)
    if n == 0:
        return [], []
    claimed = claimed_by_photos(entries, dismissed, seeds.shape, grid.px_per_mm, opts.max_defect_mm2)
    names = [Path(e["photo"]).name for e in entries]
    centres = [(e.get("pose") or {}).get("camera_center_mm") for e in entries]
    mag = np.hypot(slide_mm[..., 0], slide_mm[..., 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        zmap = (mag - opts.tolerance_mm) / sigma_mm
    two_windows = MIN_SHIFT_WINDOWS * 4.0 * np.pi * win**2
    found, light = [], []
    H, W = seeds.shape
    for i, sub in enumerate(ndimage.find_objects(labels), start=1):
        whole = labels[sub] == i
        if (whole & seeds[sub] & claimed[sub]).sum() >= 0.5 * (whole & seeds[sub]).sum():
            continue  # (mostly a photo's own defect, or its light: that one slide, decided already)
        region = whole & ~claimed[sub]
        area = float(region.sum()) * px_mm2
        core = region & seeds[sub]
        if area <= opts.max_defect_mm2 or not core.any():
            continue  # (what a photo's own defect does not decide is no larger than the verdict's area)
        # (K, pixels): which photos' measures took part, the one that found each pixel's
        took = np.where(
            pick[sub][core], own.photos[:, sub[0], sub[1]][:, core], wide.photos[:, sub[0], sub[1]][:, core]
        )
        X = grid.X[sub][core] if grid.X is not None else np.zeros((0, 3))
        point = np.nanmedian(X, axis=0) if np.isfinite(X).all(axis=-1).any() else np.full(3, np.nan)
        rays = [camera_rays(point, c) for c in centres]
        apart_px = np.zeros(int(core.sum()), bool)
        widest = None
        for k in range(len(entries)):
            for j in range(k + 1, len(entries)):
                both = took[k] & took[j]
                if rays[k] is None or rays[j] is None or not both.any() or not np.isfinite(point).all():
                    continue
                deg = angle_deg(rays[k], rays[j])
                widest = deg if widest is None else max(widest, deg)
                if deg > APART_DEG:
                    apart_px |= both
        ys, xs = np.nonzero(region)
        y0, x0 = sub[0].start, sub[1].start
        peak, median = float(np.nanmax(mag[sub][core])), float(np.nanmedian(mag[sub][core]))
        zr = float(np.nanmedian(zmap[sub][core]))
        photos = [nm for k, nm in enumerate(names) if took[k].mean() >= 0.5]
        d = {
            "kind": "shift",
            "centre_mm": [round((float(xs.mean()) + x0 + 0.5) / grid.px_per_mm, 2),
                          round((float(ys.mean()) + y0 + 0.5) / grid.px_per_mm, 2)],
            "area_mm2": round(area, 2),
            "bbox_mm": [round(v / grid.px_per_mm, 2) for v in (x0 + xs.min(), y0 + ys.min(),
                                                              x0 + xs.max() + 1, y0 + ys.max() + 1)],
            "peak_mm": round(peak, 3),
            "median_mm": round(median, 3),
            "photos": photos,
        }  # fmt: skip
        cx, cy = (int(np.clip(v * grid.px_per_mm, 0, m - 1)) for v, m in zip(d["centre_mm"], (W, H), strict=True))
        owner = int(grid.owner[cy, cx]) if grid.owner is not None else -1
        d["view"] = views[owner] if 0 <= owner < len(views) else None
        d["apart_deg"] = None if widest is None else round(widest, 1)
        by = ", ".join(photos) or "several photos"
        if apart_px.sum() >= two_windows:
            words = (
                f"the film slid {median:.2f} mm (median; up to {peak:.2f} mm) over {area:.1f} mm², measured by "
                f"{by} together (seen from up to {widest:.0f}° apart): their measures agree and, fused, exceed "
                f"the tolerance of {opts.tolerance_mm:g} mm at z = {zr:.1f}"
            )
            d["decided_by"] = {"hypothesis": "slide", "fused_from": len(photos), "z": round(zr, 2), "words": words}
            found.append(d)
            continue
        if widest is None:
            why = "they are not known to see it from different directions (no camera or surface point known there)"
        elif widest <= APART_DEG:
            why = f"they see it from within {widest:.1f}° of each other: one lamp's glint may pull their flow alike"
        else:
            why = (
                f"two of them more than {APART_DEG:g}° apart measured only {apart_px.sum() * px_mm2:.1f} mm² of it "
                f"together, under the two flow windows ({two_windows * px_mm2:.1f} mm²) a slide needs"
            )
        words = f"{by} agree on a slide of {median:.2f} mm here, but {why}: not counted"
        light.append(
            {
                "photo": by,
                "id": None,
                "kind": "shift",
                "area_mm2": d["area_mm2"],
                "centre_mm": d["centre_mm"],
                "decided_by": {"hypothesis": "light", "apart_deg": d["apart_deg"], "z": round(zr, 2), "words": words},
            }
        )
    found.sort(key=lambda d: (-d["area_mm2"], d["centre_mm"]))
    return found, light
