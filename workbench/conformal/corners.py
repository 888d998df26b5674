"""The four boundary vertices that become the corners of the print rectangle."""

from __future__ import annotations

import numpy as np

from workbench.conformal.cetm import angle_sums, triangle_angles
from workbench.errors import WorkbenchError

# A boundary turn counts as a corner when the boundary turns by at least this much
# within a window of ±WINDOW of its length: a rounded corner whose fillet spreads
# its 90° over several vertices still counts, a gently curved side does not.
MIN_TURN_RAD = np.pi / 4
WINDOW = 0.03


def boundary_turning(V: np.ndarray, F: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """Geodesic turning of the boundary at each of its vertices.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    F : (#F, 3) int
        Triangles.
    loop : (#B,) int
        Boundary loop.

    Returns
    -------
    kappa : (#B,) float
        ``π - (sum of face angles at the vertex)``, radians: π/2 at a square corner,
        0 along a straight side.
    """
    e = V[F[:, [2, 0, 1]]] - V[F[:, [1, 2, 0]]]  # edge opposite each corner
    alpha, _, _ = triangle_angles(np.linalg.norm(e, axis=2))
    return np.pi - angle_sums(F, alpha, len(V))[loop]


def choose_corners(V: np.ndarray, F: np.ndarray, loop: np.ndarray) -> tuple[np.ndarray, str]:
    """Pick four corner vertices automatically.

    Rule: the four sharpest boundary turns, each the largest turning summed over a
    window of ±3 % of the boundary length, if each turns by at least 45°; else the
    boundary vertices nearest the corners of the boundary's oriented bounding box
    (principal axes). Then A→B is a side of the longer pair (3D boundary length),
    the one that points most along the mesh's +x axis.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    F : (#F, 3) int
        Triangles.
    loop : (#B,) int
        Boundary loop, counter-clockwise.

    Returns
    -------
    corners : (4,) int
        Vertex indices A, B, C, D in counter-clockwise order.
    rule : str
        ``'sharpest-turns'`` or ``'bounding-box'``.
    """
    nb = len(loop)
    if nb < 4:
        raise WorkbenchError(f"the boundary has {nb} vertices; a rectangle needs at least 4")
    seg = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1)
    # arc length in whole units of 2**-40 of the perimeter, and turning rounded to 1e-9
    # rad: the choice must not depend on the mesh's unit, and round-off must not break
    # ties (regular grids have many) differently in mm than in m. Integers, because the
    # window's ends fall exactly on vertices of regular grids (a 6 mm pitch, a 6 mm
    # window): in floating point the sums along the two sides of a corner differ in the
    # last bit, the window took a neighbour on one side and not on the other, and the
    # corner went to the vertex beside it (101 of 576 regular grids)
    seg = np.round(seg / seg.sum() * 2.0**40).astype(np.int64)
    perimeter = int(seg.sum())
    arc = np.concatenate([[0], np.cumsum(seg)[:-1]])
    kappa = np.round(boundary_turning(V, F, loop), 9)
    # windowed turning via prefix sums over the loop taken three times (wrap-around)
    arc3 = np.concatenate([arc - perimeter, arc, arc + perimeter])
    k3 = np.concatenate([[0.0], np.cumsum(np.tile(kappa, 3))])
    w = int(round(WINDOW * perimeter))
    lo = np.searchsorted(arc3, arc - w, side="left")
    hi = np.searchsorted(arc3, arc + w, side="right")
    turn = np.round(k3[hi] - k3[lo], 9)
    picked: list[int] = []
    order = np.lexsort((np.arange(nb), -turn))
    for p in order:
        if turn[p] < MIN_TURN_RAD or len(picked) == 4:
            break
        d = np.abs(arc[p] - arc[picked])
        if np.all(np.minimum(d, perimeter - d) > 2 * w):
            # the sharpest single vertex inside the window is the corner itself
            near = np.flatnonzero(np.minimum(np.abs(arc - arc[p]), perimeter - np.abs(arc - arc[p])) <= w)
            picked.append(int(near[np.argmax(kappa[near])]))
    rule = "sharpest-turns"
    if len(picked) < 4:
        rule = "bounding-box"
        P = V[loop] - V[loop].mean(axis=0)
        _, _, Vt = np.linalg.svd(P, full_matrices=False)
        Q = P @ Vt[:2].T
        lo2, hi2 = Q.min(axis=0), Q.max(axis=0)
        picked = []
        for cx, cy in [(lo2[0], lo2[1]), (hi2[0], lo2[1]), (hi2[0], hi2[1]), (lo2[0], hi2[1])]:
            dist = np.linalg.norm(Q - [cx, cy], axis=1)
            dist[picked] = np.inf
            picked.append(int(np.argmin(dist)))
    pos = np.sort(np.array(picked))
    side = (np.roll(arc[pos], -1) - arc[pos]) % perimeter  # 3D length of each side
    starts = [0, 2] if side[0] + side[2] >= side[1] + side[3] else [1, 3]
    xdir = [V[loop[pos[(s + 1) % 4]], 0] - V[loop[pos[s]], 0] for s in starts]
    first = starts[int(np.argmax(xdir))]
    return loop[np.roll(pos, -first)], rule


