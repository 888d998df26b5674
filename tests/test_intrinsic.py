"""Intrinsic Delaunay flips keep the surface and make every edge Delaunay."""

from __future__ import annotations

import numpy as np

from workbench.conformal.cetm import angle_sums, triangle_angles
from workbench.conformal.intrinsic import intrinsic_delaunay
from workbench.mesh.topology import boundary_half_edges, unique_edges


def heron(L):
    a, b, c = L.T
    s = 0.5 * (a + b + c)
    return np.sqrt(np.maximum(s * (s - a) * (s - b) * (s - c), 0))


def test_flips_keep_the_metric_and_reach_delaunay(grid):
    P, F = grid(30, 30, np.random.default_rng(4), jitter=0.45)
    x, y = (P[:, 0] - 0.5) * 50, (P[:, 1] - 0.5) * 50
    V = np.stack([x, y, 10 * np.sin(x / 9) * np.cos(y / 11)], 1)
    L = np.linalg.norm(V[F[:, [2, 0, 1]]] - V[F[:, [1, 2, 0]]], axis=2)
    F2, L2, flips = intrinsic_delaunay(F, L)
    assert flips > 100
    # same surface: every vertex keeps its angle sum (its cone angle), total area is kept
    a1, _, _ = triangle_angles(L)
    a2, cot2, degenerate = triangle_angles(L2)
    assert not degenerate.any()
    np.testing.assert_allclose(angle_sums(F2, a2, len(V)), angle_sums(F, a1, len(V)), atol=1e-10)
    np.testing.assert_allclose(heron(L2).sum(), heron(L).sum(), rtol=1e-12)
    # same boundary, still a valid triangulation with unique edges
    assert set(map(tuple, boundary_half_edges(F2).tolist())) == set(map(tuple, boundary_half_edges(F).tolist()))
    _, _, count = unique_edges(F2)
    assert count.max() == 2
    # Delaunay: the two angles facing each interior edge sum to at most π (cotangent weight >= 0)
    E, FE, count = unique_edges(F2)
    w = np.bincount(FE.ravel(), weights=cot2.ravel(), minlength=len(E))
    assert w[count == 2].min() >= -1e-9
    # edges that were already Delaunay need no flip
    _, _, flips_again = intrinsic_delaunay(F2, L2)
    assert flips_again == 0
