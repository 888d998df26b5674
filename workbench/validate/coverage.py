"""The part's coverage: where its photos together can find each defect class, per film, and the photo to take next.

A PASS says that nothing was found. It is evidence only where the photos could have found
something: the detection maps (:mod:`workbench.validate.detection`) say, per print pixel and
photo, whether a slide of the film, ink that is gone, or a scratch would be found there. The
part's maps are the best over its photos. Per film and per defect class, the share of the film
where that class would show and the photos find it is the coverage; a part whose photos find
nothing but cover less than ``min_coverage`` of a film for a class is INCOMPLETE: the photos
were fine, there were not enough of them, and the uncovered regions say where and why, with
the photo to take next.

Where a defect class would show (its denominator) is the design's, not the photos':

- ink that is gone, or scratched off, shows where the design's colour differs from the bare
  film's by more than the colour tolerance the part is judged by (``max_delta_e``, CIE76 on the
  design's sRGB): ink paler than that is within the part's own colour tolerance when gone. The
  colour test seeks broad ink loss only where the ink's step to the film exceeds twice its
  tolerance (``dense.COLOUR_TOL``, the exposure model's error: it is what no photo can take
  away); paler ink is reported as not sought (``not_sought_mm2``), a limit of the method that
  more photos do not lift, and is left out of the share. A scratch is sought against its own
  surroundings, without that tolerance, wherever the ink shows;
- a slide of the film shows where it changes the colour seen by more than that tolerance in
  any direction, over the window a slide is judged on: the design's colour change (ΔE per mm,
  along the window's weaker direction) times a slide of twice the tolerance, the slide the
  flow is gated to find at its significance (:mod:`workbench.validate.dense`), and where it
  moves what is seen by more than the misregistration tolerance in any direction (a slide
  along a line moves the line by the share of it across the line: twice the tolerance along a
  line that turns by a few degrees over the window moves it by less than the tolerance). The flow finds a
  slide in any direction only where the print's texture has two directions over its window;
  elsewhere (along a straight edge, over stretched stripes) a slide is reported as not sought
  (``slide_not_sought_mm2``) and left out of the share.

A slide is found where the part's stated smallest slide found is at most twice the tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workbench.camera import Camera
from workbench.validate import dense, print_warp
from workbench.views.visibility import smoothed_face_normals, unoccluded_many

MIN_COVERAGE = 0.95
CLASSES = ("slide", "ink_gone", "scratch")
CLASS_WORDS = {"slide": "a slide of the film", "ink_gone": "ink that is gone", "scratch": "a scratch"}
# a slide is found where the stated smallest slide found is at most this many tolerances: the
# flow's pixels are gated so that twice the tolerance stands out at the significance
SLIDE_TOLERANCES = 2.0
MAX_REGIONS = 20  # uncovered regions listed (the largest); the rest are counted
# the next photo: cameras on the viewing sphere around the part at the photos' own distance, at
# the elevations a fixture's markers stay in view from (below 20° the plate's markers foreshorten
# beyond what the pose needs), every 30° of azimuth
NEXT_AZIMUTHS_DEG = tuple(range(0, 360, 30))
NEXT_ELEVATIONS_DEG = (20.0, 35.0, 50.0, 65.0, 80.0)
NEXT_SEARCH_PX = 800  # the candidates' depth buffers at this width: occlusion at the part's scale
NEXT_MAX_POINTS = 20000  # uncovered points the candidates are scored on (evenly spread)


@dataclass(frozen=True)
class CoverageOptions:
    """What the part's coverage is judged by.

    Attributes
    ----------
    tolerance_mm : float
        The misregistration tolerance, mm: a slide of SLIDE_TOLERANCES times it must be found.
    max_delta_e : float
        The colour tolerance (ΔE): a defect that changes the colour by less does not count.
    min_coverage : float
        The share of each film, per class, the photos must cover for a PASS (0 to 1).
    max_defect_mm2 : float
        Uncovered regions smaller than this (print mm²) are counted, not listed.
    """

    tolerance_mm: float = 0.5
    max_delta_e: float = 3.0
    min_coverage: float = MIN_COVERAGE
    max_defect_mm2: float = 4.0


def design_lab(reference: np.ndarray) -> np.ndarray:
    """CIELAB of an sRGB image (D65, OpenCV's conversion in floats); (H, W, 3) float32, L in 0-100."""
    return cv2.cvtColor(reference.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)


def where_defects_show(reference: np.ndarray, px_per_mm: float, film_rgb, opts: CoverageOptions) -> dict:
    """Where each defect class would change what the part shows by more than the colour tolerance.

    Parameters
    ----------
    reference : (H, W, 3) uint8
        The print on the analysis grid.
    px_per_mm : float
        The grid's resolution, px per print mm.
    film_rgb : (3,) float
        The bare film's colour, sRGB 0-255.
    opts : CoverageOptions

    Returns
    -------
    dict of (H, W) bool
        ``slide``, ``ink_gone``, ``scratch``, and ``ink_not_sought``: ink that shows when gone
        but whose step to the film is within the colour test's reach (see above).
    """
    lab = design_lab(reference)
    film = design_lab(np.asarray(film_rgb, np.float32).reshape(1, 1, 3))[0, 0]
    ink = np.linalg.norm(lab - film, axis=-1) > opts.max_delta_e
    step = np.abs(reference.astype(np.float32) - np.asarray(film_rgb, np.float32)).max(axis=-1)
    sought = step > 2.0 * dense.COLOUR_TOL
    # a slide s along the unit direction d changes the colour at a pixel by J d s (J the Lab
    # colour's Jacobian, ΔE per print mm); over the window a slide is judged on (the flow's wide
    # window, where a bubble's slide is found), its mean square is s² dᵀ <JᵀJ> d, smallest along
    # the weaker eigenvector of the window's tensor <JᵀJ>, eigenvalue λ2 (λ1 the stronger)
    gx = (np.roll(lab, -1, 1) - np.roll(lab, 1, 1)) * 0.5 * px_per_mm
    gy = (np.roll(lab, -1, 0) - np.roll(lab, 1, 0)) * 0.5 * px_per_mm
    sigma = 4.0 * dense.TENSOR_SIGMA_PX
    jxx = cv2.GaussianBlur((gx * gx).sum(-1), (0, 0), sigma)
    jyy = cv2.GaussianBlur((gy * gy).sum(-1), (0, 0), sigma)
    jxy = cv2.GaussianBlur((gx * gy).sum(-1), (0, 0), sigma)
    root = np.sqrt(0.25 * (jxx - jyy) ** 2 + jxy * jxy)
    weaker = np.maximum(0.5 * (jxx + jyy) - root, 0.0)
    stronger = 0.5 * (jxx + jyy) + root
    s = SLIDE_TOLERANCES * opts.tolerance_mm
    # a slide shows where even the weaker direction changes the colour by more than the colour
    # tolerance, and moves what is seen by more than the misregistration tolerance: content
    # moved by s along d is seen moved by s sqrt(dᵀ <JᵀJ> d / λ1) (an edge with normal n by
    # s |d·n|, texture of every direction by s), at least s sqrt(λ2 / λ1). Along a line that
    # turns by a few degrees over the window a slide moves the line by a fraction of itself:
    # within the tolerance, as the tiles measure misregistration
    slide = (np.sqrt(weaker) * s > opts.max_delta_e) & (weaker * SLIDE_TOLERANCES**2 > stronger)
    # the flow finds a slide where the print's texture has two directions over its window (the
    # weaker eigenvalue of the window's structure tensor at the pixel's gate, MIN_TWO_WAY grey
    # levels² per px², on the print smoothed as the flow sees it): along an edge or over a
    # stretched stripe it knows one component only, a limit of the method, not of the photos
    grey = cv2.GaussianBlur(
        cv2.cvtColor(reference, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0), dense.REGISTRATION_BLUR_PX
    )
    two_way = dense.print_texture(grey, dense.TENSOR_SIGMA_PX)[3] >= dense.MIN_TWO_WAY
    return {
        "slide": slide & two_way,
        "ink_gone": ink & sought,
        "scratch": ink,
        "ink_not_sought": ink & ~sought,
        "slide_not_sought": slide & ~two_way,
    }


def found_maps(part_maps: dict, tolerance_mm: float) -> dict:
    """Where the part's photos find each class (:func:`workbench.validate.detection.part_maps`); (H, W) bool each."""
    return {
        "slide": part_maps["part_shift_limit_um"] <= SLIDE_TOLERANCES * tolerance_mm * 1000.0,
        "ink_gone": part_maps["part_dropout"].astype(bool),
        "scratch": part_maps["part_scratch"].astype(bool),
    }


def film_coverage(found: dict, shows: dict, film: np.ndarray, px_per_mm: float, opts: CoverageOptions) -> list[dict]:
    """Each film's coverage per defect class.

    Parameters
    ----------
    found, shows : dict of (H, W) bool
        Per class: where the photos find it (:func:`found_maps`) and where it would show
        (:func:`where_defects_show`).
    film : (H, W) int
        The film under each pixel (-1: off the part).
    px_per_mm : float
        The grid's resolution.
    opts : CoverageOptions

    Returns
    -------
    list of dict
        Per film: ``film`` (1-based), ``area_mm2`` (print), ``ink_gone_not_sought_mm2`` (pale
        ink: see above), and per class ``share`` (None where the class shows nowhere on it),
        ``shows_mm2``, ``covered`` (share at least ``min_coverage``, or nothing to cover).
    """
    mm2 = 1.0 / (px_per_mm * px_per_mm)
    out = []
    for k in np.unique(film[film >= 0]):
        mine = film == k
        entry = {"film": int(k) + 1, "area_mm2": round(float(mine.sum()) * mm2, 1)}
        for c in ("slide", "ink"):
            if f"{c}_not_sought" in shows:
                name = "ink_gone" if c == "ink" else c
                entry[f"{name}_not_sought_mm2"] = round(float((mine & shows[f"{c}_not_sought"]).sum()) * mm2, 1)
        for c in CLASSES:
            where = mine & shows[c]
            n = int(where.sum())
            share = float((where & found[c]).sum() / n) if n else None
            entry[c] = {
                "share": None if share is None else round(share, 4),
                "shows_mm2": round(n * mm2, 1),
                "covered": share is None or share >= opts.min_coverage,
            }
        out.append(entry)
    return out


def uncovered_regions(uncovered: dict, combined: np.ndarray, px_per_mm: float, opts: CoverageOptions) -> dict:
    """The regions no photo covers, with why, in print millimetres.

    Parameters
    ----------
    uncovered : dict of (H, W) bool
        Per class: where it would show and no photo finds it.
    combined : (H, W) uint8
        The part's state map (the most telling state any photo gives a pixel).
    px_per_mm : float
        The grid's resolution.
    opts : CoverageOptions

    Returns
    -------
    dict
        ``regions``: the largest MAX_REGIONS regions of at least ``max_defect_mm2`` (each:
        ``centre_mm``, a point in it (:func:`region_point`), ``bbox_mm``, ``area_mm2``,
        ``classes`` it leaves uncovered, ``why``: the state that most of it has in the best photo
        and its share), ``smaller``: how many more, ``area_mm2``: all of it.
    """
    anyc = np.zeros(combined.shape, bool)
    for m in uncovered.values():
        anyc |= m
    mm2 = 1.0 / (px_per_mm * px_per_mm)
    n, lab, stats, cents = cv2.connectedComponentsWithStats(anyc.astype(np.uint8), connectivity=8)
    order = np.argsort(-stats[1:, cv2.CC_STAT_AREA], kind="stable") + 1
    regions, smaller = [], 0
    for i in order:
        area = float(stats[i, cv2.CC_STAT_AREA]) * mm2
        if area < opts.max_defect_mm2 or len(regions) >= MAX_REGIONS:
            smaller += 1
            continue
        x, y, w, h = (int(v) for v in stats[i, :4])
        box = (slice(y, y + h), slice(x, x + w))
        inside = lab[box] == i
        states, counts = np.unique(combined[box][inside], return_counts=True)
        top = int(np.argmax(counts))
        s = int(states[top])
        why = (
            "measured, but below the stated limit there (too little texture or ink contrast for the photos' "
            "noise and blur)"
            if s in print_warp.MEASURED
            else print_warp.STATE_NAMES[s]
        )
        cx, cy = region_point(inside, float(cents[i, 0]) - x, float(cents[i, 1]) - y)
        regions.append(
            {
                "centre_mm": [round((cx + x + 0.5) / px_per_mm, 2), round((cy + y + 0.5) / px_per_mm, 2)],
                "bbox_mm": [round(v / px_per_mm, 2) for v in (x, y, x + w, y + h)],
                "area_mm2": round(area, 1),
                "classes": [c for c in CLASSES if (uncovered[c][box] & inside).any()],
                "why": why,
                "why_share": round(float(counts[top]) / float(inside.sum()), 3),
            }
        )
    return {"regions": regions, "smaller": smaller, "area_mm2": round(float(anyc.sum()) * mm2, 1)}


def region_point(inside: np.ndarray, cx: float, cy: float) -> tuple[float, float]:
    """A point of a region to name it by: its centroid where that lies in it, else the nearest well inside it.

    A ring (a film's outline band, uncovered all round) has its centroid outside it, where a
    technician would look in vain; the point then is the region's pixel nearest the centroid
    among those at least half the region's largest distance from its edge.

    Parameters
    ----------
    inside : (h, w) bool
        The region in its bounding box.
    cx, cy : float
        Its centroid, box px.

    Returns
    -------
    (x, y) : float
        Box px (pixel centres at integers).
    """
    h, w = inside.shape
    ix, iy = int(round(cx)), int(round(cy))
    if 0 <= ix < w and 0 <= iy < h and inside[iy, ix]:
        return cx, cy
    # (distances to the edge, the box's border counting as outside)
    pad = np.pad(inside, 1).astype(np.uint8)
    depth = cv2.distanceTransform(pad, cv2.DIST_L2, 3)[1:-1, 1:-1]
    yy, xx = np.nonzero(depth >= 0.5 * depth.max())
    k = int(np.argmin((xx - cx) ** 2 + (yy - cy) ** 2))
    return float(xx[k]), float(yy[k])


def next_photo(
    V: np.ndarray,
    F: np.ndarray,
    X: np.ndarray,
    face: np.ndarray,
    centres: np.ndarray,
    intrinsics: Camera,
    orbit_camera,
) -> dict | None:
    """The camera on the fixture that sees the most of the uncovered surface at a scorable angle.

    Each candidate (azimuth every 30°, elevations NEXT_ELEVATIONS_DEG, at the photos' median
    distance from the part's centre, with the photos' intrinsics) counts the uncovered points in
    its frame, facing it within the obliquity a photo scores (cos θ ≥ 1 / MAX_GRAZING), not
    hidden (its own depth buffer) and seen from at least twice the lamp's mirror cone away from
    every photo that already saw it (the same view sees the same glint and blur). What it would
    then find there depends on the print's texture and ink, as in any photo: the share is of the
    surface it sees well, an upper bound.

    Parameters
    ----------
    V, F : arrays
        The part, mm.
    X : (n, 3) float
        Uncovered surface points, mm (evenly spread: each stands for the same print area).
    face : (n,) int
        Their triangles.
    centres : (k, 3) float
        The photos' camera centres, mm.
    intrinsics : Camera
        The photos' camera (K, image size).
    orbit_camera : callable
        ``(az_deg, el_deg, dist_mm, width, height, fov_deg, intrinsics) -> Camera`` around the
        part's centre (:meth:`workbench.design_dir.Design.orbit_camera`).

    Returns
    -------
    dict or None
        ``orbit``: [azimuth°, elevation°, distance mm] (azimuth 0 in front of the part, towards
        -y, counter-clockwise seen from above), ``sees_share``: the share of the uncovered
        points it sees well; None when there is nothing uncovered or no candidate sees any.
    """
    if len(X) == 0:
        return None
    if len(X) > NEXT_MAX_POINTS:
        pick = np.linspace(0, len(X) - 1, NEXT_MAX_POINTS).astype(np.int64)
        X, face = X[pick], face[pick]
    centre = 0.5 * (V.min(axis=0) + V.max(axis=0))
    dist = float(np.median(np.linalg.norm(np.asarray(centres) - centre, axis=1))) if len(centres) else 300.0
    # each photo's direction to each point
    seen_from = []
    for c in np.asarray(centres, np.float64).reshape(-1, 3):
        d = c - X
        seen_from.append(d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12))
    n = smoothed_face_normals(V, F)[face]
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    s = NEXT_SEARCH_PX / intrinsics.width
    K = intrinsics.K.copy()
    K[:2] *= s
    small = Camera(K, np.eye(3), np.zeros(3), NEXT_SEARCH_PX, max(1, round(intrinsics.height * s)))
    best, best_n = None, 0
    for el in NEXT_ELEVATIONS_DEG:
        for az in NEXT_AZIMUTHS_DEG:
            pose = orbit_camera(az, el, dist, small.width, small.height, 40.0, small)
            cam = Camera(pose.K, pose.R, pose.t, small.width, small.height)
            to_cam = cam.center - X
            cos = (n * to_cam).sum(axis=1) / np.maximum(np.linalg.norm(to_cam, axis=1), 1e-12)
            xy, z = cam.project(X)
            ok = (cos >= 1.0 / print_warp.MAX_GRAZING) & (z > 0)
            # (seen from where a photo already saw it, a point stays as it was: under the same
            # glint, at the same blur; the lamp's reflection leaves a point once the camera turns
            # by more than twice the mirror cone's half-width, dense.MIRROR_DEG)
            v = to_cam / np.maximum(np.linalg.norm(to_cam, axis=1, keepdims=True), 1e-12)
            for u in seen_from:
                ok &= (v * u).sum(axis=1) <= np.cos(np.radians(2.0 * dense.MIRROR_DEG))
            ok &= (xy[:, 0] >= 0) & (xy[:, 1] >= 0) & (xy[:, 0] <= cam.width - 1) & (xy[:, 1] <= cam.height - 1)
            if ok.sum() <= best_n:
                continue
            depth = print_warp.photo_buffers(cam, V, F)[1]
            seen = np.zeros(len(X), bool)
            unoccluded_many(depth, cam.width, cam.height, cam.K[0, 0], xy, z, seen)
            k = int((ok & seen).sum())
            if k > best_n:
                best, best_n = (az, el), k
    if best is None:
        return None
    return {"orbit": [float(best[0]), float(best[1]), round(dist, 1)], "sees_share": round(best_n / len(X), 4)}


