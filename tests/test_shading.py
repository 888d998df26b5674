"""The light a surface receives as a function of its normal: exact recovery, robustness, and its use by colour."""

from __future__ import annotations

import numpy as np

from workbench.validate.photometric import grey_levels, linear
from workbench.validate.shading import fit_irradiance, fit_shading, sh_basis, shaded, shading_factor


def _normals(n: int, seed: int = 0) -> np.ndarray:
    """Unit normals over the upper hemisphere and a little below (a part seen from above)."""
    v = np.random.default_rng(seed).normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) - 0.2
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_fit_irradiance_recovers_a_second_order_light_despite_shadows():
    rng = np.random.default_rng(1)
    n = _normals(20000)
    truth = np.array([0.6, 0.1, -0.2, 0.35, 0.05, -0.04, 0.03, 0.02, 0.06])
    albedo = rng.uniform(0.03, 0.9, len(n))
    observed = albedo * (sh_basis(n) @ truth)
    # a cast shadow over a fifth of the samples: no function of the normal explains it
    shadow = rng.random(len(n)) < 0.2
    observed[shadow] *= 0.3
    coef, inlier = fit_irradiance(albedo, observed, n)
    # (the shadowed fifth is cast out, the rest kept)
    assert (~inlier[shadow]).mean() > 0.99 and inlier[~shadow].mean() > 0.99
    # (the light it predicts, not its coefficients: over a hemisphere the harmonics are nearly
    # dependent, and the ridge moves the weights along what the normals do not tell apart)
    E, E_true = sh_basis(n) @ coef, sh_basis(n) @ truth
    assert np.abs(E / E_true - 1).max() < 1e-3


def test_fit_irradiance_on_a_flat_part_predicts_its_one_light():
    rng = np.random.default_rng(6)
    v = np.tile([0.0, 0.0, 1.0], (5000, 1)) + rng.normal(0, 0.01, (5000, 3))
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    albedo = rng.uniform(0.03, 0.9, len(n))
    coef, _ = fit_irradiance(albedo, albedo * 0.8 + rng.normal(0, 0.003, len(n)), n)
    assert np.abs(sh_basis(n) @ coef / 0.8 - 1).max() < 2e-3


def test_fit_irradiance_needs_enough_lit_samples():
    n = _normals(50)
    assert fit_irradiance(np.full(50, 0.5), np.full(50, 0.5), n) is None
    # dark ink says nothing of the light
    n = _normals(5000)
    assert fit_irradiance(np.full(5000, 0.01), np.full(5000, 0.01), n) is None


def test_shading_factor_is_the_irradiance_relative_to_its_median_and_one_off_the_part():
    n = _normals(600).reshape(20, 30, 3).astype(np.float32)
    n[0, :5] = np.nan
    coef = np.array([[0.6, 0.1, -0.2, 0.35, 0.05, -0.04, 0.03, 0.02, 0.06]] * 3)
    f = shading_factor(n, coef)
    on = np.isfinite(n).all(axis=-1)
    E = sh_basis(n[on]) @ coef[0]
    np.testing.assert_allclose(f[on][:, 1], np.clip(E / np.median(E), 0.01, None), rtol=1e-5)
    assert (f[~on] == 1).all()
    assert (shading_factor(n, None) == 1).all()


def test_the_photo_of_a_shaded_print_is_predicted_from_the_normals():
    """A photo made as design times a second-order light (in linear light): the fitted shading,
    applied to the design, gives the photo back to a grey level, up to the photo's exposure."""
    rng = np.random.default_rng(2)
    H, W = 120, 160
    # a dome's normals, as a surface has them: neighbours alike
    y, x = np.mgrid[-1 : 1 : H * 1j, -1.3 : 1.3 : W * 1j]
    n = np.stack([x, y, np.full_like(x, 1.2)], axis=-1)
    n = (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)
    design = rng.uniform(40, 250, (H, W, 3)).astype(np.float32)
    shape = np.array([0.0, 0.1, 0.0, 0.4, 0.0, 0.05, 0.0, 0.02, 0.05])
    light = np.stack([shape, shape, 0.9 * shape])
    light[:, 0] = [0.5, 0.45, 0.4]
    E = np.stack([sh_basis(n) @ light[c] for c in range(3)], axis=-1).astype(np.float32)
    photo = grey_levels(linear(design) * E)
    coef = fit_shading(photo, design, n, np.ones((H, W), bool))
    f = shading_factor(n, coef)
    # (the factor is relative to its median: the exposure is one number per channel)
    exposure = np.median(linear(photo) / np.maximum(linear(shaded(design, f)), 1e-6), axis=(0, 1))
    predicted = grey_levels(linear(shaded(design, f)) * exposure)
    assert np.abs(predicted - photo).max() < 1.0


def test_a_light_that_explains_half_the_part_is_no_light():
    """Half of a part painted over: nine harmonics per channel can bend to call the paint the
    design's shading. The fit, started from an even light with a bounded scale, casts the paint out,
    explains too little of the part, and gives no light (the local fit works alone, as before)."""
    rng = np.random.default_rng(7)
    H, W = 100, 200
    # a ridge: the left half faces one way, the right half another
    t = np.linspace(-1.2, 1.2, W)
    n = np.zeros((H, W, 3), np.float32)
    n[..., 0], n[..., 2] = np.sin(t)[None, :], np.cos(t)[None, :]
    design = rng.uniform(40, 250, (H, W, 3)).astype(np.float32)
    E = 0.3 + 0.6 * np.maximum(n[..., 2], 0)[..., None]
    photo = grey_levels(linear(design) * E)
    everywhere = np.ones((H, W), bool)
    assert fit_shading(photo, design, n, everywhere) is not None
    painted = photo.copy()
    painted[:, W // 2 :] = 128.0
    assert fit_shading(painted, design, n, everywhere) is None
    # a tenth painted over is a defect on a part whose light is measured
    tenth = photo.copy()
    tenth[:, : W // 10] = 128.0
    coef = fit_shading(tenth, design, n, everywhere)
    assert coef is not None
    f = shading_factor(n, coef)[:, W // 10 :]
    truth = (E / np.median(E))[:, W // 10 :]
    assert np.abs(f / truth - 1).max() < 0.1
