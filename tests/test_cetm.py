"""The CETM energy, its derivatives and its extension past the triangle inequality."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from workbench.conformal.cetm import (
    Metric,
    angle_sums,
    cetm_energy,
    cotan_laplacian,
    lobachevsky,
    triangle_angles,
)


@pytest.mark.parametrize("x", [0.0, 0.1, np.pi / 6, 1.0, np.pi / 2, 2.5, np.pi])
def test_lobachevsky_matches_its_integral(x):
    # Л(x) = -∫_0^x log|2 sin t| dt (integrable log singularities at 0 and π)
    ref = -quad(lambda t: np.log(abs(2 * np.sin(t))), 0, x, limit=200, points=[np.pi] if x >= np.pi else None)[0]
    assert lobachevsky(np.array([x]))[0] == pytest.approx(ref, abs=1e-12)


def test_lobachevsky_known_value():
    # Л(π/6) = Cl₂(π/3) / 2, and Cl₂(π/3) = 1.0149416064096536 is Clausen's maximum
    assert lobachevsky(np.array([np.pi / 6]))[0] == pytest.approx(1.0149416064096536 / 2, abs=1e-15)


def test_angles_of_a_right_triangle_and_the_degenerate_extension():
    alpha, cot, degenerate = triangle_angles(np.array([[3.0, 4.0, 5.0], [3.0, 1.0, 1.0]]))
    np.testing.assert_allclose(alpha[0], [np.arcsin(0.6), np.arcsin(0.8), np.pi / 2], atol=1e-15)
    np.testing.assert_allclose(cot[0], [4 / 3, 3 / 4, 0.0], atol=1e-14)
    # edge 0 longer than the other two together: angle π opposite it, 0 elsewhere, no curvature
    np.testing.assert_array_equal(alpha[1], [np.pi, 0.0, 0.0])
    np.testing.assert_array_equal(cot[1], [0.0, 0.0, 0.0])
    assert degenerate.tolist() == [False, True]


def small_metric(seed=1, n=6):
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1)
    V[:, :2] += 0.2 * rng.standard_normal((n * n, 2))
    V[:, 2] = 0.3 * rng.standard_normal(n * n)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return Metric.from_mesh(V, F), rng


@pytest.mark.parametrize("spread", [0.1, 1.5], ids=["valid", "violating"])
def test_gradient_is_target_minus_angle_sum(spread):
    metric, rng = small_metric()
    n = metric.n_vertices
    theta = rng.uniform(1, 6, n)
    u = spread * rng.standard_normal(n)
    alpha, _, degenerate = triangle_angles(metric.face_lengths(u))
    if spread > 1:
        assert degenerate.any()  # the extension is exercised
    g = theta - angle_sums(metric.F, alpha, n)
    h = 1e-6
    fd = np.array(
        [(cetm_energy(metric, u + h * e, theta) - cetm_energy(metric, u - h * e, theta)) / (2 * h) for e in np.eye(n)]
    )
    np.testing.assert_allclose(fd, g, atol=1e-6)


def test_hessian_is_the_cotangent_laplacian():
    metric, rng = small_metric(seed=2)
    n = metric.n_vertices
    u = 0.1 * rng.standard_normal(n)
    _, cot, _ = triangle_angles(metric.face_lengths(u))
    H = cotan_laplacian(metric.F, cot, n).toarray()
    h = 1e-6
    cols = []
    for e in np.eye(n):
        ap, _, _ = triangle_angles(metric.face_lengths(u + h * e))
        am, _, _ = triangle_angles(metric.face_lengths(u - h * e))
        cols.append(-(angle_sums(metric.F, ap, n) - angle_sums(metric.F, am, n)) / (2 * h))
    np.testing.assert_allclose(np.stack(cols, 1), H, atol=1e-7)
    assert np.linalg.eigvalsh(H).min() > -1e-12  # convex energy
