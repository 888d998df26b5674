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

import numpy as np

from workbench.mesh.topology import unique_edges

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
        # numba is loaded only when a mesh needs flips (it costs 0.2 s to import)
        from workbench.conformal._flips import make_delaunay

        limit = 100 * len(self.F) if max_flips is None else max_flips
        flips, done = make_delaunay(
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