def open_next_photo(still: list[dict], combined: np.ndarray, grid, seen_from: tuple) -> dict | None:
    """The next photo for the part's open regions (:func:`next_photo` on their pixels), or None.

    A region a photo cannot tell a defect from light on is decided by a photo from more than
    twice the lamp's mirror cone away from every photo that saw it (:func:`next_photo` keeps
    only such views).

    Parameters
    ----------
    still : list of dict
        The part's open defects (``bbox_mm``, print mm).
    combined : (H, W) uint8
        The part's state map (their pixels: DEFECT within their boxes).
    grid : PrintGrid
        The analysis grid (``X``, ``face``, ``px_per_mm``).
    seen_from : tuple
        (V, F, camera centres (k, 3), intrinsics Camera, orbit_camera), as :func:`part_coverage`
        takes them.

    Returns
    -------
    dict or None
        :func:`next_photo`'s answer with ``for``: "the open regions".
    """
    where = np.zeros(combined.shape, bool)
    for d in still:
        box = print_warp.box_slices(d["bbox_mm"], grid.px_per_mm)
        where[box] |= combined[box] == print_warp.DEFECT
    ii, jj = np.nonzero(where & np.isfinite(grid.X[..., 0]))
    V, F, centres, intrinsics, orbit = seen_from
    nxt = next_photo(V, F, grid.X[ii, jj], grid.face[ii, jj], centres, intrinsics, orbit)
    return None if nxt is None else {**nxt, "for": "the open regions"}


