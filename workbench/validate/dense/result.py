"""What the analysis of one photo returns, and its coverage per view."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.validate.dense.options import TENSOR_SIGMA_PX
from workbench.validate.print_warp import COLOUR_ONLY, DEFECT, FULL, MEASURED, NORMAL, OFF_PART, STATE_NAMES
from workbench.validate.slide_evidence import SlideMeasure


@dataclass
class DenseResult:
    """One photo on the print grid.

    Attributes
    ----------
    warped : (rows, cols, 3) uint8
        The photo on the print.
    state : (rows, cols) uint8
        Per pixel, one of the states (OFF_PART ... DEFECT).
    shift_px : (rows, cols, 2) float32
        Misregistration, grid px (the normal component where only that is known; NaN where
        not measured).
    shift_mm : (rows, cols) float32
        Its length on the surface, mm (NaN where not measured).
    sigma_mm : (rows, cols) float32
        Standard uncertainty of ``shift_mm``, mm on the surface (NaN where not measured):
        the photo's noise through the texture the photo resolves there, what the model does
        not explain (a PSF or colour the design does not predict), and the flow's
        forward-backward disagreement.
    colour_residual : (rows, cols) float32
        Largest channel residual after the exposure fit, grey levels (NaN where not scored).
    missing : (rows, cols) bool
        The photo shows the bare film where the design has ink.
    labels : (rows, cols) int32
        Defect number + 1 per pixel (0: none).
    flow_px : (rows, cols, 2) float32
        The flow's own misregistration vector everywhere (also where the texture does not
        determine it), grid px.
    texture : (rows, cols) uint8
        What the print's texture lets the flow know where the photo is scored: 2 the full
        vector, 1 the component across an edge, 0 nothing.
    defects : list of dict
        Each defect: centre_mm (print), area_mm2 (print), area_surface_mm2, bbox_mm, kind,
        peak_mm and mean_mm (misregistration), colour_peak (grey levels), significance_z and
        confidence.
    blur_px : float
        The photo's blur on the grid, sigma.
    noise : float
        The photo's noise on the grid, grey levels (standard deviation at the flow's scale).
    resolution : dict
        How finely the photo samples the print (photo px per surface mm, median), what it
        cannot resolve (share of the scored print) and the resolution that would resolve it.
    detection_limit : dict
        The smallest defects this photo can find: area (mm² on the print), misregistration
        (mm on the surface), and the shares of the print where it finds a slide and ink that
        is gone (:mod:`workbench.validate.detection`).
    shift_limit_mm : (rows, cols) float32
        The smallest slide of the film found at each pixel, mm on the surface (NaN: none).
    dropout_found : (rows, cols) bool
        Where ink that is gone is found.
    window_px : float
        The flow's window, Gaussian sigma, grid px: a measurement's independent neighbourhood.
    normal_dir : (rows, cols, 2) float32
        The dominant edge's unit normal, where only the component across it is measured.
    scratch_found : (rows, cols) bool
        Where a scratch (a thin line of ink gone) is found.
    not_counted : list of dict
        The regions of the colour residual taken for light, not counted as defects
        (:func:`not_counted_regions`): ``centre_mm``, ``area_mm2`` (print) and ``decided_by``
        (``rule``, the test that decided, and ``words``).
    lamp_cone : (rows, cols) bool or None
        Where the surface mirrors the lamp of the photo's sure light towards the camera
        (:func:`mirror_cone`): a glossy film's sheen may add light there below any glint. None
        on a matte film.
    placement_px : (rows, cols, 2) float32 or None
        The films' fitted placement (:func:`workbench.validate.placement.placement_field`) where
        the analysis started again from the print placed so, grid px (x, y); None where it did not.
    slide : SlideMeasure or None
        What the flow measured of the film's slide, and what the photo's slides claim
        (:mod:`workbench.validate.slide_evidence`): the part compares it with its other photos.
    shift_sigma_mm : (rows, cols) float32 or None
        The stated uncertainty of the pixel's own full vector, mm on the surface, where the
        photo measures it (NaN elsewhere): the part fuses it over its photos into its limit.
    window_sigma_mm : (rows, cols) float32 or None
        The stated uncertainty of the window's slide where the window measures it and its
        texture has two directions (NaN elsewhere): fused over the photos likewise.
    """

    warped: np.ndarray
    state: np.ndarray
    shift_px: np.ndarray
    shift_mm: np.ndarray
    colour_residual: np.ndarray
    missing: np.ndarray
    labels: np.ndarray
    defects: list
    blur_px: float
    flow_px: np.ndarray
    texture: np.ndarray
    sigma_mm: np.ndarray | None = None
    noise: float = 0.0
    resolution: dict | None = None
    detection_limit: dict | None = None
    shift_limit_mm: np.ndarray | None = None
    dropout_found: np.ndarray | None = None
    window_px: float = TENSOR_SIGMA_PX
    normal_dir: np.ndarray | None = None
    scratch_found: np.ndarray | None = None
    not_counted: list | None = None
    lamp_cone: np.ndarray | None = None
    placement_px: np.ndarray | None = None
    slide: SlideMeasure | None = None
    shift_sigma_mm: np.ndarray | None = None
    window_sigma_mm: np.ndarray | None = None


def coverage_by_view(state: np.ndarray, owner: np.ndarray, names: list[str]) -> dict:
    """Per view, the shares of its own region on the print: measured (colour, shift) and unmeasured by reason."""
    out = {}
    for vi, name in enumerate(names):
        own = state[owner == vi]
        n = max(len(own), 1)
        out[name] = {
            "measured": float(np.isin(own, MEASURED).sum() / n),
            "shift_measured": float(np.isin(own, (NORMAL, FULL, DEFECT)).sum() / n),
            "shift_full_vector": float(np.isin(own, (FULL, DEFECT)).sum() / n),
            "defective": float((own == DEFECT).sum() / n),
            "unmeasured": {
                STATE_NAMES[k]: float((own == k).sum() / n)
                for k in range(COLOUR_ONLY)
                if k != OFF_PART and (own == k).any()
            },
        }
    return out
