"""What a photo cannot show is not scored: the back of a fold, the mixed pixels along an outline."""

from __future__ import annotations

import numpy as np

from workbench.camera import Camera
from workbench.validate import dense


def quad_scene(flip: bool):
    """A 100 x 100 mm square at z = 0 under a camera 500 mm above, looking straight down."""
    V = np.array([[-50.0, -50.0, 0.0], [50.0, -50.0, 0.0], [50.0, 50.0, 0.0], [-50.0, 50.0, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise from +z: the decorated side faces the camera
    if flip:
        F = F[:, ::-1].copy()
    uv = V[:, :2] + 50.0
    rgb = np.random.default_rng(0).integers(0, 255, (79, 79, 3), dtype=np.uint8)  # 20 dpi
    grid = dense.print_grid(V, F, uv, 100.0, rgb, 20.0, None)
    cam = Camera.look_at([0.0, 0.0, 500.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 30.0, 800, 800)
    photo = np.random.default_rng(1).integers(0, 255, (800, 800, 3), dtype=np.uint8)
    return V, F, grid, cam, photo


def test_a_surface_turned_away_from_the_camera_is_not_scored():
    # the same square seen from its decorated side is scored; turned over (its triangles
    # wound the other way), nothing of it is: it is the back of the part
    V, F, grid, cam, photo = quad_scene(flip=False)
    _, state, _, _ = dense.warp_to_print(photo, cam, grid, V, F)
    on = np.isfinite(grid.X[..., 0])
    assert np.isin(state[on], (dense.FULL, dense.EDGE)).all() and (state == dense.FULL).mean() > 0.5
    V, F, grid, cam, photo = quad_scene(flip=True)
    _, state, _, _ = dense.warp_to_print(photo, cam, grid, V, F)
    assert (state[on] == dense.OCCLUDED).all()


def test_points_next_to_the_outline_in_the_photo_are_not_scored():
    # the photo's pixels along the square's outline mix it with the background: print pixels
    # seen within the band (3 photo pixels, plus twice the pre-blur) are EDGE, the rest FULL
    V, F, grid, cam, photo = quad_scene(flip=False)
    _, state, scale, _ = dense.warp_to_print(photo, cam, grid, V, F)
    xy, _ = cam.project(grid.X[np.isfinite(grid.X[..., 0])])
    lo, hi = cam.project(V)[0].min(axis=0), cam.project(V)[0].max(axis=0)
    to_outline = np.minimum(xy - lo, hi - xy).min(axis=1)
    band = dense.DEPTH_STEP_BAND_PX + 2.0 * (0.5 * np.sqrt(scale * scale - 1.0) if scale > 1.5 else 0.0)
    st = state[np.isfinite(grid.X[..., 0])]
    assert (st[to_outline < band - 1.5] == dense.EDGE).all()
    assert (st[to_outline > band + 2.5] == dense.FULL).all()


def test_depth_steps_mark_outlines_and_folds_only():
    depth = np.full((60, 80), np.inf)
    depth[10:50, 10:70] = 100.0 + np.linspace(0.0, 3.0, 60)[None, :]  # a gently sloping surface
    depth[20:30, 20:40] = 60.0  # a surface in front of it
    steps = dense.depth_steps(depth, 2.0)
    assert steps[10, 30] and steps[49, 30] and steps[30, 10]  # the outline
    assert steps[20, 30] and steps[25, 40]  # the fold's edge
    assert not steps[40, 55] and not steps[25, 30]  # the slope and the front surface's inside


def test_the_view_warp_takes_no_point_from_the_back_of_the_part():
    # the tiles' warp into a designed view (the photo's camera as the view) takes the whole
    # square seen from its decorated side, and nothing of it turned over
    from workbench.validate.score import view_surface, warp_photo

    for flip, expected in ((False, True), (True, False)):
        V, F, grid, cam, photo = quad_scene(flip)
        owner = np.zeros((79, 79), np.int16)
        surface = view_surface(cam, V, F, V[:, :2] + 50.0, 100.0, owner, 0, 20.0 / 25.4)
        _, valid = warp_photo(photo, cam, surface, V, F)
        on = np.isfinite(surface.X[..., 0])
        assert on.sum() > 1000 and (valid[on] == expected).all()
