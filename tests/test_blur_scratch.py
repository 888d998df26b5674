"""The photo's blur as the camera's, fixed in photo pixels, and the scratch a blurred photo can find."""

import cv2
import numpy as np
import pytest

from workbench.validate.dense.blur import PhotoBlur, estimate_blur
from workbench.validate.dense.lines import line_profile, thin_ink_loss
from workbench.validate.dense.options import SCRATCH_WIDTH_MM


def _texture(shape, seed):
    """A print's detail at every scale down to a pixel: noise smoothed a little, 0 to 255."""
    rng = np.random.default_rng(seed)
    t = cv2.GaussianBlur(rng.normal(0.0, 1.0, shape).astype(np.float32), (0, 0), 0.7)
    return (128.0 + 60.0 * t / t.std()).astype(np.float32)


def test_the_camera_blur_is_found_in_photo_pixels_where_the_photo_samples_the_print_unevenly():
    # a photo that sees half the print at 0.5 photo px per grid px and half at 1.5, with a camera
    # blur of 1.5 photo px: 3 grid px on the left, 1 on the right
    ref = _texture((240, 320), 1)
    fp = np.full(ref.shape, 1.5, np.float32)
    fp[:, :160] = 0.5
    photo = cv2.GaussianBlur(ref, (0, 0), 1.0)
    photo[:, :160] = cv2.GaussianBlur(ref, (0, 0), 3.0)[:, :160]
    photo += np.random.default_rng(2).normal(0.0, 2.0, ref.shape).astype(np.float32)
    mask = np.zeros(ref.shape, bool)
    mask[10:-10, 10:-10] = True
    mask[:, 150:170] = False  # (the seam between the halves mixes both blurs)
    got = estimate_blur(ref, photo, mask, fp, 1.0)
    assert got == PhotoBlur(0.0, 1.5)
    assert got.on_grid(np.array([0.5, 1.5]), 1.0) == pytest.approx([3.0, 1.0])


def test_a_sharp_photo_has_no_blur_and_a_uniform_one_its_own():
    ref = _texture((200, 200), 3)
    fp = np.full(ref.shape, 2.0, np.float32)
    mask = np.ones(ref.shape, bool)
    assert estimate_blur(ref, ref.copy(), mask, fp, 2.0) == PhotoBlur(0.0, 0.0)
    # 2 photo px at 2 photo px per grid px: 1 grid px
    assert estimate_blur(ref, cv2.GaussianBlur(ref, (0, 0), 1.0), mask, fp, 2.0).on_grid(2.0, 2.0) == pytest.approx(1.0)


@pytest.mark.parametrize("sigma", [0.0, 0.7, 1.5, 3.0])
def test_a_line_profile_is_a_box_through_a_gaussian(sigma):
    # the profile numerically: a box of 2.2 px sampled at 0.01 px (its edges' samples by the share
    # they cover), convolved with the Gaussian
    x = np.arange(-2000, 2001) * 0.01
    box = np.clip((1.1 - np.abs(x)) / 0.01 + 0.5, 0.0, 1.0)
    if sigma > 0:
        g = np.exp(-0.5 * (x / sigma) ** 2)
        box = np.convolve(box, g / g.sum(), mode="same")
    for at in (0.0, 1.0, 3.0):
        assert float(line_profile(at, 2.2, sigma)) == pytest.approx(box[2000 + int(round(at * 100))], abs=1e-4)


def _scratched(sigma, seed, ppm=4.0, ink=60.0, film=235.0, noise=2.0):
    """A 0.5 mm scratch across dark ink, as a photo blurred by ``sigma`` grid px shows it."""
    H, W = 160, 200
    mm = SCRATCH_WIDTH_MM * ppm
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    # (a box sampled at 10 x 10 points per pixel: its area exact to a tenth of a pixel)
    sub = (np.arange(10) + 0.5) / 10 - 0.5
    d = ii[..., None, None] + sub[:, None] - 0.3 * (jj[..., None, None] + sub[None, :]) - 60.0
    cover = (np.abs(d / np.hypot(1.0, 0.3)) <= mm / 2).mean(axis=(2, 3)).astype(np.float32)
    cover[:, :30] = 0.0
    cover[:, 170:] = 0.0
    line = cv2.GaussianBlur(cover, (0, 0), sigma) if sigma > 0 else cover
    rng = np.random.default_rng(seed)
    pred = np.full((H, W, 3), ink, np.float32)
    photo = pred + (film - ink) * line[..., None] + rng.normal(0.0, noise, (H, W, 3)).astype(np.float32)
    film_img = np.full((H, W, 3), film, np.float32)
    limit = np.full((H, W), 3.0 * noise, np.float32)
    return photo, pred, film_img, limit, cover > 0.5


