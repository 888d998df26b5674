"""The defects: connected regions of excess misregistration or colour, sized on the print."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from workbench.validate.dense.options import (
    MIN_DEFECT_MM2,
    MIN_SHIFT_WINDOWS,
    MISSING_GAP_MM,
    SHIFT_CLOSE_MM,
    TENSOR_SIGMA_PX,
)
from workbench.validate.print_warp import PrintGrid


def shift_explained(
    ref_n: np.ndarray,
    pho_n: np.ndarray,
    flow: np.ndarray,
    region: np.ndarray,
    factor: int = 1,
    under_light: bool = False,
) -> float | None:
    """Share of the residual over a region that moving the print by the flow takes away.

    ``under_light``: against another account of the residual than the print where it is, light
    that varies smoothly over the region (a glossy film's sheen, shading the local exposure
    normalisation leaves), a second-order surface of position, as the photometric model allows
    both of its hypotheses. Both the print where it is and the print moved by the flow are then
    taken under the surface of light that fits each best, and the flow must explain what light
    does not. A slide moves the ink's texture, which no smooth light does; a sheen's gradient over
    faint texture pulls the flow by a pixel, and "moving" the print then explains little that the
    light does not (the glossy cow's perfect photo: a 9.4 mm² region whose flow explained 0.85 of
    the unmoved residual and 0.61 of what the light leaves; a 6 mm bubble's flow 0.96 and 0.95).
    But a slide of artwork that is smooth over the region (streaks 40 px apart, a region 16 to 32
    px across) is light's look too (0.02 to 0.4): the photo alone does not tell them, and the
    lamp decides (see :func:`workbench.validate.dense.pipeline._defects`).

    Judged at the flow's own resolution: where the photo is coarser than the grid, the
    print's detail finer than the photo's pixel is a residual no shift explains (a 12 mm
    bubble's flow explained 0.37 of the full grid's residual and 0.96 of the flow grid's).

    Parameters
    ----------
    ref_n, pho_n : (h, w) float32
        The print and the photo on it, locally normalised, as the flow compared them
        (:func:`dense_flow`: on the grid reduced by ``factor``).
    flow : (H, W, 2) float32
        The dense flow, grid px.
    region : (H, W) bool
        The pixels of the region.
    factor : int
        The flow's reduction of the grid (:func:`flow_factor`).
    under_light : bool
        Each account under its best smooth light.

    Returns
    -------
    float or None
        1 - |r1 - S1|² / |r0 - S0|², with r0 the residual of the print where it is, r1 that of
        the print moved by the flow, and S0, S1 the second-order surfaces of position that fit
        them best (least squares), or 0 without ``under_light``; None for an empty region.
    """
    if factor > 1:
        h, w = ref_n.shape
        flow = cv2.resize(flow, (w, h), interpolation=cv2.INTER_AREA)
        flow[..., 0] *= w / region.shape[1]
        flow[..., 1] *= h / region.shape[0]
        region = cv2.resize(region.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) > 0.5
    ii, jj = np.nonzero(region)
    if len(ii) == 0:
        return None
    # (in floats: the normalised images are uint8, whose differences and squares wrap)
    ref_n, pho_n = ref_n.astype(np.float32), pho_n.astype(np.float32)
    y0, y1, x0, x1 = ii.min(), ii.max() + 1, jj.min(), jj.max() + 1
    box = (slice(y0, y1), slice(x0, x1))
    gx, gy = np.meshgrid(np.arange(x0, x1, dtype=np.float32), np.arange(y0, y1, dtype=np.float32))
    moved = cv2.remap(
        ref_n, gx - flow[box][..., 0], gy - flow[box][..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    inside = region[box]
    r0 = (pho_n[box] - ref_n[box])[inside].astype(np.float64)
    r1 = (pho_n[box] - moved)[inside].astype(np.float64)
    if under_light:
        # (both accounts under their smooth light: the flow must explain what light does not)
        x, y = (jj - jj.mean()) / max(x1 - x0, 1), (ii - ii.mean()) / max(y1 - y0, 1)
        e0, e1 = _smooth_light_left(r0, x, y), _smooth_light_left(r1, x, y)
    else:
        e0, e1 = float((r0 * r0).sum()), float((r1 * r1).sum())
    return 1.0 - e1 / e0 if e0 > 0 else 0.0


def _smooth_light_left(r: np.ndarray, x: np.ndarray, y: np.ndarray) -> float:
    """|r - S|² for the second-order surface S of position (x, y) that fits the residual r best; (n,) each."""
    if len(r) <= 6:
        return float((r * r).sum())
    M = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1).astype(np.float64)
    coef, *_ = np.linalg.lstsq(M, r, rcond=None)
    left = r - M @ coef
    return float((left * left).sum())


def _hull_box(ii: np.ndarray, jj: np.ndarray, reach_px: int, shape) -> tuple[tuple[slice, slice], np.ndarray]:
    """The convex hull of pixels (rows ``ii``, columns ``jj``), grown by ``reach_px``, in its box.

    Returns
    -------
    box : (slice, slice)
        The hull's box plus the reach, within ``shape`` (the dilation need not sweep the whole grid).
    hull : bool array of the box's shape
    """
    pts = np.stack([jj, ii], axis=1).astype(np.int32)
    hull = cv2.convexHull(pts)
    x0, y0 = max(int(jj.min()) - reach_px, 0), max(int(ii.min()) - reach_px, 0)
    x1, y1 = min(int(jj.max()) + reach_px + 1, shape[1]), min(int(ii.max()) + reach_px + 1, shape[0])
    sub = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillConvexPoly(sub, hull - np.array([x0, y0], np.int32), 1)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach_px + 1, 2 * reach_px + 1))
    return (slice(y0, y1), slice(x0, x1)), cv2.dilate(sub, disc).astype(bool)


def _full(shape, mask) -> np.ndarray:
    """A mask as a whole image: ``mask`` itself, or a ``(box, pixels)`` pair made whole (a new array)."""
    if isinstance(mask, np.ndarray):
        return mask
    box, pixels = mask
    out = np.zeros(shape, bool)
    out[box] = pixels
    return out


def _count(mask) -> int:
    """Pixels of a mask, whole or ``(box, pixels)``."""
    return np.count_nonzero(mask if isinstance(mask, np.ndarray) else mask[1])


def _filled(region: np.ndarray) -> np.ndarray:
    """The region with its holes filled (a bubble's plain squares are inside it, not around it)."""
    cs, _ = cv2.findContours(region.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    out = np.zeros(region.shape, np.uint8)
    cv2.drawContours(out, cs, -1, 1, thickness=cv2.FILLED)
    return out.astype(bool) | region


def find_defects(
    shift_bad,
    colour_bad,
    missing,
    shift_mm,
    colour_res,
    grid: PrintGrid,
    alpha=None,
    evidence=None,
    z_shift=None,
    z_colour=None,
    window_px: float = TENSOR_SIGMA_PX,
    extent=None,
    measured=None,
    core=None,
):
    """Connected regions of excess misregistration or colour residual, sized on the print.

    Parameters
    ----------
    shift_bad, colour_bad, missing : (H, W) bool
        Pixels beyond the misregistration tolerance, beyond the colour tolerance, and
        showing bare film.
    shift_mm, colour_res : (H, W) float
        Misregistration (mm on the surface) and colour residual (grey levels).
    grid : PrintGrid
    alpha : (H, W) float, optional
        Share of the ink gone per pixel (0 to 1). A region of missing ink is sized by its
        sum (sub-pixel, and independent of the blur, which only spreads it) and located at
        its weighted centre; a threshold would size a thin scratch by the blur's width.
    evidence : (H, W) bool, optional
        Where the misregistration actually measured (full vector, or the component across
        an edge) exceeds the tolerance; a shift region needs a quarter of its pixels there.
    z_shift, z_colour : (H, W) float, optional
        Per pixel, by how many standard uncertainties the misregistration and the colour
        residual exceed their tolerances.
    window_px : float
        The flow's window (Gaussian sigma, grid px): pixels closer than about its size share
        their evidence, so a region of n pixels holds n / (4π window²) independent ones.
    extent, measured : (H, W) float and bool, optional
        The misregistration that sizes a shift region (mm; the flow's own vector, which DIS
        spreads evenly over plain patches and across the region's edge) and where the photo
        is scored: a region extends over the scored pixels around it where ``extent`` is at
        least half its upper quartile.
    core : (H, W) bool, optional
        The part of ``evidence`` that pixels measure on their own (not a window of about a
        millimetre around them, which reaches past a slid region's rim): where it holds two
        windows of a region, it alone sets the flow's level the region is sized at (its
        place is the hull of all its evidence).

    Returns
    -------
    labels : (H, W) int32
        Defect number + 1 per pixel, 0 elsewhere.
    defects : list of dict
        In decreasing order of area.
    """
    k3 = np.ones((3, 3), np.uint8)
    # an opening drops isolated pixels (noise, JPEG), a closing joins a region's parts
    sb = cv2.morphologyEx(shift_bad.astype(np.uint8), cv2.MORPH_OPEN, k3)
    # (not ink that is gone: a scratch on a coarse grid is two pixels wide, and the opening would
    # take it; its specks are what MIN_DEFECT_MM2 drops)
    cb = cv2.morphologyEx(colour_bad.astype(np.uint8), cv2.MORPH_OPEN, k3) | (colour_bad & missing).astype(np.uint8)
    both = cv2.morphologyEx(sb | cb, cv2.MORPH_CLOSE, k3)
    # ink gone in pieces a short gap apart is one defect: a scratch across a checker loses its
    # ink on the dark squares, and over the light ones the step to the film is too small to see
    # (the gap's pixels join the region's connection, not its area; and a scratch's thin
    # stretches, which the opening drops, connect its pieces too)
    r = max(1, int(round(0.5 * MISSING_GAP_MM * grid.px_per_mm)))
    gone = colour_bad & missing
    bridge = cv2.dilate(gone.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    # (each region's bounding box with it: the bridge's pixels only widen a box, which holds all of
    # the region's pixels still)
    n, lab, boxes, _ = cv2.connectedComponentsWithStats(both | bridge, connectivity=8)
    lab[both == 0] = 0
    px_mm2 = 1.0 / grid.px_per_mm**2
    two_windows = MIN_SHIFT_WINDOWS * 4 * np.pi * window_px**2
    reach = int(math.ceil(3 * window_px))
    if extent is not None:
        # where a shift region may grow: the measured pixels' extent (-inf elsewhere), once (the
        # same pixels as extent >= level where measured: a level is half a length, never -inf)
        grow = np.where(measured, extent, -np.inf).astype(extent.dtype, copy=False)

    # each region's kind and pixels; a shift region grown to where the flow reaches half its
    # shift, and shift regions that grow into one another merged (one bubble, one defect)
    def one(k: int):
        # the region's own pixels from its bounding box (a photo with the film off has some 60
        # regions: full-size comparisons for each took a second); its masks stay in boxes until
        # merged (full-size masks of every region took a quarter gigabyte)
        x0, y0, w, h = boxes[k, :4]
        box = (slice(y0, y0 + h), slice(x0, x0 + w))
        in_box = lab[box] == k
        s_in, c_in = in_box & (sb[box] > 0), in_box & (cb[box] > 0)
        if evidence is not None and (s_in & evidence[box]).sum() < 0.25 * s_in.sum():
            s_in &= evidence[box]  # the rest is the flow's guess along an edge
        ns, nc = int(s_in.sum()), int(c_in.sum())
        if (ns + nc) == 0:
            return None
        s_px = (box, s_in)
        # a bubble's flow edges leave a little colour residual (under 1 % of its area in
        # tests); ink that is gone leaves a lot, and drags the flow around it too
        if nc >= 0.2 * ns:
            kind = "missing" if (in_box & missing[box]).sum() > 0.5 * nc else "colour"
        else:
            kind = "shift"
            if extent is not None:
                # found by significance, sized at half its height: the flow ramps from the slid
                # region's shift to 0 over the flow's window, and crosses half of it at the
                # region's edge whatever the tolerance (the tolerance's threshold would size a
                # large slide too large and a slide just above the tolerance too small)
                # (from the pixels' own evidence where it holds two windows: a millimetre
                # window's reaches past the rim, where the flow is already down; and the upper
                # quartile's half, which that reach does not lower as it would a median's)
                seeds = s_in
                if core is not None and (s_in & core[box]).sum() >= two_windows:
                    seeds = s_in & core[box]
                level = 0.5 * float(np.percentile(extent[box][seeds], 75))
                n_h, lab_h = cv2.connectedComponents((grow >= level).view(np.uint8), connectivity=8)
                hit = np.unique(lab_h[box][seeds])
                # (within the hull of its evidence and the flow's reach around it: a slid
                # region's plain patches lie between its textured edges, and beyond them the
                # flow ramps down over its window; a weak region's half height is the flow's
                # noise, which would otherwise grow it over the print: 53,000 mm² on a face)
                # (the hull of all its evidence, the windows' too: eroded by half a window, theirs
                # stays inside a slide up to about 2.5 times the tolerance and reaches past a larger
                # one's rim, 0.7 mm for a 1 mm slide, 1.4 mm for 2 mm, where the level above still
                # holds the growth; the pixels' own alone cover only where the print has texture,
                # and left a path-traced cow's 6 mm bubble, textured on one side, at 17 of 28 mm²,
                # 1.2 mm off)
                ii, jj = np.nonzero(s_in if evidence is None else s_in & evidence[box])
                hull_box, hull = _hull_box(ii + y0, jj + x0, reach, lab.shape)
                taken = np.zeros(n_h, bool)
                taken[hit[hit > 0]] = True
                # (the grown region lies in the hull's box; the seeds in the region's: both boxes)
                (hy0, hx0), (hy1, hx1) = ((b.start for b in hull_box), (b.stop for b in hull_box))
                gy0, gx0, gy1, gx1 = min(hy0, y0), min(hx0, x0), max(hy1, y0 + h), max(hx1, x0 + w)
                grown = np.zeros((gy1 - gy0, gx1 - gx0), bool)
                grown[hy0 - gy0 : hy1 - gy0, hx0 - gx0 : hx1 - gx0] = taken[lab_h[hull_box]] & hull
                grown[y0 - gy0 : y0 - gy0 + h, x0 - gx0 : x0 - gx0 + w] |= seeds
                s_px = ((slice(gy0, gy1), slice(gx0, gx1)), grown)
        return [kind, (box, in_box), s_px, (box, c_in), ns, nc]

    if n > 8:
        # (the regions one by one on two threads: most of a region's time is its components,
        # which release the GIL)
        with ThreadPoolExecutor(max_workers=2) as pool:
            regions = [r for r in pool.map(one, range(1, n)) if r is not None]
    else:
        regions = [r for r in map(one, range(1, n)) if r is not None]
    merged: list = []
    for r in sorted(regions, key=lambda r: -_count(r[2])):
        if r[0] == "shift":
            into = next((m for m in merged if m[0] == "shift" and (m[2] & _full(lab.shape, r[2])).any()), None)
            if into is not None:
                into[1] |= _full(lab.shape, r[1])
                into[2] |= _full(lab.shape, r[2])
                into[4] += r[4]
                continue
        merged.append([r[0], _full(lab.shape, r[1]), _full(lab.shape, r[2]), _full(lab.shape, r[3]), r[4], r[5]])
    found = []
    for kind, region, s_px, c_px, ns, nc in merged:
        if kind != "shift":
            sized = c_px
        elif evidence is not None and (s_px & evidence).sum() < MIN_SHIFT_WINDOWS * 4 * np.pi * window_px**2:
            # evidence within a single flow window is one measurement: DIS's errors have tails
            # its uncertainty does not describe (it drifted 13 px over a photograph's soft
            # background, 12 pixels beyond 3 sigma), so a slid region needs two windows of it
            continue
        else:
            # a shift shows only where there is texture: the slid region's plain patches between
            # its edges belong to it too (a closing of SHIFT_CLOSE_MM: 1.5 mm made a 12 mm bubble
            # 10 % too large, none left a 6 mm one 15 % too small; 1 mm: -1 % and -12 %)
            r = max(1, int(round(SHIFT_CLOSE_MM * grid.px_per_mm / 2)))
            disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
            sized = cv2.morphologyEx(s_px.astype(np.uint8), cv2.MORPH_CLOSE, disc).astype(bool) | s_px
        ii, jj = np.nonzero(sized)
        wts = np.ones(len(ii))
        if kind == "missing" and alpha is not None:
            # the blur's tails reach a few pixels beyond the thresholded region
            grown = cv2.dilate(region.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
            ii, jj = np.nonzero(grown)
            wts = alpha[ii, jj].astype(np.float64)
        area = float(wts.sum()) * px_mm2
        if area < MIN_DEFECT_MM2:
            continue
        centre = [
            float(((jj + 0.5) * wts).sum() / wts.sum() / grid.px_per_mm),
            float(((ii + 0.5) * wts).sum() / wts.sum() / grid.px_per_mm),
        ]
        sm = shift_mm[region & np.isfinite(shift_mm)]
        # the region's significance: its mean excess in standard uncertainties, times the
        # square root of its independent measurements; the confidence is the one-sided
        # normal probability that the excess is not chance
        zmap = z_colour if kind != "shift" else z_shift
        zs = zmap[sized & np.isfinite(zmap)] if zmap is not None else np.zeros(0)
        n_ind = max(1.0, len(zs) / (4 * np.pi * window_px * window_px))
        z = float(np.clip(np.mean(zs), 0, None) * np.sqrt(n_ind)) if len(zs) else None
        found.append(
            {
                "kind": kind,
                "centre_mm": centre,
                "area_mm2": area,
                "area_surface_mm2": float((grid.surface_per_print[ii, jj] ** 2 * wts).sum() * px_mm2),
                "bbox_mm": [
                    float(jj.min() / grid.px_per_mm),
                    float(ii.min() / grid.px_per_mm),
                    float((jj.max() + 1) / grid.px_per_mm),
                    float((ii.max() + 1) / grid.px_per_mm),
                ],
                "peak_mm": float(sm.max()) if len(sm) else None,
                "mean_mm": float(sm.mean()) if len(sm) else None,
                "colour_peak": float(np.nanmax(colour_res[region])) if nc else 0.0,
                "significance_z": z,
                "confidence": (float(0.5 * math.erfc(-z / math.sqrt(2))) if z is not None else None),
                "shift_area_mm2": ns * px_mm2,
                "colour_area_mm2": nc * px_mm2,
                "_mask": _filled(region),
            }
        )
    found.sort(key=lambda d: (-d["area_mm2"], d["centre_mm"]))
    labels = np.zeros(lab.shape, np.int32)
    for i, d in enumerate(found):
        labels[d.pop("_mask")] = i + 1
    return labels, found
