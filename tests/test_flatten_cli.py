"""workbench flatten end to end: files, conventions, scale modes, formats, determinism."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from conftest import ROOT, cylinder_patch, grid_corners

from workbench import __version__
from workbench.cli import main
from workbench.conformal.flatten import FlattenOptions, ScaleMode, flatten
from workbench.mesh.io import format_obj, read_mesh

PART = ROOT / "fixtures" / "default" / "part.obj"


def flatten_cli(tmp_path: Path, mesh: Path, *extra: str, name="out") -> tuple[Path, dict]:
    out = tmp_path / name
    assert main(["flatten", str(mesh), "--out", str(out), "-q", *extra]) == 0
    return out, json.loads((out / "flatten.json").read_text())


def test_default_part(tmp_path):
    before = PART.read_bytes()
    out, info = flatten_cli(tmp_path, PART)
    assert PART.read_bytes() == before  # input untouched
    V, F = read_mesh(PART)
    flat_V, flat_F = read_mesh(out / "flat.obj")
    np.testing.assert_array_equal(flat_F, F)  # same faces, same vertex numbering
    assert len(flat_V) == len(V) and np.all(flat_V[:, 2] == 0)
    # auto corners: the lid's four square corners, A→B along +x
    assert info["corners"] == [0, 149, 14999, 14850] and info["corner_rule"] == "sharpest-turns"
    A, B, C, D = (flat_V[c, :2] for c in info["corners"])
    np.testing.assert_allclose(A, 0, atol=1e-9)
    assert B[1] == pytest.approx(0, abs=1e-9) and B[0] == pytest.approx(info["width_mm"], abs=1e-9)
    np.testing.assert_allclose(C, [info["width_mm"], info["height_mm"]], atol=1e-9)
    assert info["angle_residual_max_rad"] <= 1e-9 and info["flipped_faces"] == 0
    assert info["mesh"] == {"vertices": 15000, "faces": 29502}
    s = info["stretch"]
    assert s["min"] <= s["p50"] <= s["p95"] <= s["max"]
    assert set(info["timings_s"]) >= {"read", "newton", "layout", "write"}
    png = (out / "flatten.png").read_bytes()
    assert png.startswith(b"\x89PNG")


def test_same_input_same_bytes(tmp_path):
    a, ja = flatten_cli(tmp_path, PART, name="a")
    b, jb = flatten_cli(tmp_path, PART, name="b")
    assert (a / "flat.obj").read_bytes() == (b / "flat.obj").read_bytes()
    assert (a / "flatten.png").read_bytes() == (b / "flatten.png").read_bytes()
    ja.pop("timings_s"), jb.pop("timings_s")
    assert ja == jb


def test_scale_modes(tmp_path):
    V, F, _ = cylinder_patch(30, seed=4)
    V = V * [1.0, 1.0, 0.5]  # elliptic cylinder: still developable
    corners = grid_corners(30, 30)
    width = flatten(V, F, FlattenOptions(corners=corners, scale=ScaleMode.parse("width=200")))
    assert width.width_mm == pytest.approx(200.0, rel=1e-12)
    height = flatten(V, F, FlattenOptions(corners=corners, scale=ScaleMode.parse("height=50")))
    assert height.height_mm == pytest.approx(50.0, rel=1e-12)
    assert width.width_mm / width.height_mm == pytest.approx(height.width_mm / height.height_mm, rel=1e-12)


def test_no_shrink_never_prints_larger_than_the_surface(grid):
    P, F = grid(40, 40, np.random.default_rng(1))
    x, y = (P[:, 0] - 0.5) * 80, (P[:, 1] - 0.5) * 80
    V = np.stack([x, y, 25 * np.exp(-(x * x + y * y) / 400)], 1)  # a bump: film must stretch
    r = flatten(V, F, FlattenOptions(corners=grid_corners(40, 40), scale=ScaleMode("no-shrink")))
    assert r.sigma[:, 1].min() == pytest.approx(1.0, abs=1e-12)  # tight, not just safe
    assert (r.sigma[:, 1] >= 1.0 - 1e-12).all()
    iso = flatten(V, F, FlattenOptions(corners=grid_corners(40, 40)))
    assert iso.stretch.min() < 1.0 < iso.stretch.max()  # isometric compresses somewhere
    assert r.width_mm < iso.width_mm


def test_developable_part_prints_at_true_size(tmp_path):
    V, F, exact = cylinder_patch(40, seed=6)
    mesh = tmp_path / "cyl.obj"
    mesh.write_bytes(format_obj(V, F))
    _, info = flatten_cli(tmp_path, mesh, "--corners", ",".join(map(str, grid_corners(40, 40))))
    assert info["width_mm"] == pytest.approx(80.0, abs=0.01)
    assert info["height_mm"] == pytest.approx(60.0, abs=0.01)
    assert info["stretch"]["min"] == pytest.approx(1.0, abs=1e-3)
    assert info["stretch"]["max"] == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("fmt", ["ply", "off", "stl", "glb"])
def test_other_formats_give_the_same_map(tmp_path, grid, fmt):
    P, F = grid(20, 15, np.random.default_rng(3))
    V = np.stack([P[:, 0] * 60, P[:, 1] * 40, 5 * np.sin(3 * P[:, 0])], 1)
    obj = tmp_path / "m.obj"
    obj.write_bytes(format_obj(V, F))
    other = tmp_path / f"m.{fmt}"
    trimesh.Trimesh(V, F, process=False).export(other)
    corners = ",".join(map(str, grid_corners(20, 15)))
    a, _ = flatten_cli(tmp_path, obj, "--corners", corners, name="a")
    V2, _ = read_mesh(other)
    if fmt == "stl":  # no shared vertices in STL: merged, numbered by first appearance; float32
        order = np.array([int(np.argmin(np.abs(V - v).max(1))) for v in V2])
        corners = ",".join(str(int(np.flatnonzero(order == c)[0])) for c in grid_corners(20, 15))
    else:
        order = np.arange(len(V))
        np.testing.assert_allclose(V2, V, atol=1e-5)
    b, _ = flatten_cli(tmp_path, other, "--corners", corners, name="b")
    uv_a, _ = read_mesh(a / "flat.obj")
    uv_b, _ = read_mesh(b / "flat.obj")
    np.testing.assert_allclose(uv_b, uv_a[order], atol=1e-4 if fmt == "stl" else 1e-9)


def test_units_scale_the_print(tmp_path, grid):
    P, F = grid(10, 10, np.random.default_rng(0))
    V = np.stack([P[:, 0] * 6, P[:, 1] * 4, np.zeros(len(P))], 1)  # 6 x 4 cm
    mesh = tmp_path / "cm.obj"
    mesh.write_bytes(format_obj(V, F))
    _, info = flatten_cli(tmp_path, mesh, "--units", "cm", "--corners", ",".join(map(str, grid_corners(10, 10))))
    assert info["width_mm"] == pytest.approx(60.0, rel=1e-9)
    assert info["height_mm"] == pytest.approx(40.0, rel=1e-9)


def test_round_boundary_falls_back_to_the_bounding_box():
    from scipy.spatial import Delaunay

    # a Delaunay-meshed disc of radius 30 mm: the boundary has no corners to find
    rng = np.random.default_rng(2)
    ring = np.linspace(0, 2 * np.pi, 96, endpoint=False)
    inner = rng.uniform(-1, 1, (1500, 2)) * 28
    inner = inner[np.linalg.norm(inner, axis=1) < 28]
    P = np.vstack([30 * np.stack([np.cos(ring), np.sin(ring)], 1), inner])
    F = Delaunay(P).simplices
    a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
    cw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    F[cw] = F[cw][:, ::-1]
    res = flatten(np.column_stack([P, np.zeros(len(P))]), F)
    assert res.corner_rule == "bounding-box"
    assert set(res.corners.tolist()) <= set(range(96)) and len(set(res.corners.tolist())) == 4
    assert res.flipped_faces == 0 and res.newton.residual_rad <= 1e-9


def test_failed_run_keeps_earlier_output(tmp_path):
    out, _ = flatten_cli(tmp_path, PART)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(["flatten", str(PART), "--out", str(out), "-q", "--corners", "0,1,2,3"]) == 1
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_version_and_help():
    res = subprocess.run([sys.executable, "-m", "workbench", "--version"], capture_output=True, text=True, check=True)
    assert res.stdout.strip() == f"workbench {__version__}"
    res = subprocess.run([sys.executable, "-m", "workbench", "flatten", "--help"], capture_output=True, text=True)
    assert res.returncode == 0 and "--corners A,B,C,D" in res.stdout
