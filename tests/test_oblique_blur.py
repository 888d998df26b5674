"""The photo's round blur as it lies on the print where the photo sees it obliquely: an ellipse, not a disc."""

import cv2
import numpy as np
import pytest

from workbench.validate.dense.blur import PhotoBlur, blur_locally, blur_locally_axes, estimate_blur
from workbench.validate.print_warp import footprint_axes


def test_the_footprint_along_each_axis_is_the_pulled_back_covariances():
    # a round blur of variance s² in the photo is s² (JᵀJ)⁻¹ on the grid (J: photo px per grid px);
    # its spread along x is s / fx and along y s / fy, whatever J's shear and rotation
    rng = np.random.default_rng(0)
    J = rng.normal(0.0, 1.0, (500, 2, 2))
    J = J[np.abs(np.linalg.det(J)) > 0.05]
    gxx, gxy, gyx, gyy = J[:, 0, 0], J[:, 1, 0], J[:, 0, 1], J[:, 1, 1]
    got = footprint_axes(gxx[None], gxy[None], gyx[None], gyy[None], np.ones((1, len(J)), bool))[0]
    cov = np.linalg.inv(np.einsum("nji,njk->nik", J, J))
    assert got[:, 0] == pytest.approx(1.0 / np.sqrt(cov[:, 0, 0]), rel=1e-4)
    assert got[:, 1] == pytest.approx(1.0 / np.sqrt(cov[:, 1, 1]), rel=1e-4)
    # an oblique view that foreshortens y alone: the sampling of each axis
    one = np.ones((1, 1))
    s = footprint_axes(0.8 * one, 0.0 * one, 0.0 * one, 0.33 * one, one > 0)
    assert s[0, 0] == pytest.approx([0.8, 0.33], rel=1e-5)
    # and nothing where the photo does not see the grid
    assert not footprint_axes(gxx[None], gxy[None], gyx[None], gyy[None], np.zeros((1, len(J)), bool)).any()


def test_the_footprint_of_an_affine_warp_taken_as_the_warp_takes_it():
    # the photo's x and y of each grid pixel (an affine map A, photo px per grid px) differentiated
    # as warp_to_print differentiates them: along axis 1 (a grid column's step) and axis 0 (a row's)
    A = np.array([[0.9, 0.35], [-0.2, 0.5]])  # photo (x, y) = A (grid x, grid y)
    yy, xx = np.mgrid[0:40, 0:50].astype(np.float64)
    mapx, mapy = A[0, 0] * xx + A[0, 1] * yy, A[1, 0] * xx + A[1, 1] * yy
    gxx, gxy = np.gradient(mapx, axis=1), np.gradient(mapy, axis=1)
    gyx, gyy = np.gradient(mapx, axis=0), np.gradient(mapy, axis=0)
    got = footprint_axes(gxx, gxy, gyx, gyy, np.ones(mapx.shape, bool))[20, 25]
    cov = np.linalg.inv(A.T @ A)  # a unit round blur in the photo, pulled back to the grid
    assert got == pytest.approx(1.0 / np.sqrt(np.diag(cov)), rel=1e-6)


@pytest.mark.parametrize(("sx", "sy"), [(0.0, 0.0), (0.75, 3.0), (4.5, 1.0), (2.0, 2.0)])
def test_the_two_axis_blur_is_the_gaussian_of_the_two_sigmas(sx, sy):
    img = np.random.default_rng(1).uniform(0.0, 255.0, (120, 160, 3)).astype(np.float32)
    ones = np.ones(img.shape[:2], np.float32)
    got = blur_locally_axes(img, sx * ones, sy * ones)
    want = cv2.GaussianBlur(img, (0, 0), sx, sigmaY=sy) if sx > 0 and sy > 0 else img
    assert np.abs(got - want).max() < 1e-3
    if sx == sy:
        assert np.abs(got - blur_locally(img, sx * ones)).max() < 1e-3


