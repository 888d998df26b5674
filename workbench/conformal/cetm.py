"""Discrete conformal equivalence by Newton's method on the CETM energy.

Springborn, Schröder, Pinkall, "Conformal Equivalence of Triangle Meshes" (2008):
given edge lengths ``l`` and per-vertex target angle sums ``Θ``, find logarithmic
scale factors ``u`` such that the lengths ``l̃_ij = exp((u_i + u_j) / 2) l_ij`` have
angle sum ``Θ_i`` at every vertex. The ``u`` are the minimiser of a convex energy
whose gradient is ``Θ - (angle sums)`` and whose Hessian is the cotangent Laplacian
of the current metric.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from workbench.errors import WorkbenchError, exhausted
from workbench.mesh.topology import unique_edges
from workbench.sparse import CotanAssembler, SPDSolver


def triangle_angles(l: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interior angles and their cotangents from edge lengths, extended to 0/π.

    Parameters
    ----------
    l : (#F, 3) float
        ``l[f, k]`` is the length of the edge opposite corner ``k``.

    Returns
    -------
    alpha : (#F, 3) float
        Angle at each corner, in radians. Where the lengths violate the triangle
        inequality the angle opposite the too-long edge is π and the others 0, the
        continuous extension that keeps the energy convex (CETM §4.2).
    cot : (#F, 3) float
        ``cot(alpha)``; 0 for degenerate triangles, whose extended energy is linear.
    degenerate : (#F,) bool
        Faces whose lengths violate (or meet) the triangle inequality.
    """
    a, b, c = l[:, 0], l[:, 1], l[:, 2]
    s = a + b + c
    # Half-angle form of the law of cosines: tan(α_a / 2) = sqrt((s-2b)(s-2c) / (s (s-2a))),
    # with s - 2a = b + c - a etc.; accurate for needle triangles where acos is not.
    p = np.stack([b + c - a, c + a - b, a + b - c], axis=1)
    degenerate = (p <= 0).any(axis=1)
    p = np.maximum(p, 0.0)
    num = np.sqrt(p[:, [1, 2, 0]] * p[:, [2, 0, 1]])
    den = np.sqrt(s[:, None] * p)
    alpha = 2.0 * np.arctan2(num, den)
    # cot α = (1 - t²) / (2 t) with t = num / den
    with np.errstate(divide="ignore", invalid="ignore"):
        cot = (den * den - num * num) / (2.0 * num * den)
    cot[degenerate] = 0.0
    return alpha, cot, degenerate


def _clausen_coefficients(n_terms: int = 30) -> np.ndarray:
    # Cl₂(θ) = θ - θ log θ + Σ_{k≥1} |B_2k| θ^(2k+1) / (2k (2k+1)!), valid for |θ| < 2π
    from math import factorial

    from scipy.special import bernoulli

    B = bernoulli(2 * n_terms)
    return np.array([abs(B[2 * k]) / (2 * k * factorial(2 * k + 1)) for k in range(1, n_terms + 1)], dtype=np.float64)


_CLAUSEN = _clausen_coefficients()


def lobachevsky(x: np.ndarray) -> np.ndarray:
    """Milnor's Lobachevsky function ``Л(x) = -∫_0^x log|2 sin t| dt``.

    Parameters
    ----------
    x : array of float
        Angles in radians, in [0, π].

    Returns
    -------
    array of float
        ``Л(x) = Cl₂(2x) / 2`` with Clausen's function ``Cl₂``, from its power series
        on [0, π] (30 terms: the ratio of successive terms is at most 1/4 there, so
        the truncation error is below 1e-17) and ``Cl₂(2π - θ) = -Cl₂(θ)``. 50 times
        faster than ``Im Li₂(e^{2ix}) / 2`` through SciPy's complex ``spence``.
    """
    theta = 2.0 * np.asarray(x, dtype=np.float64)
    sign = np.where(theta > np.pi, -1.0, 1.0)
    theta = np.where(theta > np.pi, 2.0 * np.pi - theta, theta)
    t2 = theta * theta
    acc = np.zeros_like(theta)
    for c in _CLAUSEN[::-1]:
        acc = acc * t2 + c
    with np.errstate(divide="ignore", invalid="ignore"):
        head = np.where(theta > 0, theta * (1.0 - np.log(theta)), 0.0)
    return 0.5 * sign * (head + acc * t2 * theta)


