"""Sparse symmetric positive definite systems: Laplacian assembly into a fixed pattern, LDLᵀ, CG."""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp


class CotanAssembler:
    """Cotangent Laplacian of a fixed triangulation, restricted to free vertices.

    The sparsity pattern is built once from the edge list; each call only sums the
    new weights into it, which is what Newton's method needs at every step. The
    matrix comes out as its upper triangle in CSR form: a row holds its diagonal,
    then its edges to higher-numbered vertices, which is the order of ``E``.

    Parameters
    ----------
    E : (#E, 2) int
        Undirected edges, ``E[:, 0] <= E[:, 1]``, sorted lexicographically
        (as :func:`workbench.mesh.topology.unique_edges` returns them); two edges
        joining the same vertices are one row (their weights add up), and loops
        ``E[:, 0] == E[:, 1]`` are left out.
    FE : (#F, 3) int
        Edge opposite each face corner.
    n_vertices : int
        #V.
    fixed : (k,) int
        Vertices left out (rows and columns removed).

    Attributes
    ----------
    free : (n,) int
        The vertices kept, in order: row ``r`` is vertex ``free[r]``.
    n : int
        Size of the matrix.
    """

    def __init__(self, E: np.ndarray, FE: np.ndarray, n_vertices: int, fixed: np.ndarray):
        self.free = np.setdiff1d(np.arange(n_vertices), fixed)
        self.n = n = len(self.free)
        free_id = np.full(n_vertices, -1, dtype=np.int64)
        free_id[self.free] = np.arange(n)
        lo, hi = free_id[E[:, 0]], free_id[E[:, 1]]
        # free_id is increasing, so kept edges stay sorted by (row, column)
        # an edge from a vertex to itself (intrinsic triangulations have them) adds
        # w (u_i - u_i)² = 0 to the energy: it has no entry at all
        self._loop = E[:, 0] == E[:, 1]
        self._kept = np.flatnonzero((lo >= 0) & (hi >= 0) & ~self._loop)
        self._lo, self._hi = lo, hi
        per_row = 1 + np.bincount(lo[self._kept], minlength=n)
        self._indptr = np.concatenate([[0], np.cumsum(per_row)]).astype(np.int32)
        self._diag = self._indptr[:-1]
        first_of_row = np.concatenate([[0], np.cumsum(per_row - 1)])[:-1]
        rank = np.arange(len(self._kept)) - first_of_row[lo[self._kept]]
        self._off = self._diag[lo[self._kept]] + 1 + rank
        self._indices = np.empty(self._indptr[-1], dtype=np.int32)
        self._indices[self._diag] = np.arange(n)
        self._indices[self._off] = hi[self._kept]
        self._FE = FE
        self._n_edges = len(E)
        self._E = E
        self._n_vertices = n_vertices

    def upper(self, cot: np.ndarray, shift: float = 0.0) -> sp.csr_matrix:
        """Upper triangle of ``L[free][:, free] + shift·max(diag)·I``, CSR.

        Parameters
        ----------
        cot : (#F, 3) float
            Cotangent of each corner angle.
        shift : float
            Relative diagonal shift (keeps a matrix with a zero row definite).

        Returns
        -------
        U : (n, n) sparse CSR, upper triangular
        """
        # w_ij = (cot α + cot β) / 2 over the corners facing edge ij
        w = np.bincount(self._FE.ravel(), weights=0.5 * cot.ravel(), minlength=self._n_edges)
        w[self._loop] = 0.0
        degree = np.bincount(self._E[:, 0], w, self._n_vertices) + np.bincount(self._E[:, 1], w, self._n_vertices)
        data = np.empty(len(self._indices))
        data[self._diag] = degree[self.free]
        data[self._off] = -w[self._kept]
        if shift:
            data[self._diag] += shift * data[self._diag].max()
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n, self.n))


def symmetric_matvec(U: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
    """``x -> A x`` for the symmetric ``A`` whose upper triangle is ``U``."""
    d = U.diagonal()
    return lambda x: U @ x + U.T @ x - (d * x.T).T


class _QDLDL:
    """``qdldl`` (OSQP's LDLᵀ, AMD ordering): portable, single-threaded."""

    name = "qdldl"

    def __init__(self, U: sp.csr_matrix):
        import qdldl

        self._solver = qdldl.Solver(U.tocsc(), upper=True)

    def refactor(self, U: sp.csr_matrix) -> None:
        self._solver.update(U.tocsc(), upper=True)

    def solve(self, b: np.ndarray) -> np.ndarray:
        if b.ndim == 1:
            return self._solver.solve(b)
        return np.stack([self._solver.solve(np.ascontiguousarray(c)) for c in b.T], axis=1)


def _point_pypardiso_at_mkl() -> None:
    """Tell pypardiso where MKL's runtime is when it sits in this environment's lib folder.

    pypardiso looks for ``mkl_rt`` with ``find_library`` (which does not search a
    virtual environment) and else globs the whole environment recursively, once per
    solver: 0.25 to 0.4 s each, two solvers per flatten. The pip wheel of MKL puts it
    in ``sys.prefix/lib``; one directory listing finds it there.
    """
    if "PYPARDISO_MKL_RT" in os.environ:
        return
    import glob
    import sys

    found = sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len)
    if found:
        os.environ["PYPARDISO_MKL_RT"] = found[0]


