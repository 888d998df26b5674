"""Bad input to workbench flatten: one clear line, exit status 1 (2 for usage), nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from workbench.cli import main
from workbench.mesh.io import format_obj, read_mesh
from workbench.mesh.topology import unique_edges


def run(capsys, tmp_path, mesh_path, *extra):
    out = tmp_path / "out"
    status = main(["flatten", str(mesh_path), "--out", str(out), "-q", *extra])
    err = capsys.readouterr().err.strip()
    assert not out.exists(), "a failed run must write nothing"
    assert "Traceback" not in err and len(err.splitlines()) == 1
    return status, err


def write(tmp_path, V, F, name="m.obj"):
    path = tmp_path / name
    path.write_bytes(format_obj(np.asarray(V, float), np.asarray(F)))
    return path


@pytest.fixture
def square(grid):
    P, F = grid(6, 5, np.random.default_rng(0))
    return np.column_stack([P * 10, np.zeros(len(P))]), F


def expect(capsys, tmp_path, path, fragment, *extra, status=1):
    got, err = run(capsys, tmp_path, path, *extra)
    assert got == status
    assert fragment in err, err
    return err


def test_closed_mesh(capsys, tmp_path):
    ico = trimesh.creation.icosphere(subdivisions=2)
    path = write(tmp_path, ico.vertices, ico.faces)
    expect(capsys, tmp_path, path, "mesh is closed (no boundary)")


def test_mesh_with_a_hole(capsys, tmp_path, grid):
    P, F = grid(8, 8, np.random.default_rng(0))
    V = np.column_stack([P, np.zeros(len(P))])
    centre = 3 * 8 + 3
    # remove an interior vertex and its faces, renumbering the rest
    V2 = np.delete(V, centre, axis=0)
    F2 = F[~(F == centre).any(1)]
    F2 = F2 - (F2 > centre)
    path = write(tmp_path, V2, F2)
    expect(capsys, tmp_path, path, "mesh has 2 boundary loops; a disc has 1")


def test_several_components(capsys, tmp_path, square):
    V, F = square
    path = write(tmp_path, np.vstack([V, V + [20, 0, 0]]), np.vstack([F, F + len(V)]))
    expect(capsys, tmp_path, path, "mesh has 2 connected components (sizes 40, 40 faces); a disc has 1")


def test_non_manifold_edge(capsys, tmp_path, square):
    V, F = square
    E, _, count = unique_edges(F)
    a, b = E[np.flatnonzero(count == 2)[0]]  # an interior edge gets a third face
    V2 = np.vstack([V, [[0, 0, 5]]])
    path = write(tmp_path, V2, np.vstack([F, [[a, b, len(V)]]]))
    err = expect(capsys, tmp_path, path, "non-manifold edges")
    assert f"edge ({min(a, b)}, {max(a, b)}) is shared by 3 faces" in err


def test_non_manifold_vertex(capsys, tmp_path, grid):
    # a strip whose two end corners are the same vertex: edge-connected, pinched at one point
    P, F = grid(10, 3, np.random.default_rng(0))
    V = np.column_stack([P * [30, 3], np.zeros(len(P))])
    F = np.where(F == 9, 0, F)  # vertex 9 (end of the first row) becomes vertex 0
    keep = np.setdiff1d(np.arange(len(V)), [9])
    remap = np.full(len(V), -1)
    remap[keep] = np.arange(len(keep))
    path = write(tmp_path, V[keep], remap[F])
    expect(capsys, tmp_path, path, "non-manifold vertices where separate fans of faces meet (vertex 0)")


def test_zero_area_face(capsys, tmp_path, square):
    V, F = square
    V = V.copy()
    f = F[7]
    V[f[2]] = 0.5 * (V[f[0]] + V[f[1]])  # collinear
    path = write(tmp_path, V, F)
    # named by the file's line (issue 41: by triangle number, which a polygon's fan shifts)
    line = 1 + [k for k, s in enumerate(path.read_text().splitlines()) if s.startswith("f ")][7]
    expect(capsys, tmp_path, path, f"faces have zero area (the face on line {line} of the file (triangle 7))")


def test_a_polygon_is_named_by_its_line(capsys, tmp_path):
    # a hexagon fan-triangulated: its first triangle (vertices 1, 2, 3 on one line) has no area
    path = tmp_path / "hex.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 0 1 0\n# a hexagon\nf 1 2 3 4 5 6\n")
    expect(capsys, tmp_path, path, "1 faces have zero area (the face on line 8 of the file (triangle 0))")


def test_unreferenced_vertex(capsys, tmp_path, square):
    V, F = square
    path = write(tmp_path, np.vstack([V, [[1, 2, 3]]]), F)
    expect(capsys, tmp_path, path, f"1 vertices are not used by any face (vertex {len(V)})")


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_non_finite_coordinates(capsys, tmp_path, square, value):
    V, F = square
    path = tmp_path / "m.obj"
    lines = format_obj(V, F).decode().splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("v "))
    lines[i] = f"v {value} 0 0"
    path.write_text("\n".join(lines) + "\n")
    expect(capsys, tmp_path, path, "vertices have NaN or infinite coordinates (vertex 0)")


def test_inconsistent_orientation(capsys, tmp_path, square):
    V, F = square
    F = F.copy()
    F[5] = F[5, ::-1]
    path = write(tmp_path, V, F)
    expect(capsys, tmp_path, path, "faces are inconsistently oriented: the faces on lines")


@pytest.mark.parametrize(
    ("corners", "fragment"),
    [
        ("0,5,29,7", "corner 7 is not on the boundary"),
        ("0,5,29,5", "corner 5 is given twice"),
        ("0,5,29,99", "corner 99 does not exist (the mesh has 30 vertices"),
        ("0,24,29,5", "not in counter-clockwise order along the boundary"),
    ],
)
def test_bad_corners(capsys, tmp_path, square, corners, fragment):
    V, F = square
    expect(capsys, tmp_path, write(tmp_path, V, F), fragment, "--corners", corners)


def test_wrong_order_suggests_the_right_one(capsys, tmp_path, square):
    V, F = square
    err = expect(capsys, tmp_path, write(tmp_path, V, F), "did you mean 0,5,29,24?", "--corners", "0,24,29,5")
    assert err.startswith("workbench flatten: error:")


@pytest.mark.parametrize("corners", ["0,5,29", "a,b,c,d", "1,2,3,4,5"])
def test_malformed_corners_are_a_usage_error(capsys, tmp_path, square, corners):
    V, F = square
    expect(capsys, tmp_path, write(tmp_path, V, F), "--corners", "--corners", corners, status=2)


@pytest.mark.parametrize("scale", ["width=-3", "height=abc", "big"])
def test_bad_scale_is_a_usage_error(capsys, tmp_path, square, scale):
    V, F = square
    expect(capsys, tmp_path, write(tmp_path, V, F), "--scale", "--scale", scale, status=2)


def test_unreadable_files(capsys, tmp_path):
    missing = tmp_path / "nope.obj"
    expect(capsys, tmp_path, missing, f"{missing}: no such file")
    garbage = tmp_path / "g.ply"
    garbage.write_bytes(b"\x00\x01 not a ply file at all")
    expect(capsys, tmp_path, garbage, f"{garbage}: cannot read mesh")
    odd = tmp_path / "m.xyz"
    odd.write_text("1 2 3\n")
    expect(capsys, tmp_path, odd, "unknown mesh type '.xyz'")
    bad_face = tmp_path / "f.obj"
    bad_face.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")
    expect(capsys, tmp_path, bad_face, f"{bad_face}:4: malformed face line")
    out_of_range = tmp_path / "r.obj"
    out_of_range.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    expect(capsys, tmp_path, out_of_range, "the face on line 4 of the file (triangle 0) refers to a vertex that does")


@pytest.mark.parametrize("depth", [0.5, 20.0], ids=["small-ear", "long-ear"])
def test_ears_are_opened_by_intrinsic_flips(capsys, tmp_path, square, depth):
    # an ear below side AB: its apex has one face, and as a non-corner its angle must
    # open to 180°; on the input triangles it collapses (the earlier refusal), with
    # Ptolemy flips the apex gains a second triangle and the map exists
    V, F = square
    ear = len(V)
    V = np.vstack([V, [[5.0, -depth, 0.0]]])
    F = np.vstack([F, [[2, ear, 3]]])
    path = write(tmp_path, V, F)
    assert main(["flatten", str(path), "--out", str(tmp_path / "o"), "-q", "--corners", "0,5,29,24"]) == 0
    info = json.loads((tmp_path / "o" / "flatten.json").read_text())
    assert info["intrinsic_flips"] > 0 and info["flipped_faces"] == 0
    assert info["collapsed_faces"]["count"] == 0
    flat, Fo = read_mesh(tmp_path / "o" / "flat.obj")
    assert len(flat) == info["output_mesh"]["vertices"] and len(Fo) == info["output_mesh"]["faces"]
    a, b, c = flat[Fo[:, 0], :2], flat[Fo[:, 1], :2], flat[Fo[:, 2], :2]
    cross = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    assert (cross > 0).all()
    # the ear's apex lies on side AB of the rectangle
    assert flat[ear, 1] == pytest.approx(0.0, abs=1e-9)


def test_usage_error_without_mesh(capsys):
    assert main(["flatten"]) == 2
    assert "the following arguments are required: MESH" in capsys.readouterr().err


def test_tab_separated_obj_lines_are_read(tmp_path, square):
    # a face line separated by TABs (and an indented vertex line) is read, not skipped
    V, F = square
    text = format_obj(V, F).decode().splitlines()
    i = next(k for k, line in enumerate(text) if line.startswith("f "))
    text[i] = text[i].replace(" ", "\t")
    j = next(k for k, line in enumerate(text) if line.startswith("v "))
    text[j] = "  " + text[j]
    path = tmp_path / "tabs.obj"
    path.write_text("\n".join(text) + "\n")
    V2, F2 = read_mesh(path)
    np.testing.assert_array_equal(F2, F)
    np.testing.assert_allclose(V2, V, atol=1e-9)
