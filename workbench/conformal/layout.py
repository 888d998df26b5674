"""Layout of a flat metric with a rectangular boundary into the plane."""

from __future__ import annotations

import numpy as np

from workbench.errors import WorkbenchError, exhausted
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
    if len(assembler.free) == 0:
        return xy  # every vertex on the boundary: the outline is the layout
    rhs = -(L[assembler.free][:, loop] @ boundary_xy)
    try:
        xy[assembler.free] = SPDSolver(assembler.upper(cot)).solve(rhs)
    except Exception as exc:  # noqa: BLE001 - any backend's failure is one refusal (but the machine's memory)
        if exhausted(exc):
            raise
        raise WorkbenchError(f"layout failed: the harmonic solve broke down ({type(exc).__name__})") from None
    if not np.isfinite(xy).all():
        raise WorkbenchError("layout failed: the harmonic solve gave non-finite positions")
    return xy


def polygon_self_intersections(xy: np.ndarray) -> np.ndarray:
    """Pairs of edges of a closed polygon that cross or touch, other than neighbours.

    Edges are binned on a uniform grid by their bounding boxes (about one edge per
    cell), and only edges sharing a cell are tested, so the cost stays near linear in
    the number of edges for an outline that does not cross itself.

    Parameters
    ----------
    xy : (#B, 2) float
        Polygon vertices in order; edge i joins vertex i to vertex i + 1 (mod #B).

    Returns
    -------
    pairs : (#pairs, 2) int
        Edge indices (i < j) of every crossing pair, sorted; empty when the polygon
        is simple.
    """
    n = len(xy)
    if n < 4:
        return np.zeros((0, 2), dtype=np.int64)
    a, b = xy, np.roll(xy, -1, axis=0)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    span = np.maximum(xy.max(axis=0) - xy.min(axis=0), 1e-300)
    cells = max(1, int(np.sqrt(n)))
    size = span / cells
    c0 = np.floor((lo - xy.min(axis=0)) / size).astype(np.int64).clip(0, cells - 1)
    c1 = np.floor((hi - xy.min(axis=0)) / size).astype(np.int64).clip(0, cells - 1)
    # one (edge, cell) row per cell an edge's box covers
    counts = (c1[:, 0] - c0[:, 0] + 1) * (c1[:, 1] - c0[:, 1] + 1)
    edge = np.repeat(np.arange(n), counts)
    k = np.arange(len(edge)) - np.repeat(np.cumsum(counts) - counts, counts)
    w = np.repeat(c1[:, 0] - c0[:, 0] + 1, counts)
    cx, cy = c0[edge, 0] + k % w, c0[edge, 1] + k // w
    cell = cx * cells + cy
    order = np.lexsort((edge, cell))
    edge, cell = edge[order], cell[order]
    starts = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])
    ends = np.r_[starts[1:], len(cell)]
    pairs = []
    for s, e in zip(starts, ends, strict=True):
        if e - s < 2:
            continue
        ids = edge[s:e]
        i, j = np.triu_indices(len(ids), 1)
        pairs.append(np.stack([ids[i], ids[j]], axis=1))
    if not pairs:
        return np.zeros((0, 2), dtype=np.int64)
    P = np.unique(np.sort(np.concatenate(pairs), axis=1), axis=0)
    # neighbours share a vertex; they touch by construction
    P = P[((P[:, 1] - P[:, 0]) % n != 1) & ((P[:, 0] - P[:, 1]) % n != 1)]
    P = P[np.all(lo[P[:, 0]] <= hi[P[:, 1]], axis=1) & np.all(lo[P[:, 1]] <= hi[P[:, 0]], axis=1)]

    # segments p→q and r→s cross when r, s lie on opposite sides (or on) the line p q,
    # and p, q on opposite sides of r s: the signs of the cross products differ
    def orient(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    p, q, r, s = a[P[:, 0]], b[P[:, 0]], a[P[:, 1]], b[P[:, 1]]
    d1, d2, d3, d4 = orient(p, q, r), orient(p, q, s), orient(r, s, p), orient(r, s, q)
    cross = (d1 * d2 <= 0) & (d3 * d4 <= 0)
    return P[cross]