def part_coverage(
    maps: dict, grid, combined: np.ndarray, photos, opts: CoverageOptions, photos_px_per_mm: float | None = None
) -> tuple[dict, dict]:
    """The part's coverage per film and class, its uncovered regions and the next photo.

    Parameters
    ----------
    maps : dict
        The part's detection maps (:func:`workbench.validate.detection.part_maps`).
    grid : PrintGrid
        The analysis grid (its films, surface and faces).
    combined : (H, W) uint8
        The part's state map.
    photos : tuple
        (V, F, camera centres (k, 3), intrinsics Camera or None, orbit_camera): what the next
        photo is sought from (:func:`next_photo`); None for no suggestion.
    opts : CoverageOptions
    photos_px_per_mm : float, optional
        The finest photo's photo pixels per print mm (median over what it scores): what a
        finer photo is asked for against (:func:`finer_photo`).

    Returns
    -------
    coverage : dict
        ``min_coverage``, ``films`` (:func:`film_coverage`), ``complete``, ``uncovered``
        (:func:`uncovered_regions`), ``next_photo`` (:func:`next_photo`) and ``finer_photo``
        (:func:`finer_photo`) when incomplete, and ``note``.
    uncovered : dict of (H, W) bool
        Per class, where it would show and no photo finds it.
    """
    from workbench.render.defects import FILM_RGB

    on = np.isfinite(grid.X[..., 0])
    film = grid.film if grid.film is not None else np.where(on, 0, -1)
    shows = where_defects_show(grid.reference, grid.px_per_mm, FILM_RGB, opts)
    found = found_maps(maps, opts.tolerance_mm)
    films = film_coverage(found, shows, film, grid.px_per_mm, opts)
    uncovered = {c: shows[c] & ~found[c] & (film >= 0) for c in CLASSES}
    complete = all(f[c]["covered"] for f in films for c in CLASSES)
    out = {
        "min_coverage": opts.min_coverage,
        "complete": complete,
        "films": films,
        "uncovered": uncovered_regions(uncovered, combined, grid.px_per_mm, opts),
        "note": (
            "per film and defect class, the share of the film where the defect would show (ink and scratches: "
            f"where the design's colour differs from the bare film's by more than ΔE {opts.max_delta_e:g}; a "
            f"slide: where one of {SLIDE_TOLERANCES:g} times the tolerance, in any direction, changes the colour by "
            "more than that and moves what is seen by more than the tolerance) "
            "and the part's photos together find it (detection.npz, part_*); a part that passes with a share "
            "below min_coverage is INCOMPLETE. Broad ink loss is not sought where the ink's step to the film is "
            f"within {2 * dense.COLOUR_TOL:g} grey levels (the colour test's tolerance, twice): "
            "ink_gone_not_sought_mm2; a slide is not sought where the print's texture has one direction only over "
            "the flow's window: slide_not_sought_mm2. Both are limits of the method that more photos do not lift"
        ),
    }
    anyc = np.zeros(on.shape, bool)
    for m in uncovered.values():
        anyc |= m
    if anyc.any():
        # what a photo measured and still could not find a defect in (texture or ink contrast too
        # low for its noise, detail finer than its pixels, the lamp's glint over uniform ink) asks
        # for a finer photo or another angle; what none measured (hidden, oblique, at an edge,
        # under a highlight) for another angle
        out["uncovered"]["measured_share"] = round(float(np.isin(combined[anyc], print_warp.MEASURED).mean()), 4)
    if not complete:
        out["finer_photo"] = finer_photo(maps, uncovered["slide"], opts.tolerance_mm, photos_px_per_mm)
    if not complete and photos is not None:
        V, F, centres, intrinsics, orbit = photos
        ii, jj = np.nonzero(anyc)
        if intrinsics is not None:
            out["next_photo"] = next_photo(V, F, grid.X[ii, jj], grid.face[ii, jj], centres, intrinsics, orbit)
    return out, uncovered


