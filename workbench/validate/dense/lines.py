"""Thin lines of ink gone (scratches), and telling them from a glint."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.special import erf

from workbench.validate.dense.options import (
    DETECT_Z,
    KEPT_CONTRAST,
    KEPT_TEXTURE,
    LOST_MIN_CONTRAST,
    MIN_CORE_PX,
    NOISE_BLOCK_PX,
    NOISE_FLOOR,
    SCRATCH_MM,
    SCRATCH_WIDTH_MM,
    SIGNIFICANCE_Z,
)
from workbench.validate.print_warp import _csum, _length


def line_profile(x: float, width_px: float, sigma_px) -> np.ndarray:
    """A line's share of its full step at ``x`` from its axis, through a Gaussian blur.

    A box of width w convolved with a Gaussian of sigma σ:
    ``p(x) = (erf((x + w/2) / (√2 σ)) - erf((x - w/2) / (√2 σ))) / 2``.

    Parameters
    ----------
    x : float
        Distance from the line's axis, px.
    width_px : float
        The line's width, px.
    sigma_px : float or (H, W) float
        The blur, Gaussian sigma, px (0: none).

    Returns
    -------
    float32 array of ``sigma_px``'s shape
        0 to 1.
    """
    s = np.sqrt(2.0) * np.maximum(np.asarray(sigma_px, np.float32), 1e-3)
    return (0.5 * (erf((x + 0.5 * width_px) / s) - erf((x - 0.5 * width_px) / s))).astype(np.float32)


MAX_LINE_ROUNDS = 3  # rounds of the thin test's floor without the lines it found (thin_ink_loss)


def thin_ink_loss(
    photo: np.ndarray,
    pred: np.ndarray,
    film: np.ndarray,
    scored: np.ndarray,
    px_per_mm: float,
    limit: np.ndarray,
    blur: np.ndarray | float = 0.0,
    noise: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a line thinner than a scratch's width steps the photo towards the bare film, over any ink.

    t = (photo - pred) · u, u the unit step from the design's colour to the film's: how far
    the photo moved towards the film, grey levels. Shading, a highlight or an exposure error
    change t over areas much broader than a scratch; a white top-hat of t (t less its
    opening by a disc of SCRATCH_MM) keeps what is thinner than about half the disc. The photo's
    blur spreads a line: one SCRATCH_WIDTH_MM wide, seen through a Gaussian of sigma σ, keeps
    ``reach = p(0) - p(r)`` of the step to the film in the top-hat (:func:`line_profile` at its
    core less at the disc's radius r, where the opening takes its value). A pixel has lost its
    ink where the top-hat reaches half of that step and exceeds ``limit`` (the noise, and half
    a pixel's placement at the design's edges) and t itself exceeds ``limit`` (beside ink the
    photo shows darker than the model, the opening sinks): over pale ink too, where a broad
    step of that size is shading or light. (The colour test's fixed tolerance is for what is broad; a thin line of film
    over a light grey square is what a scratch across a checker shows.) Such a scratch is
    found, with 95 % probability, where its core exceeds that threshold by DETECT_Z of the
    top-hat's own noise, and its step at the core, ``p(0)``, exceeds ``limit`` by DETECT_Z of
    the residual's ``noise``.

    Parameters
    ----------
    photo, pred, film : (H, W, 3) float32
        The photo on the print, the model, and the bare film's colour as the photo would show it.
    scored : (H, W) bool
    px_per_mm : float
    limit : (H, W) float32
        Grey levels.
    blur : (H, W) float32 or float
        The photo's blur at each pixel, Gaussian sigma, grid px.
    noise : float
        The residual's noise, grey levels (the line's own step is stated found where it exceeds
        ``limit`` by DETECT_Z of it).

    Returns
    -------
    found : (H, W) bool
        Ink gone along a thin line.
    findable : (H, W) bool
        Where a scratch SCRATCH_WIDTH_MM wide is found (its blurred core beyond the threshold
        by DETECT_Z of the noise, the step to the film at least twice LOST_MIN_CONTRAST):
        the detection limit's scratch map.
    alpha : (H, W) float32
        Where sought (scored, the step to the film at least twice LOST_MIN_CONTRAST and twice
        ``limit``), the share of the step to the film the line takes against its surroundings
        (0 to 1); 0 elsewhere.
    """
    step = film - pred
    size = _length(step)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = _csum((photo - pred) * step) / np.maximum(size, 1e-3)
    t = np.where(scored, t, 0.0).astype(np.float32)
    r = max(1, int(round(0.5 * SCRATCH_MM * px_per_mm)))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    hat = cv2.morphologyEx(t, cv2.MORPH_TOPHAT, disc)
    # the share of the step a scratch of SCRATCH_WIDTH_MM keeps in the top-hat through the blur:
    # its blurred profile at the core less at the disc's radius, where the opening takes its value
    # (a face mask's 0.5 mm scratch seen at 1.6 grid px: 0.45 predicted at its core, 0.46
    # measured in four photos)
    w = SCRATCH_WIDTH_MM * px_per_mm
    at_core = line_profile(0.0, w, blur)
    reach = at_core - line_profile(float(r), w, blur)
    step_core = reach * size
    # (a step to the film under LOST_MIN_CONTRAST twice over is pale ink a line of film barely
    # changes: a perfect render's antialiased edges reach half of it, measured 6 grey levels)
    pale = size < 2.0 * LOST_MIN_CONTRAST
    # (and the line itself beyond the limit: beside ink the photo shows darker than the model,
    # the opening sinks and a pale gap that matches the model stands 20 grey levels above it)
    # (and beyond what the top-hat makes of the photo's own noise: the opening follows the noise's
    # troughs, so the hat of a sound photo sits a few noise levels up, and a path tracer's
    # correlated noise over pale ink passed the pixel's limit in 55 places of one perfect part;
    # the hat's median and spread over the scored print, where lines are a minute share, are
    # that noise's own)
    # (and the photo's noise is not one level over the print: it grows with the light (a camera's
    # shot noise, a path tracer's under light the part throws on itself) and with how coarsely the
    # photo samples the print (one photo pixel's noise over many grid pixels is a speckle the
    # top-hat keeps whole): the hat's median and spread are also taken per block of
    # NOISE_BLOCK_PX, and the larger floor holds. A pale petal lit by the part itself in a path
    # tracer's photo at 0.7 photo px per grid px: 36 and 22 grey levels against the photo's 13 and
    # 8; its speckles, joined along the light's edge, made 11 mm² of "scratch")
    ref = hat[scored]
    med, spread = 0.0, 1.0
    if ref.size:
        med = float(np.median(ref))
        spread = max(1.4826 * float(np.median(np.abs(ref - med))), NOISE_FLOOR)
    sought = scored & ~pale
    # (and the line itself beyond the limit at its core, as found lines must be: over pale ink on a
    # photo whose model misses by 12 grey levels, a scratch's top-hat cleared its threshold along
    # its whole length, the line itself along a third)
    core = at_core * size

    def lines_at(where: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # the floor from the blocks' pixels ``where``: the lines found above it, where a scratch would be
        local_med, local_spread = block_median_spread(hat, where, NOISE_BLOCK_PX, med, spread)
        sd = np.maximum(spread, local_spread)
        floor = np.maximum(med + SIGNIFICANCE_Z * sd, local_med + SIGNIFICANCE_Z * local_spread)
        threshold = np.maximum(np.maximum(0.5 * step_core, limit), floor)
        findable = sought & (step_core - DETECT_Z * sd >= threshold) & (core - DETECT_Z * noise >= limit)
        excess = np.where(sought, np.minimum(hat - threshold, t - limit), np.nan).astype(np.float32)
        # a line, not speckles: a component at least SCRATCH_MM long (a path tracer's noise in a
        # glossy highlight sparkles in single pixels, which the bridging of ink gone would join)
        found = sought & (excess > 0)
        n, lab, stats, _ = cv2.connectedComponentsWithStats(found.astype(np.uint8), connectivity=8)
        span = np.hypot(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
        keep = span >= SCRATCH_MM * px_per_mm
        keep[0] = False
        return keep[lab], findable

    found, findable = lines_at(scored)
    # a scratch is a share of its blocks' pixels and raises their spread itself (a 0.5 mm line over
    # pale ink: by a third, and found over 80 % of its length): the blocks' statistics again without
    # the lines found and their blurred flanks, and the lines found against that, until no more are
    # (each round finds more of a line, whose rest raised its blocks less; three rounds at most)
    for _ in range(MAX_LINE_ROUNDS):
        if not found.any():
            break
        flank = cv2.dilate(found.astype(np.uint8), disc).astype(bool)
        more, findable = lines_at(scored & ~flank)
        if not (more & ~found).any():
            break
        found |= more
    with np.errstate(invalid="ignore", divide="ignore"):
        # (where the step to the film is twice the limit: below, the share is the noise's)
        alpha = np.where(sought & (size >= 2.0 * limit), np.clip(hat / np.maximum(size, 1e-3), 0.0, 1.0), 0.0)
    return found, findable, alpha.astype(np.float32)


def _row_median(a: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The median of each row's finite values, (k, m) float32 with n (k,) finite each; (k,) float32.

    NaN sorts last, so the middle of a row's n finite values is at (n - 1) / 2 of its sorted row;
    rows with every value finite, most of them, by a partition about their common middle, in
    linear time.
    """
    out = np.empty(len(a), np.float32)
    full = n == a.shape[1]
    mid = [(a.shape[1] - 1) // 2, a.shape[1] // 2]
    if full.any():
        part = np.partition(a[full], mid, axis=1)
        out[full] = 0.5 * (part[:, mid[0]] + part[:, mid[1]])
    if (~full).any():
        s, k = np.sort(a[~full], axis=1), n[~full]
        lo = np.take_along_axis(s, ((k - 1) // 2)[:, None], axis=1)[:, 0]
        hi = np.take_along_axis(s, (k // 2)[:, None], axis=1)[:, 0]
        out[~full] = 0.5 * (lo + hi)
    return out


def block_median_spread(
    values: np.ndarray, where: np.ndarray, block: int, fill_median: float, fill_spread: float
) -> tuple[np.ndarray, np.ndarray]:
    """The median of ``values`` and their spread around it, per block, the larger of each block's and its neighbours'.

    Each ``block`` x ``block`` block's median and spread (1.4826 times the median absolute
    deviation: the standard deviation of normal values) over its pixels ``where`` holds; a block
    where that is fewer than a quarter of its pixels takes the fill values. Then each block
    takes the largest median and the largest spread of itself and its eight neighbours (between
    a noisy block and a quiet one the interpolation below would halve the noisy one's at its
    edge), and both are interpolated bilinearly between the blocks' centres.

    Parameters
    ----------
    values : (H, W) float32
        The values (grey levels, say).
    where : (H, W) bool
        The pixels they are taken over.
    block : int
        Block size, px.
    fill_median, fill_spread : float
        For blocks with too few pixels (the whole image's, say); the values' unit.

    Returns
    -------
    median, spread : (H, W) float32
        The values' unit.
    """
    H, W = values.shape
    ny, nx = -(-H // block), -(-W // block)
    pad = np.full((ny * block, nx * block), np.nan, np.float32)
    pad[:H, :W] = np.where(where, values, np.nan)
    v = pad.reshape(ny, block, nx, block).transpose(0, 2, 1, 3).reshape(ny * nx, block * block)
    count = np.isfinite(v).sum(axis=1)
    enough = count >= max(block * block // 4, 1)
    med = np.full(ny * nx, fill_median, np.float32)
    spread = np.full(ny * nx, fill_spread, np.float32)
    if enough.any():
        rows, n = v[enough], count[enough]
        m = _row_median(rows, n)
        med[enough] = m
        spread[enough] = 1.4826 * _row_median(np.abs(rows - m[:, None]), n)
    kernel = np.ones((3, 3), np.uint8)
    med = cv2.dilate(med.reshape(ny, nx), kernel)
    spread = cv2.dilate(spread.reshape(ny, nx), kernel)
    # (block centres at (k + 0.5) block px of the whole image: a resize of the block grid by
    # ``block`` puts them there)
    size = (nx * block, ny * block)
    med_px = cv2.resize(med, size, interpolation=cv2.INTER_LINEAR)[:H, :W]
    spread_px = cv2.resize(spread, size, interpolation=cv2.INTER_LINEAR)[:H, :W]
    return med_px, spread_px


def thin_told(
    thin: np.ndarray, photo: np.ndarray, pred: np.ndarray, core: np.ndarray | None = None, gap_px: int = 0
) -> np.ndarray:
    """Each thin line of film-ward step told as light or as ink gone, where the ink under it varies.

    Light added to the ink (a glint along a ridge) keeps the ink's variation along the line:
    the photo follows the design there (correlation KEPT_TEXTURE at least, at a gain of
    KEPT_CONTRAST at least), as a highlight over a checker does. Ink that is gone shows the
    film all along it, whatever ink it crosses. Where the ink under the line is uniform (its
    grey levels' spread below LOST_MIN_CONTRAST) nothing tells them apart in one photo.
    Judged on the line's ``core`` where it holds MIN_CORE_PX: a scratch two photo pixels wide
    is blurred into its flanks, where the photo keeps most of the ink's variation (a gain of
    0.4 to 0.6 over a line whose core keeps a quarter), while added light keeps it in its core
    too.

    Parameters
    ----------
    thin : (H, W) bool
        :func:`thin_ink_loss`'s lines.
    photo, pred : (H, W, 3) float32
    core : (H, W) bool, optional
        The lines' pixels that take at least half the step to the film.
    gap_px : int
        Pieces of line this close are one line (a scratch across a checker is found in pieces,
        over the dark squares, each over uniform ink; as one it crosses the checker).

    Returns
    -------
    (H, W) uint8
        Per pixel of a line: 1 light, 2 ink gone, 3 not told (uniform ink); 0 off the lines.
    """
    out = np.zeros(thin.shape, np.uint8)
    joined = thin.astype(np.uint8)
    if gap_px > 0:
        joined = cv2.dilate(joined, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * gap_px + 1,) * 2))
    n, lab = cv2.connectedComponents(joined, connectivity=8)
    if n <= 1:
        return out
    use = thin
    if core is not None:
        # (a line's core where it has one: MIN_CORE_PX of its pixels; its whole elsewhere)
        n_core = np.bincount(lab[thin & core], minlength=n)
        use = thin & (core | (n_core[lab] < MIN_CORE_PX))
    g_ph = cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY)[use].astype(np.float64)
    g_pr = cv2.cvtColor(pred, cv2.COLOR_RGB2GRAY)[use].astype(np.float64)
    k = lab[use]

    def per(v):
        return np.bincount(k, v, n)

    cnt = np.maximum(per(np.ones_like(g_ph)), 1.0)
    mx, my = per(g_pr) / cnt, per(g_ph) / cnt
    vx = per(g_pr * g_pr) / cnt - mx * mx
    vy = per(g_ph * g_ph) / cnt - my * my
    cxy = per(g_pr * g_ph) / cnt - mx * my
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cxy / np.sqrt(vx * vy)
        gain = cxy / vx
    varied = np.sqrt(np.maximum(vx, 0.0)) >= LOST_MIN_CONTRAST
    light = varied & (corr >= KEPT_TEXTURE) & (gain >= KEPT_CONTRAST)
    verdict = np.where(varied, np.where(light, 1, 2), 3).astype(np.uint8)
    verdict[0] = 0
    out[thin] = verdict[lab[thin]]
    return out
