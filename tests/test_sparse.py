"""Sparse SPD solves: every backend, refactoring, preconditioned CG."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.conformal.cetm import Metric, triangle_angles
from workbench.sparse import CotanAssembler, SPDSolver, _backends, preconditioned_cg, symmetric_matvec


@pytest.fixture
def laplacian(grid):
    P, F = grid(40, 30, np.random.default_rng(7))
    V = np.column_stack([P * [40, 30], np.sin(P[:, 0] * 3)])
    _, cot, _ = triangle_angles(Metric.from_mesh(V, F).face_lengths(np.zeros(len(V))))
    m = Metric.from_mesh(V, F)
    asm = CotanAssembler(m.E, m.FE, len(V), np.array([0]))
    return asm, cot


@pytest.mark.parametrize("backend", [b.name for b in _backends()])
def test_backends_solve_and_refactor(laplacian, backend):
    asm, cot = laplacian
    U = asm.upper(cot)
    A = (U + U.T).toarray() - np.diag(U.diagonal())
    x_true = np.random.default_rng(0).standard_normal(asm.n)
    s = SPDSolver(U, backend=backend)
    assert s.backend == backend
    np.testing.assert_allclose(s.solve(A @ x_true), x_true, rtol=0, atol=1e-9 * np.abs(x_true).max())
    s.refactor(asm.upper(2.0 * cot))  # same pattern, new values
    np.testing.assert_allclose(s.solve(2.0 * (A @ x_true)), x_true, rtol=0, atol=1e-9)


def test_assembler_matches_the_dense_laplacian(laplacian, grid):
    asm, cot = laplacian
    from workbench.conformal.cetm import cotan_laplacian

    P, F = grid(40, 30, np.random.default_rng(7))
    L = cotan_laplacian(F, cot, len(P)).toarray()[1:, 1:]
    U = asm.upper(cot)
    np.testing.assert_allclose((U + U.T).toarray() - np.diag(U.diagonal()), L, atol=1e-13)


def test_cg_with_a_nearby_factorisation_reaches_round_off(laplacian):
    asm, cot = laplacian
    near = SPDSolver(asm.upper(cot * 1.01))  # 1 % off, like the previous Newton step
    U = asm.upper(cot)
    b = np.random.default_rng(1).standard_normal(asm.n)
    x, iterations, res = preconditioned_cg(symmetric_matvec(U), b, near.solve)
    assert res <= 1e-13 and iterations <= 10