@dataclass(frozen=True)
class Metric:
    """Edge log-lengths of a mesh and the face-to-edge map that reads them.

    Attributes
    ----------
    F : (#F, 3) int
        Triangles.
    E : (#E, 2) int
        Undirected edges.
    FE : (#F, 3) int
        Edge opposite each corner, rows of ``E``.
    lam : (#E,) float
        ``2 log l`` of every edge.
    n_vertices : int
        #V.
    """

    F: np.ndarray
    E: np.ndarray
    FE: np.ndarray
    lam: np.ndarray
    n_vertices: int

    @classmethod
    def from_lengths(cls, F: np.ndarray, L: np.ndarray, n_vertices: int) -> Metric:
        """The metric given by edge lengths: ``L`` (#F, 3) opposite each corner of ``F``."""
        E, FE, _ = unique_edges(F)
        lam = np.empty(len(E))
        lam[FE.ravel()] = 2.0 * np.log(L.ravel())
        return cls(F=F, E=E, FE=FE, lam=lam, n_vertices=n_vertices)

    @classmethod
    def from_mesh(
        cls, V: np.ndarray, F: np.ndarray, E: np.ndarray | None = None, FE: np.ndarray | None = None
    ) -> Metric:
        """The metric of a mesh embedded in space: ``V`` (#V, 3), ``F`` (#F, 3).

        ``E``, ``FE`` are :func:`unique_edges` of ``F`` when already computed.
        """
        if E is None or FE is None:
            E, FE, _ = unique_edges(F)
        lam = 2.0 * np.log(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1))
        return cls(F=F, E=E, FE=FE, lam=lam, n_vertices=len(V))

    def edge_lengths(self, u: np.ndarray) -> np.ndarray:
        """Lengths ``exp((λ + u_i + u_j) / 2)`` of every edge of the scaled metric; (#E,)."""
        return np.exp(0.5 * (self.lam + u[self.E[:, 0]] + u[self.E[:, 1]]))

    def face_log_lengths(self, u: np.ndarray) -> np.ndarray:
        """``λ̃[f, k] = λ + u_i + u_j`` for the edge (i, j) opposite corner k; (#F, 3)."""
        F = self.F
        return self.lam[self.FE] + u[F[:, [1, 2, 0]]] + u[F[:, [2, 0, 1]]]

    def face_lengths(self, u: np.ndarray) -> np.ndarray:
        """Edge lengths of the scaled metric, opposite each corner; (#F, 3)."""
        lt = self.face_log_lengths(u)
        # lengths are only compared within a triangle: removing the face's mean
        # log-length avoids overflow without changing any angle
        return np.exp(0.5 * (lt - lt.mean(axis=1, keepdims=True)))


def angle_sums(F: np.ndarray, alpha: np.ndarray, n_vertices: int) -> np.ndarray:
    """Sum of the corner angles at every vertex; (#V,) float, radians."""
    return np.bincount(F.ravel(), weights=alpha.ravel(), minlength=n_vertices)


def cotan_laplacian(F: np.ndarray, cot: np.ndarray, n_vertices: int) -> sp.csc_matrix:
    """Positive semi-definite cotangent Laplacian.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.
    cot : (#F, 3) float
        Cotangent of the angle at each corner.
    n_vertices : int
        #V.

    Returns
    -------
    L : (#V, #V) sparse float
        ``L_ij = -w_ij``, ``L_ii = Σ_j w_ij`` with ``w_ij = (cot α + cot β) / 2`` over
        the corners facing edge ij. Equals the CETM Hessian.
    """
    i = F[:, [1, 2, 0]].ravel()
    j = F[:, [2, 0, 1]].ravel()
    w = 0.5 * cot.ravel()
    rows = np.concatenate([i, j, i, j])
    cols = np.concatenate([j, i, i, j])
    vals = np.concatenate([-w, -w, w, w])
    return sp.csc_matrix((vals, (rows, cols)), shape=(n_vertices, n_vertices))


