"""A glossy film's reflection of the room: Fresnel's share, against the textbook's forms."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.validate.dense.reflection import fresnel_reflectance, luminance, room_reflection


def _by_angles(theta_i: float, n: float) -> float:
    """Fresnel's unpolarised reflectance written with the angles (an independent form of the same law)."""
    if theta_i == 0.0:
        return ((n - 1) / (n + 1)) ** 2
    theta_t = np.arcsin(np.sin(theta_i) / n)
    rs = (np.sin(theta_t - theta_i) / np.sin(theta_t + theta_i)) ** 2
    rp = (np.tan(theta_t - theta_i) / np.tan(theta_t + theta_i)) ** 2
    return 0.5 * (rs + rp)


@pytest.mark.parametrize("n", [1.49, 1.5, 1.65])
@pytest.mark.parametrize("deg", [0.0, 20.0, 45.0, 60.0, 70.0, 80.0, 89.0])
def test_fresnel_reflectance_is_the_textbooks(n, deg):
    theta = np.radians(deg)
    assert float(fresnel_reflectance(np.cos(theta), n)) == pytest.approx(_by_angles(theta, n), rel=1e-4, abs=1e-6)


def test_face_on_four_percent_grazing_all_and_nothing_polarised_at_brewster():
    assert float(fresnel_reflectance(1.0, 1.5)) == pytest.approx(0.04, abs=1e-6)
    assert float(fresnel_reflectance(0.0, 1.5)) == pytest.approx(1.0, abs=1e-6)
    # at Brewster's angle (tan θ = n) the p polarisation is not reflected: the mean is half of s's
    theta_b = np.arctan(1.5)
    theta_t = np.pi / 2 - theta_b
    rs = (np.sin(theta_t - theta_b) / np.sin(theta_t + theta_b)) ** 2
    assert float(fresnel_reflectance(np.cos(theta_b), 1.5)) == pytest.approx(rs / 2, rel=1e-5)


def test_a_tilted_plane_mirrors_fresnels_share_of_the_white_and_nothing_off_the_part():
    # a plane through the origin tilted by 70° from the camera's direction: every pixel sees it at
    # about that incidence (the camera 10 m away)
    tilt = np.radians(70.0)
    normal = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    u = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    s = np.linspace(-1.0, 1.0, 5)
    X = s[:, None, None] * u + s[None, :, None] * np.array([0.0, 1.0, 0.0])
    X[0, 0] = np.nan
    N = np.broadcast_to(normal, X.shape).copy()
    N[0, 0] = np.nan
    out = room_reflection(X, N, np.array([0.0, 0.0, 10000.0]), white=0.8)
    assert np.isnan(out[0, 0])
    expected = 0.8 * float(fresnel_reflectance(np.cos(tilt)))
    assert np.allclose(out[np.isfinite(out)], expected, rtol=2e-3)


def test_luminance_of_white_is_one_and_of_each_primary_its_rec709_weight():
    assert float(luminance(np.ones(3))) == pytest.approx(1.0, abs=1e-6)
    assert np.allclose(luminance(np.eye(3)), [0.2126, 0.7152, 0.0722])


def _plane_at(deg: float, shape=(20, 30)):
    """Surface points and normals of a plane seen at ``deg`` of incidence from a camera far above."""
    tilt = np.radians(deg)
    normal = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    u = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    ii, jj = np.mgrid[0 : shape[0], 0 : shape[1]].astype(float)
    X = (jj[..., None] * u + ii[..., None] * np.array([0.0, 1.0, 0.0])) * 0.1
    return X, np.broadcast_to(normal, X.shape).copy(), np.array([0.0, 0.0, 1e5])


def test_a_reflection_of_the_room_on_dark_ink_is_explained_and_ink_gone_is_not():
    from workbench.validate import photometric
    from workbench.validate.dense.reflection import within_room_reflection

    X, N, c = _plane_at(75.0)
    shape = X.shape[:2]
    film = np.full((*shape, 3), 230.0, np.float32)
    dark = np.full((*shape, 3), 30.0, np.float32)
    white = float(luminance(photometric.linear(film[0, 0])))
    share = float(fresnel_reflectance(np.cos(np.radians(75.0))))
    # the dark ink with 90 % of the most the room can add at 75°, and with the bare film in its place
    lifted = photometric.grey_levels(photometric.linear(dark) + 0.9 * share * white)
    seen = np.ones(shape, bool)
    explained, mimics = within_room_reflection(lifted, dark, film, seen, X, N, c, noise=1.0, z=3.0)
    assert explained.all() and not mimics.any()
    explained, _ = within_room_reflection(film.copy(), dark, film, seen, X, N, c, noise=1.0, z=3.0)
    assert not explained.any()
    # face on, the room adds at most 6 %: the same lift on dark ink is more than that
    X0, N0, c0 = _plane_at(0.0)
    explained, _ = within_room_reflection(lifted, dark, film, seen, X0, N0, c0, noise=1.0, z=3.0)
    assert not explained.any()


def test_pale_ink_gone_is_not_found_where_the_room_may_brighten_it_as_much():
    from workbench.validate.dense.reflection import within_room_reflection

    shape = (20, 30)
    film = np.full((*shape, 3), 230.0, np.float32)
    pale = np.full((*shape, 3), 215.0, np.float32)  # (ink gone there brightens it by about 12 % of the white)
    seen = np.ones(shape, bool)
    for deg, expected in ((20.0, False), (75.0, True)):
        X, N, c = _plane_at(deg)
        _, mimics = within_room_reflection(pale, pale, film, seen, X, N, c, noise=1.0, z=3.0)
        assert mimics.all() == expected and mimics.any() == expected, deg
