"""A scan's caps (a corner on the opposite edge) flipped away, the surface unchanged."""

from __future__ import annotations

import numpy as np

from workbench.mesh.caps import flip_caps
from workbench.mesh.topology import boundary_loops, unique_edges
from workbench.mesh.validate import face_areas, zero_area_faces


def grid(n: int = 6):
    """An n x n grid of 1 mm squares at z = 0, two triangles each, counter-clockwise from +z."""
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    F = np.stack([np.stack([i, i + 1, i + n + 2], -1), np.stack([i, i + n + 2, i + n + 1], -1)], 1).reshape(-1, 3)
    return V, F


def normals_z(V, F):
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    return np.cross(e1, e2)[:, 2]


def test_a_cap_is_flipped_with_its_neighbour_and_the_surface_stays_the_same():
    V, F = grid()
    # square 14's lower triangle (i, i+1, i+8): its corner i+1 moved onto the diagonal (i, i+8)
    f = 2 * 14
    i = F[f, 0]
    V[i + 1] = 0.5 * (V[i] + V[i + 8])
    assert list(zero_area_faces(V, F)) == [f]
    before = face_areas(V, F).sum()
    G, flipped = flip_caps(V, F)
    assert flipped == 1 and not len(zero_area_faces(V, G))
    # only the cap and its neighbour across the diagonal changed, in place
    assert set(np.flatnonzero((G != F).any(axis=1))) == {f, f + 1}
    assert abs(face_areas(V, G).sum() - before) < 1e-12 and (normals_z(V, G) > 0).all()
    # still a manifold with one rim, the same as before
    assert unique_edges(G)[2].max() == 2 and len(boundary_loops(G)) == 1
    assert sorted(boundary_loops(G)[0]) == sorted(boundary_loops(F)[0])


def test_a_cap_on_the_rim_and_a_needle_stay():
    # the cap (0, 1, 2), corner 2 on its edge (0, 1), which is the rim: no neighbour to flip with
    V = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    F = np.array([[0, 1, 2], [2, 1, 3], [0, 2, 3]])
    assert list(zero_area_faces(V, F)) == [0]
    G, flipped = flip_caps(V, F)
    assert flipped == 0 and (G == F).all()
    # a needle: two corners at one point (square 0's corner 8 on corner 0), which no flip mends
    V, F = grid()
    V[8] = V[0]
    G, flipped = flip_caps(V, F)
    assert flipped == 0 and (G == F).all() and len(zero_area_faces(V, F))


def test_a_flip_that_would_leave_a_cap_again_is_not_made():
    # the cap (a, b, c), c 0.001 mm from b, its neighbour's corner d 1e-9 mm off the line ab:
    # the flip's (d, b, c) would have no area either, and the next round would flip it back
    V = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.999, 0, 0], [1.5, 1e-9, 0]])
    F = np.array([[0, 1, 2], [1, 0, 3]])
    G, flipped = flip_caps(V, F)
    assert flipped == 0 and (G == F).all()
