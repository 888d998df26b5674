"""workbench flatten against closed-form conformal maps (100 x 100 jittered grids, random splits)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import annulus_sector, cylinder_patch, grid_corners, mercator_patch

from workbench.conformal.cetm import Metric, angle_sums
from workbench.conformal.flatten import FlattenOptions, flatten
from workbench.conformal.layout import signed_areas

N = 100


def similarity_error(uv: np.ndarray, exact: np.ndarray) -> float:
    """Max vertex distance after the best complex similarity uv -> exact, over the exact diagonal."""
    zu = uv[:, 0] + 1j * uv[:, 1]
    ze = exact[:, 0] + 1j * exact[:, 1]
    A = np.stack([zu, np.ones_like(zu)], 1)
    coef = np.linalg.lstsq(A, ze, rcond=None)[0]
    diag = np.hypot(*(exact.max(0) - exact.min(0)))
    return float(np.abs(A @ coef - ze).max() / diag)


def layout_corner_angles(uv, F, corners):
    """Angle sum at each corner vertex measured from the laid-out positions."""
    e = uv[F[:, [2, 0, 1]]] - uv[F[:, [1, 2, 0]]]
    la = np.linalg.norm(e, axis=2)
    # law of cosines on the laid-out triangles (independent of the solver's angles)
    a, b, c = la[:, 0], la[:, 1], la[:, 2]
    alpha = np.stack(
        [
            np.arccos((b * b + c * c - a * a) / (2 * b * c)),
            np.arccos((c * c + a * a - b * b) / (2 * c * a)),
            np.arccos((a * a + b * b - c * c) / (2 * a * b)),
        ],
        1,
    )
    return angle_sums(F, alpha, len(uv))[list(corners)]


@pytest.mark.parametrize("surface", [annulus_sector, mercator_patch], ids=["annulus-log", "sphere-mercator"])
def test_matches_closed_form_map(surface):
    V, F, exact = surface(N)
    corners = grid_corners(N, N)
    r = flatten(V, F, FlattenOptions(corners=corners))
    assert similarity_error(r.uv, exact) <= 1e-5
    assert r.newton.residual_rad <= 1e-9
    assert r.flipped_faces == 0 and (signed_areas(r.uv, F) > 0).all()
    # the metric's corner angles, and the corners of the laid-out rectangle
    metric_corner = angle_sums(F, r.newton.alpha, len(V))[list(corners)]
    np.testing.assert_allclose(metric_corner, np.pi / 2, atol=1e-9)
    np.testing.assert_allclose(layout_corner_angles(r.uv, F, corners), np.pi / 2, atol=1e-9)
    # the rectangle has the exact map's aspect ratio
    ext = exact.max(0) - exact.min(0)
    assert r.width_mm / r.height_mm == pytest.approx(ext[0] / ext[1], rel=2e-5)


def test_cylinder_unrolls_isometrically_in_mm():
    V, F, exact = cylinder_patch(N)
    r = flatten(V, F, FlattenOptions(corners=grid_corners(N, N)))  # default scale: isometric
    # rigid fit only (rotation + translation, no scale): the print is true size
    zu = r.uv[:, 0] + 1j * r.uv[:, 1]
    ze = exact[:, 0] + 1j * exact[:, 1]
    rot = np.exp(1j * np.angle(np.sum((ze - ze.mean()) * np.conj(zu - zu.mean()))))
    err = np.abs(rot * (zu - zu.mean()) - (ze - ze.mean())).max()
    assert err <= 0.005
    assert r.width_mm == pytest.approx(80.0, abs=0.005)
    assert r.height_mm == pytest.approx(60.0, abs=0.005)
    assert r.flipped_faces == 0


def test_layout_reproduces_the_flat_metric():
    V, F, _ = mercator_patch(60, seed=3)
    r = flatten(V, F, FlattenOptions(corners=grid_corners(60, 60)))
    metric = Metric.from_mesh(V, F)
    flat_lengths = metric.edge_lengths(r.newton.u)
    laid = np.linalg.norm(r.uv[metric.E[:, 0]] - r.uv[metric.E[:, 1]], axis=1)
    ratio = laid / flat_lengths  # one global scale factor, nothing accumulated
    assert ratio.std() / ratio.mean() <= 1e-9


def test_corners_follow_the_convention():
    V, F, _ = annulus_sector(40, seed=5)
    corners = grid_corners(40, 40)
    r = flatten(V, F, FlattenOptions(corners=corners))
    A, B, C, D = (r.uv[c] for c in corners)
    np.testing.assert_allclose(A, [0, 0], atol=1e-9)
    np.testing.assert_allclose(B, [r.width_mm, 0], atol=1e-9)
    np.testing.assert_allclose(C, [r.width_mm, r.height_mm], atol=1e-9)
    np.testing.assert_allclose(D, [0, r.height_mm], atol=1e-9)
    assert r.uv[:, 0].min() >= -1e-9 and r.uv[:, 1].min() >= -1e-9


@pytest.mark.slow
@pytest.mark.parametrize("surface", [annulus_sector, mercator_patch], ids=["annulus-log", "sphere-mercator"])
def test_error_falls_as_h_squared_up_to_160k_vertices(surface):
    errors = []
    for n in (100, 200, 400):
        V, F, exact = surface(n)
        r = flatten(V, F, FlattenOptions(corners=grid_corners(n, n)))
        assert r.flipped_faces == 0 and r.newton.residual_rad <= 1e-9
        errors.append(similarity_error(r.uv, exact))
    order = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert (order > 1.7).all(), (errors, order)


def squashed_disc(grid, seed):
    """A square grid squashed onto a radius-30 disc: slivers at its four former corners."""
    P, F = grid(25, 25, np.random.default_rng(seed))
    q = 2 * P - 1
    d = q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-12) * np.abs(q).max(1, keepdims=True)
    return np.column_stack([d * 30, np.zeros(len(d))]), F


def check_subdivision(r, V, F):
    """The output mesh is an exact refinement of the input, laid out without a fold."""
    n = len(V)
    assert r.n_input_vertices == n
    np.testing.assert_array_equal(r.V[:n], V)  # input vertices first, in their order
    # every output triangle lies in its parent input triangle: its corners have
    # non-negative barycentric coordinates there
    P = F[r.parent]
    for k in range(3):
        a, b, c = V[P[:, 0]], V[P[:, 1]], V[P[:, 2]]
        p = r.V[r.F[:, k]]
        n_f = np.cross(b - a, c - a)
        area2 = np.einsum("ij,ij->i", n_f, n_f)
        bary = [
            np.einsum("ij,ij->i", np.cross(c - b, p - b), n_f) / area2,
            np.einsum("ij,ij->i", np.cross(a - c, p - c), n_f) / area2,
        ]
        assert min(bary[0].min(), bary[1].min(), (1 - bary[0] - bary[1]).min()) >= -1e-9
    # the refinement covers the surface exactly once: areas add up per input face
    area_in = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1) / 2
    np.testing.assert_allclose(np.bincount(r.parent, r.area_3d, len(F)), area_in, rtol=1e-9, atol=1e-12)
    # and the flat layout covers the rectangle (or the free outline) exactly once, no flipped triangle
    flat = signed_areas(r.uv, r.F)
    assert r.flipped_faces == 0 and (flat > 0).all()
    if len(r.corners):
        assert flat.sum() == pytest.approx(r.width_mm * r.height_mm, rel=1e-9)
    else:  # a free outline: the triangles fill the polygon of the boundary
        from workbench.mesh.topology import boundary_loops

        x, y = r.uv[boundary_loops(r.F)[0]].T
        polygon = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        assert flat.sum() == pytest.approx(polygon, rel=1e-9)


@pytest.mark.parametrize("seed", [2, 9])
def test_slivers_are_solved_with_intrinsic_flips(grid, seed):
    # corners at the middle of the sides: the former corners become boundary vertices
    # whose one or two squashed faces would have to open to 180°
    V, F = squashed_disc(grid, seed)
    corners = (12, 324, 612, 300)
    r = flatten(V, F, FlattenOptions(corners=corners))
    assert r.intrinsic_flips > 0
    assert r.newton.residual_rad <= 1e-9
    np.testing.assert_allclose(
        r.uv[list(corners)], [[0, 0], [r.width_mm, 0], [r.width_mm, r.height_mm], [0, r.height_mm]], atol=1e-9
    )
    # the common subdivision maps every input triangle exactly: no fold, nothing collapsed
    check_subdivision(r, V, F)
    assert not r.collapsed.any()


def test_slivers_degenerate_on_their_own_triangulation(grid):
    # the reason for the flips: on the input triangles the metric degenerates
    from workbench.conformal.cetm import DegenerateMetricError, conformal_scale_factors
    from workbench.conformal.flatten import input_log_lengths
    from workbench.conformal.intrinsic import IntrinsicTriangulation
    from workbench.mesh.topology import boundary_loops

    V, F = squashed_disc(grid, 9)
    theta = np.full(len(V), 2 * np.pi)
    theta[boundary_loops(F)[0]] = np.pi
    theta[[12, 324, 612, 300]] = np.pi / 2
    tri = IntrinsicTriangulation.from_mesh(F, input_log_lengths(V, F), len(V))
    with pytest.raises(DegenerateMetricError):
        conformal_scale_factors(tri, theta, fixed=12, flip=False)
    tri = IntrinsicTriangulation.from_mesh(F, input_log_lengths(V, F), len(V))
    r = conformal_scale_factors(tri, theta, fixed=12)
    assert r.flips > 0 and r.residual_rad <= 1e-9 and not r.degenerate.any()
