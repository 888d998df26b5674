"""Layout of a flat metric with a rectangular boundary into the plane."""

from __future__ import annotations

import numpy as np

from workbench.conformal.cetm import cotan_laplacian
from workbench.errors import WorkbenchError
from workbench.sparse import SPDSolver


def rectangle_boundary(loop_lengths: np.ndarray, corner_pos: np.ndarray) -> tuple[np.ndarray, float, float, float]:
    """Positions of the boundary vertices on an axis-aligned rectangle.

    A flat metric with angle sum π at every boundary vertex but four, and π/2 at
    those four, has straight sides meeting at right angles, so each boundary vertex
    sits at its arc length along its side: no error accumulates.

    Parameters
    ----------
    loop_lengths : (#B,) float
        Length of boundary edge ``loop[i] -> loop[i + 1]`` in the flat metric.
    corner_pos : (4,) int
        Positions in the loop of corners A, B, C, D, with ``corner_pos[0] == 0`` and
        increasing: the loop runs counter-clockwise, A→B along +x, B→C along +y.

    Returns
    -------
    xy : (#B, 2) float
        Boundary positions, A at the origin.
    width, height : float
        Rectangle size: the mean of the two opposite sides' lengths.
    mismatch : float
        Largest relative difference between opposite sides (0 for an exact metric).
    """
    nb = len(loop_lengths)
    ends = np.append(corner_pos, nb)
    cum = [np.concatenate([[0.0], np.cumsum(loop_lengths[ends[s] : ends[s + 1]])]) for s in range(4)]
    side = np.array([c[-1] for c in cum])
    width, height = 0.5 * (side[0] + side[2]), 0.5 * (side[1] + side[3])
    mismatch = float(max(abs(side[0] - side[2]) / width, abs(side[1] - side[3]) / height))
    xy = np.empty((nb, 2))
    # fraction of each side walked, so opposite sides of slightly different metric
    # length still meet the corners exactly
    for s, (x0, y0, dx, dy, length) in enumerate(
        [
            (0, 0, width, 0, side[0]),
            (width, 0, 0, height, side[1]),
            (width, height, -width, 0, side[2]),
            (0, height, 0, -height, side[3]),
        ]
    ):
        t = cum[s][:-1] / length
        xy[ends[s] : ends[s + 1]] = np.stack([x0 + t * dx, y0 + t * dy], axis=1)
    return xy, float(width), float(height), mismatch


def harmonic_interior(
    F: np.ndarray, cot: np.ndarray, boundary: np.ndarray, boundary_xy: np.ndarray, n_vertices: int
) -> np.ndarray:
    """Interior positions of a flat metric given its boundary positions.

    A planar triangulation is harmonic for its own cotangent weights (the
    cotangent Laplacian annihilates linear functions, and each coordinate is one),
    so solving ``L_II x_I = -L_IB x_B`` with the flat metric's cotangents reproduces
    the metric exactly: one sparse SPD solve, no accumulation along a tree.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.
    cot : (#F, 3) float
        Cotangents of the flat metric's corner angles.
    boundary : (#B,) int
        Boundary vertices.
    boundary_xy : (#B, 2) float
        Their positions.
    n_vertices : int
        #V.

    Returns
    -------
    xy : (#V, 2) float
        All positions.
    """
    L = cotan_laplacian(F, cot, n_vertices)
    interior = np.setdiff1d(np.arange(n_vertices), boundary)
    xy = np.zeros((n_vertices, 2))
    xy[boundary] = boundary_xy
    if len(interior):
        L_ii = L[interior][:, interior]
        rhs = -(L[interior][:, boundary] @ boundary_xy)
        xy[interior] = SPDSolver(L_ii).solve(rhs)
    if not np.isfinite(xy).all():
        raise WorkbenchError("layout failed: the flat metric's Laplacian is singular")
    return xy


def signed_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Signed area of every triangle in the plane; (#F,) float, positive when CCW."""
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