def corner_positions(loop: np.ndarray, corners: np.ndarray, n_vertices: int) -> np.ndarray:
    """Check user-given corners and find them along the boundary loop.

    Parameters
    ----------
    loop : (#B,) int
        Boundary loop, counter-clockwise.
    corners : (4,) int
        Vertex indices A, B, C, D.
    n_vertices : int
        #V.

    Returns
    -------
    pos : (4,) int
        Positions of A, B, C, D in ``loop`` rotated to start at A (so ``pos[0] == 0``
        and ``pos`` increases).

    Raises
    ------
    WorkbenchError
        A corner that does not exist, is repeated, is not on the boundary, or an
        order that is not counter-clockwise along the boundary.
    """
    corners = [int(c) for c in corners]
    for c in corners:
        if not 0 <= c < n_vertices:
            raise WorkbenchError(f"corner {c} does not exist (the mesh has {n_vertices} vertices, numbered from 0)")
    for i, c in enumerate(corners):
        if c in corners[:i]:
            raise WorkbenchError(f"corner {c} is given twice; give four different boundary vertices")
    where = {int(v): i for i, v in enumerate(loop)}
    for c in corners:
        if c not in where:
            raise WorkbenchError(f"corner {c} is not on the boundary")
    raw = np.array([where[c] for c in corners])
    pos = (raw - raw[0]) % len(loop)
    if not np.all(np.diff(pos) > 0):
        ccw = [int(v) for v in loop[np.sort(raw)]]
        start = ccw.index(corners[0])
        fixed = ccw[start:] + ccw[:start]
        raise WorkbenchError(
            f"corners {','.join(map(str, corners))} are not in counter-clockwise order along the boundary "
            f"(seen from the decorated side); did you mean {','.join(map(str, fixed))}?"
        )
    return pos


def candidate_corners(
    V: np.ndarray, loop: np.ndarray, rotations: int = 8, sides: tuple[float, ...] = (0.15, 0.25, 0.35)
) -> list[np.ndarray]:
    """Corner quadruples spread along the boundary, for a search over corners.

    Rule: for each of ``rotations`` starting points ``t`` evenly spaced over half the
    perimeter (a quadruple and its half-turn are the same four corners) and each side
    fraction ``s``, the boundary vertices at arc-length fractions
    ``t, t + s, t + 1/2, t + 1/2 + s``.

    Parameters
    ----------
    V : (#V, 3) float
        Vertex positions.
    loop : (#B,) int
        Boundary loop, counter-clockwise.
    rotations : int
        Number of starting points.
    sides : tuple of float
        Fractions of the perimeter between the first two corners.

    Returns
    -------
    list of (4,) int
        Quadruples A, B, C, D, counter-clockwise, no two with the same four vertices.
    """
    seg = np.linalg.norm(V[np.roll(loop, -1)] - V[loop], axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / seg.sum()
    out, seen = [], set()
    for side in sides:
        for r in range(rotations):
            t = 0.5 * r / rotations
            fr = (t + np.array([0.0, side, 0.5, 0.5 + side])) % 1.0
            pos = sorted({int(np.argmin(np.minimum(np.abs(arc - x), 1 - np.abs(arc - x)))) for x in fr})
            if len(pos) < 4 or frozenset(pos) in seen:
                continue
            seen.add(frozenset(pos))
            out.append(loop[np.array(pos)].astype(np.int64))
    return out