def cetm_energy(metric: Metric, u: np.ndarray, theta: np.ndarray) -> float:
    """The convex CETM energy whose gradient is ``Θ - (angle sums)``.

    Parameters
    ----------
    metric : Metric
        Original edge log-lengths.
    u : (#V,) float
        Log scale factors.
    theta : (#V,) float
        Target angle sums, radians.

    Returns
    -------
    float
        ``E(u) = Σ_f Σ_k (α_k λ̃_k + 2 Л(α_k) - π/2 λ̃_k) + Σ_i Θ_i u_i``.
        Its derivative in ``λ̃_k`` is ``α_k`` (Schläfli-type identity, because
        ``l_k / sin α_k`` is the same for the three edges), so ``∂E/∂u_i`` collects
        ``(π - α_i) - π = -α_i`` from every face at ``i``.
    """
    lt = metric.face_log_lengths(u)
    alpha, _, _ = triangle_angles(metric.face_lengths(u))
    tri = (alpha - 0.5 * np.pi) * lt + 2.0 * lobachevsky(alpha)
    return float(tri.sum() + theta @ u)


class DegenerateMetricError(WorkbenchError):
    """The conformal metric exists only with degenerate triangles on this triangulation.

    Attributes
    ----------
    faces : (k,) int
        The degenerate faces.
    """

    def __init__(self, message: str, faces: np.ndarray):
        super().__init__(message)
        self.faces = faces


@dataclass(frozen=True)
class NewtonOptions:
    """Stopping rule of the CETM Newton solve.

    Attributes
    ----------
    tol_rad : float
        Stop when every vertex's angle sum is within this of its target.
    max_iterations : int
        Give up (with an error) after this many Newton steps.
    """

    tol_rad: float = 1e-9
    max_iterations: int = 50


