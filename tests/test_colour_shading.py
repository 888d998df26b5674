"""Colour under a directional light: the shading that follows the orientation taken out, an ink's error kept."""

from __future__ import annotations

import numpy as np

from workbench.validate.colour import delta_e00, lab_to_xyz, orientation_shading, xyz_to_lab


def _normals(n: int, seed: int = 0) -> np.ndarray:
    """Unit normals over the upper hemisphere and a little below (a part seen from above)."""
    v = np.random.default_rng(seed).normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) - 0.2
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_colour_takes_the_light_out_of_all_three_coordinates():
    """A saturated ink shaded by a light that follows the normal: with the shading taken out of
    X, Y and Z, nothing is left (taken out of L* alone, a* and b* kept the shading's scale)."""
    rng = np.random.default_rng(4)
    m = 4000
    n = _normals(m, seed=5)
    proof = np.column_stack([rng.uniform(35, 70, m), rng.uniform(-60, 60, m), rng.uniform(-60, 60, m)])
    n_chart = np.array([0.0, 0.0, 1.0])
    b = np.array([0.12, -0.08, 0.2])
    # ln((L* + 16) / (L*_proof + 16)) = ln(k) / 3 = b · (n − n_chart): the model's own form
    k = np.exp(3.0 * (n - n_chart) @ b)
    got = xyz_to_lab(lab_to_xyz(proof) * k[:, None])
    r = orientation_shading(proof, got, n, n_chart, delta_e00(proof, got))
    assert r["delta_e00"]["mean"] < 0.05, r
    assert r["mean_abs_delta_l"] > 2.0  # (the shading was there to take out)


def test_colour_takes_a_lamps_clamped_shading_out_and_keeps_an_inks_error():
    """A lamp's shading (ambient plus a clamped cosine) is no linear function of the normal: what
    the linear model leaves follows the orientation and is shading too; an ink 5 L* too dark, or
    off by 5 in a* and b*, stays."""
    rng = np.random.default_rng(8)
    m = 20000
    v = rng.normal(size=(m, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.3
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    proof = np.column_stack([rng.uniform(35, 80, m), rng.uniform(-50, 50, m), rng.uniform(-50, 50, m)])
    lamp = np.array([0.3, -0.5, 1.0]) / np.linalg.norm([0.3, -0.5, 1.0])
    n_chart = np.array([0.0, 0.0, 1.0])
    k = (0.35 + 0.65 * np.maximum(n @ lamp, 0)) / (0.35 + 0.65 * max(n_chart @ lamp, 0))
    got = xyz_to_lab(lab_to_xyz(proof) * k[:, None])
    # (the linear model alone left 0.73 here, the cells 0.43)
    assert orientation_shading(proof, got, n, n_chart, delta_e00(proof, got))["delta_e00"]["mean"] < 0.6
    dark = got.copy()
    dark[:, 0] -= 5.0
    assert orientation_shading(proof, dark, n, n_chart, delta_e00(proof, dark))["delta_e00"]["mean"] > 3.0
    hue = got.copy()
    hue[:, 1:] += 5.0
    assert orientation_shading(proof, hue, n, n_chart, delta_e00(proof, hue))["delta_e00"]["mean"] > 3.0
