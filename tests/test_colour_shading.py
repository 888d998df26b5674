"""Colour under a directional light: the shading that follows the orientation taken out, an ink's error kept."""

from __future__ import annotations

import numpy as np
import pytest

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
    r = orientation_shading(proof, got, n, n_chart, delta_e00(proof, got))[0]
    assert r["delta_e00"]["mean"] < 0.05, r
    assert r["mean_abs_delta_l"] > 2.0  # (the shading was there to take out)


LAMP = np.array([0.3, -0.5, 1.0]) / np.linalg.norm([0.3, -0.5, 1.0])
N_CHART = np.array([0.0, 0.0, 1.0])


def _under_the_lamp(v: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """Random inks on surfaces of normals along ``v`` (m, 3), and the photo of them under a lamp
    (ambient plus a clamped cosine, against the chart's light): the proof and the photo, CIELAB."""
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    m = len(n)
    proof = np.column_stack([rng.uniform(35, 80, m), rng.uniform(-50, 50, m), rng.uniform(-50, 50, m)])
    k = (0.35 + 0.65 * np.maximum(n @ LAMP, 0)) / (0.35 + 0.65 * max(N_CHART @ LAMP, 0))
    return proof, xyz_to_lab(lab_to_xyz(proof) * k[:, None])


def test_colour_takes_a_lamps_clamped_shading_out_and_keeps_an_inks_error():
    """A lamp's shading (ambient plus a clamped cosine) is no linear function of the normal: what
    the linear model leaves follows the orientation and is shading too; an ink off by 5 in a* and
    b*, or one ink of two 8 L* too dark, stays. A print 5 L* too dark all over is the light's
    level under a lamp: not judged, and reported as such."""
    rng = np.random.default_rng(8)
    v = rng.normal(size=(20000, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.3
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    proof, got = _under_the_lamp(v, rng)
    n_chart = N_CHART
    # (the linear model alone left 0.73 here, the cells 0.43, the level left free 0.31)
    perfect = orientation_shading(proof, got, n, n_chart, delta_e00(proof, got))[0]
    assert perfect["delta_e00"]["mean"] < 0.6 and perfect["directional"] and not perfect["level"]["judged"]
    assert abs(perfect["level"]["delta_l"]) < 0.5
    hue = got.copy()
    hue[:, 1:] += 5.0
    assert orientation_shading(proof, hue, n, n_chart, delta_e00(proof, hue))[0]["delta_e00"]["mean"] > 3.0
    one = got.copy()
    one[::2, 0] -= 8.0
    assert orientation_shading(proof, one, n, n_chart, delta_e00(proof, one))[0]["delta_e00"]["mean"] > 3.0
    dark = got.copy()
    dark[:, 0] -= 5.0
    level = orientation_shading(proof, dark, n, n_chart, delta_e00(proof, dark))[0]["level"]
    assert level["delta_l"] == pytest.approx(-5.0, abs=0.5) and not level["judged"]


def test_a_part_seen_from_behind_its_lamp_is_judged_without_the_lights_level():
    """A part seen from behind its lamp: the linear model's light at the chart's normal is an
    extrapolation (a clamped cosine's log is no linear function), which put a perfect print 1.3
    ΔE00 off here, the cow seen from behind 4.3. Under a directional light the level is left
    free, and a real ink error in a* and b* stays."""
    rng = np.random.default_rng(3)
    v = rng.normal(size=(20000, 3))
    v[:, 1] = np.abs(v[:, 1]) + 0.8  # turned away from the lamp (its y is negative)
    v[:, 2] = np.abs(v[:, 2])
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    proof, got = _under_the_lamp(v, rng)
    n_chart = N_CHART
    r = orientation_shading(proof, got, n, n_chart, delta_e00(proof, got))[0]
    assert r["directional"] and r["delta_e00"]["mean"] < 0.6, r
    assert r["level"]["delta_l"] < -1.0  # (what the extrapolated level would have called ink)
    # (the same light on inks off by 3.5 in a* and 4.5 in b*: the photo's XYZ over the proof's)
    off = xyz_to_lab(lab_to_xyz(proof + [0.0, 3.5, 4.5]) * (lab_to_xyz(got) / lab_to_xyz(proof))[:, 1:2])
    assert orientation_shading(proof, off, n, n_chart, delta_e00(proof, off))[0]["delta_e00"]["mean"] > 3.0