@pytest.mark.parametrize("sigma", [0.0, 1.0, 1.6, 2.5, 4.0, 6.0])
def test_a_scratch_is_found_wherever_the_map_states_it(sigma):
    # the map states a scratch found where the blurred line's core clears the finding rule by the
    # noise: there the scratch must be found over its whole length, and a photo blurred so much that
    # the line is lost in the noise must not state it
    photo, pred, film, limit, truth = _scratched(sigma, 5)
    scored = np.ones(truth.shape, bool)
    blur = np.full(truth.shape, sigma, np.float32)
    found, findable, _ = thin_ink_loss(photo, pred, film, scored, 4.0, limit, blur, 2.0)
    stated = float(findable[truth].mean())
    near = cv2.dilate(found.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    share = float(near[truth].mean())
    if stated >= 0.75:
        assert share >= 0.9, (sigma, stated, share)
    # the core of a 0.5 mm line at 4 px per mm through sigma 6 is 0.13 of the step: 23 grey levels
    # against a noise of 2, of which the top-hat keeps a third; it is not stated
    if sigma >= 6.0:
        assert stated == 0.0
    if sigma <= 2.5:
        assert stated == 1.0 and share >= 0.9


def _colour_test(seed: int):
    """A scratch 1 px blurred over ink of 180, the film at 235, and the colour test on it.

    Returns the truth (H, W) bool and ``test(photo, pred, film, design)``: :func:`colour_residuals`
    with the scratch's own residual, weights (the scratch left out of the noise) and a flat blur.
    """
    from workbench.validate.dense.exposure import colour_residuals

    photo, pred, film, _, truth = _scratched(1.0, seed, ink=180.0, film=235.0)
    H, W = truth.shape
    scored = np.ones((H, W), bool)
    fp = np.ones((H, W), np.float32)
    blur = np.ones((H, W), np.float32)
    res = np.abs(photo - pred).max(axis=2)
    weight = (~truth).astype(np.float32)

    def test(pho, model, film_, design):
        return colour_residuals(pho, model, film_, res, weight, scored, fp, 4.0, blur, design)

    return (photo, pred, film, truth), test


def test_no_step_to_the_film_is_sought_where_the_film_comes_out_darker_than_the_ink():
    # ink only absorbs: where the film the ink around tells is darker than the model of the ink
    # itself (two accounts of the light that disagree at a shadow's edge), a dark line in the photo
    # is no step towards the film; where the film is brighter, the same line brightened is a scratch
    (photo, pred, film, truth), test = _colour_test(7)
    found = test(photo, pred, film, pred)[9]
    assert found[truth].mean() > 0.9
    # the same line darker than the ink, with the film the ink around tells at 150
    dark = 2.0 * pred - photo
    found = test(dark, pred, np.full_like(film, 150.0), pred)[9]
    assert not found.any()


def test_ink_is_gone_only_where_the_design_lays_it_down():
    # where a photo's white is clipped, the exposure fit takes its gain from the ink beside it and
    # may put the design's white below the film the ink around tells (a perfect face: 225 against
    # 254). A brighter line there steps "towards the film" in the model, but the design lays no ink
    # on it: nothing is gone. The same line over ink the design does lay down is a scratch.
    from workbench.validate.dense.options import COLOUR_TOL

    (photo, pred, film, truth), test = _colour_test(11)
    white = np.full_like(pred, 255.0)
    on_ink = test(photo, pred, film, pred)
    on_white = test(photo, pred, film, white)
    gone, inked, thin = 5, 7, 9
    assert on_ink[gone][truth].mean() > 0.9 and on_ink[thin][truth].mean() > 0.9
    assert not on_white[gone].any() and not on_white[inked].any() and not on_white[thin].any()
    # and broad ink loss is sought where the design's own step to the film exceeds twice the colour
    # test's tolerance (as the part's coverage counts it), whatever the model's step
    pale = np.full_like(pred, 255.0 - 2 * COLOUR_TOL + 1.0)
    dark = np.full_like(pred, 255.0 - 2 * COLOUR_TOL - 1.0)
    ink100 = np.full_like(pred, 100.0)  # the model's step to the film: 135 grey levels
    assert not test(ink100, ink100, film, pale)[inked].any()
    assert test(ink100, ink100, film, dark)[inked].all()
    # (and a model's step of 135 grey levels over a design that lays no ink is no ink)
    assert not test(ink100, ink100, film, white)[inked].any()


def test_the_noise_a_scratch_is_told_from_is_the_photos_there_not_its_median():
    # pale ink (205, the film 235), two fifths of the print seen through a coarse, noisy photo: its
    # noise a speckle three grid px across (one photo pixel), four times the rest's (pale ink lit
    # by the part itself in a path tracer's photo); a true scratch across both. The speckle's
    # chance peaks, joined along lines, made 195 px of "scratch" when its noise was taken as the
    # photo's median
    photo, pred, film, limit, truth = _scratched(1.0, 7, ink=205.0)
    H, W = truth.shape
    rng = np.random.default_rng(11)
    speckle = cv2.resize(rng.normal(0.0, 1.0, (H // 3 + 1, W // 3 + 1, 3)).astype(np.float32), None, fx=3, fy=3)
    noisy = np.zeros((H, W), bool)
    noisy[:, :80] = True
    photo[noisy] = pred[noisy] + 8.0 * speckle[:H, :W][noisy] / speckle.std()
    blur = np.ones((H, W), np.float32)
    found, findable, _ = thin_ink_loss(photo, pred, film, np.ones((H, W), bool), 4.0, limit, blur, 2.0)
    assert not found[noisy].any()
    # the scratch is found wherever the map states it, and stated over the quiet rest (beyond a
    # block of the noisy part's: 40 px, the noise's blocks, and their neighbours)
    near = cv2.dilate(found.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert near[truth & findable].mean() >= 0.9
    far = truth.copy()
    far[:, :140] = False
    assert far.sum() > 50 and findable[far].mean() >= 0.9 and near[far].mean() >= 0.9


def test_a_blocks_median_and_spread_are_the_largest_of_its_own_and_its_neighbours():
    from workbench.validate.dense.lines import block_median_spread

    rng = np.random.default_rng(3)
    # (a shape that is no multiple of the 40 px blocks: the last row and column of blocks are partial)
    v = rng.normal(0.0, 1.0, (130, 250)).astype(np.float32)
    v[:, 120:] = 5.0 + 3.0 * v[:, 120:]
    where = np.ones(v.shape, bool)
    med, spread = block_median_spread(v, where, 40, -1.0, 9.0)

    # (at a block's centre, pixel 59 of the second 40 px block, its own where its neighbours are alike:
    # each block's median and spread from its 1600 pixels, standard errors 1.25 and 1.17 sigma / 40,
    # and the largest of nine such within four of them)
    def near(got, sigma, mean):
        return abs(got - mean) < 4.0 * 1.25 * sigma / 40.0

    assert near(med[59, 59], 1.0, 0.0) and near(med[59, 179], 3.0, 5.0)
    assert abs(spread[59, 59] - 1.0) < 4 * 1.17 / 40 and abs(spread[59, 179] - 3.0) < 4 * 1.17 * 3 / 40
    # (beside a noisier block, the noisier's: the quiet block next to it, and the partial last ones)
    assert near(med[59, 99], 3.0, 5.0) and abs(spread[59, 99] - 3.0) < 4 * 1.17 * 3 / 40
    assert spread[125, 245] > 2.5
    # (a block with too few of its pixels: the fill values)
    where[:] = False
    where[:5, :5] = True
    med, spread = block_median_spread(v, where, 40, -1.0, 9.0)
    assert (med == -1.0).all() and (spread == 9.0).all()


@pytest.mark.parametrize("ink", [160.0, 170.0])
def test_a_scratch_does_not_hide_itself_by_the_noise_it_adds_to_its_blocks(ink):
    # a 0.5 mm scratch over pale ink blurred 2.5 px: a share of every block it crosses, it raised
    # their spread by a third, and the photo's own map stated it found over 42 % of its length
    # (ink 170) where the sound photo's map stated all of it; the blocks' floor without the lines
    # found gives it back (over paler ink, 185, the photo's own map still states none of it: a
    # limit that docs/validation.md states)
    photo, pred, film, limit, truth = _scratched(2.5, 3, ink=ink)
    H, W = truth.shape
    scored, blur = np.ones((H, W), bool), np.full((H, W), 2.5, np.float32)
    rng = np.random.default_rng(8)
    sound = pred + rng.normal(0.0, 2.0, pred.shape).astype(np.float32)
    _, stated, _ = thin_ink_loss(sound, pred, film, scored, 4.0, limit, blur, 2.0)
    found, own, _ = thin_ink_loss(photo, pred, film, scored, 4.0, limit, blur, 2.0)
    near = cv2.dilate(found.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert stated[truth].mean() >= 0.9 and near[truth & stated].mean() >= 0.9 and own[truth].mean() >= 0.9
