"""Intrinsic triangulations in Penner coordinates: Ptolemy flips to the Delaunay triangulation of a scaled metric.

Gillespie, Springborn and Crane, "Discrete Conformal Equivalence of Polyhedral
Surfaces" (2021): the edge lengths ``l`` of a triangulation are the λ-lengths of a
decorated ideal hyperbolic surface (one ideal vertex per mesh vertex, a horocycle
at each). Flipping an edge with Ptolemy's relation ``l_ad l_bc = l_ab l_cd + l_ac l_bd``
keeps that decorated surface, so it keeps the discrete conformal class. Scaling by
``u`` multiplies both sides of Ptolemy's relation by the same ``exp((u_a+u_b+u_c+u_d)/2)``:
the flips can be done on the unscaled lengths ``λ = 2 log l`` (Penner coordinates)
whatever ``u`` is, and only the Delaunay test reads the scaled ones. Keeping the
triangulation Delaunay for the current ``u`` during Newton's method is what makes a
conformal map exist for any target angles (their main theorem).

Every vertex also carries a reference direction, tracked through the flips as a
corner and an offset along that vertex's horocycle (the arc a corner cuts from the
horocycle at ``v`` in triangle ``(v, w, x)`` has length ``l_wx / (l_vw l_vx)``, and a
flip splits or joins these arcs without changing their sum). From it the input
edges are traced over the final triangulation (:mod:`workbench.conformal.overlay`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from workbench.mesh.topology import unique_edges

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}

# An edge is flipped when the Delaunay sum (cos α + cos β, see below) is below
# -DELAUNAY_TOL: a cocircular quad sits at 0 whichever diagonal it has, and the
# tolerance keeps round-off from flipping it back and forth.
DELAUNAY_TOL = 1e-10


def corner_twins(F: np.ndarray, FE: np.ndarray | None = None) -> np.ndarray:
    """Twin of every face corner's opposite edge.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles of an edge-manifold, consistently oriented mesh.
    FE : (#F, 3) int, optional
        :func:`unique_edges` of ``F``, when already computed.

    Returns
    -------
    T : (#F, 3) int
        ``T[f, k] = 3 g + m`` when the edge opposite corner ``k`` of ``f`` is the
        edge opposite corner ``m`` of ``g``; -1 on the boundary.
    """
    if FE is None:
        _, FE, _ = unique_edges(F)
    e = FE.ravel()
    order = np.argsort(e, kind="stable")
    same = e[order][1:] == e[order][:-1]
    a, b = order[:-1][same], order[1:][same]
    T = np.full(3 * len(F), -1, dtype=np.int64)
    T[a], T[b] = b, a
    return T.reshape(-1, 3)


def horocycle_arcs(lam: np.ndarray) -> np.ndarray:
    """Length of the horocyclic arc each face corner cuts, in the decoration of ``lam``.

    Parameters
    ----------
    lam : (#F, 3) float
        Penner coordinates ``2 log l`` of the edge opposite each corner.

    Returns
    -------
    h : (#F, 3) float
        ``h[f, k] = l_opposite / (l_adjacent1 l_adjacent2)``: Penner's h-length.
    """
    return np.exp(0.5 * (lam - lam[:, [1, 2, 0]] - lam[:, [2, 0, 1]]))


def delaunay_sums(F: np.ndarray, T: np.ndarray, lam: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Delaunay test of every interior edge for the metric scaled by ``u``.

    With lengths ``a`` opposite the corner and ``b``, ``c`` beside it,
    ``2 cos α = (b² + c² - a²) / (b c)``, which is defined for any positive
    lengths, even those that violate the triangle inequality. The edge is
    Delaunay when the two corners facing it sum to at most π, i.e. when
    ``cos α + cos β >= 0``.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.
    T : (#F, 3) int
        Corner twins (:func:`corner_twins`).
    lam : (#F, 3) float
        Penner coordinates of the edge opposite each corner.
    u : (#V,) float
        Log scale factors.

    Returns
    -------
    s : (#F, 3) float
        ``2 cos α + 2 cos β`` for the edge opposite each corner; +inf on the
        boundary.
    """
    lt = lam + u[F[:, [1, 2, 0]]] + u[F[:, [2, 0, 1]]]
    b, c = lt[:, [1, 2, 0]], lt[:, [2, 0, 1]]
    # (b² + c² - a²) / (b c) with squared lengths e^λ̃: every term a ratio of exponentials
    cos2 = np.exp(0.5 * (b - c)) + np.exp(0.5 * (c - b)) - np.exp(lt - 0.5 * (b + c))
    s = np.full(F.shape, np.inf)
    inner = T >= 0
    s[inner] = cos2[inner] + cos2.ravel()[T[inner]]
    return s


@numba.njit(inline="always", **_JIT)
def _cos2(F, lam, u, f, k):
    i, j = F[f, (k + 1) % 3], F[f, (k + 2) % 3]
    a = lam[f, k] + u[i] + u[j]
    b = lam[f, (k + 1) % 3] + u[F[f, (k + 2) % 3]] + u[F[f, k]]
    c = lam[f, (k + 2) % 3] + u[F[f, k]] + u[F[f, (k + 1) % 3]]
    return np.exp(0.5 * (b - c)) + np.exp(0.5 * (c - b)) - np.exp(a - 0.5 * (b + c))


@numba.njit(inline="always", **_JIT)
def _arc(lam, f, k):
    return np.exp(0.5 * (lam[f, k] - lam[f, (k + 1) % 3] - lam[f, (k + 2) % 3]))


@numba.njit(inline="always", **_JIT)
def _renumber(t, f, g, k1, k2, m1, m2):
    # where an outer edge of the quad goes: ab -> f' corner 2, ca -> g' 0, bd -> f' 0, dc -> g' 2
    if t == 3 * f + k2:
        return 3 * f + 2
    if t == 3 * f + k1:
        return 3 * g
    if t == 3 * g + m1:
        return 3 * f
    if t == 3 * g + m2:
        return 3 * g + 2
    return t


@numba.njit(**_JIT)
def _flip(F, T, lam, ref_face, ref_corner, ref_off, f, k):
    t = T[f, k]
    g, m = t // 3, t % 3
    k1, k2, m1, m2 = (k + 1) % 3, (k + 2) % 3, (m + 1) % 3, (m + 2) % 3
    # f = (a, b, c) with a at corner k; g = (d, c, b) with d at corner m
    a, b, c, d = F[f, k], F[f, k1], F[f, k2], F[g, m]
    l_bc, l_ab, l_ca, l_bd, l_dc = lam[f, k], lam[f, k2], lam[f, k1], lam[g, m1], lam[g, m2]
    # Ptolemy: l_ad l_bc = l_ab l_cd + l_ac l_bd, in logarithms (no overflow at any scale)
    l_ad = 2.0 * np.logaddexp(0.5 * (l_ab + l_dc), 0.5 * (l_ca + l_bd)) - l_bc
    h_bg, h_cf = _arc(lam, g, m2), _arc(lam, f, k2)
    # new arcs: a in f' = (a, b, d) and d in g' = (d, c, a)
    h_af = np.exp(0.5 * (l_bd - l_ab - l_ad))
    h_dg = np.exp(0.5 * (l_ca - l_dc - l_ad))
    # reference directions: old corners split (a, d) or join (b, c) along the horocycles.
    # Matched by corner, not by vertex: after loops and double edges a vertex can hold
    # two corners of the quad (a == d, or b == c).
    upd_v = np.full(4, -1, dtype=np.int64)
    upd_f = np.zeros(4, dtype=np.int64)
    upd_c = np.zeros(4, dtype=np.int64)
    upd_o = np.zeros(4)
    for slot in range(4):
        v = (a, d, b, c)[slot]
        rf, rc, o = ref_face[v], ref_corner[v], ref_off[v]
        if slot == 0 and rf == f and rc == k:
            upd_v[0] = v
            upd_f[0], upd_c[0], upd_o[0] = (f, 0, o) if o < h_af else (g, 2, o - h_af)
        elif slot == 1 and rf == g and rc == m:
            upd_v[1] = v
            upd_f[1], upd_c[1], upd_o[1] = (g, 0, o) if o < h_dg else (f, 2, o - h_dg)
        elif slot == 2 and ((rf == g and rc == m2) or (rf == f and rc == k1)):
            upd_v[2] = v
            upd_f[2], upd_c[2], upd_o[2] = (f, 1, o) if rf == g else (f, 1, o + h_bg)
        elif slot == 3 and ((rf == f and rc == k2) or (rf == g and rc == m1)):
            upd_v[3] = v
            upd_f[3], upd_c[3], upd_o[3] = (g, 1, o) if rf == f else (g, 1, o + h_cf)
    for slot in range(4):
        if upd_v[slot] >= 0:
            v = upd_v[slot]
            ref_face[v], ref_corner[v], ref_off[v] = upd_f[slot], upd_c[slot], upd_o[slot]
    # outer edges; one may be glued to another outer edge of the same quad (after
    # loops and double edges), so its twin slot is renumbered like the faces
    t_ab = _renumber(T[f, k2], f, g, k1, k2, m1, m2)
    t_ca = _renumber(T[f, k1], f, g, k1, k2, m1, m2)
    t_bd = _renumber(T[g, m1], f, g, k1, k2, m1, m2)
    t_dc = _renumber(T[g, m2], f, g, k1, k2, m1, m2)
    F[f, 0], F[f, 1], F[f, 2] = a, b, d
    F[g, 0], F[g, 1], F[g, 2] = d, c, a
    lam[f, 0], lam[f, 1], lam[f, 2] = l_bd, l_ad, l_ab
    lam[g, 0], lam[g, 1], lam[g, 2] = l_ca, l_ad, l_dc
    T[f, 0], T[f, 1], T[f, 2] = t_bd, 3 * g + 1, t_ab
    T[g, 0], T[g, 1], T[g, 2] = t_ca, 3 * f + 1, t_dc
    for slot, twin in ((3 * f, t_bd), (3 * f + 2, t_ab), (3 * g, t_ca), (3 * g + 2, t_dc)):
        if twin >= 0:
            T[twin // 3, twin % 3] = slot


@numba.njit(**_JIT)
def _make_delaunay(F, T, lam, u, ref_face, ref_corner, ref_off, seed_f, seed_k, max_flips):
    n = len(seed_f)
    cap = max(16, 2 * n)
    qf = np.empty(cap, dtype=np.int64)
    qk = np.empty(cap, dtype=np.int64)
    qf[:n] = seed_f
    qk[:n] = seed_k
    head, tail, flips = 0, n, 0
    while head != tail:
        f, k = qf[head % cap], qk[head % cap]
        head += 1
        t = T[f, k]
        if t < 0:
            continue
        g, m = t // 3, t % 3
        if g == f:
            continue  # an edge glued to its own triangle (a folded cone): no quad to flip
        if _cos2(F, lam, u, f, k) + _cos2(F, lam, u, g, m) >= -DELAUNAY_TOL:
            continue
        if flips == max_flips:
            return flips, False
        _flip(F, T, lam, ref_face, ref_corner, ref_off, f, k)
        flips += 1
        if tail - head + 4 > cap:
            # grow the ring buffer, unrolled from head
            bigger = 2 * cap
            nf = np.empty(bigger, dtype=np.int64)
            nk = np.empty(bigger, dtype=np.int64)
            for i in range(tail - head):
                nf[i], nk[i] = qf[(head + i) % cap], qk[(head + i) % cap]
            qf, qk, tail, head, cap = nf, nk, tail - head, 0, bigger
        # the four outer edges of the quad may have stopped being Delaunay
        for ff, kk in ((f, 0), (f, 2), (g, 0), (g, 2)):
            qf[tail % cap], qk[tail % cap] = ff, kk
            tail += 1
    return flips, True


@dataclass
class IntrinsicTriangulation:
    """A triangulation of the input's vertices with Penner coordinates, changed by Ptolemy flips.

    Attributes
    ----------
    F : (#F, 3) int64
        Current triangles (counter-clockwise, the input's vertices). Two edges may
        join the same two vertices, and an edge may join a vertex to itself: the
        Delaunay triangulation of a scaled metric can need both.
    T : (#F, 3) int64
        Corner twins (:func:`corner_twins`) of ``F``.
    lam : (#F, 3) float64
        Penner coordinates ``2 log l`` of the edge opposite each corner, in the
        input's decoration (``u = 0``); equal on both sides of an edge.
    ref_face, ref_corner : (#V,) int64
        Corner holding each vertex's reference direction.
    ref_offset : (#V,) float64
        Horocyclic offset of that direction from the corner's first edge
        (counter-clockwise).
    flips : int
        Ptolemy flips made so far.
    """

    F: np.ndarray
    T: np.ndarray
    lam: np.ndarray
    ref_face: np.ndarray
    ref_corner: np.ndarray
    ref_offset: np.ndarray
    flips: int = 0

    @classmethod
    def from_mesh(
        cls, F: np.ndarray, lam: np.ndarray, n_vertices: int, FE: np.ndarray | None = None, flips: bool = True
    ) -> IntrinsicTriangulation:
        """The input triangulation itself.

        Parameters
        ----------
        F : (#F, 3) int
            Triangles of a disc, counter-clockwise.
        lam : (#F, 3) float
            ``2 log`` of the length of the edge opposite each corner.
        n_vertices : int
            #V.
        FE : (#F, 3) int, optional
            :func:`unique_edges` of ``F``, when already computed.
        flips : bool
            False: the triangulation will not be flipped; twins and reference
            directions are left empty.

        Returns
        -------
        IntrinsicTriangulation
            With each vertex's reference direction along the first edge of one of
            its corners: for a boundary vertex the corner that starts at its
            outgoing boundary edge, so that its corners run from there
            counter-clockwise (see :func:`reference_corners`).
        """
        F = np.array(F, dtype=np.int64)
        if not flips:
            # a solve that keeps the triangulation reads only F and lam
            empty = np.empty(0, dtype=np.int64)
            return cls(
                F=F,
                T=np.empty((0, 3), dtype=np.int64),
                lam=np.array(lam, dtype=np.float64),
                ref_face=empty,
                ref_corner=empty,
                ref_offset=np.empty(0),
            )
        T = corner_twins(F, FE)
        ref_face, ref_corner = reference_corners(F, T, n_vertices)
        return cls(
            F=F,
            T=T,
            lam=np.array(lam, dtype=np.float64),
            ref_face=ref_face,
            ref_corner=ref_corner,
            ref_offset=np.zeros(n_vertices),
        )

    def copy(self) -> IntrinsicTriangulation:
        return IntrinsicTriangulation(
            self.F.copy(),
            self.T.copy(),
            self.lam.copy(),
            self.ref_face.copy(),
            self.ref_corner.copy(),
            self.ref_offset.copy(),
            self.flips,
        )

    def make_delaunay(self, u: np.ndarray, max_flips: int | None = None) -> int:
        """Flip (Ptolemy) until every interior edge is Delaunay for the metric scaled by ``u``.

        Parameters
        ----------
        u : (#V,) float
            Log scale factors; the scaled lengths are ``exp((λ + u_i + u_j) / 2)``.
        max_flips : int, optional
            Give up beyond this many flips (default 100 #F).

        Returns
        -------
        int
            Flips made; -1 when ``max_flips`` was reached.
        """
        s = delaunay_sums(self.F, self.T, self.lam, u)
        seed_f, seed_k = np.nonzero(s < -DELAUNAY_TOL)
        if len(seed_f) == 0:
            return 0
        limit = 100 * len(self.F) if max_flips is None else max_flips
        flips, done = _make_delaunay(
            self.F,
            self.T,
            self.lam,
            np.ascontiguousarray(u, dtype=np.float64),
            self.ref_face,
            self.ref_corner,
            self.ref_offset,
            seed_f.astype(np.int64),
            seed_k.astype(np.int64),
            limit,
        )
        self.flips += flips
        return flips if done else -1


def reference_corners(F: np.ndarray, T: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """One corner per vertex to measure directions from.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.
    T : (#F, 3) int
        Corner twins.
    n_vertices : int
        #V.

    Returns
    -------
    face, corner : (#V,) int64
        A corner at each vertex; at a boundary vertex the one whose first edge
        (counter-clockwise) is the outgoing boundary edge.
    """
    face = np.zeros(n_vertices, dtype=np.int64)
    corner = np.zeros(n_vertices, dtype=np.int64)
    f = np.repeat(np.arange(len(F)), 3)
    k = np.tile(np.arange(3), len(F))
    v = F.ravel()
    face[v], corner[v] = f, k
    # corner k's first edge is F[f,k] -> F[f,k+1], the edge opposite corner k+2
    first_on_boundary = T[f, (k + 2) % 3] < 0
    face[v[first_on_boundary]], corner[v[first_on_boundary]] = f[first_on_boundary], k[first_on_boundary]
    return face, corner
