"""Ptolemy flips: Delaunay for any scale factors, the decorated surface kept, directions tracked."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import annulus_sector, grid_corners, grid_mesh, mercator_patch
from test_conformal_maps import check_subdivision, similarity_error

from workbench.conformal.cetm import scaled_face_angles
from workbench.conformal.flatten import FlattenOptions, flatten, input_log_lengths
from workbench.conformal.intrinsic import IntrinsicTriangulation, delaunay_sums, horocycle_arcs
from workbench.mesh.topology import boundary_half_edges


def bumpy(grid, n=30, seed=4):
    P, F = grid(n, n, np.random.default_rng(seed), jitter=0.45)
    x, y = (P[:, 0] - 0.5) * 50, (P[:, 1] - 0.5) * 50
    return np.stack([x, y, 10 * np.sin(x / 9) * np.cos(y / 11)], 1), F


@pytest.mark.parametrize("spread", [0.0, 0.5, 3.0])
def test_flips_reach_delaunay_and_keep_the_decorated_surface(grid, spread):
    V, F = bumpy(grid)
    lam = input_log_lengths(V, F)
    tri = IntrinsicTriangulation.from_mesh(F, lam, len(V))
    arcs_before = np.bincount(F.ravel(), horocycle_arcs(lam).ravel(), len(V))
    u = spread * np.random.default_rng(1).standard_normal(len(V))
    flips = tri.make_delaunay(u)
    assert flips > 50
    # Delaunay for the scaled metric: the corners facing each interior edge sum to at most π
    assert delaunay_sums(tri.F, tri.T, tri.lam, u).min() >= -1e-9
    # a Delaunay triangulation in Penner coordinates satisfies the triangle inequality
    # (the theorem covers closed surfaces; on a disc, boundary edges are not flipped,
    # so under wild scale factors triangles at the boundary can still degenerate)
    _, _, degenerate = scaled_face_angles(tri.F, tri.lam, u)
    if spread <= 0.5:
        assert not degenerate.any()
    # the decoration is kept: each vertex's horocycle has the same total length
    arcs_after = np.bincount(tri.F.ravel(), horocycle_arcs(tri.lam).ravel(), len(V))
    np.testing.assert_allclose(arcs_after, arcs_before, rtol=1e-10)
    # same boundary, twins consistent (double edges and loops are allowed)
    bf, bk = np.nonzero(tri.T < 0)
    after = set(zip(tri.F[bf, (bk + 1) % 3].tolist(), tri.F[bf, (bk + 2) % 3].tolist(), strict=True))
    assert after == set(map(tuple, boundary_half_edges(F).tolist()))
    inner = tri.T >= 0
    back = tri.T.ravel()[tri.T[inner]]
    np.testing.assert_array_equal(back, np.flatnonzero(inner.ravel()))
    # reference directions stay inside their corners
    h = horocycle_arcs(tri.lam)[tri.ref_face, tri.ref_corner]
    assert ((tri.ref_offset >= 0) & (tri.ref_offset < h)).all()
    # already Delaunay: nothing more to flip
    assert tri.make_delaunay(u) == 0


def test_ptolemy_flips_do_not_depend_on_the_unit(grid):
    V, F = bumpy(grid)
    u = 0.8 * np.random.default_rng(2).standard_normal(len(V))
    results = []
    for unit in (1e-3, 1.0, 1e3):
        tri = IntrinsicTriangulation.from_mesh(F, input_log_lengths(V * unit, F), len(V))
        tri.make_delaunay(u)
        results.append(tri)
    for tri in results[1:]:
        np.testing.assert_array_equal(tri.F, results[0].F)
        np.testing.assert_allclose(tri.lam, results[0].lam, atol=1e-12)


def test_forced_flips_match_the_closed_form_at_every_subdivision_vertex():
    # A Delaunay mesh of an annulus sector (its Penner class is the surface's own), solved
    # with flips forced: the input vertices land where w = log z sends them as closely as
    # without flips, and so does every crossing point of the common subdivision, up to
    # the O(h²) by which the smooth map bends between a straight edge's ends
    # (h²/8 · |w''| ≈ 4e-5 here). A wrong position along an edge would be off by O(h).
    n = 60
    P, F = grid_mesh(n, n, np.random.default_rng(0), jitter=0.0)
    w = P[:, 0] * np.log(2.0) + 1j * P[:, 1]
    z = np.exp(w)
    V, exact = np.stack([z.real, z.imag, np.zeros(len(z))], 1), np.stack([w.real, w.imag], 1)
    corners = grid_corners(n, n)
    plain = flatten(V, F, FlattenOptions(corners=corners, flips=False))
    r = flatten(V, F, FlattenOptions(corners=corners, flips=True))
    assert r.intrinsic_flips > 10 and len(r.V) > len(V)
    check_subdivision(r, V, F)
    zz = r.V[:, 0] + 1j * r.V[:, 1]
    ww = np.stack([np.log(np.abs(zz)), np.angle(zz)], 1)
    assert similarity_error(r.uv[: len(V)], exact) <= 1.01 * similarity_error(plain.uv, exact) + 1e-9
    assert similarity_error(r.uv, ww) <= 6e-5
    assert r.newton.residual_rad <= 1e-9


@pytest.mark.parametrize("surface", [annulus_sector, mercator_patch], ids=["annulus-log", "sphere-mercator"])
def test_forced_flips_on_a_jittered_mesh_stay_close_to_the_closed_form(surface):
    # On a mesh that is not Delaunay, the Penner class of its own triangulation is not
    # quite the surface's: a known loss of accuracy (flips are only used where the input
    # triangulation cannot carry the solution); the map stays exact and fold-free.
    n = 60
    V, F, exact = surface(n)
    r = flatten(V, F, FlattenOptions(corners=grid_corners(n, n), flips=True))
    check_subdivision(r, V, F)
    assert similarity_error(r.uv[: len(V)], exact) <= 2e-3
