"""Real disc meshes (scans, CAD, coarse and broken patches): flattened without a fold, or refused in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_conformal_maps import check_subdivision

from workbench.cli import main
from workbench.conformal.flatten import FlattenOptions, flatten
from workbench.errors import WorkbenchError
from workbench.mesh.io import read_mesh

HERE = Path(__file__).resolve().parent
SHARED = HERE.parents[1] / "shared" / "meshes"
CORPUS = sorted((HERE / "data" / "corpus").glob("*.npz"))
# a representative subset for `make test`; `make bench` runs them all
FAST = {"bunny-0", "fandisk-1-needles", "lion-1-valence3", "cow-valence30", "decimated-knight-0-noise", "beetle-1"}


def load(path: Path):
    d = np.load(path)
    return d["V"].astype(np.float64), d["F"].astype(np.int64)


def flattens_or_is_refused_for_crowding(V, F, name):
    try:
        r = flatten(V, F, name=name)
    except WorkbenchError as exc:
        assert "below" in str(exc) and "in the print (largest region" in str(exc), str(exc)
        return None
    check_subdivision(r, V, F)
    assert not r.collapsed.any() or r.area_3d[r.collapsed].sum() <= 1e-3 * r.area_3d.sum()
    return r


@pytest.mark.parametrize(
    "path",
    [pytest.param(p, id=p.stem, marks=() if p.stem in FAST else pytest.mark.slow) for p in CORPUS],
)
def test_corpus_disc(path):
    V, F = load(path)
    for size in (None, 150.0):
        s = 1.0 if size is None else size / np.linalg.norm(V.max(0) - V.min(0))
        flattens_or_is_refused_for_crowding(V * s, F, path.name)


def test_corpus_is_large_enough():
    assert len(CORPUS) >= 30


@pytest.mark.skipif(not SHARED.is_dir(), reason="the shared meshes are not beside this checkout")
@pytest.mark.parametrize("name", ["camelhead.off", "lilium.obj", "face.obj"])
def test_same_map_at_any_unit(name):
    # a conformal map does not depend on scale: the same mesh in µm-, mm- and m-sized
    # numbers gives the same map up to that scale, and the same triangulation
    V, F = read_mesh(SHARED / name)
    # the map alone: a print resolution fine enough that crowding never refuses
    # (it is physical and scales with the part; the map does not)
    fine = 1e-6 * np.linalg.norm(V.max(0) - V.min(0))
    ref = flatten(V, F, FlattenOptions(min_print_mm=fine))
    check_subdivision(ref, V, F)
    diag = np.linalg.norm(ref.uv.max(0) - ref.uv.min(0))
    for unit in (1e-3, 1e3):
        r = flatten(V * unit, F, FlattenOptions(min_print_mm=fine * unit))
        np.testing.assert_array_equal(r.F, ref.F)
        assert np.abs(r.uv / unit - ref.uv).max() <= 1e-9 * diag


@pytest.mark.skipif(not SHARED.is_dir(), reason="the shared meshes are not beside this checkout")
def test_crowded_part_is_refused_in_one_line(capsys, tmp_path):
    # camel_b: legs and head that any rectangle shrinks to nothing
    out = tmp_path / "o"
    assert main(["flatten", str(SHARED / "camel_b.obj"), "--out", str(out), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "in the print (largest region" in err
    assert "another outline or several films" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "path",
    [pytest.param(p, id=p.stem, marks=() if p.stem in FAST else pytest.mark.slow) for p in CORPUS],
)
def test_corpus_disc_with_auto_corners(path):
    # --corners auto: a rectangle that prints every face without a fold, or one line
    # saying that none of the quadruples it predicted does, and by how much at best
    from workbench.conformal.flatten import flatten_auto_corners

    V, F = load(path)
    V = V * (150.0 / np.linalg.norm(V.max(0) - V.min(0)))
    try:
        r, search = flatten_auto_corners(V, F, name=path.name)
    except WorkbenchError as exc:
        msg = str(exc)
        assert "\n" not in msg and "prints every face onto a rectangle" in msg and "several films" in msg, msg
        return
    check_subdivision(r, V, F)
    assert r.flipped_faces == 0
    assert r.area_3d[r.crowded].sum() <= 1e-3 * r.area_3d.sum()
    # the winner is the least distorted of those that print, and the automatic corners are
    # among those compared: never worse than them
    from workbench.conformal.corners import choose_corners
    from workbench.conformal.flatten import area_distortion
    from workbench.mesh.validate import check_disc

    ok = [c["area_distortion"] for c in search["candidates"] if c["outcome"] == "ok"]
    assert area_distortion(r) == pytest.approx(min(ok), abs=1e-12)
    first = search["candidates"][0]
    assert first["corners"] == choose_corners(V, F, check_disc(V, F)[0])[0].tolist()
    if first["outcome"] == "ok":
        assert area_distortion(r) <= first["area_distortion"] + 1e-12
