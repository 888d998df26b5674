"""The analysis of one photo on the print, stage by stage (:func:`analyse`)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from workbench.validate import detection, photometric
from workbench.validate.dense import reflection
from workbench.validate.dense._channels import _cmax, _cmin
from workbench.validate.dense.blur import blur_locally_axes, estimate_blur, unresolved_detail
from workbench.validate.dense.defects import find_defects, shift_explained
from workbench.validate.dense.exposure import (
    _residual,
    colour_residuals,
    colour_z,
    exposure_fit,
    film_colour,
    photo_gain,
    texture_lost,
    window_ratio,
)
from workbench.validate.dense.flow import dis_flow, flow_start, median_flow, tensor_weighted_flow, window_two_way
from workbench.validate.dense.light import (
    LIGHT_RULES,
    along_fold,
    grid_folds,
    lamp_cone,
    least_residual_under_light,
    light_range,
    mirrors_highlights,
    not_counted_regions,
    regions_mostly_in,
    taken_along_fold,
)
from workbench.validate.dense.lines import thin_told
from workbench.validate.dense.options import (
    COLOUR_TOL,
    DETECT_Z,
    EXPOSURE_SIGMA_PX,
    LOST_MIN_CONTRAST,
    MIN_DEFECT_MM2,
    MIN_EDGE,
    MIN_TWO_WAY,
    MISSING_GAP_MM,
    NOISE_FLOOR,
    SATURATED,
    SHADOW,
    SHIFT_EXPLAINS,
    SIGNIFICANCE_Z,
    THIN_MAX_STRETCH,
)
from workbench.validate.dense.result import DenseResult
from workbench.validate.dense.stages import _Colour, _Found, _Frame, _Measures, _Model, _Start, _SureLight
from workbench.validate.dense.uncertainty import (
    effective_samples,
    flow_floor,
    flow_uncertainty,
    forward_backward,
    noise_correlation,
    stated_shift_limit,
    window_mismatch,
)
from workbench.validate.placement import placement_field
from workbench.validate.print_warp import (
    COLOUR_ONLY,
    DEFECT,
    EDGE,
    FULL,
    HIGHLIGHT,
    NORMAL,
    OFF_PART,
    SHADOWED,
    UNRESOLVED,
    PrintGrid,
    _csum,
    rim_band,
)
from workbench.validate.shading import fit_shading, shaded, shading_factor
from workbench.validate.slide_evidence import SlideMeasure


def analyse(
    grid: PrintGrid,
    warped: np.ndarray,
    state: np.ndarray,
    tolerance_mm: float,
    scale: float = 1.0,
    footprint: np.ndarray | None = None,
    camera_center: np.ndarray | None = None,
    footprint_axes: np.ndarray | None = None,
    finish: str = "glossy",
) -> DenseResult:
    """Dense misregistration with its uncertainty, colour residuals, masks and defects of one photo on the print.

    Parameters
    ----------
    grid : PrintGrid
    warped : (rows, cols, 3) uint8
        The photo on the print (:func:`warp_to_print`).
    state : (rows, cols) uint8
        Its visibility states.
    tolerance_mm : float
        Misregistration beyond this (mm on the surface) by more than SIGNIFICANCE_Z of its
        uncertainty is a defect.
    scale : float
        Photo pixels per grid pixel (:func:`warp_to_print`): where the photo is coarser than
        the grid, both images are smoothed to its resolution before the flow (detail the photo
        cannot resolve would otherwise move edges).
    footprint : (rows, cols) float, optional
        Photo pixels per grid pixel at each grid pixel (:func:`warp_to_print`); ``scale``
        everywhere when not given.
    camera_center : (3,) float, optional
        The photo's camera centre, mm in the mesh frame: on a glossy film a colour region that
        mirrors the lamp like the photo's own highlights is one of them (:func:`mirrors_highlights`).
    footprint_axes : (rows, cols, 2) float, optional
        Photo pixels per grid pixel that the camera's blur sees along the grid's columns and
        rows (:func:`workbench.validate.print_warp.footprint_axes`): the model blurs the print
        by an ellipse where the photo sees it obliquely. ``footprint`` both ways when not given.
    finish : str
        The film's surface, ``"glossy"`` or ``"matte"``. A glossy film adds light of its own (the
        lamp's and the room's reflections); a matte film adds none, and the light that reaches its
        ink (shading, the part's own interreflection) scales the ink's colour
        (:func:`workbench.validate.photometric.judge_region`).

    Returns
    -------
    DenseResult
    """
    # what needs neither the flow nor the photo's fit (the flow back, the print's own texture, its
    # unresolved detail) is computed on a second thread meanwhile: numpy and OpenCV release the
    # GIL in their loops, so on two cores that work costs little wall time; the same numbers
    if finish not in ("glossy", "matte"):
        raise ValueError(f"finish {finish!r}: glossy or matte")
    with ThreadPoolExecutor(max_workers=1) as later:
        return _analyse(
            grid,
            warped,
            state,
            tolerance_mm,
            scale,
            footprint,
            camera_center,
            later,
            footprint_axes,
            finish == "glossy",
        )


def _analyse(grid, warped, state, tolerance_mm, scale, footprint, camera_center, later, axes, glossy) -> DenseResult:
    """:func:`analyse`, with ``later`` the executor of the work that can run beside it."""
    state = rim_band(state)
    pho = warped.astype(np.float32)
    H, W = state.shape
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    # (surface mm per grid px: print mm times the film's local stretch)
    mm_per_px = (grid.surface_per_print / grid.px_per_mm).astype(np.float32)
    fp = footprint if footprint is not None else np.full((H, W), scale, np.float32)
    fp_axes = axes if axes is not None else np.stack([fp, fp], axis=-1)
    on = _Frame(grid, warped, pho, tolerance_mm, scale, fp, camera_center, later, jj, ii, mm_per_px, fp_axes, glossy)
    start = _placed_flow(on, state)
    model = _photo_model(on, start)
    light = _sure_light(on, start, model)
    # the colour test (with the scratch test and where ink that is gone would be found) needs
    # nothing of the flow's uncertainty: beside it; and after it a window's slide (below)
    colour_test = later.submit(
        colour_residuals, pho, model.pred, light.film_lit.film, model.res, model.weight, light.scored, fp,
        grid.px_per_mm, model.local_blur, model.moved,
    )  # fmt: skip
    measures = _flow_measures(on, start, model, light)
    colour = _light_or_ink(on, start, model, light, measures, colour_test.result())
    found = _defects(on, start, measures, colour)
    return _result(on, start, model, measures, colour, found)


def _placed_flow(on: _Frame, state: np.ndarray) -> _Start:
    """The flow from the print, and again from the print as the film's placement puts it where that moves it."""
    grid, pho, warped, scale, later = on.grid, on.pho, on.warped, on.scale, on.later
    jj, ii, mm_per_px, tolerance_mm = on.jj, on.ii, on.mm_per_px, on.tolerance_mm
    ref = grid.reference.astype(np.float32)
    # the shading: a function of the surface's normal over the whole part (:mod:`workbench.validate.shading`), so
    # that what the photo is compared with is the print as the part's light shows it. The local
    # exposure fit works in windows of the print, and where the design squeezed the print (the
    # scanned face's crown: 12 surface mm a print mm) one window spans a surface turning through
    # the lamp's light: the photo's shading there went from 0.25 to 0.97 of the print across a
    # window whose fitted gain stayed at 0.40, and the lit side read as ink gone. (Fitted on the
    # print before the flow: a global fit of nine numbers does not feel a millimetre's slide.)
    shade, light = np.ones_like(ref), None
    if grid.normal is not None:
        sat = _cmin(warped) >= SATURATED
        light = fit_shading(pho, ref, grid.normal, (state == FULL) & ~sat)
        shade = shading_factor(grid.normal, light)
    fs = flow_start(shaded(ref, shade), pho, warped, state, scale, later)
    H, W = state.shape
    # placement is not a defect: each film's placement (an affine field over the film, fitted to
    # this first flow where the print has texture both ways) is judged as placement, and the
    # analysis starts again from the print placed so, when that placement moves it anywhere by
    # more than a measuring pixel's uncertainty may be. Local defects are then what remains: a
    # film 0.8 mm off is no 10,000 mm² "shift", a bubble on it is still found, and the print's
    # texture the flow and its windows weigh is the texture the photo shows there (the print
    # where it is, 9 grid px from it, drew a slide along every rim)
    two_way = fs.seen & ~fs.sat & (fs.texture.result()[1] >= MIN_TWO_WAY)
    ones = np.ones((H, W), np.float32)
    early, _ = placement_field(
        fs.m, np.zeros_like(fs.m), two_way, np.zeros_like(two_way), ones, grid.film, np.inf, fs.win
    )
    if np.any(np.hypot(early[..., 0], early[..., 1]) * mm_per_px > tolerance_mm / SIGNIFICANCE_Z):
        mx, my = jj - early[..., 0], ii - early[..., 1]
        ref = cv2.remap(ref, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        # (what the placement brings in from beyond the film's outline is no print: the film's rim as placed)
        on_film = np.isfinite(grid.X[..., 0]).astype(np.uint8)
        from_film = cv2.remap(on_film, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0) > 0
        state[(state == FULL) & ~from_film] = OFF_PART
        state = rim_band(state)
        state[(state == OFF_PART) & on_film.astype(bool)] = EDGE
        fs = flow_start(shaded(ref, shade), pho, warped, state, scale, later)
        held = np.zeros_like(early)
    else:
        held, early = early, np.zeros_like(early)
    return _Start(fs, state, ref, early, shade, held, light)


def _photo_model(on: _Frame, start: _Start) -> _Model:
    """The model of the photo: the print moved by the flow's median, blurred like the photo, in its exposure."""
    grid, pho, scale, fp, later, jj, ii = on.grid, on.pho, on.scale, on.fp, on.later, on.jj, on.ii
    fs, ref = start.fs, start.ref
    seen, sat, inner, rg, pg = fs.seen, fs.sat, fs.inner, fs.rg, fs.pg
    back = later.submit(dis_flow, fs.ref_n, fs.pho_n)
    # the print moved by the flow: what the photo shows if only misregistration happened;
    # then the photo's blur, measured on the aligned pair
    # (the colour's model follows the flow's median over about 2 mm: a film's slide is smooth at
    # that scale, and the flow's own wiggle along a scratch or a dropout's rim, which pulls the
    # neighbouring ink over the bare film, would explain the ink that is gone away)
    mc = median_flow(fs.m, grid.px_per_mm)
    moved = cv2.remap(ref, jj - mc[..., 0], ii - mc[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    # the blur where the photo samples the print coarser than its median (a surface seen
    # obliquely or from farther): a photo pixel spans 1 / footprint grid pixels there, so its
    # blur on the grid grows in proportion (one blur for a whole photo of a deep part made
    # the creases seen at a slant "colour defects": the print's detail the photo cannot show)
    photo_blur = estimate_blur(cv2.cvtColor(moved, cv2.COLOR_RGB2GRAY), pg, inner & ~sat, fp, scale, on.fp_axes)
    blur = float(photo_blur.on_grid(scale, scale))
    # (the median's where the photo is not scored: nothing there asks for more)
    local_blur = np.where(inner, photo_blur.on_grid(fp, scale), np.float32(blur))
    # detail the photo cannot resolve: its flow follows the photo's PSF, not the print
    detail = later.submit(unresolved_detail, rg, local_blur, MIN_EDGE)
    # the model's blur is the photo's round blur as it lies on the grid: an ellipse, wider along
    # the axis the photo samples coarser (a surface seen obliquely); as wide both ways as the
    # coarser axis needs, it blurred a flank's text across its strokes, which the photo shows
    # sharp, and the gaps between them read as lines of ink gone (:func:`footprint_axes`). (Its
    # spread along each grid axis: an ellipse lying diagonally to the grid is taken as wide
    # along both axes as its spread there, and stays wider across its narrow side than it is)
    sx = np.where(inner, photo_blur.on_grid(on.fp_axes[..., 0], scale), np.float32(blur))
    sy = np.where(inner, photo_blur.on_grid(on.fp_axes[..., 1], scale), np.float32(blur))
    moved = blur_locally_axes(moved, sx, sy)
    weight = (inner & ~sat).astype(np.float32)
    shade = start.shade
    lit = shaded(moved, shade)
    # exposure: a robust local fit of the photo to the shaded print (a second pass without the
    # first pass's outliers), which is left the exposure, vignetting and what the normal's
    # shading does not hold (cast shadows, interreflections)
    gain, offset, _ = exposure_fit(lit, pho, weight, EXPOSURE_SIGMA_PX)
    res = _residual(pho, gain * lit + offset)
    weight = weight * (res < COLOUR_TOL)
    gain, offset, contrast = exposure_fit(lit, pho, weight, EXPOSURE_SIGMA_PX)
    pred = gain * lit + offset
    res = _residual(pho, pred)
    # the gain of the print itself, in grey levels: the fit's times the shading's at the film's
    # white (grey(E · lin(255)) = grey(E)), so that gain · 255 + offset is the film's white exactly
    at_white = photometric.grey_levels(shade) / np.float32(255.0)
    gain = gain * at_white
    # (the design's own contrast in the window, not the shaded design's: where the shading is
    # wrong, and takes the contrast away, the decoration painted over is still the design's)
    contrast = contrast / np.maximum(at_white, np.float32(1e-3))
    # the design's texture gone from the photo: light scales it (shading, vignetting) or adds
    # to it (glare), never takes it away; where the window's design has contrast, a local gain
    # that collapses against the photo's own is the decoration painted over, covered or torn
    # off, which the fit would otherwise absorb into its offset
    determined = contrast >= LOST_MIN_CONTRAST
    g0 = photo_gain(gain, determined, seen & ~sat)
    # (the light that is there: the photo's local mean over the design's, in the fit's window; the
    # weights cancel in the ratio, and a design darker than a grey level there is taken as one)
    brightness = window_ratio(pho, moved, seen & ~sat, EXPOSURE_SIGMA_PX)
    lost = texture_lost(gain, determined, seen & ~sat, g0, brightness)
    white = gain * np.float32(255.0) + offset  # the film's white as the exposure fit extrapolates it
    return _Model(back, detail, blur, local_blur, moved, weight, gain, offset, pred, res, g0, lost, white, shade, lit)


def _sure_light(on: _Frame, start: _Start, model: _Model) -> _SureLight:
    """The light the photo shows for sure (beyond the bare film) and the deep shadows, marked in the states."""
    pho = on.pho
    seen, state = start.fs.seen, start.state
    moved, weight, offset = model.moved, model.weight, model.offset
    res, lost, white = model.res, model.lost, model.white
    # the photometric model (:mod:`workbench.validate.photometric`): the bare film as the ink around
    # each pixel shows it, in linear light (the exposure fit's white is extrapolated in grey levels
    # from the ink's level to the film's, over dark ink wrong by tens of grey levels: a dropout
    # there looked brighter than its film). Light for sure is what is brighter than the bare film
    # could be, in every channel (a clipped channel where the film stays below clipping); what
    # clips where the film may clip too, a white dropout included, is judged with its region below
    noise0 = float(1.4826 * np.median(res[weight > 0])) if (weight > 0).any() else NOISE_FLOOR
    sheen = photometric.linear(np.maximum(_cmin(offset), 0.0))  # the light the exposure fit adds over the ink
    # (each inked pixel measures the film as the shading lights it there: the print shaded, its
    # level then the exposure's, smooth over the window; the shading put back per pixel)
    film_lit = photometric.film_level(
        pho, model.lit, weight > 0, noise0, 0.5 * EXPOSURE_SIGMA_PX, white, sheen,
        photometric.window_shares(on.grid.X),
    )  # fmt: skip
    known = film_lit.sigma < photometric.UNKNOWN
    film_lit.film[known] = shaded(film_lit.film, model.shade)[known]
    if (unknown := film_lit.sigma >= photometric.UNKNOWN).any():
        # (where no ink around tells the film, the exposure fit's white in the film's one colour)
        film_lit.film[unknown] = film_colour(white, moved, weight > 0, unknown)[unknown]
    past_film = seen & photometric.beyond_film(pho, film_lit, noise0, SIGNIFICANCE_Z)
    highlight = past_film & ~lost
    # (what decided each pixel taken for light, for validation.json's not_counted)
    why_light = {"beyond_film": highlight}
    shadow = seen & ~highlight & (_cmax(white) < SHADOW)
    state[highlight] = HIGHLIGHT
    state[shadow] = SHADOWED
    scored = state == FULL
    return _SureLight(film_lit, past_film, highlight, why_light, scored)


def _flow_measures(on: _Frame, start: _Start, model: _Model, light: _SureLight) -> _Measures:
    """Where the flow measures the full vector or the component across an edge, with its uncertainty."""
    fp, later, tolerance_mm, mm_per_px = on.fp, on.later, on.tolerance_mm, on.mm_per_px
    fs, state, early = start.fs, start.state, start.early
    sat, rgb_, pgb_, ref_n, pho_n = fs.sat, fs.rgb_, fs.pgb_, fs.ref_n, fs.pho_n
    m, reg, flow_k, win = fs.m, fs.reg, fs.flow_k, fs.win
    blur, pred, weight = model.blur, model.pred, model.weight
    scored = light.scored
    H, W = state.shape
    # (the slide's windows leave out the light known by then and the flow's reach around it,
    # below; the light known now is most often all of it: the slide for it is computed beside
    # the rest, and again below only where telling light from ink adds to it)
    r_lit = max(1, int(round(4 * win)))
    lit_disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r_lit + 1,) * 2)
    # (white-out is no light for sure, the bare film may clip too, but its rim moves with the light
    # that clips it, not with the print: the flow's windows leave it out as they leave out light)
    lit_now = cv2.dilate(((state == HIGHLIGHT) | sat).astype(np.uint8), lit_disc).astype(bool)
    slide = later.submit(tensor_weighted_flow, rgb_, m, 4 * win, ~lit_now)
    # what the flow can know there: the photo's noise and what the model does not explain,
    # through the texture the photo resolves (the model is the print blurred like the photo,
    # in the photo's own contrast), and where the flow back disagrees, half that disagreement
    pred_s = cv2.GaussianBlur(cv2.cvtColor(pred, cv2.COLOR_RGB2GRAY), (0, 0), reg)
    corr = noise_correlation(reg, fp)
    floor = flow_floor(fp, flow_k)
    weak, strong, e1, noise, l1, l2 = flow_uncertainty(
        pred_s, pgb_, scored & (weight > 0), win, max(1.0, float(np.hypot(blur, reg))), corr, floor
    )
    fb = forward_backward(m, ref_n, pho_n, flow_k, model.back.result())
    weak = np.hypot(weak, 0.5 * fb)
    strong = np.hypot(strong, 0.5 * fb)
    # a pixel measures misregistration where the flow there is its own (MIN_EDGE) and its
    # uncertainty lets a shift of twice the tolerance stand out at SIGNIFICANCE_Z
    # (σ ≤ tolerance / Z); the full vector where the weakest direction does, the component
    # across the edge where only that one does
    usable = tolerance_mm / SIGNIFICANCE_Z
    # (p1, p2 in grey levels² per pixel of the flow's grid: the gates hold for the images the
    # flow compares)
    p1, p2, l1_wide, l2_wide = fs.texture.result()
    full = scored & (p2 >= MIN_TWO_WAY) & (weak * mm_per_px <= usable)
    normal = scored & ~full & (p1 >= MIN_EDGE) & (strong * mm_per_px <= usable)
    unresolved, needed_blur = model.detail.result()
    unresolved &= scored
    full &= ~unresolved
    normal &= ~unresolved
    stated = scored.copy()  # (before light is told from ink: that depends on the defect)
    measurable = stated & ~unresolved
    # a window of about a millimetre's slide (below): its uncertainty is the photo's noise
    # through the window's weaker direction, what the photo's windows err by beyond it at
    # their texture (κ², their median over the photo, less the placement every window shares:
    # :func:`window_mismatch`), and the floor, none of it raised by a defect
    n_wide = effective_samples(4 * win, corr)
    windows = measurable & ~lit_now & (l2_wide > 0)
    n_typical = float(np.median(n_wide[windows])) if np.ndim(n_wide) and windows.any() else float(np.max(n_wide))
    kappa2 = window_mismatch(slide.result() - start.held, rgb_, 4 * win, windows, noise, n_typical)
    with np.errstate(divide="ignore", invalid="ignore"):
        wide_sigma = np.sqrt((noise * noise / n_wide + kappa2) / l2_wide + floor * floor) * mm_per_px
    with np.errstate(over="ignore"):  # (beyond float32's range where the window has no texture: inf, as it is)
        wide_sigma = np.nan_to_num(wide_sigma, nan=np.inf).astype(np.float32)
    # the detection limit, stated for a sound part (needed only for the result: beside the rest)
    shift_limit = later.submit(
        stated_shift_limit, tolerance_mm, noise, l1, l2, effective_samples(win, corr), floor, mm_per_px, wide_sigma,
        measurable & (p2 >= MIN_TWO_WAY), measurable, usable, l1_wide, l2_wide,
    )  # fmt: skip
    # (the misregistration reported is the whole of it: the placement's and the rest)
    m_total = m + early
    shift = np.full((H, W, 2), np.nan, np.float32)
    np.copyto(shift, m_total, where=full[..., None])
    mn = _csum(m_total * e1)[..., None] * e1  # the component across the edge
    np.copyto(shift, mn, where=normal[..., None])
    state[scored & ~full & ~normal] = COLOUR_ONLY
    state[unresolved] = UNRESOLVED
    state[full] = FULL
    state[normal] = NORMAL
    texture = np.zeros((H, W), np.uint8)
    texture[normal] = 1
    texture[full] = 2
    shift_mm = np.hypot(shift[..., 0], shift[..., 1]) * mm_per_px
    sigma_mm = np.full((H, W), np.nan, np.float32)
    np.copyto(sigma_mm, weak * mm_per_px, where=full)
    np.copyto(sigma_mm, strong * mm_per_px, where=normal)
    two_way_window = window_two_way(l1_wide, l2_wide)
    return _Measures(
        lit_disc, lit_now, slide, shift_limit, noise, e1, usable, full, normal, unresolved, needed_blur, stated,
        wide_sigma, two_way_window, m_total, shift, texture, shift_mm, sigma_mm,
    )  # fmt: skip


def _light_or_ink(on: _Frame, start: _Start, model: _Model, light: _SureLight, measures: _Measures, ct) -> _Colour:
    """The colour test's regions told light or ink: the photometric model, lost texture, thin lines, the lamp, folds.

    ``ct`` is :func:`colour_residuals`'s answer. Marks what is taken for light in the states and
    takes it out of ``measures``' maps (in place).
    """
    grid, pho, fp, later, camera_center = on.grid, on.pho, on.fp, on.later, on.camera_center
    state, rg, seen = start.state, start.fs.rg, start.fs.seen
    local_blur, moved, gain = model.local_blur, model.moved, model.gain
    pred, g0, lost = model.pred, model.g0, model.lost
    film_lit, past_film, highlight = light.film_lit, light.past_film, light.highlight
    why_light, scored = light.why_light, light.scored
    full, normal, shift = measures.full, measures.normal, measures.shift
    shift_mm, sigma_mm, texture = measures.shift_mm, measures.sigma_mm, measures.texture
    colour_scored = scored  # colour is judged wherever the photo is scored (unresolved detail too)
    alpha, colour_limit, colour_noise, res_raw, res, gone, colour_bad = ct[:7]
    inked, dropout_found, thin, thin_found = ct[7:]
    colour = np.where(colour_scored, res, np.nan).astype(np.float32)
    # light, not ink, again: a glossy film's highlight adds the light's colour over the ink's,
    # broad and soft-edged; ink that is gone replaces the ink's colour by the film's, with
    # the sharp edge of the ink's own rim
    # (the light's colour only where light_or_ink asks: at the failed pixels, which it closes by
    # a pixel; the whole image's took a twentieth of a second)
    # each region judged by the photometric model: light added against ink gone, by the likelihood
    # ratio on its core with the photo's own noise (one independent sample per photo pixel where
    # the photo is coarser than the grid) and the model's error around it
    light_rgb = np.median(film_lit.film[seen][::97], axis=0) if seen.any() else np.ones(3, np.float32)
    light_rgb = np.maximum(light_rgb, 1.0) / max(float(light_rgb.max()), 1.0)
    verdicts = photometric.judge_regions(
        colour_bad, gone, pho, pred, film_lit.film, light_rgb, colour_limit, colour_noise, film_lit.sigma,
        colour_scored & ~colour_bad, local_blur, np.minimum(fp * fp, 1.0), SIGNIFICANCE_Z, on.glossy,
    )  # fmt: skip
    glossed = verdicts.light.copy()
    gone = gone & ~glossed
    why_light["photometric"] = glossed.copy()
    told_gone = np.zeros_like(gone)  # regions the model tells for ink gone
    for r, j in verdicts.judgements.items():
        if j["hypothesis"] == "ink gone":
            told_gone |= verdicts.labels == r
    # (a region stepped only part of the way towards the film is judged by the colour test
    # that allows shading, like any other colour)
    colour_bad = (colour_scored & (res > colour_limit)) | gone
    colour_bad &= ~glossed
    if lost.any():
        # judged against the design at the photo's own gain: the fit's collapsed gain would
        # have explained the lost texture away
        local_mean = cv2.GaussianBlur(moved, (0, 0), EXPOSURE_SIGMA_PX)
        res_lost = _residual(pho, pred + (g0 - gain) * (moved - local_mean))
        beyond = (lost & colour_scored & ~glossed & (res_lost > colour_limit)).astype(np.uint8)
        # (the limit's allowance at the design's edges cuts a painted-over checker into its
        # squares; the lost texture between them is one region)
        lost &= cv2.morphologyEx(beyond, cv2.MORPH_CLOSE, np.ones((7, 7), np.uint8)).astype(bool) & colour_scored
        colour_bad |= lost
        res = np.where(lost, res_lost, res)
        colour = np.where(colour_scored, res, np.nan).astype(np.float32)
    cone = room = None
    # ink gone that no test told from light: ink gone only where the film adds no light (a matte
    # film), else open (the photo cannot tell it; the part's other photos may)
    untold = verdicts.not_told & colour_bad
    if camera_center is not None:
        # thin lines of ink gone are told by the ink along them: a glint keeps the ink's
        # variation, a scratch shows the film; one over uniform ink is not told, and like a
        # region the photometric model cannot tell, is left to the lamp (below)
        told = thin_told(thin, pho, pred, alpha >= 0.5, int(round(0.5 * MISSING_GAP_MM * grid.px_per_mm)))
        if not on.glossy:
            # (a matte film shows no glint: a line that keeps some of the ink's variation is not
            # told by it (a scratch's blurred flanks keep it too; light along a fold is judged
            # below). The camel's 20 mm scratch over pale ink, lens look: found, told ink gone by the
            # photometric model, then taken for a glint, and the photo passed)
            told = np.where(told == 1, np.uint8(3), told).astype(told.dtype)
        # (a line told ink gone stays ink gone where the model took the region it joins for
        # light: a scratch across a glossy sheen is one region with it)
        told_ink = told == 2
        # (but a line brighter than the bare film could be is light: text washed out under a glint)
        washed = regions_mostly_in(told_ink, past_film)
        told_ink &= ~washed
        why_light["beyond_film_line"] = washed
        why_light["thin_told"] = (told == 1) & ~glossed
        glossed |= washed
        glossed &= ~told_ink
        gone |= told_ink
        colour_bad |= told_ink
        glossed |= told == 1
        # the light the photo shows for sure: beyond the film, and regions light explains better
        sure = highlight | glossed
        # the stated limit, honestly: where the surface mirrors the lamp of the photo's sure
        # highlights, ink that is gone is not told from light (a line over uniform ink neither)
        # (needed only for the result: beside the rest, applied below) (a matte film mirrors no
        # lamp: the light on its ink is the gain the photometric model weighed, and on Mitsuba's
        # matte lily the cone of the lamps the regions it took for light would mirror hid 5.4 % of
        # the film's ink from the ink-gone map over six photos)
        if on.glossy:
            cone = later.submit(lamp_cone, sure, grid.X, camera_center, rg, grid.px_per_mm)
        # a region the photo cannot tell (ink gone or light) is taken for light only where the
        # surface mirrors that lamp: elsewhere no light the photo shows reaches the camera from it,
        # and it stays ink gone by default (``untold``: ink gone on a matte film, open on a glossy
        # one, whose lamps the photo may show nowhere else)
        not_told = (verdicts.not_told | (told == 3)) & colour_bad & ~glossed & ~told_ink
        untold = not_told
        mirrored = mirrors_highlights(not_told, sure, grid.X, camera_center) if on.glossy else np.zeros_like(not_told)
        why_light["mirrors_highlights"] = mirrored
        glossed |= mirrored
        colour_bad &= ~glossed
        gone &= ~glossed
        if grid.normal is not None and on.glossy:
            # ink gone, or the room mirrored: a region no brighter than a glossy film's reflection of
            # the room could make it there (the fixture's white squares near the silhouette of
            # Mitsuba's glossy face, 1 to 10 mm² of "missing" in every photo) is explained by either
            room_ok, room = reflection.within_room_reflection(
                pho, pred, film_lit.film, seen, grid.X, grid.normal, camera_center, colour_noise, SIGNIFICANCE_Z
            )
            by_room = regions_mostly_in(gone & colour_bad & ~glossed, room_ok)
            why_light["mirrors_room"] = by_room
            glossed |= by_room
            colour_bad &= ~glossed
            gone &= ~glossed
    # light along a fold: where the surface folds, its two sides face the light differently and a
    # ridge catches it in a line, sharper than the exposure fit follows and, over uniform ink, as
    # bright as film (perfect photos of the scanned lion: lines of 5 to 14 mm² along folds whose
    # normals turn 14 to 22° from their mean). A colour region half of which the light a fold
    # gives the pixels on and beside it explains is light (:func:`_fold_light`); ink gone is not
    # found where that light may pass for it, and the stated limit says so (below)
    # (never a region the model tells for ink gone)
    folded = colour_bad & ~glossed & ~told_gone
    folded = folded & ~told_ink if camera_center is not None else folded
    explained, fold, fold_line = _fold_light(
        on, start, model, film_lit.film, colour_limit, colour_noise, folded, dropout_found | thin_found
    )
    # (light only where the stated maps find nothing either; the region's other pixels stay what
    # they are)
    fold_lit = taken_along_fold(explained, fold, fold_line, thin, gone)
    along = along_fold(folded, fold_lit) & fold_lit
    glossed |= along
    colour_bad &= ~glossed
    gone &= ~glossed
    why_light["along_fold"] = along
    # what was taken for light, and by which test (the regions of the colour residual; a clipped or
    # glaring area is listed where it covers a region too)
    not_counted = not_counted_regions(why_light, glossed | highlight, grid.px_per_mm, MIN_DEFECT_MM2, verdicts)
    state[glossed] = HIGHLIGHT
    colour_scored = colour_scored & ~glossed
    scored = scored & ~glossed
    full &= ~glossed
    normal &= ~glossed
    for a in (shift, shift_mm, sigma_mm, colour):
        a[glossed] = np.nan
    texture[glossed] = 0
    missing = gone
    return _Colour(
        alpha, colour_limit, colour_noise, res_raw, res, colour, colour_bad, missing, inked, dropout_found, thin,
        thin_found, verdicts, scored, cone, fold, fold_line, not_counted, room, untold & missing,
    )  # fmt: skip


def _fold_light(
    on: _Frame,
    start: _Start,
    model: _Model,
    film: np.ndarray,
    colour_limit: np.ndarray,
    noise: float,
    asked: np.ndarray,
    sought: np.ndarray,
):
    """Where a fold's light explains the photo, and where it could pass for ink that is gone or for a scratch.

    On a fold and within its blur of one, a photo's pixel shows light between the least and the
    largest that the surface within its blur receives (:func:`light_range`, from the photo's own
    fitted light), while the model shades it by its smooth normal alone. The photo is explained
    by the fold's light where some light in that range brings the model within the colour test's
    limit. Ink that is gone shows the film under that light too: the film at its least light
    against the ink at some light in the range; where even these come within the limit at which
    ink gone is found (the scratch test's, for a scratch), the fold's light may pass for it, and
    it is not found there. Over ink dark enough that no light around brightens it to the film, a
    fold hides nothing. Without a model of the light the fold may be anything, and all three are
    the fold and its blur's reach.

    Parameters
    ----------
    film : (H, W, 3) float32
        The bare film as the photo shows it under the model's light, grey levels.
    colour_limit : (H, W) float32
        The colour test's limit, grey levels.
    noise : float
        The residual's noise, grey levels.
    asked, sought : (H, W) bool
        Where the photo is to be explained (the colour test's regions), and where ink that is
        gone or a scratch would be found: the only pixels computed (the maps on both).

    Returns
    -------
    explains, may_be_film, may_be_line : (H, W) bool
        On the fold and within the photo's blur of it only (and of ``asked``, ``sought``).
    """
    grid = on.grid
    crease = grid_folds(grid)
    # (a photo pixel reaches over about twice its blur's sigma: within that of a fold it shows the
    # fold's light too. The blur on the grid grows where the photo sees the surface at a slant or
    # from farther: its 90th percentile over the fold, not its median over the photo)
    over = crease & np.isfinite(model.local_blur)
    blur = float(np.percentile(model.local_blur[over], 90)) if over.any() else model.blur
    reach = max(1, int(np.ceil(2.0 * blur)))
    box = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    fold = cv2.dilate(crease.view(np.uint8), box).view(bool) & np.isfinite(grid.X[..., 0])
    if start.light is None or grid.normal is None:
        return fold, fold, fold
    fold &= np.isfinite(grid.normal[..., 0]) & (asked | sought)
    ii, jj = np.nonzero(fold)
    lo, hi = light_range(grid.normal, grid.X, start.light, fold, reach)
    shade = start.shade[ii, jj]
    # the print's light under the model's shading, and the exposure fit's own gain over it (the
    # model's is the print's, at the film's white)
    lit = photometric.linear(model.moved[ii, jj]) * shade
    gain = model.gain[ii, jj] * (np.float32(255.0) / photometric.grey_levels(shade))
    offset, limit = model.offset[ii, jj], colour_limit[ii, jj]
    explains, may_be_film, may_be_line = (np.zeros(fold.shape, bool) for _ in range(3))
    a = asked[ii, jj]
    explains[ii[a], jj[a]] = (
        least_residual_under_light(on.pho[ii[a], jj[a]], lit[a], gain[a], offset[a], lo[a], hi[a]) <= limit[a]
    )
    # (the film as the ink around shows it, at least the model: ink only absorbs)
    film_lo = shaded(np.clip(film[ii, jj], model.pred[ii, jj], np.float32(255.0)), lo)
    to_film = least_residual_under_light(film_lo, lit, gain, offset, lo, hi)
    # (at the limit ink gone is found at, :func:`colour_residuals`'s; a scratch's is that less
    # COLOUR_TOL, the tolerance for what is broad)
    may_be_film[ii, jj] = to_film <= limit + DETECT_Z * noise
    may_be_line[ii, jj] = to_film <= limit - COLOUR_TOL + DETECT_Z * noise
    return explains, may_be_film, may_be_line


def _defects(on: _Frame, start: _Start, measures: _Measures, colour: _Colour) -> _Found:
    """The defects: a slide the flow measures significantly, colour beyond its test, ink gone; marked in the states."""
    grid, tolerance_mm, mm_per_px = on.grid, on.tolerance_mm, on.mm_per_px
    state, fs = start.state, start.fs
    sat, rgb_, ref_n, pho_n, m, flow_k, win = fs.sat, fs.rgb_, fs.ref_n, fs.pho_n, fs.m, fs.flow_k, fs.win
    lit_disc, lit_now, slide = measures.lit_disc, measures.lit_now, measures.slide
    e1, usable, full, normal = measures.e1, measures.usable, measures.full, measures.normal
    unresolved, wide_sigma = measures.unresolved, measures.wide_sigma
    shift_mm, sigma_mm = measures.shift_mm, measures.sigma_mm
    alpha, colour_limit, colour_noise = colour.alpha, colour.colour_limit, colour.colour_noise
    res_raw, res, colour_bad, missing = colour.res_raw, colour.res, colour.colour_bad, colour.missing
    thin, verdicts, scored = colour.thin, colour.verdicts, colour.scored
    # a slide over a window of about a millimetre: the least-squares vector its pixels' texture
    # supports (each pixel's flow through its gradients: :func:`tensor_weighted_flow`), with the
    # window's own uncertainty (``wide_sigma``: the photo's noise through its weaker direction,
    # what the photo's windows err by beyond it, and the floor, which no window averages away).
    # Along an edge a pixel knows only the component
    # across it, which a slide parallel to it leaves 0 (a bubble cut into stripes), and DIS's
    # own vector there is its guess (it drifted 13 px over a photograph's soft background); a
    # window whose edges turn knows the whole slide. Usable where its uncertainty is, as a
    # pixel's (no gate on the texture's grey levels: a photograph's soft edges measure well)
    # (light, not ink, moves an edge for the flow too: DIS follows a glint along a ridge as if
    # the print had slid under it, 0.5 mm on a glossy photo's perfect part; the windows leave
    # out what light covers and the reach of the flow's patches around it). On a matte film the
    # light the photometric model takes a region for is a gain of the ink, which the flow's local
    # normalisation divides away: it moves no edge, and only the light the photo shows for sure
    # (clipped, beyond the film) is left out. (A 12 mm bubble slid 1 mm on the fandisk's matte
    # photo: the edges it moved, stepped towards the film, were taken for light over 71 px, and
    # the windows' evidence of the slide went with them over most of the bubble)
    lit = cv2.dilate(((state == HIGHLIGHT) | sat).astype(np.uint8), lit_disc).astype(bool) if on.glossy else lit_now
    # (the slide computed beside the rest where the light is the same: the same numbers)
    m_wide = slide.result() if np.array_equal(lit, lit_now) else tensor_weighted_flow(rgb_, m, 4 * win, ~lit)
    # (local defects in the flow from the placed print; the misregistration reported is the whole of it)
    local_shift = np.where(normal[..., None], _csum(m * e1)[..., None] * e1, m)
    local_mm = np.where(full | normal, np.hypot(local_shift[..., 0], local_shift[..., 1]) * mm_per_px, np.nan)
    # (and where the window's texture has two directions: along an edge that barely turns over the
    # window its slide along the edge is what the detection limit states it answers only
    # WINDOW_GAIN_ALONG_EDGE of, and its errors there are not its noise's: on a path tracer's
    # perfect photo a pale lobe's rim, an arc of uniform ink against white, slid "0.46 mm" in
    # three windows' regions of 24 to 52 mm², z 11 to 26, where the pixels' own flow said 0.01)
    # (on a matte film over the pixels scored before light was told from ink, as the detection limit
    # is stated: a gain moves no edge, and the edges a slide moves, stepped towards the film, are
    # what the photometric model may take for light; a 6 mm bubble slid 0.5 mm on the bunny's matte
    # photo, stated found over 98 % of it, lost its windows' evidence to 29 such pixels and passed)
    windowed = scored if on.glossy else measures.stated
    wide_ok = windowed & ~unresolved & ~lit & (wide_sigma <= usable) & measures.window_two_way
    wide_mm = np.hypot(m_wide[..., 0], m_wide[..., 1]) * mm_per_px
    z_wide = np.where(wide_ok, (wide_mm - tolerance_mm) / wide_sigma, np.nan)
    # the honest measures (the full vector, the component across an edge, a window's slide)
    # significantly beyond the tolerance: a region without any is the flow's guess, not a defect
    z_shift = (local_mm - tolerance_mm) / sigma_mm
    # (a window's slide spreads past a slid region's rim by about its own radius: eroded by
    # half the window's width, the window's evidence stays inside the region it measured)
    e = max(1, int(round(2 * win)))
    wide_evidence = cv2.erode(
        (wide_ok & (z_wide > SIGNIFICANCE_Z)).astype(np.uint8),
        cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * e + 1, 2 * e + 1)),
    ).astype(bool)
    own_evidence = (full | normal) & ~lit & (z_shift > SIGNIFICANCE_Z)
    evidence = own_evidence | wide_evidence
    shift_bad = evidence
    z_region = np.fmax(z_shift, z_wide)
    # (sized by the flow's own vector, whose edges are sharp: the window's blurs a bubble's rim)
    m_mm = np.hypot(m[..., 0], m[..., 1]) * mm_per_px
    # (a line is thin on the part only where the film is not spread out: the thin test works on
    # the print, and where the film stretches 6 to 11-fold over the face mask's nose 0.75 mm of
    # print is 4 to 8 mm of surface, which shading crosses: a perfect photo's lines there came
    # out at z 8.8 to 9.8 without the broad allowance, 2.0 to 2.5 with it; the scratch that
    # needed it lies where the film is 0.76 of the print)
    line = thin & missing & (grid.surface_per_print <= THIN_MAX_STRETCH)
    z_colour = colour_z(res, res_raw, missing, line, colour_limit, colour_noise)
    # (a region's slide as what found it measured it: the pixel's own where its own evidence
    # found it, the window's where only the window's did; the pixel's own there, under the
    # tolerance, stated a 32 mm² slide "up to 0.08 mm" against a tolerance of 0.2)
    decided_mm = np.where(wide_evidence & ~own_evidence, wide_mm, local_mm)
    labels, defects = find_defects(
        shift_bad,
        colour_bad,
        missing,
        decided_mm,
        res,
        grid,
        alpha,
        evidence,
        z_region,
        z_colour,
        win,
        m_mm,
        scored,
        own_evidence,
    )
    # a moved film explains the photo: the print moved by the region's flow must take most of
    # the residual away; a flow that explains little follows shading, gloss or the photo's
    # blur over faint texture, not the film
    keep = []
    ink_left = np.zeros_like(missing)
    set_aside = np.zeros_like(missing)  # the slid regions this photo's tests took for light

    def in_lamp(region: np.ndarray) -> bool:
        # (most of the region within the lamp's mirror cone; no lamp without a camera centre)
        if colour.cone is None:
            return False
        return bool(colour.cone.result()[0][region].mean() >= 0.5)

    for i, d in enumerate(defects):
        if d["kind"] == "shift":
            d["explained_share"] = shift_explained(
                ref_n, pho_n, m, (labels == i + 1) & (full | normal | wide_ok), flow_k
            )
            rule = None
            if d["explained_share"] is not None and d["explained_share"] < SHIFT_EXPLAINS:
                rule = "shift_not_explained"
            elif d["explained_share"] is not None:
                # a slide the photo does not tell from a smooth light (a sheen over faint or smooth
                # artwork) is light only where the surface mirrors the lamp of the photo's sure
                # light, as a region of colour the photometric model does not tell
                d["explained_under_light_share"] = shift_explained(
                    ref_n, pho_n, m, (labels == i + 1) & (full | normal | wide_ok), flow_k, under_light=True
                )
                if d["explained_under_light_share"] < SHIFT_EXPLAINS and in_lamp(labels == i + 1):
                    rule = "shift_as_light"
                elif d["explained_under_light_share"] < SHIFT_EXPLAINS:
                    # (out of the lamp's cone: open, on either finish; a glint moves between the
                    # part's photos and a slide does not, but a light the matte film's shading
                    # model misses may not move either)
                    d["told"] = False
            if rule is not None:
                # (its ink that is gone is still gone: a scratch drags the flow around it over
                # five times its own area, and the region took the flow's kind; 12.6 mm² of a
                # 20 mm scratch went with a 72 mm² region its flow did not explain)
                ink_left |= (labels == i + 1) & colour_bad & missing
                set_aside |= labels == i + 1
                # (and the QA engineer sees it set aside, and why)
                decided = {"rule": rule, "words": LIGHT_RULES[rule], "explained_share": round(d["explained_share"], 3)}
                if "explained_under_light_share" in d:
                    decided["explained_under_light_share"] = round(d["explained_under_light_share"], 3)
                colour.not_counted.append(
                    {
                        "centre_mm": [round(float(c), 2) for c in d["centre_mm"]],
                        "area_mm2": round(float(d["area_mm2"]), 2),
                        "decided_by": decided,
                    }
                )
                continue
        keep.append(i)
    if len(keep) < len(defects):
        relabel = np.zeros(len(defects) + 1, np.int32)
        relabel[np.asarray(keep, np.int64) + 1] = np.arange(1, len(keep) + 1)
        labels = relabel[labels]
        defects = [defects[i] for i in keep]
    if ink_left.any():
        # the ink that is gone under shift regions set aside, as regions of its own
        lab_ink, more = find_defects(
            np.zeros_like(ink_left), ink_left, ink_left, shift_mm, res, grid, alpha, None, None, z_colour, win
        )
        more = [d for d in more if d["kind"] == "missing"]
        if more:
            labels = np.where((labels == 0) & (lab_ink > 0) & (lab_ink <= len(more)), lab_ink + len(defects), labels)
            defects = defects + more
    for i, d in enumerate(defects):
        if d["kind"] != "missing":
            continue
        # what the photometric model said of a region of ink gone
        region = labels == i + 1
        if (j := photometric.judgement_at(region, verdicts)) is not None:
            d["photometric"] = j
        # told ink gone (by the photometric model, a line's ink), or ink gone by default over most
        # of its ink that is gone: neither told from light, and no lamp the photo shows mirrored there
        gone_px = int((region & missing).sum())
        d["told"] = not (gone_px and int((region & colour.untold).sum()) > 0.5 * gone_px)
    # (only where the photo was scored: a filled hole may hold a highlight, which stays masked)
    state[(labels > 0) & np.isin(state, (COLOUR_ONLY, UNRESOLVED, NORMAL, FULL))] = DEFECT
    # what the flow measured of the film's slide, for the part's other photos to compare: the
    # pixel's own measure (the full vector, or the component across the edge) where it has one,
    # else the window's slide (the part compares like with like: a window answers a small
    # bubble's slide at a fraction of it, in every photo alike), the photo's placement beside
    # it, and where a kept slide's measure is beyond the tolerance significantly, its claim
    own = (full | normal) & ~lit
    window = ~own & wide_ok
    reach = int(np.ceil(3 * win))
    reach_disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2)
    slide_px = np.where(own[..., None], local_shift, np.where(window[..., None], m_wide, np.nan))
    slide_mm = slide_px * mm_per_px[..., None]
    slide_sigma = np.where(own, sigma_mm, np.where(window, wide_sigma, np.nan))
    shifts = np.zeros(len(defects) + 1, bool)
    shifts[1:] = [d["kind"] == "shift" for d in defects]
    with np.errstate(invalid="ignore", divide="ignore"):
        significant = (np.hypot(slide_mm[..., 0], slide_mm[..., 1]) - tolerance_mm) / slide_sigma > SIGNIFICANCE_Z
    # (half precision: a millimetre to a thousandth, a grid of 4 Mpx in 92 MB a photo)
    slide = SlideMeasure(
        slide_mm.astype(np.float16),
        (start.early * mm_per_px[..., None]).astype(np.float16),
        slide_sigma.astype(np.float16),
        np.where((normal & own)[..., None], e1, np.float32(0.0)).astype(np.float16),
        window,
        np.where(shifts[labels] & significant, labels, 0).astype(np.int16),
        float(tolerance_mm),
        np.where(wide_ok[..., None], m_wide * mm_per_px[..., None], np.nan).astype(np.float16),
        np.where(wide_ok, wide_sigma, np.nan).astype(np.float16),
        float(win),
        # (and the flow's reach around them, where it ramps down: the part fuses none of it)
        cv2.dilate(set_aside.view(np.uint8), reach_disc).view(bool) if set_aside.any() else set_aside,
    )
    return _Found(labels, defects, lit, slide)


