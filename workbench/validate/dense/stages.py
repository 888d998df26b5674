"""The dense analysis's stages: what each hands the next (:mod:`workbench.validate.dense.pipeline`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.validate.dense.flow import FlowStart
from workbench.validate.print_warp import PrintGrid
from workbench.validate.slide_evidence import SlideMeasure


@dataclass
class _Frame:
    """What every stage reads: the grid, the photo on it and the analysis's settings.

    Attributes
    ----------
    grid : PrintGrid
    warped : (H, W, 3) uint8
        The photo on the print.
    pho : (H, W, 3) float32
        The same in floats.
    tolerance_mm, scale : float
        As :func:`analyse` takes them.
    fp : (H, W) float32
        Photo pixels per grid pixel at each grid pixel (``scale`` everywhere when not given).
    camera_center : (3,) float or None
    later : Executor
        Where the work that can run beside the rest goes.
    jj, ii : (H, W) float32
        Each grid pixel's column and row.
    mm_per_px : (H, W) float32
        Surface mm per grid px: print mm times the film's local stretch.
    fp_axes : (H, W, 2) float32
        Photo pixels per grid pixel that the camera's blur sees along x (axis 1) and y (axis 0).
    glossy : bool
        The film adds light of its own (:func:`analyse`'s ``finish``).
    """

    grid: PrintGrid
    warped: np.ndarray
    pho: np.ndarray
    tolerance_mm: float
    scale: float
    fp: np.ndarray
    camera_center: np.ndarray | None
    later: object
    jj: np.ndarray
    ii: np.ndarray
    mm_per_px: np.ndarray
    fp_axes: np.ndarray
    glossy: bool = True


@dataclass
class _Start:
    """The flow from the print as the film's placement puts it (:func:`_placed_flow`).

    Attributes
    ----------
    fs : FlowStart
        The masks, the images the flow compares and the flow, from the placed print.
    state : (H, W) uint8
        The visibility states (the film's rim as placed); the later stages write into it.
    ref : (H, W, 3) float32
        The print as placed.
    early : (H, W, 2) float32
        The placement's misregistration, grid px (0 where it moves the print by less than a
        measuring pixel's uncertainty may be).
    shade : (H, W, 3) float32
        The shading of the surface's normal relative to its median (:func:`shading_factor`),
        linear light; 1 without a model. The flow compares the photo with the print so shaded.
    held : (H, W, 2) float32
        The placement the flow still holds, grid px: the fitted placement where it was too small
        to place the print by (``early`` 0), else 0. Every window shares it: it is no window's
        error (:func:`window_mismatch`).
    light : (3, 9) float or None
        The photo's light as a function of the normal (:func:`fit_shading`); None without a model.
    """

    fs: FlowStart
    state: np.ndarray
    ref: np.ndarray
    early: np.ndarray
    shade: np.ndarray
    held: np.ndarray
    light: np.ndarray | None = None


@dataclass
class _Model:
    """The model of the photo: the print moved by the flow, blurred like the photo, in its exposure.

    Attributes
    ----------
    back, detail : Future
        The flow back (:func:`dis_flow`) and the print's unresolved detail (:func:`unresolved_detail`).
    blur : float
        The photo's blur on the grid where it samples the print at its median, grid px.
    local_blur : (H, W) float32
        Its blur at each grid pixel (:meth:`~workbench.validate.dense.blur.PhotoBlur.on_grid`).
    moved : (H, W, 3) float32
        The print moved by the flow's median and blurred like the photo.
    weight : (H, W) float32
        The exposure fit's weights (its inliers).
    gain, offset : (H, W, 3) float32
        The exposure fit.
    pred : (H, W, 3) float32
        The model: the exposure fit of the print as the shading shows it (:mod:`workbench.validate.shading`), about
        ``gain · moved + offset``.
    res : (H, W) float32
        Its largest channel residual.
    g0 : (3,) float or None
        The photo's own gain (:func:`photo_gain`).
    lost : (H, W) bool
        Where the photo has lost the design's texture (:func:`texture_lost`).
    white : (H, W, 3) float32
        The film's white as the exposure fit extrapolates it.
    shade : (H, W, 3) float32
        The shading of the surface's normal relative to its median (:func:`shading_factor`),
        linear light; 1 without a model.
    lit : (H, W, 3) float32
        ``moved`` as the shading shows it (:func:`shaded`), grey levels.
    """

    back: object
    detail: object
    blur: float
    local_blur: np.ndarray
    moved: np.ndarray
    weight: np.ndarray
    gain: np.ndarray
    offset: np.ndarray
    pred: np.ndarray
    res: np.ndarray
    g0: np.ndarray | None
    lost: np.ndarray
    white: np.ndarray
    shade: np.ndarray
    lit: np.ndarray


@dataclass
class _SureLight:
    """The light the photo shows for sure, beyond the bare film (:func:`_sure_light`).

    Attributes
    ----------
    film_lit : photometric film level
        The bare film as the ink around each pixel shows it (:func:`photometric.film_level`).
    past_film : (H, W) bool
        Brighter than the bare film could be.
    highlight : (H, W) bool
        ``past_film`` where the texture is not lost.
    why_light : dict of str to (H, W) bool
        What decided each pixel taken for light (:func:`not_counted_regions`); later stages add to it.
    scored : (H, W) bool
        The pixels still scored (FULL) after highlights and deep shadows.
    """

    film_lit: object
    past_film: np.ndarray
    highlight: np.ndarray
    why_light: dict
    scored: np.ndarray


@dataclass
class _Measures:
    """What the flow measures where, with its uncertainty (:func:`_flow_measures`).

    Attributes
    ----------
    lit_disc : (k, k) uint8
        The flow's reach around light.
    lit_now : (H, W) bool
        The light known before light is told from ink, with that reach.
    slide, shift_limit : Future
        The window's slide with ``lit_now`` left out (:func:`tensor_weighted_flow`) and the
        stated slide limit (:func:`stated_shift_limit`).
    noise : float
        The photo's noise at the flow's scale, grey levels.
    e1 : (H, W, 2) float32
        The dominant edge's normal.
    usable : float
        The largest uncertainty a measuring pixel may have, mm on the surface.
    full, normal : (H, W) bool
        Where the full vector, and only the component across the edge, is measured.
    unresolved : (H, W) bool
        The print's detail the photo does not resolve.
    needed_blur : (H, W) float32
        The blur that would resolve it (:func:`unresolved_detail`).
    stated : (H, W) bool
        The pixels the detection limit is stated over.
    wide_sigma : (H, W) float32
        The window's slide's uncertainty, mm on the surface.
    window_two_way : (H, W) bool
        The window's texture has two directions (its weaker eigenvalue at least
        WINDOW_TWO_WAY_STATED of its stronger): its slide is measured in any direction.
    m_total : (H, W, 2) float32
        The whole misregistration: the placement's and the rest, grid px.
    shift : (H, W, 2) float32
        The misregistration where measured (NaN elsewhere), grid px.
    texture : (H, W) uint8
        2 the full vector, 1 the component across an edge, 0 nothing.
    shift_mm, sigma_mm : (H, W) float32
        The misregistration's length and its uncertainty, mm on the surface.
    """

    lit_disc: np.ndarray
    lit_now: np.ndarray
    slide: object
    shift_limit: object
    noise: float
    e1: np.ndarray
    usable: float
    full: np.ndarray
    normal: np.ndarray
    unresolved: np.ndarray
    needed_blur: np.ndarray
    stated: np.ndarray
    wide_sigma: np.ndarray
    window_two_way: np.ndarray
    m_total: np.ndarray
    shift: np.ndarray
    texture: np.ndarray
    shift_mm: np.ndarray
    sigma_mm: np.ndarray


@dataclass
class _Colour:
    """The colour test with light told from ink (:func:`_light_or_ink`).

    Attributes
    ----------
    alpha, colour_limit, colour_noise, res_raw : as :func:`colour_residuals` returns them
    res : (H, W) float32
        The colour residual (against the photo's own gain where texture is lost).
    colour : (H, W) float32
        ``res`` where colour is judged, NaN elsewhere.
    colour_bad : (H, W) bool
        Beyond the colour test, light taken out.
    missing : (H, W) bool
        Ink that is gone.
    inked, dropout_found, thin, thin_found : as :func:`colour_residuals` returns them
    verdicts : photometric region verdicts
    scored : (H, W) bool
        The pixels scored, light taken out.
    cone : Future or None
        The lamp's mirror cone (:func:`lamp_cone`), with a camera centre, on a glossy film
        (None on a matte one: it mirrors no lamp).
    fold : (H, W) bool
        Where the surface folds and its light may pass for ink that is gone (:func:`_fold_light`):
        ink gone is not found there.
    fold_line : (H, W) bool
        Where it may pass for a scratch: a scratch is not found there.
    not_counted : list of dict
        The regions taken for light (:func:`not_counted_regions`).
    room : (H, W) bool or None
        Where ink that is gone would brighten the ink by no more than a glossy film's reflection
        of the room may (:func:`reflection.within_room_reflection`): ink gone is not found there.
        None on a matte film, which mirrors nothing.
    untold : (H, W) bool
        Ink that is gone by default: no test told it from light (the photometric model's "not
        told", a line over uniform ink), and no lamp the photo shows is mirrored there.
    """

    alpha: np.ndarray
    colour_limit: np.ndarray
    colour_noise: float
    res_raw: np.ndarray
    res: np.ndarray
    colour: np.ndarray
    colour_bad: np.ndarray
    missing: np.ndarray
    inked: np.ndarray
    dropout_found: np.ndarray
    thin: np.ndarray
    thin_found: np.ndarray
    verdicts: object
    scored: np.ndarray
    cone: object
    fold: np.ndarray
    fold_line: np.ndarray
    not_counted: list
    room: np.ndarray | None = None
    untold: np.ndarray | None = None


@dataclass
class _Found:
    """The defects (:func:`_defects`).

    Attributes
    ----------
    labels : (H, W) int32
        Defect number + 1 per pixel (0: none).
    defects : list of dict
    lit : (H, W) bool
        The light known at the end, with the flow's reach around it.
    slide : SlideMeasure
        What the flow measured of the film's slide, and what the kept slides claim.
    """

    labels: np.ndarray
    defects: list
    lit: np.ndarray
    slide: SlideMeasure
