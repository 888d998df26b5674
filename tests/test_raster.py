"""Rasterisation: each pixel centre to exactly one face, exact barycentrics, perspective-correct depth."""

from __future__ import annotations

import numpy as np

from workbench.camera import Camera
from workbench.raster import depth_buffer, rasterize_triangles


def test_every_pixel_centre_belongs_to_exactly_one_face(grid):
    # vertices on pixel centres: many centres lie on shared edges and shared vertices
    P, F = grid(11, 9, np.random.default_rng(1), jitter=0.0)
    P = P * [40, 32]
    cover = np.zeros((33, 41), int)
    for f in range(len(F)):
        face, _ = rasterize_triangles(P, F[f : f + 1], 41, 33)
        cover += face >= 0
    # shared edges and vertices go to exactly one face; on the outer boundary the
    # rule gives two sides of the rectangle to no one (print pixel centres never lie there)
    assert (cover[1:-1, 1:-1] == 1).all()
    assert cover.max() == 1


def test_barycentrics_reproduce_the_pixel_centre(grid):
    P, F = grid(20, 15, np.random.default_rng(3), jitter=0.3)
    P = P * [199.3, 148.7] + [0.25, 0.4]
    face, bary = rasterize_triangles(P, F, 201, 151)
    ii, jj = np.nonzero(face >= 0)
    f = face[ii, jj]
    pos = np.einsum("ij,ijk->ik", bary[ii, jj], P[F[f]])
    np.testing.assert_allclose(pos, np.stack([jj, ii], 1), atol=1e-9)
    assert (bary[ii, jj] >= -1e-12).all()


def test_depth_is_perspective_correct():
    # a tilted plane z = 300 + 0.5 x seen by a camera at the origin: the depth at each
    # pixel is where the pixel's ray meets the plane, not a linear blend of vertex depths
    cam = Camera(
        K=np.array([[400.0, 0, 99.5], [0, 400.0, 74.5], [0, 0, 1]]), R=np.eye(3), t=np.zeros(3), width=200, height=150
    )
    xs, ys = np.meshgrid(np.linspace(-120, 120, 7), np.linspace(-90, 90, 6))
    V = np.stack([xs.ravel(), ys.ravel(), 300 + 0.5 * xs.ravel()], 1)
    idx = np.arange(42).reshape(6, 7)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    xy, z = cam.project(V)
    face, depth = depth_buffer(xy, z, F, 200, 150)
    jj, ii = np.meshgrid(np.arange(200.0), np.arange(150.0))
    # ray (u, v, 1) t with u = (j - cx) / f: plane z = 300 + 0.5 u z  ->  z = 300 / (1 - 0.5 u)
    u = (jj - 99.5) / 400.0
    truth = 300.0 / (1 - 0.5 * u)
    seen = face >= 0
    assert seen.mean() > 0.95
    np.testing.assert_allclose(depth[seen], truth[seen], rtol=1e-12)


def test_nearest_surface_wins():
    cam = Camera(
        K=np.array([[100.0, 0, 49.5], [0, 100.0, 49.5], [0, 0, 1]]), R=np.eye(3), t=np.zeros(3), width=100, height=100
    )
    quad = np.array([[-50.0, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]])
    V = np.concatenate([quad + [0, 0, 200], quad * 0.3 + [0, 0, 100]])  # far big, near small
    F = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    xy, z = cam.project(V)
    face, depth = depth_buffer(xy, z, F, 100, 100)
    assert set(np.unique(face[50, 45:55])) <= {2, 3} and np.allclose(depth[50, 45:55], 100.0)
    assert set(np.unique(face[30, 26:32])) <= {0, 1} and np.allclose(depth[30, 26:32], 200.0)
    assert (face[5, 5:10] == -1).all() and np.isinf(depth[5, 5:10]).all()
