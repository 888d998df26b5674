"""Layout of a flat metric with a rectangular boundary into the plane."""

from __future__ import annotations

import numpy as np

from workbench.errors import WorkbenchError
from workbench.sparse import CotanAssembler, SPDSolver, preconditioned_cg, symmetric_matvec


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


def boundary_flux(loop: np.ndarray, boundary_xy: np.ndarray, n_vertices: int) -> np.ndarray:
    """Cotangent Laplacian of the coordinate functions of a planar layout.

    For a planar, counter-clockwise triangulation the conformal energy ``E_D - A``
    (Dirichlet energy minus signed area) vanishes at the identity map, which is its
    minimum, so ``L x = ∇A``: zero inside and, at a boundary vertex ``i`` between
    ``i-1`` and ``i+1``, ``(L x)_i = (y_{i+1} - y_{i-1}) / 2`` and
    ``(L y)_i = (x_{i-1} - x_{i+1}) / 2``. Only the boundary enters.

    Parameters
    ----------
    loop : (#B,) int
        Boundary loop, counter-clockwise.
    boundary_xy : (#B, 2) float
        Its positions.
    n_vertices : int
        #V.

    Returns
    -------
    b : (#V, 2) float
        ``L [x y]``.
    """
    nxt = np.roll(boundary_xy, -1, axis=0)
    prv = np.roll(boundary_xy, 1, axis=0)
    b = np.zeros((n_vertices, 2))
    b[loop, 0] = 0.5 * (nxt[:, 1] - prv[:, 1])
    b[loop, 1] = 0.5 * (prv[:, 0] - nxt[:, 0])
    return b


def flat_layout(
    cot: np.ndarray,
    loop: np.ndarray,
    boundary_xy: np.ndarray,
    assembler: CotanAssembler,
    preconditioner: SPDSolver | None = None,
) -> np.ndarray:
    """All vertex positions of a flat metric whose boundary positions are known.

    A planar triangulation is harmonic for its own cotangent weights, up to the
    boundary term of :func:`boundary_flux`; solving ``L X = flux`` with the flat
    metric's cotangents (one vertex held at its position) reproduces the metric to
    round-off: one sparse solve, no accumulation along a spanning tree. The Newton
    solve's last factorisation preconditions conjugate gradients, so no new
    factorisation is needed.

    Parameters
    ----------
    cot : (#F, 3) float
        Cotangents of the flat metric's corner angles.
    loop : (#B,) int
        Boundary loop, counter-clockwise.
    boundary_xy : (#B, 2) float
        Boundary positions; the vertex the assembler leaves out must be at the origin.
    assembler : CotanAssembler
        The triangulation's Laplacian without that vertex.
    preconditioner : SPDSolver, optional
        Factorisation of a nearby matrix with the same pattern; a fresh one otherwise.

    Returns
    -------
    xy : (#V, 2) float
        Positions; the boundary ones exactly ``boundary_xy``.
    """
    n_vertices = len(assembler.free) + 1
    U = assembler.upper(cot)
    if preconditioner is None:
        preconditioner = SPDSolver(U)
    flux = boundary_flux(loop, boundary_xy, n_vertices)[assembler.free]
    matvec = symmetric_matvec(U)
    xy = np.zeros((n_vertices, 2))
    xy[assembler.free], _, res = preconditioned_cg(matvec, flux, preconditioner.solve)
    if not res <= 1e-10:
        raise WorkbenchError(f"layout failed: the linear solve stalled at relative residual {res:.1e}")
    xy[loop] = boundary_xy  # equal to round-off; exact corners and straight sides
    return xy


def signed_areas(uv: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Signed area of every triangle in the plane; (#F,) float, positive when CCW."""
    a, b, c = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def free_boundary(loop_lengths: np.ndarray, angle_sums: np.ndarray) -> tuple[np.ndarray, float]:
    """Positions of the boundary of a flat metric whose boundary angles are free.

    Walking the loop counter-clockwise, the boundary turns left at each vertex by
    ``π - (angle sum there)``; with the edge lengths that draws the outline. For a
    flat disc the turns add up to 2π and the outline closes; the round-off gap is
    spread along the loop by arc length.

    Parameters
    ----------
    loop_lengths : (#B,) float
        Length of boundary edge ``loop[i] -> loop[i + 1]`` in the flat metric.
    angle_sums : (#B,) float
        Angle sum of the flat metric at each boundary vertex, radians.

    Returns
    -------
    xy : (#B, 2) float
        Boundary positions, ``loop[0]`` at the origin, its edge along +x.
    gap : float
        The closing gap before it was spread, relative to the perimeter.
    """
    turn = np.pi - angle_sums
    # edge i leaves vertex i: its direction has turned at vertices 1..i
    heading = np.concatenate([[0.0], np.cumsum(turn[1:])])
    steps = loop_lengths[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    xy = np.concatenate([[[0.0, 0.0]], np.cumsum(steps, axis=0)])
    gap = xy[-1].copy()
    arc = np.concatenate([[0.0], np.cumsum(loop_lengths)])
    xy -= (arc / arc[-1])[:, None] * gap
    return xy[:-1], float(np.linalg.norm(gap) / arc[-1])


def dirichlet_layout(
    F: np.ndarray, cot: np.ndarray, loop: np.ndarray, boundary_xy: np.ndarray, assembler: CotanAssembler
) -> np.ndarray:
    """Interior positions of a flat metric from its boundary positions: one harmonic solve.

    A planar triangulation is harmonic at its interior vertices for its own
    cotangent weights, so ``L_II X_I = -L_IB X_B`` reproduces the metric.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles of the flat metric.
    cot : (#F, 3) float
        Cotangents of its corner angles.
    loop : (#B,) int
        Boundary loop.
    boundary_xy : (#B, 2) float
        Boundary positions.
    assembler : CotanAssembler
        The triangulation's Laplacian without the boundary vertices (``L_II``).

    Returns
    -------
    xy : (#V, 2) float
        All positions.
    """
    from workbench.conformal.cetm import cotan_laplacian

    n = len(assembler.free) + len(loop)
    L = cotan_laplacian(F, cot, n).tocsr()
    xy = np.zeros((n, 2))
    xy[loop] = boundary_xy
    rhs = -(L[assembler.free][:, loop] @ boundary_xy)
    xy[assembler.free] = SPDSolver(assembler.upper(cot)).solve(rhs)
    if not np.isfinite(xy).all():
        raise WorkbenchError("layout failed: the harmonic solve gave non-finite positions")
    return xy