# a finer photo is asked for up to this many times the finest photo's pixels per mm: beyond it,
# the slide limit there is not set by the photo's sampling
MAX_FINER = 4.0


def finer_photo(maps: dict, uncovered_slide: np.ndarray, tolerance_mm: float, px_per_mm: float | None) -> dict | None:
    """How much finer a photo must sample the print to find a slide where the photos state they find only larger ones.

    The smallest slide a photo finds is its flow's uncertainty times the significance over the
    tolerance; the uncertainty is the photo's noise through the texture it resolves and the
    flow's floor, both in photo pixels (``dense.PHOTO_FLOOR_PX``), so in mm it scales with the
    photo's pixel on the print. Where the part's stated smallest slide is larger than the slide
    the coverage asks for (SLIDE_TOLERANCES times the tolerance), a photo finer by their ratio
    finds it; the figure is the ratio that covers 90 % of those pixels, and the pixels where no
    slide is found at all (no texture the photo resolves) are counted apart.

    Parameters
    ----------
    maps : dict
        The detection maps (``part_shift_limit_um``).
    uncovered_slide : (H, W) bool
        Where a slide would show and no photo finds one.
    tolerance_mm : float
    px_per_mm : float or None
        The finest photo's pixels per print mm.

    Returns
    -------
    dict or None
        ``factor`` (at most MAX_FINER), ``needed_photo_px_per_mm``, ``photo_px_per_mm``,
        ``share_found_at_factor`` (of the uncovered slide area), ``share_without_limit`` (no slide
        found there at any size); None when nothing is uncovered for a slide.
    """
    n = int(uncovered_slide.sum())
    if n == 0:
        return None
    limit = maps["part_shift_limit_um"][uncovered_slide].astype(np.float64)
    from workbench.validate.detection import NONE_UM

    finite = limit < NONE_UM
    ratio = limit[finite] / (SLIDE_TOLERANCES * tolerance_mm * 1000.0)
    factor = float(min(np.percentile(ratio, 90), MAX_FINER)) if len(ratio) else MAX_FINER
    return {
        "factor": round(factor, 2),
        "photo_px_per_mm": None if px_per_mm is None else round(px_per_mm, 2),
        "needed_photo_px_per_mm": None if px_per_mm is None else round(px_per_mm * factor, 2),
        "share_found_at_factor": round(float((ratio <= factor).sum()) / n, 4),
        "share_without_limit": round(float((~finite).sum()) / n, 4),
    }