class _Pardiso:
    """MKL PARDISO through ``pypardiso``: supernodal, multi-threaded, separate phases."""

    name = "pardiso"

    def __init__(self, U: sp.csc_matrix):
        # MKL's parallel kernels sum in a thread-dependent order unless conditional
        # numerical reproducibility is on; without it two runs differ in the last bits
        # (seen: flat.obj differing in the 12th digit). Must be set before MKL loads.
        os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")
        _point_pypardiso_at_mkl()
        import pypardiso

        # mtype 2: real symmetric positive definite; PARDISO reads the upper triangle in CSR
        self._ps = pypardiso.PyPardisoSolver(mtype=2)
        self._A = U
        self._ps._check_A(self._A)
        self._phase(11, self._A)  # ordering and symbolic analysis, once per pattern
        self._phase(22, self._A)  # numeric factorisation

    def _phase(self, phase: int, A: sp.csr_matrix, b: np.ndarray | None = None) -> np.ndarray:
        self._ps.set_phase(phase)
        return self._ps._call_pardiso(A, np.zeros(A.shape[0]) if b is None else b)

    def refactor(self, U: sp.csr_matrix) -> None:
        self._A = U
        self._phase(22, self._A)

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._phase(33, self._A, np.asfortranarray(b))

    def __del__(self):
        try:
            self._ps.free_memory(everything=True)
        except Exception:  # interpreter shutdown: MKL may already be gone
            pass


def _backends() -> list[type]:
    try:
        import pypardiso  # noqa: F401

        return [_Pardiso, _QDLDL]
    except ImportError:  # no MKL on this platform
        return [_QDLDL]


class SPDSolver:
    """Factorisation of a sparse symmetric positive definite matrix, refactorable.

    Newton's method factorises matrices of one sparsity pattern again and again, so
    the ordering and symbolic analysis are done once and ``refactor`` only redoes
    the numeric part. SciPy has no sparse Cholesky (``splu`` repeats its ordering
    every call: 1.15 s on a 160k-vertex Laplacian). Backends, fastest available
    first: MKL PARDISO via ``pypardiso`` on x86-64 (analysis 0.52 s, refactor
    0.12 s there, 2 cores), else ``qdldl`` (1.3 s, 0.67 s). Both give bit-identical
    results from run to run.

    Parameters
    ----------
    U : (n, n) sparse CSR
        Upper triangle of a symmetric positive definite matrix.
    backend : {'pardiso', 'qdldl'}, optional
        Force a backend; default the fastest available.
    """

    def __init__(self, U: sp.csr_matrix, backend: str | None = None):
        choices = _backends()
        if backend is not None:
            choices = [b for b in (_Pardiso, _QDLDL) if b.name == backend]
        self._impl = choices[0](U)
        self.backend = self._impl.name

    def refactor(self, U: sp.csr_matrix) -> None:
        """Factorise a new matrix with the sparsity pattern of the first one."""
        self._impl.refactor(U)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``A x = b`` for ``b`` of shape (n,) or (n, k)."""
        return self._impl.solve(np.ascontiguousarray(b, dtype=np.float64))


def preconditioned_cg(
    matvec: Callable[[np.ndarray], np.ndarray],
    b: np.ndarray,
    precondition: Callable[[np.ndarray], np.ndarray],
    rtol: float = 1e-14,
    max_iterations: int = 60,
) -> tuple[np.ndarray, int, float]:
    """Conjugate gradients with a preconditioner, for an SPD system, one or more right-hand sides.

    With the factorisation of a nearby matrix as preconditioner (the Hessian of the
    previous Newton step) a few iterations reach round-off, at a fraction of the
    cost of a new factorisation. Columns of ``b`` are independent systems solved
    side by side (one preconditioner call per iteration for all of them).

    Parameters
    ----------
    matvec : callable
        ``X -> A X`` for (n,) or (n, k) arrays.
    b : (n,) or (n, k) float
        Right-hand side(s).
    precondition : callable
        ``R -> M⁻¹ R`` with ``M ≈ A`` symmetric positive definite, same shapes.
    rtol : float
        Stop when ``|b - A x| <= rtol |b|`` for every column.
    max_iterations : int
        Upper bound on iterations.

    Returns
    -------
    x : like ``b``
        Solution.
    iterations : int
        Iterations made.
    relative_residual : float
        Largest ``|b - A x| / |b|`` over the columns.
    """
    B = b.reshape(len(b), -1)
    bnorm = np.linalg.norm(B, axis=0)
    bnorm[bnorm == 0] = 1.0
    X = precondition(B)
    R = B - matvec(X)
    Z = precondition(R)
    P = Z.copy()
    rz = np.einsum("ij,ij->j", R, Z)
    res = np.linalg.norm(R, axis=0) / bnorm
    best_res, best_X = res.copy(), X.copy()
    it = 0
    while best_res.max() > rtol and it < max_iterations:
        AP = matvec(P)
        alpha = rz / np.einsum("ij,ij->j", P, AP)
        X += alpha * P
        R -= alpha * AP
        it += 1
        res = np.linalg.norm(R, axis=0) / bnorm
        better = res < best_res
        best_res[better], best_X[:, better] = res[better], X[:, better]
        if (res > 10 * best_res).all():
            break  # round-off floor reached: CG is only wandering now
        Z = precondition(R)
        rz_new = np.einsum("ij,ij->j", R, Z)
        P = Z + (rz_new / rz) * P
        rz = rz_new
    return best_X.reshape(b.shape), it, float(best_res.max())
