"""The photometric model: the bare film as the ink around shows it, and light against ink gone by likelihood."""

from __future__ import annotations

import cv2
import numpy as np

from workbench.validate import photometric as pm

NOISE = 2.0  # grey levels
COLOUR_TOL = 40.0  # the colour test's broad allowance (dense.COLOUR_TOL), grey levels


def checker_rgb(shape=(160, 160), square=10, tint=(200.0, 180.0, 160.0)):
    """A pale tinted checker at 60 % contrast (grey levels, float32 RGB)."""
    ii, jj = np.indices(shape)
    dark = ((ii // square + jj // square) % 2).astype(np.float32)[..., None]
    return np.asarray(tint, np.float32) * (1.0 - 0.6 * dark)


def blob(shape, centre, sigma):
    ii, jj = np.indices(shape)
    return np.exp(-((ii - centre[1]) ** 2 + (jj - centre[0]) ** 2) / (2.0 * sigma**2)).astype(np.float32)


def judged(photo, pred, film_level=250.0, film_sigma=0.05, additive=True):
    """Each region of the colour residual judged; per pixel the hypothesis (str array, "" off the regions).

    ``additive``: the film adds light of its own (glossy) or only scatters what reaches its ink (matte).
    """
    film = np.full(pred.shape, film_level, np.float32)
    step = film - pred
    alpha = np.clip(((photo - pred) * step).sum(axis=2) / (step * step).sum(axis=2), 0.0, 1.0)
    res = np.abs(photo - pred).max(axis=2)
    limit = np.full(res.shape, COLOUR_TOL + 3 * NOISE, np.float32)
    bad = res > limit
    gone = bad & (alpha > 0.5)
    v = pm.judge_regions(
        bad, gone, photo.astype(np.float32), pred, film, np.ones(3, np.float32), limit, NOISE,
        np.full(res.shape, film_sigma, np.float32), ~bad, np.full(res.shape, 1.0, np.float32), 1.0, 3.0, additive,
    )  # fmt: skip
    out = np.full(res.shape, "", object)
    for r, j in v.judgements.items():
        out[v.labels == r] = j["hypothesis"]
    assert (out[v.light] == "light").all() and np.isin(out[v.not_told], ["not told"]).all()
    return bad, out


def test_a_highlight_over_textured_ink_is_light():
    # a glossy film's highlight: up to 120 grey levels of white light added over a checker; the
    # checker stays in the photo (at a gain): the ink is there
    pred = checker_rgb()
    photo = np.clip(0.9 * pred + 120.0 * blob(pred.shape[:2], (80, 80), 10.0)[..., None], 0, 255)
    bad, h = judged(photo, pred)
    assert bad.sum() > 200  # the colour test alone would call it a defect
    assert (h[bad] == "light").mean() > 0.95


def test_ink_gone_over_textured_ink_is_ink_gone():
    # a dropout: the bare film (250) in a disc of radius 12 px; the checker's texture is gone
    pred = checker_rgb()
    photo = pred.copy()
    ii, jj = np.indices(pred.shape[:2])
    disc = np.hypot(ii - 80.0, jj - 80.0) < 12
    photo[disc] = 250.0
    # (the model is the design blurred like the photo)
    photo, pred = cv2.GaussianBlur(photo, (0, 0), 1.0), cv2.GaussianBlur(pred, (0, 0), 1.0)
    bad, h = judged(photo, pred)
    assert (h[disc & bad] == "ink gone").mean() > 0.95 and not (h == "light").any()


def test_a_soft_sheen_over_flat_ink_is_light_and_a_thin_scratch_through_it_is_not():
    # flat pale ink: a broad sheen steps 60 % of the way to white and never shows the bare film
    # alone in its core (ink gone there would); a scratch 3 px wide of bare film, narrower than
    # the blur lets reach the film, is not light
    pred = np.full((160, 160, 3), (150.0, 130.0, 170.0), np.float32)
    sheen = blob(pred.shape[:2], (50, 80), 14.0)[..., None]
    photo = pred + 0.6 * sheen * (250.0 - pred)
    photo[78:81, 110:150] = 250.0
    photo = cv2.GaussianBlur(photo, (0, 0), 1.0)
    bad, h = judged(photo, pred)
    assert (h[:, :90][bad[:, :90]] == "light").mean() > 0.95
    assert bad[78:81, 110:150].mean() > 0.9 and not (h[:, 100:] == "light").any()


def test_a_glint_over_coloured_ink_is_light_and_a_scratch_there_is_ink_gone():
    # saturated green ink: a small glint (white light added, 90 grey levels at its peak, 2 px)
    # whitens the green, where ink gone shows the film's colour through it; a scratch 3 px wide
    # of bare film beside it keeps that direction (a glint on a scanned lion's green mane was a
    # 4.3 mm² "missing" on a perfect glossy photo)
    pred = np.full((160, 160, 3), (40.0, 150.0, 80.0), np.float32)
    photo = pred + 90.0 * blob(pred.shape[:2], (50, 80), 2.0)[..., None]
    photo[78:81, 110:150] = 250.0
    photo = cv2.GaussianBlur(photo, (0, 0), 1.0)
    bad, h = judged(photo, pred)
    assert bad[:, :90].sum() >= 5 and (h[:, :90][bad[:, :90]] == "light").all()
    assert (h[78:81, 110:150] == "ink gone").mean() > 0.9
    # over neutral ink the two directions are one: the photo cannot tell them
    grey = np.full((160, 160, 3), 120.0, np.float32)
    photo = cv2.GaussianBlur(grey + 100.0 * blob(grey.shape[:2], (50, 80), 2.0)[..., None], (0, 0), 1.0)
    bad, h = judged(photo, grey)
    assert bad.any() and (h[bad] == "not told").all()


def noisy(photo, seed=0):
    """The photo with the photo's noise (NOISE grey levels per channel)."""
    return photo + np.random.default_rng(seed).normal(0.0, NOISE, photo.shape).astype(np.float32)


def test_on_a_matte_film_a_dropout_over_dark_textured_ink_is_ink_gone_that_light_added_would_not_tell():
    # a dark photograph's ink (a checker of 50 and 20 grey levels, 6 px squares) and a dropout of
    # the bare film in a disc of radius 12 px: in linear light the ink's texture is a few hundredths
    # of the film's level, so white light added over the ink matches the film as well as the film
    # does; a matte film adds no light, and light that reaches its ink scales the ink's texture
    dark = checker_rgb(square=6, tint=(50.0, 40.0, 35.0))
    ii, jj = np.indices(dark.shape[:2])
    disc = np.hypot(ii - 80.0, jj - 80.0) < 12
    photo = dark.copy()
    photo[disc] = 250.0
    photo, pred = noisy(cv2.GaussianBlur(photo, (0, 0), 1.0)), cv2.GaussianBlur(dark, (0, 0), 1.0)
    bad, glossy = judged(photo, pred)
    assert bad[disc].mean() > 0.9 and (glossy[disc & bad] == "not told").all()
    bad, matte = judged(photo, pred, additive=False)
    assert (matte[disc & bad] == "ink gone").all()


def test_on_a_matte_film_light_is_a_gain_of_the_ink_within_the_shading_allowance():
    # a region's core over textured ink: more light on it (a gain of 1.5, texture kept) is light,
    # and the bare film in its place is ink gone
    rng = np.random.default_rng(5)
    ii, jj = np.indices((20, 20))
    xy = np.stack([ii.ravel(), jj.ravel()], axis=1).astype(np.float64)
    ink = checker_rgb((20, 20), square=4, tint=(120.0, 90.0, 70.0)).reshape(-1, 3)
    film = np.full(ink.shape, 250.0, np.float32)

    def judge(photo):
        photo = np.clip(photo + rng.normal(0.0, NOISE, photo.shape), 0, 255).astype(np.float32)
        args = (ink, film, np.ones(3, np.float32), NOISE, 0.02, 0.05, float(len(ink)), 3.0, xy)
        return pm.judge_region(photo, *args, additive=False)

    lit = judge(pm.grey_levels(pm.linear(ink) * 1.5))
    assert lit.hypothesis == "light" and abs(lit.gain - 1.5) < 0.05
    assert judge(film.copy()).hypothesis == "ink gone"
    # (and three times the light of a blue ink over a sharp-edged disc: no gain within the allowance
    # explains it, and the region stays a colour defect)
    blue = np.full((160, 160, 3), (60.0, 120.0, 180.0), np.float32)
    disc = np.hypot(*(np.indices((160, 160)) - 80.0)) < 20
    photo = blue.copy()
    photo[disc] = np.clip(pm.grey_levels(pm.linear(blue[disc]) * 3.0), 0, 255)
    bad, h = judged(noisy(photo), blue, additive=False)
    assert bad[disc].mean() > 0.9 and not (h[disc] == "light").any()


def test_a_band_brighter_than_the_film_is_light_and_one_at_the_film_is_not_told():
    # the lion's perfect glossy photo at 6000 x 4000: a glint along a ridge over pale grey ink
    # (150) on a film the lamp lights to 200 reached 245, beyond the film, in a band with the
    # sharp rim of ink gone and the same (neutral) direction: only its brightness tells it
    pred = np.full((160, 160, 3), 150.0, np.float32)
    band = np.zeros(pred.shape[:2], bool)
    band[70:82, 20:140] = True

    def hyp(level, film_level, film_sigma=0.05):
        photo = pred.copy()
        photo[band] = level
        bad, h = judged(cv2.GaussianBlur(photo, (0, 0), 1.0), pred, film_level, film_sigma)
        assert bad[band].mean() > 0.8
        return h[band & bad]

    assert (hyp(245.0, 200.0) == "light").mean() > 0.95
    # at the film's level, flat and neutral: light added to pale neutral ink looks the same, and the
    # photo alone cannot tell (the command asks where the lamp is mirrored)
    assert (hyp(200.0, 200.0) == "not told").mean() > 0.95
    # the film's estimate 9 % low (in linear light 20 %, 4 of its sigmas): not light, not told
    assert (hyp(205.0, 188.0) == "not told").mean() > 0.95
    # where the film is as uncertain as over dark ink (a quarter in log), 245 is within it
    assert (hyp(245.0, 200.0, 0.25) == "not told").mean() > 0.95


def test_the_film_is_measured_by_the_ink_around_it_with_its_uncertainty():
    # a shading field over a design of pale and dark ink: the photo is A · F in linear light, F
    # the film under the shading (smooth, 0.3 to 0.8), plus noise; pale ink tells the film to a
    # few per cent, dark ink (0.01 linear) much less well, and the uncertainty says so
    rng = np.random.default_rng(0)
    H, W = 200, 300
    ii, jj = np.indices((H, W))
    F = (0.3 + 0.5 * jj / W).astype(np.float32)
    A = np.where(jj < 150, 0.6, 0.01).astype(np.float32) * (1.0 + 0.3 * ((ii // 8 + jj // 8) % 2))
    design = pm.grey_levels(np.repeat(A[..., None], 3, axis=2))
    photo = pm.grey_levels(np.repeat((A * F)[..., None], 3, axis=2)) + rng.normal(0, NOISE, (H, W, 3))
    photo = np.clip(photo, 0, 255).astype(np.float32)
    fit = pm.film_level(photo, design, np.ones((H, W), bool), NOISE, 10.0, np.full((H, W, 3), 255.0, np.float32))
    got = pm.linear(fit.film)[..., 1]
    err = np.log(got / F)
    pale, dark = (slice(20, 180), slice(20, 130)), (slice(20, 180), slice(170, 280))
    assert np.abs(err[pale]).max() < 0.05 and np.abs(err[dark]).max() < 0.3
    assert np.median(fit.sigma[dark]) > 2 * np.median(fit.sigma[pale])
    # the truth within 3 sigma nearly everywhere
    assert (np.abs(err) < 3 * fit.sigma)[20:180, 20:280].mean() > 0.95


def test_clipping_is_light_only_where_the_film_cannot_clip():
    film = pm.FilmLevel(np.full((10, 20, 3), 180.0, np.float32), np.full((10, 20), 0.05, np.float32))
    photo = np.full((10, 20, 3), 120.0, np.float32)
    photo[:, :10] = 255.0
    over = pm.beyond_film(photo, film, NOISE, 3.0)
    assert over[:, :10].all() and not over[:, 10:].any()
    # a film the photo shows at 245 may clip itself: a clipped pixel is then no proof of light
    film = pm.FilmLevel(np.full((10, 20, 3), 245.0, np.float32), np.full((10, 20), 0.05, np.float32))
    assert not pm.beyond_film(photo, film, NOISE, 3.0).any()
    # and where the film is unknown, nothing is beyond it
    film = pm.FilmLevel(np.full((10, 20, 3), 100.0, np.float32), np.full((10, 20), pm.UNKNOWN, np.float32))
    assert not pm.beyond_film(photo, film, NOISE, 3.0).any()


def test_a_region_with_no_core_is_judged_whole():
    # a region 3 px wide has no pixel clear of its blurred rim: all of it is judged
    region = np.zeros((20, 40), bool)
    region[9:12, 5:35] = True
    core = pm.region_core(region, 1.0)
    assert (core == region).all()
    wide = np.zeros((40, 40), bool)
    wide[5:35, 5:35] = True
    core = pm.region_core(wide, 1.0)
    assert core.sum() < wide.sum() and core[20, 20] and not core[5, 5]


def test_where_the_print_is_squeezed_the_film_window_keeps_its_surface_size():
    # a flat part mapped to the grid at 1 mm per grid pixel, except a band of columns squeezed ten
    # times (10 mm of surface per grid pixel, as a dome's cap on a conformal print); the shading
    # follows the surface: a film level varying along x of the surface, smooth over 60 mm. Over
    # the squeezed band it varies within a few grid pixels, and a window of the usual size in grid
    # pixels averages it away
    H, W = 120, 200
    step = np.where((np.arange(W) >= 85) & (np.arange(W) < 115), 10.0, 1.0)
    x = np.concatenate([[0.0], np.cumsum(step)[:-1]])  # mm of surface at each grid column
    X = np.zeros((H, W, 3))
    X[..., 0] = x[None, :]
    X[..., 1] = np.arange(H)[:, None]
    share = pm.window_shares(X)
    assert np.allclose(share[:-1, 86:114], 0.1) and np.allclose(share[:-1, :80], 1.0)
    F = (0.45 + 0.35 * np.sin(2 * np.pi * x / 400.0)).astype(np.float32)[None, :].repeat(H, axis=0)
    rng = np.random.default_rng(1)
    ii, jj = np.indices((H, W))
    A = (0.5 + 0.3 * ((ii // 4 + jj // 4) % 2)).astype(np.float32)
    design = pm.grey_levels(np.repeat(A[..., None], 3, axis=2))
    photo = pm.grey_levels(np.repeat((A * F)[..., None], 3, axis=2)) + rng.normal(0, NOISE, (H, W, 3))
    photo = np.clip(photo, 0, 255).astype(np.float32)
    fallback = np.full((H, W, 3), 255.0, np.float32)
    ones = np.ones((H, W), bool)
    wide = pm.film_level(photo, design, ones, NOISE, 10.0, fallback)
    local = pm.film_level(photo, design, ones, NOISE, 10.0, fallback, window_share=share)
    band = (slice(10, 110), slice(90, 110))
    err_wide = np.abs(np.log(pm.linear(wide.film)[..., 1] / F))[band]
    err_local = np.abs(np.log(pm.linear(local.film)[..., 1] / F))[band]
    # (the usual window errs by a factor of two there, far beyond its stated uncertainty; the
    # window of the surface's size by a few per cent, within its own)
    assert np.median(err_wide) > 0.3 and (err_wide < 3 * wide.sigma[band]).mean() < 0.5
    assert np.median(err_local) < 0.1 and (err_local < 3 * local.sigma[band]).mean() > 0.95
    # where the print is not squeezed the two are the same
    assert np.array_equal(wide.film[:, :60], local.film[:, :60])