def _result(
    on: _Frame, start: _Start, model: _Model, measures: _Measures, colour: _Colour, found: _Found
) -> DenseResult:
    """The result: the maps, the defects, how finely the photo samples the print and what it can find."""
    grid, warped, fp = on.grid, on.warped, on.fp
    tolerance_mm, mm_per_px = on.tolerance_mm, on.mm_per_px
    state, win = start.state, start.fs.win
    blur, local_blur = model.blur, model.local_blur
    unresolved, needed_blur, sigma_mm = measures.unresolved, measures.needed_blur, measures.sigma_mm
    stated, normal, e1 = measures.stated, measures.normal, measures.e1
    scored, colour_limit, inked = colour.scored, colour.colour_limit, colour.inked
    dropout_found, thin_found, fold = colour.dropout_found, colour.thin_found, colour.fold
    lit = found.lit
    # how finely the photo samples the print, and what it cannot resolve
    photo_px_per_mm = np.where(scored, fp / mm_per_px, np.nan)
    median_res = float(np.nanmedian(photo_px_per_mm)) if scored.any() else None
    needed, factor = None, None
    if unresolved.any():
        # the photo's blur scales with its pixel: to bring it from ``blur`` down to what the
        # detail needs, the photo needs blur / needed_blur times as many pixels per mm
        k = local_blur[unresolved] / needed_blur[unresolved]
        factor = float(np.percentile(k, 90))
        needed = median_res * factor if median_res else None
    n_scored = max(int(scored.sum()), 1)
    resolution = {
        "photo_px_per_mm": median_res,
        "unresolved_share": float(unresolved.sum() / n_scored),
        "needed_resolution_factor": factor,
        "needed_photo_px_per_mm": needed,
        "note": (
            "detail of the print finer than about two photo pixels (strokes of small text) is "
            "'unresolved': its misregistration is not measured; a photo needed_resolution_factor times as "
            "fine (needed_photo_px_per_mm on the median) would resolve 90 % of it"
        ),
    }
    med_sigma = float(np.nanmedian(sigma_mm)) if np.isfinite(sigma_mm).any() else None
    # a defect must cover MIN_DEFECT_MM2 and span a few photo pixels each way (the opening
    # and closing in find_defects work on 3 x 3 grid pixels) to be found
    px_mm = (1.0 / median_res) if median_res else None
    limit_mm, stated_sigma_mm, window_sigma_mm = measures.shift_limit.result()
    # (the flow near light is not the print's: see lit above; and what was taken for light is not
    # scored, which on a matte film lit leaves in)
    unmeasured = lit | (state == HIGHLIGHT)
    limit_mm[unmeasured] = np.nan
    stated_sigma_mm[unmeasured] = np.nan
    window_sigma_mm[unmeasured] = np.nan
    in_cone = None
    if colour.cone is not None:
        in_cone, flat_in_cone = colour.cone.result()
        dropout_found &= ~in_cone
        thin_found &= ~flat_in_cone
    if colour.room is not None:
        # (ink gone that a glossy film's reflection of the room could look like: not found there)
        dropout_found &= ~colour.room
        thin_found &= ~colour.room
    dropout_found &= ~fold
    thin_found &= ~colour.fold_line
    ink_step = float(np.median(colour_limit[stated])) if stated.any() else COLOUR_TOL
    limit = {
        "min_area_mm2": max(MIN_DEFECT_MM2, (3.0 * px_mm) ** 2 if px_mm else 0.0, (3.0 / grid.px_per_mm) ** 2),
        "min_shift_mm": (tolerance_mm + SIGNIFICANCE_Z * med_sigma) if med_sigma is not None else None,
        "significance_z": SIGNIFICANCE_Z,
        **detection.summary(
            limit_mm, dropout_found & stated, stated, inked & stated, max(2 * COLOUR_TOL, ink_step), thin_found & stated
        ),
        "note": (
            "stated for a sound part from the design, the photo's noise, blur and sampling: a slide of the film is "
            "found where the print has texture the photo resolves (min_shift_mm_*: over the pixels that find one), "
            "ink that is gone where its step to the bare film exceeds min_ink_step_grey_levels, a scratch (a line of "
            "ink gone, thinner than about 0.7 mm) wherever the ink differs from the film by twice the noise and "
            "placement (the noise the photo shows around it), but on a glossy film not over uniform ink within the "
            "lamp's reflection, where a glint looks the same; the maps "
            "are in detection.npz"
        ),
    }
    return DenseResult(
        warped,
        state,
        measures.shift,
        measures.shift_mm.astype(np.float32),
        colour.colour,
        colour.missing,
        found.labels,
        found.defects,
        blur,
        measures.m_total,
        measures.texture,
        sigma_mm,
        measures.noise,
        resolution,
        limit,
        limit_mm,
        dropout_found & stated,
        win,
        np.where(normal[..., None], e1, np.float32(0.0)).astype(np.float32),
        thin_found & stated,
        colour.not_counted,
        in_cone,
        start.early if start.early.any() else None,
        found.slide,
        stated_sigma_mm,
        window_sigma_mm,
    )
