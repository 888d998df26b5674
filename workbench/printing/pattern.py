"""The forming calibration film's pattern: dense, locally unique random dots."""

from __future__ import annotations

import cv2
import numpy as np

PATTERN = {
    "kind": "random dots",
    "seed": 20,
    # dot radii, mm: a range, so that no neighbourhood repeats another (locally unique), large
    # enough for a photo at 10 px/mm to resolve, small enough that every window of the dense
    # flow (about 1 mm) holds texture in two directions
    "radius_mm": [0.2, 0.45],
    "density_per_mm2": 1.2,
    "ink": [20, 20, 20],
    # (not white: a photo clips the film's white to 255, which validate takes for a highlight)
    "paper": [230, 230, 230],
}


def pattern_for(rows: int, cols: int, dpi: float, definition: dict = PATTERN) -> dict:
    """The pattern's definition for a print of ``rows`` x ``cols`` px at ``dpi``: its dots scaled up
    where validate's analysis grid is coarser than they are.

    validate measures the landing on the print reduced to at most ``MAX_GRID_PX`` pixels (a
    large print or a sheet of several films: a whole factor coarser); a dot must span at least
    a grid pixel there, or the flow sees no texture. The density falls with the square of the
    scale, so the pattern keeps its look at the grid's resolution.
    """
    from workbench.validate.print_warp import MAX_GRID_PX

    factor = max(1, int(np.ceil(np.sqrt(rows * cols / MAX_GRID_PX))))
    grid_mm = 25.4 / dpi * factor
    scale = max(1.0, grid_mm / definition["radius_mm"][0])
    if scale == 1.0:
        return dict(definition)
    return {
        **definition,
        "radius_mm": [round(r * scale, 4) for r in definition["radius_mm"]],
        "density_per_mm2": round(definition["density_per_mm2"] / scale**2, 5),
        "scaled": f"x {scale:.3g}: validate's analysis grid of this print has {grid_mm:.3g} mm pixels",
    }


def dot_pattern(rows: int, cols: int, dpi: float, definition: dict = PATTERN) -> np.ndarray:
    """The pattern on a print of ``rows`` x ``cols`` px at ``dpi``; (rows, cols, 3) uint8 RGB.

    Dot centres uniform over the print (seeded), radii uniform in ``radius_mm``, drawn
    antialiased at 1/16 px: the same definition gives the same pixels.
    """
    ppm = dpi / 25.4
    rng = np.random.default_rng(int(definition["seed"]))
    area = rows * cols / ppm**2
    n = int(round(definition["density_per_mm2"] * area))
    xy = rng.uniform(0, 1, (n, 2)) * [cols, rows]
    lo, hi = definition["radius_mm"]
    r = rng.uniform(lo, hi, n) * ppm
    img = np.full((rows, cols, 3), definition["paper"], np.uint8)
    ink = tuple(int(c) for c in definition["ink"])
    s = 16
    for (x, y), rad in zip(xy, r, strict=True):
        cv2.circle(img, (int(round(x * s)), int(round(y * s))), int(round(rad * s)), ink, -1, cv2.LINE_AA, 4)
    return img
