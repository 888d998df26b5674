"""Rectangle corners searched by the first-order response of the conformal scale to moving them.

A full flatten per corner quadruple costs a Newton solve; a boundary of #B vertices has
``C(#B, 4)`` quadruples. The smooth problem behind a conformal map to a rectangle is
linear in the log scale factor ``u``: ``Δu = K`` inside, ``∂u/∂n = κ_target - κ`` on the
boundary, with the target geodesic curvature ``κ_target`` zero along the sides and a
point turn of π/2 at each corner. So the map onto a rectangle is the map with the
boundary's turning spread evenly along it (a disc-like map, no corner at all) plus four
Neumann Green's functions, one per corner. On the discrete side, at a solution the angle
sums meet their targets, and changing the targets by ``Δθ`` changes ``u`` by
``-H⁻¹ Δθ`` to first order, ``H`` the Hessian of the conformal energy (the cotangent
Laplacian of the solved intrinsic Delaunay triangulation).

So one solve and ``k`` back-substitutions give the scale of every quadruple of ``k``
boundary sites as a sum of four columns, and a search over thousands of quadruples costs
less than one more solve; the few best are then flattened in full. On a flat disc, where
the map onto a rectangle is Schwarz-Christoffel's, ``log|f'| = c - ½ Σ log|z - z_k|``, a
column matches ``-½ log|z - z_c|`` (within 0.013 beyond a quarter of the radius, 4,921
vertices) and a predicted quadruple matches the solved map within 0.01 beyond a tenth of the
radius from its corners (0.003 to 0.006 measured; ``tests/test_corner_search.py``).
"""

from __future__ import annotations

import numpy as np

from workbench.errors import WorkbenchError, exhausted
from workbench.sparse import CotanAssembler, SPDSolver

# Default number of corner sites spread over the boundary by arc length.
SITES = 64


def boundary_sites(V: np.ndarray, loop: np.ndarray, k: int = SITES) -> np.ndarray:
    """Boundary positions spread evenly by arc length, candidates for corners.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    loop : (#B,) int
        Boundary loop.
    k : int
        Number of sites wanted (fewer when the loop is shorter).

    Returns
    -------
    pos : (m,) int
        Increasing positions in ``loop``, m <= min(k, #B).
    """
    seg = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / seg.sum()
    want = np.arange(k) / k
    return np.unique(np.clip(np.searchsorted(arc, want), 0, len(loop) - 1))