# Budget of a solve on the fixed input triangulation before flips take over: a clean
# mesh converges in 2 to 6 steps with full steps.
FIXED_MAX_ITERATIONS = 20
FIXED_MAX_HALVINGS = 4


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of :func:`conformal_scale_factors`.

    Attributes
    ----------
    u : (#V,) float
        Log scale factors, ``u[fixed] == 0``.
    alpha : (#F, 3) float
        Corner angles of the scaled metric on the final triangulation.
    cot : (#F, 3) float
        Their cotangents.
    degenerate : (#F,) bool
        Final triangles whose scaled lengths violate (or meet) the triangle inequality.
    iterations : int
        Newton steps taken.
    residual_rad : float
        Final max |Θ - angle sum|.
    history : list of float
        Residual before each step and after the last.
    flips : int
        Ptolemy flips made during the solve.
    assembler : CotanAssembler
        Builds the final triangulation's Laplacian without the fixed vertex.
    solver : SPDSolver or None
        Factorisation of the last Hessian on the final triangulation (None if
        there was none): a close preconditioner for systems with the final
        Laplacian.
    """

    u: np.ndarray
    alpha: np.ndarray
    cot: np.ndarray
    degenerate: np.ndarray
    iterations: int
    residual_rad: float
    history: list[float]
    flips: int
    assembler: CotanAssembler
    solver: SPDSolver | None


def scaled_face_angles(F: np.ndarray, lam: np.ndarray, u: np.ndarray):
    """:func:`triangle_angles` of the lengths ``exp((λ + u_i + u_j) / 2)``.

    Parameters
    ----------
    F : (#F, 3) int
        Triangles.
    lam : (#F, 3) float
        ``2 log l`` of the edge opposite each corner.
    u : (#V,) float
        Log scale factors.

    Returns
    -------
    alpha, cot, degenerate
        As :func:`triangle_angles`.
    """
    lt = lam + u[F[:, [1, 2, 0]]] + u[F[:, [2, 0, 1]]]
    # only ratios within a triangle matter: removing the face's mean log-length
    # keeps every exponential in range, whatever the scale factors
    return triangle_angles(np.exp(0.5 * (lt - lt.mean(axis=1, keepdims=True))))


def _newton_direction(assembler: CotanAssembler, cot: np.ndarray, g: np.ndarray, solver: SPDSolver | None):
    """``-H⁻¹ g`` on the free vertices, with fallbacks when a factorisation fails.

    The Hessian is positive semi-definite; a vertex whose triangles are all
    degenerate has an empty row. A tiny diagonal shift makes it definite; when a
    backend still reports a zero pivot, the portable backend and then a larger
    shift are tried.
    """
    rhs = -g[assembler.free]
    attempts = [(1e-12, None), (1e-12, "qdldl"), (1e-8, "qdldl"), (1e-6, "qdldl")]
    for shift, backend in attempts:
        H = assembler.upper(cot, shift=shift)
        try:
            with np.errstate(all="ignore"):
                if solver is not None and backend is None and shift == attempts[0][0]:
                    solver.refactor(H)
                else:
                    solver = SPDSolver(H, backend=backend)
                x = solver.solve(rhs)
        except Exception as exc:  # noqa: BLE001 - any backend failure (zero pivot, MKL error) has a fallback
            if exhausted(exc):  # (but not the machine's memory)
                raise
            solver = None
            continue
        if np.all(np.isfinite(x)):
            return x, solver
        solver = None
    raise WorkbenchError("conformal map: the Newton system could not be factorised (singular Hessian)")


def conformal_scale_factors(
    tri,
    theta: np.ndarray,
    fixed: int | np.ndarray = 0,
    options: NewtonOptions = NewtonOptions(),
    progress: Callable[[int, float], None] | None = None,
    flip: bool = True,
    edges: tuple[np.ndarray, np.ndarray] | None = None,
) -> NewtonResult:
    """Log scale factors giving prescribed angle sums, by Newton's method with Ptolemy flips.

    At every evaluation the triangulation is made Delaunay for the current scaled
    metric (:meth:`IntrinsicTriangulation.make_delaunay`): then the energy is a
    convex, twice differentiable function of ``u`` alone, with gradient
    ``Θ - (angle sums)`` and Hessian the cotangent Laplacian of the Delaunay
    triangulation, and a minimiser exists for any valid targets (Gillespie,
    Springborn, Crane 2021). Each Newton step is shortened until the directional
    derivative along it is no longer negative (the convex energy then has not
    increased; Campen et al. 2021) unless it at least halves the residual.

    Parameters
    ----------
    tri : IntrinsicTriangulation
        Triangulation and Penner coordinates; flipped in place.
    theta : (#V,) float
        Target angle sum at every vertex, radians; NaN where it is free. When all
        are given they must satisfy Gauss-Bonnet (``Σ Θ = π #F``), otherwise no
        solution exists.
    fixed : int or (k,) int
        Vertices whose ``u`` stays 0. With all targets given, one vertex (the
        energy is invariant under adding a constant to ``u``; fixing one removes
        the Hessian's null space); with free boundary angles (NaN targets), those
        vertices (Dirichlet boundary: the film keeps the rim's lengths).
    options : NewtonOptions
        Stopping rule.
    progress : callable(iteration, residual_rad), optional
        Called before every step.
    flip : bool
        False: keep the triangulation as it is (Springborn, Schröder, Pinkall
        2008) and give up early, with :class:`DegenerateMetricError`, as soon as
        a step has to leave a triangle degenerate, needs a long line search, or
        the solve drags on: the caller then solves again with flips.
    edges : (E, FE), optional
        :func:`unique_edges` of ``tri.F`` as given, when already computed.

    Returns
    -------
    NewtonResult

    Raises
    ------
    DegenerateMetricError
        With ``flip=False``: the fixed triangulation does not carry the solution.
    WorkbenchError
        No convergence, a line search that cannot descend, flips that do not
        terminate, or a Hessian that cannot be factorised.
    """
    n = len(theta)
    n_faces = len(tri.F)
    fixed_v = np.atleast_1d(np.asarray(fixed, dtype=np.int64))
    # NaN target: the angle sum is free there (its u stays 0, so it must be fixed)
    free_angle = np.isnan(theta)
    if not np.isin(np.flatnonzero(free_angle), fixed_v).all():
        raise WorkbenchError("conformal map: a vertex with a free angle sum must have its scale factor fixed")
    if not free_angle.any() and abs(theta.sum() - np.pi * n_faces) > 1e-6 * n_faces:
        raise WorkbenchError(
            f"target angles violate Gauss-Bonnet: sum {theta.sum():.6f} rad, needed π·#F = {np.pi * n_faces:.6f}"
        )
    flips_before = tri.flips

    def state(u: np.ndarray, trial: bool = False):
        # a trial step can overshoot wildly (crowded meshes): overflow then gives a
        # non-finite residual, which the line search rejects like any worse point
        with np.errstate(over="ignore", invalid="ignore"):
            if flip and tri.make_delaunay(u) < 0:
                if trial:
                    # so far out that the flips cannot settle: a shorter step will. Every
                    # flip kept the metric, so the half-flipped triangulation is valid
                    return None, None, None, None, np.inf
                raise WorkbenchError("conformal map: Delaunay edge flips did not terminate")
            alpha, cot, degenerate = scaled_face_angles(tri.F, tri.lam, u)
            g = theta - angle_sums(tri.F, alpha, n)
            g[free_angle] = 0.0
            res = float(np.abs(g).max())
        return alpha, cot, degenerate, g, res if np.isfinite(res) else np.inf

    u = np.zeros(n)
    alpha, cot, degenerate, g, res = state(u)
    assembler, pattern, solver = None, -1, None
    if edges is not None and tri.flips == flips_before:
        assembler, pattern = CotanAssembler(edges[0], edges[1], n, fixed_v), tri.flips
    history: list[float] = []
    for it in range(options.max_iterations + 1):
        history.append(res)
        if progress is not None:
            progress(it, res)
        if res <= options.tol_rad:
            break
        if not np.isfinite(res):
            raise WorkbenchError("conformal map: the angle residual is not finite")
        if not flip and it == FIXED_MAX_ITERATIONS:
            raise DegenerateMetricError(f"no convergence in {it} steps on the input triangulation", np.array([]))
        if it == options.max_iterations:
            raise WorkbenchError(f"conformal map did not converge in {it} Newton steps (angle residual {res:.2e} rad)")
        if pattern != tri.flips:
            # flips change the sparsity pattern: new assembly, new symbolic analysis
            E, FE, _ = unique_edges(tri.F)
            assembler, pattern, solver = CotanAssembler(E, FE, n, fixed_v), tri.flips, None
        x, solver = _newton_direction(assembler, cot, g, solver)
        step = np.zeros(n)
        step[assembler.free] = x
        t = 1.0
        for halvings in range(60):
            if not flip and halvings == FIXED_MAX_HALVINGS:
                raise DegenerateMetricError("a long line search on the input triangulation", np.array([]))
            trial = u + t * step
            new = state(trial, trial=True)
            # accept: residual halved (quadratic regime), or the convex energy's slope
            # along the step still non-positive (so the energy has not increased)
            if new[4] <= 0.5 * res or (np.isfinite(new[4]) and float(new[3] @ step) <= 0.0):
                break
            t *= 0.5
        else:
            raise WorkbenchError(f"conformal map: line search failed at angle residual {res:.2e} rad")
        u = trial
        alpha, cot, degenerate, g, res = new
        if not flip and degenerate.any():
            bad = np.flatnonzero(degenerate)
            raise DegenerateMetricError(f"{len(bad)} triangles degenerate on the input triangulation", bad)
    if pattern != tri.flips:
        E, FE, _ = unique_edges(tri.F)
        assembler, solver = CotanAssembler(E, FE, n, fixed_v), None
    return NewtonResult(
        u=u,
        alpha=alpha,
        cot=cot,
        degenerate=degenerate,
        iterations=it,
        residual_rad=res,
        history=history,
        flips=tri.flips - flips_before,
        assembler=assembler,
        solver=solver,
    )
