"""Corners searched by the first-order response of the map: exact against Schwarz-Christoffel, useful on real meshes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay
from test_real_meshes import CORPUS, SHARED, load

from workbench.conformal.cetm import conformal_scale_factors
from workbench.conformal.corner_search import corner_response, even_turning_targets
from workbench.conformal.flatten import (
    CrowdingError,
    FlattenOptions,
    flatten,
    flatten_auto_corners,
    input_log_lengths,
)
from workbench.conformal.intrinsic import IntrinsicTriangulation
from workbench.errors import WorkbenchError
from workbench.mesh.io import read_mesh
from workbench.mesh.validate import check_disc

RADIUS = 50.0


def flat_disc(rings: int):
    """A flat disc of radius 50 mm: rings of 6i vertices, Delaunay triangulated."""
    pts = [np.zeros(2)]
    for i in range(1, rings + 1):
        t = 2 * np.pi * (np.arange(6 * i) + 0.5 * (i % 2)) / (6 * i)
        pts += list(RADIUS * i / rings * np.column_stack([np.cos(t), np.sin(t)]))
    P = np.array(pts)
    F = Delaunay(P).simplices
    e1, e2 = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    ccw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0
    F[~ccw] = F[~ccw][:, [0, 2, 1]]
    return np.column_stack([P, np.zeros(len(P))]), F


def evenly_turning_map(V, F):
    loop, E, FE = check_disc(V, F)
    theta, w = even_turning_targets(V, loop, len(V))
    tri = IntrinsicTriangulation.from_mesh(F, input_log_lengths(V, F), len(V), FE, flips=True)
    return loop, w, conformal_scale_factors(tri, theta, fixed=int(loop[0]), edges=(E, FE))


def test_corner_response_is_the_neumann_green_function_of_the_disc():
    # Schwarz-Christoffel: the disc onto a rectangle has log|f'| = c - ½ Σ log|z - z_k|,
    # so making z_c a corner adds -½ log|z - z_c| (plus a constant) to the log scale
    V, F = flat_disc(40)
    loop, w, newton = evenly_turning_map(V, F)
    sites = loop[:: len(loop) // 8]
    G = corner_response(newton.assembler, newton.cot, sites, loop, w, len(V))
    z = (V[:, 0] + 1j * V[:, 1]) / RADIUS
    for j, c in enumerate(sites):
        exact = -0.5 * np.log(np.maximum(np.abs(z - z[c]), 1e-300))
        away = np.abs(z - z[c]) > 0.25
        assert np.ptp(G[away, j] - exact[away]) < 0.02, (j, np.ptp(G[away, j] - exact[away]))


def test_predicted_map_matches_the_solved_rectangle_and_schwarz_christoffel():
    V, F = flat_disc(40)
    loop, w, newton = evenly_turning_map(V, F)
    z = (V[:, 0] + 1j * V[:, 1]) / RADIUS
    nb = len(loop)
    for q in ([3, nb // 3, nb // 2 + 5, 4 * nb // 5], [0, 5, 40, 60]):
        corners = loop[np.array(q)]
        predicted = newton.u + corner_response(newton.assembler, newton.cot, corners, loop, w, len(V)).sum(axis=1)
        solved = flatten(V, F, FlattenOptions(corners=tuple(int(c) for c in corners))).newton.u[: len(V)]
        exact = -0.5 * sum(np.log(np.maximum(np.abs(z - z[c]), 1e-300)) for c in corners)
        near = np.min([np.abs(z - z[c]) for c in corners], axis=0)
        # up to a constant: the scale of the rectangle is set afterwards
        assert np.ptp((predicted - solved)[near > 0.1]) < 0.01
        assert np.ptp((solved - exact)[near > 0.25]) < 0.005


def test_auto_corners_print_a_mesh_the_automatic_corners_crowd():
    V, F = load(next(p for p in CORPUS if p.stem == "beetle-0"))
    V = V * 150 / np.linalg.norm(V.max(0) - V.min(0))
    with pytest.raises(CrowdingError):
        flatten(V, F)
    r, search = flatten_auto_corners(V, F, name="beetle-0")
    assert r.corner_rule == "auto" and r.flipped_faces == 0
    assert r.area_3d[r.crowded].sum() <= 1e-3 * r.area_3d.sum()
    assert search["predicted"] > 1000 and search["sites"] == 64
    won = next(c for c in search["candidates"] if c["corners"] == r.corners.tolist())
    assert "predicted" in won and won["outcome"] == "ok"
    # the prediction is close to what the solve gives
    assert won["area_distortion"] == pytest.approx(won["predicted"]["area_distortion"], abs=0.05)


def test_auto_corners_refuse_a_part_no_rectangle_prints_naming_the_least_crowded():
    # cow-1: the legs and head crowd whatever the corners; the refusal says by how much at best
    V, F = load(next(p for p in CORPUS if p.stem == "cow-1"))
    V = V * 150 / np.linalg.norm(V.max(0) - V.min(0))
    with pytest.raises(WorkbenchError) as exc:
        flatten_auto_corners(V, F, name="cow-1")
    msg = str(exc.value)
    assert "quadruples predicted, the least crowded still crowds" in msg and "several films" in msg
    share = float(msg.split("still crowds ")[1].split(" %")[0]) / 100
    assert share > 1e-2


@pytest.mark.skipif(not (SHARED / "camel_b.obj").is_file(), reason="the shared meshes are not beside this checkout")
def test_an_overshooting_newton_step_is_shortened_not_fatal():
    # camel_b's evenly turning map: the first full Newton step goes so far that the
    # Delaunay flips at the trial point cannot settle; the line search must shorten it
    # (it used to stop with "Delaunay edge flips did not terminate")
    V, F = read_mesh(SHARED / "camel_b.obj")
    loop, w, newton = evenly_turning_map(V * 150 / np.linalg.norm(V.max(0) - V.min(0)), F)
    assert newton.residual_rad <= 1e-9 and not newton.degenerate.any()
