"""The photo in print coordinates: a dense misregistration field, colour residuals, local defects, coverage."""

# Every photo is mapped onto the print (each print pixel takes the photo's colour of its
# surface point), so one grid serves every view and every photo of a part. There:
#
# - **Misregistration** at every pixel with texture: DIS optical flow (OpenCV) between the
#   warped photo and the print, both normalised for local exposure. A per-pixel structure
#   tensor of the print says what the flow can know: texture in two directions gives the full
#   vector; along a single edge only the component across it (the aperture problem), which is
#   what is kept there (``normal``); no texture, nothing (``colour_only``).
# - **Colour**: the photo against the print blurred like it, after a local per-channel gain
#   and offset fit (shading, vignetting, exposure) on the print moved by the flow (so a shift
#   is not also a colour error). Residuals beyond what noise and the fit explain are colour
#   defects; where the photo shows the bare film's colour, ink is missing.
# - **Light or ink**: light beyond the bare film and each region of the colour residual judged
#   light or ink gone by :mod:`workbench.validate.photometric`; what it cannot tell is left to
#   the lamp (light only in the mirror cone of the photo's sure light). Deep shadows are not
#   scored; neither is surface that turns its back to the camera (occluded), nor what the photo
#   sees next to a step in depth (the part's outline, a fold: its pixels mix two surfaces),
#   nor a band along the edge of what is seen; each is reported as unmeasured with its reason,
#   and every region set aside as light with the test that decided it (``not_counted``).
#
# The print's grid, the photo warped onto it and its visibility states are in
# :mod:`workbench.validate.print_warp`; the film's placement in :mod:`workbench.validate.placement`.
# All functions here are numeric (arrays in, arrays out); the command does the I/O.
# Conventions: print pixel (i, j) of the analysis grid has its centre at
# ((j + 0.5), (i + 0.5)) / ``px_per_mm`` mm from the trim's top-left corner (x right, y down).

from __future__ import annotations

from workbench.validate.dense.blur import unresolved_detail
from workbench.validate.dense.defects import shift_explained
from workbench.validate.dense.exposure import colour_z, film_colour
from workbench.validate.dense.flow import (
    dense_flow,
    flow_factor,
    local_normalise,
    masked_normalise,
    median_flow,
    print_texture,
    tensor_weighted_flow,
    window_gain,
)
from workbench.validate.dense.light import LIGHT_RULES, mirrors_highlights, not_counted_regions, regions_mostly_in
from workbench.validate.dense.lines import thin_told
from workbench.validate.dense.options import (
    APART_DEG,
    COLOUR_TOL,
    DETECT_Z,
    FLOW_FLOOR_PX,
    MIN_DEFECT_MM2,
    MIN_EDGE,
    MIN_TWO_WAY,
    MIRROR_DEG,
    NOISE_FLOOR,
    NORM_SIGMA_PX,
    PHOTO_FLOOR_PX,
    REGISTRATION_BLUR_PX,
    SHIFT_EXPLAINS,
    SIGNIFICANCE_Z,
    TENSOR_SIGMA_PX,
    WINDOW_GAIN,
    WINDOW_GAIN_ALONG_EDGE,
)
from workbench.validate.dense.pipeline import analyse
from workbench.validate.dense.result import DenseResult, coverage_by_view
from workbench.validate.dense.uncertainty import (
    agreement,
    effective_samples,
    flow_floor,
    flow_uncertainty,
    forward_backward,
    noise_correlation,
)

__all__ = [
    "COLOUR_TOL",
    "FLOW_FLOOR_PX",
    "MIN_DEFECT_MM2",
    "MIN_EDGE",
    "MIN_TWO_WAY",
    "DETECT_Z",
    "MIRROR_DEG",
    "APART_DEG",
    "NOISE_FLOOR",
    "NORM_SIGMA_PX",
    "PHOTO_FLOOR_PX",
    "REGISTRATION_BLUR_PX",
    "SHIFT_EXPLAINS",
    "SIGNIFICANCE_Z",
    "TENSOR_SIGMA_PX",
    "WINDOW_GAIN",
    "WINDOW_GAIN_ALONG_EDGE",
    "dense_flow",
    "flow_factor",
    "local_normalise",
    "masked_normalise",
    "median_flow",
    "print_texture",
    "tensor_weighted_flow",
    "window_gain",
    "agreement",
    "effective_samples",
    "flow_floor",
    "flow_uncertainty",
    "forward_backward",
    "noise_correlation",
    "unresolved_detail",
    "thin_told",
    "colour_z",
    "film_colour",
    "LIGHT_RULES",
    "mirrors_highlights",
    "not_counted_regions",
    "regions_mostly_in",
    "shift_explained",
    "DenseResult",
    "coverage_by_view",
    "analyse",
]