def coverage_words(films: list[dict], opts: CoverageOptions) -> str:
    """What is not covered, in a line: each film and class below ``min_coverage``."""
    short = []
    for f in films:
        for c in CLASSES:
            share = f[c]["share"]
            if share is not None and share < opts.min_coverage:
                short.append(f"{CLASS_WORDS[c]} on {100 * share:.0f} % of film {f['film']}")
        if short and len(films) == 1:
            short = [s.replace(f" of film {f['film']}", " of the film") for s in short]
    return f"the photos find {', '.join(short)} (at least {100 * opts.min_coverage:.0f} % needed)"


def next_photo_line(nxt: dict) -> str:
    """The next photo (:func:`next_photo`, with ``for`` when it is for the open regions) in words."""
    az, el, dist = nxt["orbit"]
    return (
        f"next photo: azimuth {az:g}°, elevation {el:g}°, {dist:g} mm from the part's centre (it sees "
        f"{100 * nxt['sees_share']:.0f} % of {nxt.get('for', 'what is uncovered')} from a new angle)"
    )


def next_photo_words(cov: dict) -> str:
    """The advice for the next photo, from the part's coverage (:func:`part_coverage`)."""
    words = []
    nxt = cov.get("next_photo")
    if nxt:
        words.append(next_photo_line(nxt))
    measured = (cov.get("uncovered") or {}).get("measured_share")
    if measured:
        words.append(
            f"{100 * measured:.0f} % of what is uncovered was measured and is below the stated limit there: "
            "a finer photo (closer, or more pixels) or one without the lamp's glint there"
        )
    fine = cov.get("finer_photo")
    if fine and fine.get("needed_photo_px_per_mm"):
        words.append(
            f"a slide is found on {100 * fine['share_found_at_factor']:.0f} % of where it is not yet with a photo "
            f"{fine['factor']:g} times finer ({fine['needed_photo_px_per_mm']:g} photo px per print mm; the finest "
            f"now: {fine['photo_px_per_mm']:g})"
        )
    return "; ".join(words)
