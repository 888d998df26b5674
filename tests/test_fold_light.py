"""A fold's light: the range of light its turned normals receive, what it explains, and what it hides."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np

from workbench.validate.dense.exposure import _residual
from workbench.validate.dense.light import grid_folds, least_residual_under_light, light_range, taken_along_fold
from workbench.validate.dense.options import DETECT_Z
from workbench.validate.dense.pipeline import _fold_light
from workbench.validate.photometric import grey_levels, linear
from workbench.validate.print_warp import PrintGrid
from workbench.validate.shading import shaded

ALL = np.ones((80, 80), bool)
LAMP = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)


def _lamp_coef(ambient: float = 0.4, direct: float = 0.6) -> np.ndarray:
    """E(n) = ambient + direct · n·l, exactly first order in the harmonics; (3, 9)."""
    c = np.zeros(9)
    c[0], c[1:4] = ambient, direct * LAMP
    return np.tile(c, (3, 1))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_the_light_around_a_ridge_runs_from_its_dark_facet_to_its_bright_one():
    on, start, model, film, _ = _folded_photo(128.0)
    grid = on.grid
    lo, hi = light_range(grid.normal, grid.X, start.light, np.ones((80, 80), bool), 2)
    lo, hi = lo.reshape(80, 80, 3)[..., 0], hi.reshape(80, 80, 3)[..., 0]
    E = lambda nn: 0.4 + 0.6 * (nn @ LAMP)  # noqa: E731
    tilt = np.radians(20.0)
    bright, dark = E(np.array([np.sin(tilt), 0, np.cos(tilt)])), E(np.array([-np.sin(tilt), 0, np.cos(tilt)]))
    own = E(grid.normal[0].astype(np.float64))
    # (the two pixels astride the ridge see both facets' own normals within two pixels: the light
    # around them runs from the dark facet's to the bright one's, exactly; the pixels beside the
    # ridge take both facets' blend)
    for col in (39, 40):
        np.testing.assert_allclose(lo[:, col], dark / own[col], rtol=1e-5)
        np.testing.assert_allclose(hi[:, col], bright / own[col], rtol=1e-5)
    assert (lo <= 1.0).all() and (hi >= 1.0).all()
    # on a plane side, beyond the smooth normal's blend (1.5 mm) and two pixels, the light is the model's
    np.testing.assert_allclose(lo[:, :25], 1.0, atol=1e-5)
    np.testing.assert_allclose(hi[:, :25], 1.0, atol=1e-5)
    np.testing.assert_allclose(hi[:, 55:], 1.0, atol=1e-5)


def test_the_least_residual_under_light_finds_the_light_in_its_range_and_stops_at_its_ends():
    rng = np.random.default_rng(4)
    n = 500
    # (below the photo's clipping at every light tried: a clipped channel tells nothing)
    moved = rng.uniform(20, 120, (n, 3)).astype(np.float32)
    shade = rng.uniform(0.5, 1.5, (n, 3)).astype(np.float32)
    gain = rng.uniform(0.8, 1.1, (n, 3)).astype(np.float32)
    offset = rng.uniform(0, 10, (n, 3)).astype(np.float32)
    light = linear(moved) * shade
    lo = np.full((n, 3), 0.7, np.float32)
    hi = np.full((n, 3), 1.6, np.float32)
    # a light on the path's steps is matched exactly; one beyond its end is matched at the end
    for g in (0.7, np.sqrt(0.7 * 1.6), 1.6):
        target = gain * shaded(moved, shade * np.float32(g)) + offset
        assert least_residual_under_light(target, light, gain, offset, lo, hi).max() < 0.05
    far = gain * shaded(moved, shade * np.float32(2.5)) + offset
    at_end = np.abs(far - (gain * shaded(moved, shade * np.float32(1.6)) + offset)).max(axis=-1)
    np.testing.assert_allclose(least_residual_under_light(far, light, gain, offset, lo, hi), at_end, rtol=1e-5)


def _folded_photo(ink: float):
    """A ridge of 2 x 20° under a lamp from +x: the print of grey ``ink``, photographed by its facets' light.

    The model shades by the smooth normal (the facets' blended over 1.5 mm either side of the
    ridge, as vertex normals blend them over a scan's triangles); the photo shows each facet's
    own light, as a real faceted part does.
    """
    ppm, size = 8.0, 80
    x = (np.arange(size) + 0.5) / ppm
    # (laid out as print_grid lays a print: its rows run down, the flat layout's y up, so that the
    # grid's own derivatives give a normal into the part)
    xx, yy = np.meshgrid(x, x[::-1])
    tilt = np.radians(20.0)
    z = np.tan(tilt) * np.minimum(xx, 10.0 - xx)
    X = np.dstack([xx, yy, z]).astype(np.float32)
    side = np.where(xx < 5.0, -1.0, 1.0)
    facet = _unit(np.dstack([side * np.sin(tilt), 0 * xx, np.full_like(xx, np.cos(tilt))]))
    blend = np.clip((xx - 5.0) / 1.5, -1.0, 1.0)
    smooth = _unit(np.dstack([blend * np.sin(tilt), 0 * xx, np.full_like(xx, np.cos(tilt))])).astype(np.float32)
    coef = _lamp_coef()
    E = lambda nn: (0.4 + 0.6 * (nn @ LAMP))[..., None] * np.ones(3)  # noqa: E731
    shade = (E(smooth)).astype(np.float32)
    print_rgb = np.full((size, size, 3), ink, np.float32)
    grid = PrintGrid(
        X, np.zeros((size, size), np.int32), ppm, 1, np.ones((size, size), np.float32),
        print_rgb.astype(np.uint8), np.zeros((size, size), np.int32), normal=smooth,
    )  # fmt: skip
    photo = shaded(print_rgb, E(facet).astype(np.float32))
    pred = shaded(print_rgb, shade)
    on = SimpleNamespace(grid=grid, pho=photo)
    start = SimpleNamespace(light=coef, shade=shade)
    model = SimpleNamespace(
        gain=grey_levels(shade) / np.float32(255.0),
        offset=np.zeros_like(pred),
        moved=print_rgb,
        pred=pred,
        blur=1.0,
        local_blur=np.ones((size, size), np.float32),
    )
    film = shaded(np.full_like(print_rgb, 255.0), shade)
    return on, start, model, film, np.abs(photo - pred).max(axis=-1)


def test_a_folds_light_explains_the_photo_and_hides_ink_gone_only_where_it_could_reach_the_film():
    for ink, hides in ((245.0, True), (60.0, False)):
        on, start, model, film, off = _folded_photo(ink)
        fold = np.nan_to_num(grid_folds(on.grid)) > 0
        # (a colour test's limit half of what the smooth model misses on the fold at most, so that
        # only the fold's light explains the photo there, and below the ink's step to the film
        # under the model's light, so that only the fold's light lets it pass for the film)
        noise = 0.5
        step = np.abs(film - model.pred).max(axis=-1)[fold].min() - DETECT_Z * noise
        limit = np.full((80, 80), 0.5 * min(off[fold].max(), step), np.float32)
        explains, may_be_film, may_be_line = _fold_light(on, start, model, film, limit, noise, ALL, ALL)
        # (the two pixels astride the ridge take both facets' mean: their own turn is 9°)
        assert fold[:, 36:39].all() and fold[:, 41:44].all() and not fold[:, :20].any()
        # the fold's light explains the photo on the fold (and within its blur's reach: it shows
        # its light too), nowhere else
        near = cv2.dilate(fold.view(np.uint8), np.ones((5, 5), np.uint8)) > 0
        assert explains[fold].all() and not explains[~near].any()
        # pale ink lit from the fold's bright side passes for the film under its dark side: ink gone
        # is not found there; dark ink is nowhere near, and a fold hides neither ink gone nor a
        # scratch on it
        assert may_be_film[fold].all() == hides and may_be_film[fold].any() == hides
        assert not may_be_film[~near].any() and not may_be_line[~near].any()
        if not hides:
            assert not may_be_line.any()
    # without a model of the light, the fold may be anything
    on, start, model, film, _ = _folded_photo(60.0)
    start.light = None
    limit = np.full((80, 80), 8.0, np.float32)
    # (and the photo's pixels within its blur's reach of it, twice its sigma: 2 grid px here)
    near = cv2.dilate(grid_folds(on.grid).view(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert all((m == near).all() for m in _fold_light(on, start, model, film, limit, 2.0, ALL, ALL))


def test_the_least_residual_under_light_is_the_least_of_a_dense_search():
    rng = np.random.default_rng(5)
    n = 20000
    moved = rng.uniform(5, 250, (n, 3)).astype(np.float32)
    light = linear(moved) * rng.uniform(0.3, 1.5, (n, 3)).astype(np.float32)
    gain = rng.uniform(0.7, 1.2, (n, 3)).astype(np.float32)
    offset = rng.uniform(0, 15, (n, 3)).astype(np.float32)
    lo = rng.uniform(0.01, 1.0, (n, 3)).astype(np.float32)
    hi = (lo * np.exp(rng.uniform(0, np.log(100.0), (n, 3)))).astype(np.float32)
    target = rng.uniform(0, 255, (n, 3)).astype(np.float32)
    got = least_residual_under_light(target, light, gain, offset, lo, hi)
    # (the residual as the colour test takes it: a channel clipped in the target where the model is
    # bright too says nothing)
    # a search over 4,001 points of the path: above the true least by at most half a step's move,
    # 534 / 4000 / 2 = 0.07 grey levels (the model moves by at most 534 over the path: see light.py)
    best = np.full(n, np.inf, np.float32)
    for t in np.linspace(0.0, 1.0, 4001, dtype=np.float32):
        g = lo ** (1 - t) * hi**t
        best = np.minimum(best, _residual(target, (gain * grey_levels(light * g) + offset).astype(np.float32)))
    # never below the true least (the search's points lie on the path), and within half a grey
    # level of it (the stated stop)
    assert (got >= best - 0.07).all()
    assert (got - best).max() <= 0.5


def test_a_fold_takes_only_what_the_maps_do_not_find():
    explained = np.ones(6, bool)
    may_be_film = np.array([True, False, True, False, False, False])
    may_be_line = np.array([False, False, True, False, False, True])
    thin = np.array([False, False, True, True, False, False])
    gone = np.array([True, True, True, True, False, False])
    # ink gone where its map finds nothing; ink gone it finds; a scratch its map misses; one it
    # finds; a colour that is no step to the film (it hides no ink gone), whatever the maps
    taken = taken_along_fold(explained, may_be_film, may_be_line, thin, gone)
    assert taken.tolist() == [True, False, True, False, True, True]
    assert not taken_along_fold(~explained, may_be_film, may_be_line, thin, gone).any()


def test_the_folds_reach_is_twice_the_photos_blur_over_the_fold():
    # (a photo blurred 2.5 grid px over the fold, 1 elsewhere: the reach is 5 px, not the median's 2)
    on, start, model, film, _ = _folded_photo(60.0)
    fold = grid_folds(on.grid)
    model.local_blur = np.where(fold, np.float32(2.5), np.float32(1.0))
    start.light = None
    got = _fold_light(on, start, model, film, np.full((80, 80), 8.0, np.float32), 2.0, ALL, ALL)[0]
    assert (got == (cv2.dilate(fold.view(np.uint8), np.ones((11, 11), np.uint8)) > 0)).all()
