"""The dense field's parts, against what is known: slides, edges, photos coarser than the grid, the stated limit.

Each test builds its images from a known truth (a texture moved by a known slide, edges of
known directions, a film placed by a known similarity) and checks the figure validate reports.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from test_uncertainty import shifted, texture

from workbench.validate import dense, detection, placement


def test_a_photo_coarser_than_the_grid_is_compared_at_its_own_resolution():
    # the print on a grid three times finer than the photo: the photo (noise in its own pixels)
    # upsampled onto the grid as the warp does. The flow at the photo's resolution finds the
    # slide to a sixth of a photo pixel, and its uncertainty, counting one noise sample per
    # photo pixel and the photo's own floor, is not an underestimate
    rng = np.random.default_rng(7)
    k = 3
    fine = texture((480, 480), seed=8, sigma=6.0, contrast=25.0)
    moved = shifted(fine, 1.2, -0.9)
    coarse = cv2.resize(moved, (160, 160), interpolation=cv2.INTER_AREA)
    coarse += rng.normal(0.0, 8.0, coarse.shape).astype(np.float32)
    photo = cv2.resize(coarse, (480, 480), interpolation=cv2.INTER_LINEAR)
    assert dense.flow_factor(1.0 / k) == k and dense.flow_factor(1.0) == 1
    reg = float(k)
    rs, ps = cv2.GaussianBlur(fine, (0, 0), reg), cv2.GaussianBlur(photo, (0, 0), reg)
    scored = np.ones(fine.shape, bool)
    m = dense.dense_flow(rs, ps, scored, factor=k)
    inner = (slice(60, -60), slice(60, -60))
    err = m[inner] - np.array([1.2, -0.9], np.float32)
    measured = float(np.sqrt((err**2).mean(axis=-1).mean()))
    assert measured < 0.5  # grid px: a sixth of a photo pixel
    pred_s = cv2.GaussianBlur(moved, (0, 0), reg)
    fp = np.full(fine.shape, 1.0 / k, np.float32)
    corr = dense.noise_correlation(reg, fp)
    floor = dense.flow_floor(fp, k)
    win = dense.TENSOR_SIGMA_PX * k
    weak, strong, *_ = dense.flow_uncertainty(pred_s, ps, scored, win, reg, corr, floor)
    predicted = float(np.sqrt(np.median((weak**2 + strong**2)[inner]) / 2))
    assert predicted >= 0.65 * measured, (measured, predicted)
    # (a clean synthetic photo errs less than a rendered one: here the photo's floor, measured on
    # rendered photos, is most of the prediction)
    assert predicted == pytest.approx(dense.PHOTO_FLOOR_PX * k, rel=0.25)


def test_a_windows_slide_combines_the_edges_it_holds():
    # lines in two directions: each pixel on a line knows only the component across it, and
    # the flow along it is a guess (here 3 px of nonsense). The window's least-squares slide,
    # through the pixels' gradients, is the true one
    H = W = 200
    img = np.full((H, W), 60.0, np.float32)
    for t in range(10, W, 24):
        cv2.line(img, (t, 0), (t + 60, H - 1), 200.0, 3)
        cv2.line(img, (0, t), (W - 1, t + 20), 200.0, 3)
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    true = np.array([0.8, -0.5], np.float32)
    gx, gy = cv2.Sobel(img, cv2.CV_32F, 1, 0), cv2.Sobel(img, cv2.CV_32F, 0, 1)
    g = np.stack([gx, gy], axis=-1)
    n = g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-6)
    along = np.stack([-n[..., 1], n[..., 0]], axis=-1)
    flow = (true * n).sum(-1, keepdims=True) * n + 3.0 * along  # across the edge right, along it wrong
    v = dense.tensor_weighted_flow(img, flow.astype(np.float32), 12.0)
    err = np.linalg.norm(v[50:-50, 50:-50] - true, axis=-1)
    assert np.percentile(err, 95) < 0.1
    # where the lines are, the flow's own vector was 3 px off
    on = np.linalg.norm(g, axis=-1)[50:-50, 50:-50] > 100
    assert np.linalg.norm(flow[50:-50, 50:-50] - true, axis=-1)[on].mean() > 2.0


def test_the_colours_flow_drops_a_thin_wiggle_and_keeps_a_slid_disc():
    # a scratch's flow wiggle (0.7 mm wide, 8 px of nonsense) goes; a bubble's slide (a disc of
    # 6 mm slid 2 px) stays, its rim where it was
    px_per_mm = 10.0
    flow = np.zeros((300, 300, 2), np.float32)
    flow[148:155, 20:280, 1] = 8.0
    ii, jj = np.indices((300, 300))
    disc = np.hypot(ii - 80.0, jj - 200.0) < 30
    flow[disc, 0] = 2.0
    med = dense.median_flow(flow, px_per_mm)
    assert np.abs(med[140:166, 40:260, 1]).max() < 0.5
    inside = np.hypot(ii - 80.0, jj - 200.0) < 24
    outside = (np.hypot(ii - 80.0, jj - 200.0) > 36) & (np.hypot(ii - 80.0, jj - 200.0) < 50)
    assert np.abs(med[inside, 0] - 2.0).max() < 0.05 and np.abs(med[outside, 0]).max() < 0.05


def test_the_explained_share_is_taken_in_floats_on_the_flows_own_images():
    # the normalised images the flow compares are uint8: their differences must not wrap
    ref = texture((160, 160), seed=11, sigma=2.0)
    photo = shifted(ref, 2.0, 0.0) + np.random.default_rng(12).normal(0, 1.0, ref.shape).astype(np.float32)
    m, r, p = dense.dense_flow(ref, photo, np.ones(ref.shape, bool), normalised=True)
    assert r.dtype == np.uint8
    region = np.zeros(ref.shape, bool)
    region[40:120, 40:120] = True
    assert dense.shift_explained(r, p, m, region) > 0.9
    # on a grid reduced for the flow (the images at its resolution, the region on the full grid)
    big_ref, big_photo = (cv2.resize(a, (320, 320), interpolation=cv2.INTER_CUBIC) for a in (ref, photo))
    m2, r2, p2 = dense.dense_flow(big_ref, big_photo, np.ones((320, 320), bool), normalised=True, factor=2)
    assert r2.shape == (160, 160)
    big_region = cv2.resize(region.astype(np.uint8), (320, 320), interpolation=cv2.INTER_NEAREST) > 0
    assert dense.shift_explained(r2, p2, m2, big_region, 2) > 0.9


@pytest.mark.parametrize("with_full", [False, True])
def test_the_film_is_placed_from_edges_alone(with_full):
    # a logo's outline: edges in every direction, each pixel the component across its edge of
    # the film's known misregistration (offset 0.3, -0.2 mm, rotation 0.2°, scale 0.1 %)
    ppm, rows, cols = 10.0, 400, 600
    c = np.array([cols, rows]) / ppm / 2
    # (fit_film's convention: the content designed at p shows at p' with p = M p' + t, a film
    # rotated by θ and scaled by k has M = R(θ) / k)
    a = np.radians(0.2)
    M = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) / 1.001
    d = np.array([0.3, -0.2])
    t = M @ d  # m at the centre: M⁻¹ t' = d
    ii, jj = np.indices((rows, cols))
    y = np.stack([jj + 0.5, ii + 0.5], axis=-1) / ppm - c
    m = y @ (np.eye(2) - M).T + t  # print mm
    rng = np.random.default_rng(3)
    theta = rng.uniform(0, np.pi, (rows, cols))
    n = np.stack([np.cos(theta), np.sin(theta)], axis=-1).astype(np.float32)
    texture_ = np.zeros((rows, cols), np.uint8)
    rings = (np.hypot(y[..., 0] - 5, y[..., 1]) % 6 < 0.6) | (np.abs(y[..., 0] + 12) < 0.3)
    texture_[rings] = 1
    if with_full:
        texture_[::7, ::7] = 2
    shift_px = ((m * n).sum(-1, keepdims=True) * n * ppm).astype(np.float32)
    shift_px[texture_ == 2] = (m * ppm)[texture_ == 2]
    flow_px = (m * ppm).astype(np.float32)
    flow_px[texture_ == 1] = shift_px[texture_ == 1] + 5.0 * np.stack([-n[..., 1], n[..., 0]], -1)[texture_ == 1]
    sigma = np.full((rows, cols), 0.01, np.float32)
    dr = dense.DenseResult(
        None, None, shift_px, None, None, None, None, [], 0.0, flow_px, texture_, sigma,
        window_px=3.0, normal_dir=np.where((texture_ == 1)[..., None], n, 0.0).astype(np.float32),
    )  # fmt: skip

    class Grid:
        px_per_mm = ppm
        surface_per_print = np.ones((rows, cols), np.float32)

    got = placement.dense_placement(dr, Grid, 0.05, (cols / ppm, rows / ppm))
    film = got["film"]
    assert film is not None and got["windows"] > 20
    assert np.allclose(film["offset_mm"], d, atol=1e-3)
    assert film["rotation_deg"] == pytest.approx(0.2, abs=0.01) and film["scale_pct"] == pytest.approx(0.1, abs=0.01)
    assert got["uncertainty_mm"] < 0.02


def test_the_stated_limit_is_a_slide_in_any_direction():
    weak = np.array([[0.01, 0.5, np.inf, 0.03]], np.float32)
    window = np.array([[0.02, 0.02, 0.5, np.inf]], np.float32)
    two_way = np.array([[True, True, False, True]])
    measurable = np.ones((1, 4), bool)
    lim = detection.shift_limit(0.2, 3.0, weak, window, two_way, measurable, 0.0667)
    # the better of the pixel's full vector and the window's slide; nothing where neither measures
    assert lim[0, 0] == pytest.approx(0.23) and lim[0, 1] == pytest.approx(0.26)
    assert np.isnan(lim[0, 2]) and lim[0, 3] == pytest.approx(0.29)
    # a window that answers half a slide finds one of twice its limit; the pixel's own is as before
    half = detection.shift_limit(0.2, 3.0, weak, window, two_way, measurable, 0.0667, window_gain=0.5)
    assert half[0, 0] == pytest.approx(0.23) and half[0, 1] == pytest.approx(0.52)
    # a window along a barely turning edge answers a twentieth of a slide: it finds only a large one
    gain = np.array([[1.0, 0.05, 1.0, 1.0]], np.float32)
    along = detection.shift_limit(0.2, 3.0, weak, window, two_way, measurable, 0.0667, window_gain=gain)
    assert along[0, 1] == pytest.approx(0.26 / 0.05) and along[0, 3] == pytest.approx(0.29)
    # which share a window gets: its texture's two directions within a factor of 10, or not
    got = dense.window_gain(np.array([[4.0, 4.0]], np.float32), np.array([[1.0, 0.2]], np.float32))
    assert got[0, 0] == pytest.approx(dense.WINDOW_GAIN) and got[0, 1] == pytest.approx(dense.WINDOW_GAIN_ALONG_EDGE)
    # a bubble is above the limit where half its footprint finds its slide, ink gone where three
    # quarters do, and what is found exceeds the verdict's area
    fp = np.zeros((10, 10), bool)
    fp[2:8, 2:8] = True
    um = np.full((10, 10), detection.NONE_UM, np.uint16)
    um[2:5, 2:8] = 300
    drop = np.zeros((10, 10), np.uint8)
    drop[2:6, 2:8] = 1  # two thirds of it
    area = {"area_mm2": 10.0, "max_defect_mm2": 4.0}
    assert detection.above_limit("bubble", fp, um, drop, 0.5, **area)[0]
    assert not detection.above_limit("bubble", fp, um, drop, 0.25, **area)[0]
    assert not detection.above_limit("dropout", fp, um, drop, **area)[0]
    drop[6:8, 2:8] = 1
    assert detection.above_limit("scratch", fp, um, drop, **area)[0]
    # all of a 3 mm² dropout found is still under a verdict of 4 mm²
    assert not detection.above_limit("dropout", fp, um, drop, area_mm2=3.0, max_defect_mm2=4.0)[0]


def test_a_scratch_found_in_pieces_across_a_checker_is_ink_gone_and_a_glint_is_light():
    # a checker of 8 px squares (a millimetre at 200 dpi), a line along row 60 blurred by a coarse
    # photo: its core (rows 59 to 61) takes 0.75 of the step to the film, its flanks 0.4
    H, W, film = 120, 400, 250.0
    ii, jj = np.indices((H, W))
    grey = np.where(((ii // 8) + (jj // 8)) % 2 == 0, 60.0, 200.0).astype(np.float32)
    pred = np.repeat(grey[..., None], 3, axis=2)
    share = np.zeros((H, W), np.float32)
    share[57:64, 20:380] = 0.4
    share[59:62, 20:380] = 0.75
    scratch = pred * (1 - share[..., None]) + film * share[..., None]
    glint = np.where(share[..., None] > 0, np.minimum(0.9 * pred + 60.0 * share[..., None] / 0.75, 255.0), pred)
    # found in pieces, one per square: at the checker's edges the limit allows for half a
    # pixel's placement of the edge, and the line is lost there
    thin = (share > 0) & (np.abs(((jj + 4) % 8) - 4) >= 2)
    core = share >= 0.5
    pieces = dense.thin_told(thin, scratch, pred)
    assert set(np.unique(pieces[thin])) == {3}  # each piece over uniform ink: not told
    told = dense.thin_told(thin, scratch, pred, core, gap_px=6)
    assert set(np.unique(told[thin])) == {2}  # one line across the checker: the film shows, ink gone
    # (its flanks alone keep 0.6 of the ink's contrast: judged on them, the line would be light)
    assert set(np.unique(dense.thin_told(thin & ~core, scratch, pred, None, gap_px=6)[thin & ~core])) == {1}
    told = dense.thin_told(thin, glint.astype(np.float32), pred, core, gap_px=6)
    assert set(np.unique(told[thin])) == {1}  # light added over the ink keeps its variation