def _checker(shape=(160, 240), size=8) -> np.ndarray:
    """Dark squares of ``size`` grid px on white film (text's strokes both ways), 0 to 255 in three channels."""
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    img = np.full((*shape, 3), 250.0, np.float32)
    img[((xx // size) + (yy // size)) % 2 == 0] = 40.0
    return img


def test_a_photo_that_sees_the_print_obliquely_is_modelled_by_an_ellipse():
    # the photo samples the print at 0.8 photo px per grid px along x and 0.4 along y (the surface
    # foreshortened): a camera blur of 1.2 photo px lies on the grid as 1.5 grid px along x and 3
    # along y. One round blur as wide as the coarser axis needs (3 grid px both ways) blurs the
    # print's detail along x that the photo keeps: the film between the dark squares comes out
    # darker in it than in the photo, a step towards the film (on a scanned elephant's flank seen
    # from above, lines of "ink gone" beside every letter)
    ref = _checker()
    H, W = ref.shape[:2]
    axes = np.empty((H, W, 2), np.float32)
    axes[..., 0], axes[..., 1] = 0.8, 0.4
    camera = PhotoBlur(0.0, 1.2)
    sx, sy = camera.on_grid(axes[..., 0], 0.5), camera.on_grid(axes[..., 1], 0.5)
    photo = cv2.GaussianBlur(ref, (0, 0), float(sx[0, 0]), sigmaY=float(sy[0, 0]))
    photo += np.random.default_rng(2).normal(0.0, 1.0, photo.shape).astype(np.float32)
    ellipse = blur_locally_axes(ref, sx, sy)
    disc = blur_locally(ref, camera.on_grid(axes.min(axis=-1), 0.5))
    inner = (slice(12, -12), slice(12, -12))
    assert np.abs(photo - ellipse)[inner].max() < 6.0  # (1.0 the noise's sigma: its largest of 70,000 about 4.5)
    film = (ref[..., 0] > 128)[inner]
    step = (photo - disc)[inner].mean(axis=-1)
    # the round blur's film is darker than the photo's, its ink lighter, both beyond the noise
    assert step[film].mean() > 10.0 and step[~film].mean() < -10.0
    # (and the ellipse along each axis is needed: as wide as the finer axis both ways, too sharp)
    too_sharp = blur_locally(ref, camera.on_grid(axes.max(axis=-1), 0.5))
    assert np.abs(photo - too_sharp)[inner].max() > 6.0


def test_the_camera_blur_is_measured_where_the_photo_samples_the_print_alike_both_ways():
    # three quarters of the print seen obliquely (1 photo px per grid px along x, 0.4 along y), the
    # rest face on: a camera blur of 1 photo px is 1 grid px round on the last quarter, an ellipse
    # of 1 by 2.5 on the rest. A round candidate over all of it splits the difference (measured:
    # 0.5 photo px); where the photo samples both ways alike it is the camera's
    rng = np.random.default_rng(3)
    ref = cv2.GaussianBlur(rng.normal(0.0, 1.0, (240, 320)).astype(np.float32), (0, 0), 0.7)
    ref = 128.0 + 60.0 * ref / ref.std()
    axes = np.ones((240, 320, 2), np.float32)
    axes[:, :240, 0], axes[:, :240, 1] = 1.0, 0.4
    photo = cv2.GaussianBlur(ref, (0, 0), 1.0)
    photo[:, :240] = cv2.GaussianBlur(ref, (0, 0), 1.0 / 1.0, sigmaY=1.0 / 0.4)[:, :240]
    photo += rng.normal(0.0, 2.0, ref.shape).astype(np.float32)
    mask = np.zeros(ref.shape, bool)
    mask[12:-12, 12:-12] = True
    mask[:, 220:260] = False
    fp = axes.min(axis=-1)
    assert estimate_blur(ref, photo, mask, fp, 1.0, axes) == PhotoBlur(0.0, 1.0)
    assert estimate_blur(ref, photo, mask, fp, 1.0) != PhotoBlur(0.0, 1.0)
