"""A mesh whose edges longer than a given length are split at their midpoints, its shape unchanged."""

from __future__ import annotations

import numpy as np

from workbench.mesh.topology import unique_edges

# rounds of splitting: each halves the longest edge, so 40 take a 1 km edge below a micrometre
MAX_ROUNDS = 40


def _emit(a, b, c, m_ab, m_bc, m_ca, V, pattern):
    """The triangles replacing faces (a, b, c) whose split edges are ``pattern`` (in the canonical turn).

    ``pattern`` is "ab" (one edge split), "ab+bc" (all but ca) or "all"; counter-clockwise
    as the face was. Returns (k, 3) int triangles per face, stacked as (n, k, 3).
    """
    if pattern == "ab":
        return np.stack([np.stack([a, m_ab, c], 1), np.stack([m_ab, b, c], 1)], 1)
    if pattern == "all":
        return np.stack(
            [
                np.stack([a, m_ab, m_ca], 1),
                np.stack([m_ab, b, m_bc], 1),
                np.stack([m_ca, m_bc, c], 1),
                np.stack([m_ab, m_bc, m_ca], 1),
            ],
            1,
        )
    # ab and bc split: the corner (m_ab, b, m_bc) and the quad a, m_ab, m_bc, c cut along its
    # shorter diagonal (a to m_bc, or m_ab to c)
    via_a = np.linalg.norm(V[a] - V[m_bc], axis=1) <= np.linalg.norm(V[m_ab] - V[c], axis=1)
    first = np.where(via_a[:, None], np.stack([a, m_ab, m_bc], 1), np.stack([a, m_ab, c], 1))
    second = np.where(via_a[:, None], np.stack([a, m_bc, c], 1), np.stack([m_ab, m_bc, c], 1))
    return np.stack([np.stack([m_ab, b, m_bc], 1), first, second], 1)


def subdivide_to_edge(V: np.ndarray, F: np.ndarray, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """Split every edge longer than ``max_edge`` at its midpoint, and its faces with it, until none is.

    A CAD export spans a flat side with two triangles and a fillet with long slivers; what is
    chosen on the surface in whole faces, or measured along edges, needs them shorter. Only
    the long edges are split (a face with one split edge becomes two, with two three, with
    three four; a quad left by two splits is cut along its shorter diagonal): a box of 12
    triangles split to 2.4 mm edges has 24,576 faces, where splitting every face with a long
    edge in four gave 49,152 (a fillet's long slivers, both long sides split, need as many
    either way: the 5 mm filleted box's 5,628 triangles become 181,392). A midpoint lies on
    its edge: flat faces stay where they
    were, a curved surface keeps its tessellation's shape, and an edge is split from both of
    its faces, so no crack opens. A mesh with no longer edge is returned as it is (the same
    arrays).

    Parameters
    ----------
    V : (#V, 3) float
        Vertices, mm.
    F : (#F, 3) int
        Triangles.
    max_edge : float
        The longest edge allowed, mm.

    Returns
    -------
    V : (#W, 3) float
        The vertices, mm: the mesh's, then the midpoints (each once) in the order they were made.
    F : (#G, 3) int
        The triangles, oriented as the ones they were split from, in their order.
    """
    V0, F0 = V, F
    V, F = np.asarray(V, np.float64), np.asarray(F, np.int64)
    for _ in range(MAX_ROUNDS):
        E, FE, _ = unique_edges(F)
        long = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1) > max_edge
        if not long.any():
            break
        mid = np.full(len(E), -1, np.int64)
        mid[long] = len(V) + np.arange(int(long.sum()))
        V = np.vstack([V, 0.5 * (V[E[long, 0]] + V[E[long, 1]])])
        a, b, c = F[:, 0], F[:, 1], F[:, 2]
        # FE[:, k] is the edge opposite corner k: ab opposite c, bc opposite a, ca opposite b
        m_ab, m_bc, m_ca = mid[FE[:, 2]], mid[FE[:, 0]], mid[FE[:, 1]]
        s_ab, s_bc, s_ca = m_ab >= 0, m_bc >= 0, m_ca >= 0
        n = s_ab.astype(int) + s_bc + s_ca
        pieces = [(np.flatnonzero(n == 0), F[n == 0][:, None, :])]
        # each pattern turned so that its split edges are the canonical ones
        turns = (
            (a, b, c, m_ab, m_bc, m_ca),  # as it is
            (b, c, a, m_bc, m_ca, m_ab),  # bc becomes ab
            (c, a, b, m_ca, m_ab, m_bc),  # ca becomes ab
        )
        one = (s_ab & ~s_bc & ~s_ca, s_bc & ~s_ca & ~s_ab, s_ca & ~s_ab & ~s_bc)
        two = (s_ab & s_bc & ~s_ca, s_bc & s_ca & ~s_ab, s_ca & s_ab & ~s_bc)
        for turn, w1, w2 in zip(turns, one, two, strict=True):
            for which, pattern in ((w1, "ab"), (w2, "ab+bc")):
                idx = np.flatnonzero(which)
                if len(idx):
                    pieces.append((idx, _emit(*(x[idx] for x in turn), V, pattern)))
        idx = np.flatnonzero(n == 3)
        if len(idx):
            pieces.append((idx, _emit(*(x[idx] for x in turns[0]), V, "all")))
        # (the new faces in the order of the faces they replace: deterministic, and local)
        order = np.concatenate([np.repeat(i, p.shape[1]) for i, p in pieces])
        faces = np.concatenate([p.reshape(-1, 3) for _, p in pieces])
        F = faces[np.argsort(order, kind="stable")]
    return (V0, F0) if len(V) == len(V0) else (V, F)
