"""What a photo cannot show is not scored: the back of a fold, the mixed pixels along an outline."""

from __future__ import annotations

import numpy as np

from workbench.camera import Camera
from workbench.validate import print_warp


def quad_scene(flip: bool):
    """A 100 x 100 mm square at z = 0 under a camera 500 mm above, looking straight down."""
    V = np.array([[-50.0, -50.0, 0.0], [50.0, -50.0, 0.0], [50.0, 50.0, 0.0], [-50.0, 50.0, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise from +z: the decorated side faces the camera
    if flip:
        F = F[:, ::-1].copy()
    uv = V[:, :2] + 50.0
    rgb = np.random.default_rng(0).integers(0, 255, (79, 79, 3), dtype=np.uint8)  # 20 dpi
    grid = print_warp.print_grid(V, F, uv, 100.0, rgb, 20.0, None)
    cam = Camera.look_at([0.0, 0.0, 500.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 30.0, 800, 800)
    photo = np.random.default_rng(1).integers(0, 255, (800, 800, 3), dtype=np.uint8)
    return V, F, grid, cam, photo


def test_a_surface_turned_away_from_the_camera_is_not_scored():
    # the same square seen from its decorated side is scored; turned over (its triangles
    # wound the other way), nothing of it is: it is the back of the part
    V, F, grid, cam, photo = quad_scene(flip=False)
    state = print_warp.warp_to_print(photo, cam, grid, V, F).state
    on = np.isfinite(grid.X[..., 0])
    assert np.isin(state[on], (print_warp.FULL, print_warp.EDGE)).all() and (state == print_warp.FULL).mean() > 0.5
    V, F, grid, cam, photo = quad_scene(flip=True)
    state = print_warp.warp_to_print(photo, cam, grid, V, F).state
    assert (state[on] == print_warp.OCCLUDED).all()


def test_points_next_to_the_outline_in_the_photo_are_not_scored():
    # the photo's pixels along the square's outline mix it with the background: print pixels
    # seen within the band (3 photo pixels, plus twice the pre-blur) are EDGE, the rest FULL
    V, F, grid, cam, photo = quad_scene(flip=False)
    pw = print_warp.warp_to_print(photo, cam, grid, V, F)
    state, scale = pw.state, pw.scale
    xy, _ = cam.project(grid.X[np.isfinite(grid.X[..., 0])])
    lo, hi = cam.project(V)[0].min(axis=0), cam.project(V)[0].max(axis=0)
    to_outline = np.minimum(xy - lo, hi - xy).min(axis=1)
    band = print_warp.DEPTH_STEP_BAND_PX + 2.0 * (0.5 * np.sqrt(scale * scale - 1.0) if scale > 1.5 else 0.0)
    st = state[np.isfinite(grid.X[..., 0])]
    assert (st[to_outline < band - 1.5] == print_warp.EDGE).all()
    assert (st[to_outline > band + 2.5] == print_warp.FULL).all()


def test_depth_steps_mark_outlines_and_folds_only():
    depth = np.full((60, 80), np.inf)
    depth[10:50, 10:70] = 100.0 + np.linspace(0.0, 3.0, 60)[None, :]  # a gently sloping surface
    depth[20:30, 20:40] = 60.0  # a surface in front of it
    steps = print_warp.depth_steps(depth, 2.0)
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


def test_a_steep_surface_is_no_step_and_a_jump_is():
    # a plane seen at 75 degrees from its normal (cos 0.26: beyond what is scored, but one
    # surface) changes depth by tan 75° · z / fx per pixel, steadily: it mixes nothing. The same
    # plane with a 2 mm ledge across it (another surface in front) steps there
    fx = 1000.0
    z = 500.0 + np.arange(120)[None, :] * np.tan(np.radians(75.0)) * 500.0 / fx
    depth = np.full((80, 160), np.inf)
    depth[20:60, 20:140] = np.repeat(z, 40, axis=0)
    steps = print_warp.depth_steps(depth, 2.0, fx)
    assert not steps[25:55, 25:135].any()  # the slope's inside
    assert steps[20, 60] and steps[59, 60] and steps[40, 20] and steps[40, 139]  # its outline
    depth[20:60, 80:140] -= 2.0  # a ledge 2 mm nearer the camera from column 80 on
    steps = print_warp.depth_steps(depth, 2.0, fx)
    assert steps[40, 79] and steps[40, 80] and not steps[40, 60] and not steps[40, 100]


def scan_scene(flipped: np.ndarray):
    """A 100 x 100 mm grid of 2 mm squares at z = 0 seen from 500 mm above; the triangles
    ``flipped`` wound the other way (a scan's tiny folded-over triangles)."""
    n = 51
    x, y = np.meshgrid(np.linspace(-50.0, 50.0, n), np.linspace(-50.0, 50.0, n))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    i = np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]
    F = np.concatenate([np.stack([i, i + 1, i + n + 1], -1), np.stack([i, i + n + 1, i + n], -1)]).reshape(-1, 3)
    F[flipped] = F[flipped][:, ::-1]
    rgb = np.random.default_rng(0).integers(0, 255, (394, 394, 3), dtype=np.uint8)  # 100 dpi
    grid = print_warp.print_grid(V, F, V[:, :2] + 50.0, 100.0, rgb, 100.0, None)
    cam = Camera.look_at([0.0, 0.0, 500.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 30.0, 800, 800)
    photo = np.random.default_rng(1).integers(0, 255, (800, 800, 3), dtype=np.uint8)
    return V, F, grid, cam, photo


def test_a_scans_folded_over_triangles_open_no_hole_in_what_is_seen():
    # 40 scattered triangles turned over inside a surface that faces the camera: the part's
    # surface there faces it, so they are seen, and nothing around them is masked; the whole
    # sheet turned over is the back of the part
    flipped = np.random.default_rng(2).choice(5000, 40, replace=False)
    V, F, grid, cam, photo = scan_scene(flipped)
    state = print_warp.warp_to_print(photo, cam, grid, V, F).state
    on = np.isfinite(grid.X[..., 0])
    assert not (state[on] == print_warp.OCCLUDED).any()
    band = print_warp.rim_band(state)
    inner = np.zeros_like(on)
    inner[30:-30, 30:-30] = True  # farther than the rim band and the outline's from the film's outline
    assert (band[inner] == print_warp.FULL).all()
    V, F, grid, cam, photo = scan_scene(np.arange(5000))
    state = print_warp.warp_to_print(photo, cam, grid, V, F).state
    assert (state[on] == print_warp.OCCLUDED).all()


def test_the_rim_band_follows_the_films_outline_and_the_frame_only():
    # a hole that is hidden or too oblique in the middle of what is seen opens no band; the
    # film's outline (off the part) and the photo's frame (not seen) do, EDGE_PX wide
    state = np.full((100, 100), print_warp.FULL, np.uint8)
    state[:, :10] = print_warp.OFF_PART
    state[90:, :] = print_warp.NOT_SEEN
    state[40:50, 40:50] = print_warp.OCCLUDED
    state[60:70, 60:70] = print_warp.GRAZING
    out = print_warp.rim_band(state)
    e = print_warp.EDGE_PX
    # (the grid's own border is a frame too)
    assert (out[:90, 10 : 10 + e] == print_warp.EDGE).all() and (
        out[e : 90 - e, 10 + e : 100 - e] != print_warp.EDGE
    ).all()
    assert (out[90 - e : 90, 10:] == print_warp.EDGE).all()
    assert (out[0:e, 10:] == print_warp.EDGE).all() and (out[:, 100 - e :][: 90 - e] == print_warp.EDGE).all()
    assert (out[35:55, 35:55][state[35:55, 35:55] == print_warp.FULL] == print_warp.FULL).all()
    assert (out[55:75, 55:75][state[55:75, 55:75] == print_warp.FULL] == print_warp.FULL).all()


def test_the_smooth_surface_decides_what_faces_the_photo_and_its_contour_is_an_edge():
    # the square's triangles face the camera, but its smooth normal (what both renderers and a
    # real part shade by) turns away on the half x > 10 mm: the photo shows the film's back
    # there (a faceted shell curling under, Mitsuba's glossy cow: 6.9 mm² of "colour" where the
    # back's grey met the film). That half is turned away, and the photo's pixels within the
    # band of the contour, where the film's side and its back mix, are EDGE
    import dataclasses

    V, F, grid, cam, photo = quad_scene(flip=False)
    on = np.isfinite(grid.X[..., 0])
    away = on & (grid.X[..., 0] > 10.0)
    normal = grid.normal.copy()
    normal[away] = np.array([0.6, 0.0, -0.8], np.float32)  # faces away from a camera 500 mm above
    # (by its triangles alone, as without a smooth normal: seen, and scored but at the outline)
    before = print_warp.warp_to_print(photo, cam, dataclasses.replace(grid, normal=None), V, F).state
    assert (before[away] == print_warp.FULL).mean() > 0.8
    grid = dataclasses.replace(grid, normal=normal)
    pw = print_warp.warp_to_print(photo, cam, grid, V, F)
    state, scale = pw.state, pw.scale
    assert (state[away] == print_warp.OCCLUDED).all()
    # the contour in the photo: the column where x = 10 mm projects
    xy, _ = cam.project(grid.X[on])
    contour_px = cam.project(np.array([[10.0, 0.0, 0.0]]))[0][0, 0]
    lo, hi = cam.project(V)[0].min(axis=0), cam.project(V)[0].max(axis=0)
    to_outline = np.minimum(xy - lo, hi - xy).min(axis=1)
    band = print_warp.DEPTH_STEP_BAND_PX + 2.0 * (0.5 * np.sqrt(scale * scale - 1.0) if scale > 1.5 else 0.0)
    st, front = state[on], ~away[on]
    to_contour = contour_px - xy[:, 0]
    assert (st[front & (to_contour < band - 1.5)] == print_warp.EDGE).all()
    far = front & (to_contour > band + 2.5) & (to_outline > band + 2.5)
    assert far.sum() > 1000 and (st[far] == print_warp.FULL).all()


def test_the_contour_band_reaches_its_radius_around_the_back_the_photo_shows():
    xy = np.array([[50.0, 40.0], [51.0, 40.0], [52.0, 40.0]])
    band = print_warp.contour_band(xy, 3.0, (80, 100))
    assert band[40, 50:53].all() and band[37, 51] and band[40, 55] and band[43, 51]
    assert not band[40, 56] and not band[36, 51] and not band[44, 51] and band.sum() < 60
    assert not print_warp.contour_band(np.zeros((0, 2)), 3.0, (80, 100)).any()