def even_turning_targets(V: np.ndarray, loop: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Angle-sum targets of the map whose boundary turns evenly: 2π inside, π minus a share of 2π on the rim.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    loop : (#B,) int
        Boundary loop.
    n_vertices : int
        #V.

    Returns
    -------
    theta : (#V,) float
        Targets, radians; they meet Gauss-Bonnet (the rim turns 2π in all).
    w : (#B,) float
        Each rim vertex's share of the turning: half its two rim edges' length over the perimeter.
    """
    seg = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1)
    w = 0.5 * (seg + np.roll(seg, 1)) / seg.sum()
    theta = np.full(n_vertices, 2.0 * np.pi)
    theta[loop] = np.pi - 2.0 * np.pi * w
    return theta, w


def corner_response(
    assembler: CotanAssembler, cot: np.ndarray, sites: np.ndarray, loop: np.ndarray, w: np.ndarray, n_vertices: int
) -> np.ndarray:
    """Change of the log scale factors when each site becomes a corner, to first order.

    Parameters
    ----------
    assembler : CotanAssembler
        Laplacian of the solved triangulation; its fixed vertex keeps ``u = 0``.
    cot : (#F, 3) float
        Cotangents of the solved metric's angles.
    sites : (k,) int
        Boundary vertices.
    loop : (#B,) int
        Boundary loop.
    w : (#B,) float
        The solved map's share of the rim's turning at each rim vertex (sums to 1).
    n_vertices : int
        #V.

    Returns
    -------
    G : (#V, k) float
        Column ``j``: ``(π/2) H⁺ (e_j - w)``. A rectangle's rim turns π/2 at each of
        four corners where the solved map turned ``2π w``, so its ``u`` is the solved
        one plus the sum of its corners' columns (the right-hand sides sum to zero, so
        the Laplacian's constant null space does not matter).
    """
    # lowering the target angle sum at c by π/2 and raising the rim's by (π/2) w gives
    # Δθ = -(π/2)(e_c - w) and δu = -H⁻¹ Δθ
    rhs = np.zeros((n_vertices, len(sites)))
    rhs[sites, np.arange(len(sites))] = 1.0
    rhs[loop] -= w[:, None]
    G = np.zeros_like(rhs)
    free = assembler.free
    # as Newton's own solves: a zero pivot in one backend (a vertex whose triangles all
    # degenerated) gets the portable backend and a larger diagonal shift
    for backend, shift in ((None, 1e-12), ("qdldl", 1e-9), ("qdldl", 1e-6)):
        try:
            x = SPDSolver(assembler.upper(cot, shift=shift), backend).solve(rhs[free])
        except Exception as exc:  # each backend raises its own error type on a failed factorisation
            if exhausted(exc):  # (not the machine's memory)
                raise
            continue
        if np.isfinite(x).all():
            G[free] = x
            return 0.5 * np.pi * G
    raise WorkbenchError("the corner response's Laplacian cannot be factorised")


def predicted_crowding(
    area: np.ndarray, X: np.ndarray, min_print_mm: float, crowding: float, median: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crowded share and area distortion of several predicted maps at once.

    The map is scaled isometrically (area-weighted mean log scale zero), as flatten's
    default for a rectangle; with another scale mode the absolute size test is off by
    that mode's factor, and only the full flattens that follow the search decide.

    Parameters
    ----------
    area : (#F,) float
        Surface face areas, mm².
    X : (#F, k) float
        Log scale factor of each face (the mean of its vertices') in ``k`` maps.
    min_print_mm : float
        What the print can carry, mm.
    crowding : float
        A face is crowded when it prints below ``min_print_mm`` and this many times
        smaller than the map's typical (area-weighted median) scale.
    median : (k,) float, optional
        That typical log scale, when known (a search moving one corner at a time
        reuses the current map's: moving one corner barely moves the median, and
        sorting every column dominated the cost).

    Returns
    -------
    share : (k,) float
        Share of the surface area crowded.
    distortion : (k,) float
        Area-weighted standard deviation of the log area scale (0 for an isometry).
    median : (k,) float
        The typical log scale used, after the isometric normalisation.
    """
    w = area / area.sum()
    mean = w @ X
    X = X - mean
    if median is None:
        order = np.argsort(X, axis=0, kind="stable")
        cum = np.cumsum(w[order], axis=0)
        median = np.take_along_axis(X, order, 0)[np.argmax(cum >= 0.5, axis=0), np.arange(X.shape[1])]
    else:
        median = median - mean
    # a face of area A at log scale x prints about √A·eˣ across: below min_print when
    # x < log(min_print / √A)
    crowded = (X < np.log(min_print_mm / np.sqrt(area))[:, None]) & (X + np.log(crowding) < median)
    return w @ crowded, np.sqrt(w @ (2.0 * X) ** 2), median


def search_corners(
    area: np.ndarray,
    F: np.ndarray,
    base: np.ndarray,
    G: np.ndarray,
    starts: list[np.ndarray],
    min_print_mm: float,
    crowding: float,
    max_crowded: float,
    max_sweeps: int = 6,
) -> tuple[list[tuple[np.ndarray, float, float]], int]:
    """Local search over corner quadruples of the sites, from several starts.

    Each sweep moves one corner at a time to the site that best improves the
    prediction (all sites compared at once), until no move improves it. A quadruple
    is better when it crowds at most ``max_crowded`` of the surface and the other
    does not, else when it has less area distortion (crowded ones: less crowding).

    Parameters
    ----------
    area : (#F,) float
        Surface face areas, mm².
    F : (#F, 3) int
        Triangles.
    base : (#V,) float
        Log scale factors of the map whose rim turns evenly (no corner at all).
    G : (#V, k) float
        :func:`corner_response` of the sites.
    starts : list of (4,) int
        Starting quadruples, as site indices.
    min_print_mm, crowding : float
        As for :func:`predicted_crowding`.
    max_crowded : float
        Largest crowded share that counts as printing every face.
    max_sweeps : int
        Sweeps per start.

    Returns
    -------
    optima : list of (quad, share, distortion)
        Distinct local optima (``quad``: (4,) increasing site indices), best first,
        each predicted with its own median.
    evaluated : int
        Quadruples predicted.
    """
    k = G.shape[1]
    # a face's log scale is the mean of its vertices': work per face from here on
    Xb = base[F].mean(axis=1)
    XG = G[F].mean(axis=1)

    def rank(share, dist):
        # lexicographic: printable first, then the least distortion; unprintable by crowding
        return np.where(share <= max_crowded, dist, 1e6 * (1.0 + share))

    def exact(quad):
        share, dist, median = predicted_crowding(area, (Xb + XG[:, quad].sum(axis=1))[:, None], min_print_mm, crowding)
        return (float(rank(share, dist)[0]), float(share[0]), float(dist[0])), float(median[0])

    found: dict[tuple[int, ...], tuple[float, float, float]] = {}
    evaluated = 0
    for start in starts:
        quad = sorted({int(s) for s in start})
        if len(quad) < 4:
            continue
        best, median = exact(quad)
        evaluated += 1
        for _ in range(max_sweeps):
            moved = False
            for slot in range(4):
                others = [quad[j] for j in range(4) if j != slot]
                trial = np.setdiff1d(np.arange(k), others)
                X = (Xb + XG[:, others].sum(axis=1))[:, None] + XG[:, trial]
                current_mean = float(area @ (Xb + XG[:, quad].sum(axis=1)) / area.sum())
                share, dist, _ = predicted_crowding(
                    area, X, min_print_mm, crowding, np.full(len(trial), median + current_mean)
                )
                evaluated += len(trial)
                r = rank(share, dist)
                j = int(np.argmin(r))
                if r[j] < best[0] - 1e-12:
                    candidate = sorted(others + [int(trial[j])])
                    again, again_median = exact(candidate)
                    if again[0] < best[0] - 1e-12:
                        best, median, quad, moved = again, again_median, candidate, True
            if not moved:
                break
        found[tuple(quad)] = best
    optima = sorted(found.items(), key=lambda kv: (kv[1][0], kv[0]))
    return [(np.array(q, dtype=np.int64), s, d) for q, (_, s, d) in optima], evaluated
