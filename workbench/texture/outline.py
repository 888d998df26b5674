"""The film's outline on the print grid: which pixels the film covers, and a bleed that follows it."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.mesh.topology import boundary_loops

# cv2.fillPoly's fixed-point vertices: 4 fractional bits, 1/16 px
_SHIFT = 4


def film_mask(P: np.ndarray, F: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Pixels whose centre lies inside the film's outline.

    Parameters
    ----------
    P : (#V, 2) float
        Flat layout in print pixel coordinates (x right, y down; pixel (i, j) has its
        centre at (j, i)), as :meth:`PrintGrid.to_pixels` gives.
    F : (#F, 3) int
        Triangles of a disc.
    rows, cols : int
        Print size, pixels.

    Returns
    -------
    mask : (rows, cols) bool
        True inside the outline (the boundary loop of ``F``); pixels on the outline
        itself count as inside, so the film's edge is never left unprinted.
    """
    mask = np.zeros((rows, cols), dtype=np.uint8)
    # fillPoly treats integer vertices as pixel centres, which is the convention of P
    loops = [np.round(P[loop] * (1 << _SHIFT)).astype(np.int32) for loop in boundary_loops(F)]
    cv2.fillPoly(mask, loops, 1, lineType=cv2.LINE_8, shift=_SHIFT)
    return mask.astype(bool)


def bleed_beyond_outline(rgb: np.ndarray, mask: np.ndarray, bleed_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Extend a print beyond its outline by repeating the nearest pixel inside it.

    Parameters
    ----------
    rgb : (rows, cols, 3) uint8
        The print; pixels outside ``mask`` are ignored.
    mask : (rows, cols) bool
        The film (see :func:`film_mask`); must hold at least one pixel.
    bleed_px : float
        How far the bleed reaches beyond the outline, pixels.

    Returns
    -------
    rgb : (rows, cols, 3) uint8
        Inside the outline unchanged; within ``bleed_px`` of it, the colour of the
        nearest pixel inside; beyond, unchanged (covered by ``alpha`` 0).
    alpha : (rows, cols) uint8
        255 on the film and its bleed, 0 beyond.
    """
    # distance and index of the nearest film pixel (the zero pixels of the input) for
    # every pixel; labels count the zero pixels in scan order, as flatnonzero does
    dist, labels = cv2.distanceTransformWithLabels(
        (~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE, labelType=cv2.DIST_LABEL_PIXEL
    )
    inside = np.flatnonzero(mask.ravel())
    bleed = (~mask) & (dist <= bleed_px)
    out = rgb.copy()
    src = inside[labels[bleed] - 1]
    out[bleed] = rgb.reshape(-1, rgb.shape[2])[src]
    alpha = np.where(mask | bleed, 255, 0).astype(np.uint8)
    return out, alpha
