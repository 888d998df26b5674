"""suggest-views: ranked viewpoints for the surface no view owns, measured against a dense
search of the viewing sphere, and against what design then owns."""

from __future__ import annotations

import itertools
import json
import re
import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import ROOT

from workbench.cli import main
from workbench.design import read_image
from workbench.job import load_job
from workbench.job_views import assign_job_views
from workbench.mesh.io import format_obj, read_mesh
from workbench.mesh.topology import unique_edges
from workbench.mesh.validate import face_areas
from workbench.views.suggest import (
    SuggestOptions,
    evaluate,
    remaining_surface,
    sphere_search,
    suggest_views,
    view_camera,
)
from workbench.views.visibility import assign_views, face_adjacency, view_visibility

FIXTURES = ROOT / "fixtures"
CORPUS = ROOT / "tests" / "data" / "corpus"


def job_with_views(tmp_path: Path, name: str, keep: list[str]) -> Path:
    """A bundled job with only the views named in ``keep``, its paths made absolute."""
    src = FIXTURES / name / "job.toml"
    doc = tomllib.loads(src.read_text())
    text = src.read_text().split("[[views]]")[0].replace('mesh = "part.obj"', f'mesh = "{src.parent / "part.obj"}"')
    for v in doc["views"]:
        if v["name"] in keep:
            text += "\n[[views]]\n" + "".join(
                f"{k} = {json.dumps(str(src.parent / x) if k == 'image' else x)}\n" for k, x in v.items()
            )
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def corpus_job(tmp_path: Path, name: str) -> Path:
    """A corpus mesh as a 150 mm part with one view along its mean normal, 400 mm away."""
    d = np.load(CORPUS / f"{name}.npz")
    V = d["V"].astype(np.float64)
    F = d["F"].astype(np.int64)
    V = (V - 0.5 * (V.min(0) + V.max(0))) / np.ptp(V, axis=0).max() * 150
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]).sum(axis=0)
    n /= np.linalg.norm(n)
    up = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    (tmp_path / f"{name}.obj").write_bytes(format_obj(V, F))
    cv2.imwrite(str(tmp_path / f"{name}.png"), np.full((600, 800, 3), 128, np.uint8))
    path = tmp_path / f"{name}.toml"
    path.write_text(
        f'[object]\nmesh = "{name}.obj"\n\n[print]\ndpi = 150\noutline = "free"\n\n[[views]]\nname = "first"\n'
        f'image = "{name}.png"\nposition = {(400 * n).tolist()}\nlook_at = [0, 0, 0]\nup = {up.tolist()}\n'
        "fov_deg = 30\n"
    )
    return path


def remaining(job_path: Path, options: SuggestOptions):
    job = load_job(job_path)
    V, F = read_mesh(job.object.mesh, job.object.units)
    images = [read_image(v.image, v.name) for v in job.views]
    cameras, _, status = assign_job_views(job, V, F, images)
    return job, remaining_surface(V, F, status, cameras, job.print.dpi, options)


def angles_deg(suggestions) -> list[float]:
    return [
        float(np.degrees(np.arccos(np.clip(a.direction @ b.direction, -1, 1))))
        for a, b in itertools.combinations(suggestions, 2)
    ]


def check_against_dense_search(rem, options, suggestions, n_directions=500):
    """The best suggestion owns at a good angle at least 90 % of what the best of a dense
    lattice of directions (same distance, same image size) owns; the top 3 are 20° apart."""
    assert len(suggestions) == 3
    best = suggestions[0]
    size = (best.camera.width, best.camera.height)
    dirs, good = sphere_search(rem, n_directions, best.distance_mm, size, options)
    assert len(dirs) >= 500
    assert best.good_mm2 >= 0.9 * good.max(), (best.good_mm2, good.max())
    assert min(angles_deg(suggestions)) >= 20.0
    # ranked: best first
    assert [s.score for s in suggestions] == sorted((s.score for s in suggestions), reverse=True)
    return best.good_mm2 / good.max()


def test_visibility_of_a_subset_of_faces_is_the_same():
    V, F = read_mesh(FIXTURES / "default" / "part.obj")
    cam = view_camera_for(V, [120.0, -200.0, 150.0])
    full = view_visibility(V, F, cam)
    faces = np.arange(0, len(F), 3)
    sub = view_visibility(V, F, cam, faces=faces)
    assert np.array_equal(sub.full[faces], full.full[faces]) and np.array_equal(sub.partial[faces], full.partial[faces])
    others = np.setdiff1d(np.arange(len(F)), faces)
    assert not sub.full[others].any() and not sub.partial[others].any()
    assert np.array_equal(sub.depth, full.depth)


def view_camera_for(V, position):
    from workbench.camera import Camera

    return Camera.look_at(position, [0, 0, 0], [0, 0, 1], 40, 400, 300)


def test_a_candidate_owns_what_design_would_give_it(tmp_path):
    # evaluate() is the last step of assign_views: the job's views, then the candidate
    # appended, gives the candidate exactly the faces evaluate() says, on the same mesh
    job, rem = remaining(job_with_views(tmp_path, "default", ["logo"]), SuggestOptions())
    images = [read_image(v.image, v.name) for v in job.views]
    cameras, visibilities, _ = assign_job_views(job, rem.V, rem.F, images)
    for direction in ([0.3, -0.8, 0.5], [-0.6, 0.2, 0.77]):
        cam = view_camera(rem, np.array(direction), 300.0, 500, 375)[0]
        cov = evaluate(rem, cam, 60.0)
        _, FE, _ = unique_edges(rem.F)
        status = assign_views(
            [*visibilities, view_visibility(rem.V, rem.F, cam)],
            ["largest", "largest"],
            face_adjacency(FE),
            face_areas(rem.V, rem.F),
        )
        assert np.array_equal(status[:, -1], cov.status)
        first = np.argmax(status != 0, axis=1)
        mine = (status != 0).any(axis=1) & (first == 1)
        assert cov.covers_mm2 == pytest.approx(rem.area[mine].sum(), rel=1e-12) and cov.covers_mm2 > 0


def test_default_job_without_its_front_view(tmp_path):
    # the lid with its logo view alone: two thirds of it undecorated. With the default lens
    # (the whole lid in the frame) the best suggestion owns all of it within 60° of face on:
    # no direction can own more. Through a 20° lens that frames only part of it, at a fixed
    # 320 x 240 image (so that the dense search stays quick), the best of 3 suggestions owns
    # at a good angle at least 90 % of what the best of 500 directions owns (measured:
    # 100.2 %); both times the three are 20° apart
    options = SuggestOptions(size_px=(320, 240))
    job, rem = remaining(job_with_views(tmp_path, "default", ["logo"]), options)
    share = rem.undecorated_mm2 / rem.area.sum()
    assert 0.6 < share < 0.75
    suggestions = suggest_views(rem, options)
    assert suggestions[0].good_mm2 == pytest.approx(rem.undecorated_mm2, rel=1e-9)
    assert len(suggestions) == 3 and min(angles_deg(suggestions)) >= 20.0
    options = SuggestOptions(size_px=(320, 240), fov_deg=20.0)
    job, rem = remaining(job_with_views(tmp_path, "default", ["logo"]), options)
    suggestions = suggest_views(rem, options)
    assert suggestions[0].covers_mm2 < 0.75 * rem.undecorated_mm2
    check_against_dense_search(rem, options, suggestions)
    assert all((s.camera.width, s.camera.height) == (320, 240) for s in suggestions)


def test_elevation_and_distance_constraints(tmp_path):
    options = SuggestOptions(size_px=(320, 240), min_elevation_deg=10.0, distance_mm=(300.0, 500.0), up=(0, 0, 1))
    _, rem = remaining(job_with_views(tmp_path, "default", ["logo"]), options)
    suggestions = suggest_views(rem, options)
    assert len(suggestions) == 3
    for s in suggestions:
        assert np.degrees(np.arcsin(s.direction[2])) >= 10.0 - 1e-9
        assert 300.0 - 1e-3 <= s.distance_mm <= 500.0 + 1e-3


def test_favoured_and_avoided_faces_move_the_best_view():
    # the two-views ridge, no view yet: its west and east slopes are alike. Avoiding the east
    # slope, the best view looks from the west, low enough not to own the east; favouring the
    # west slope with a 30° obliquity limit (seen from above, both slopes are beyond it), too
    from workbench.camera import Camera

    V, F = read_mesh(FIXTURES / "two-views" / "part.obj")
    cam = Camera.look_at([0, 0, 300], [0, 0, 0], [0, 1, 0], 40, 320, 240)
    status = np.zeros((len(F), 1), np.int8)
    centroid = V[F].mean(axis=1)
    east, west = centroid[:, 0] > 5, centroid[:, 0] < -5
    for kw, obliquity in (({"avoid": east}, 60.0), ({"favour": west}, 30.0)):
        options = SuggestOptions(
            size_px=(320, 240),
            distance_mm=(300, 300),
            up=(0, 0, 1),
            count=1,
            max_obliquity_deg=obliquity,
            search_directions=96,
        )
        rem = remaining_surface(V, F, status, [cam], 300, options, **kw)
        (best,) = suggest_views(rem, options)
        assert best.direction[0] < -0.15, (kw.keys(), best.direction)
        if "avoid" in kw:
            assert not best.new[east].any()


def test_suggestion_pasted_into_the_job_is_owned_as_said(tmp_path):
    # the command end to end on the lid without its front view, through a 20° lens that
    # frames only part of it: the TOML, one template per suggestion at its size, the
    # picture; the first table pasted into the job makes design own covers_mm2 (within 2 %;
    # measured: equal to 1e-5), and design reports the undecorated share it divides
    job = job_with_views(tmp_path, "default", ["logo"])
    out = tmp_path / "s" / "suggest.toml"
    args = ["suggest-views", str(job), "-o", str(out), "--size", "400x300", "--fov-deg", "20", "-q"]
    assert main(args) == 0
    doc = tomllib.loads(out.read_text())
    assert [v["name"] for v in doc["views"]] == ["suggest-1", "suggest-2", "suggest-3"]
    for v in doc["views"]:
        img = cv2.imread(str(job.parent / v["image"]))
        assert img.shape == (v["height_px"], v["width_px"], 3) == (300, 400, 3)
        assert 0.5 < v["covers_share"] < 0.9
    assert (tmp_path / "s" / "suggest-views.png").stat().st_size > 10_000
    first = out.read_text().split("\n[[views]]\n")[1]
    pasted = tmp_path / "pasted.toml"
    pasted.write_text(job.read_text() + "\n[[views]]\n" + first)
    d = tmp_path / "d"
    assert main(["design", str(pasted), "--out", str(d), "-q"]) == 0
    info = json.loads((d / "design.json").read_text())
    owned = info["views"][1]["surface_owned_mm2"]
    covers = doc["views"][0]["covers_mm2"]
    assert owned == pytest.approx(covers, rel=0.02)
    # before: the job without the suggestion; its undecorated surface is what covers_share divides
    d0 = tmp_path / "d0"
    assert main(["design", str(job), "--out", str(d0), "-q"]) == 0
    before = json.loads((d0 / "design.json").read_text())
    assert owned / before["undecorated_mm2"] == pytest.approx(doc["views"][0]["covers_share"], rel=0.02)
    assert info["undecorated_mm2"] == pytest.approx(before["undecorated_mm2"] - owned, rel=1e-6, abs=1e-6)


def test_design_reports_the_undecorated_share(tmp_path, capsys):
    job = job_with_views(tmp_path, "default", ["logo"])
    assert main(["design", str(job), "--out", str(tmp_path / "d")]) == 0
    err = capsys.readouterr().err
    info = json.loads((tmp_path / "d" / "design.json").read_text())
    total = info["mesh"]["surface_area_mm2"]
    assert info["undecorated_mm2"] == pytest.approx(total - info["views"][0]["surface_owned_mm2"], rel=1e-9)
    assert info["undecorated_share"] == pytest.approx(info["undecorated_mm2"] / total, rel=1e-9)
    line = next(x for x in err.splitlines() if x.startswith("undecorated:"))
    assert f"{100 * info['undecorated_share']:.1f} % of the surface" in line and "workbench suggest-views" in line


def test_bad_input(tmp_path, capsys):
    job = job_with_views(tmp_path, "default", ["logo"])
    out = tmp_path / "s.toml"
    for args, status, words in (
        (["-n", "0"], 2, "-n 0"),
        (["--distance-mm", "10"], 1, "--distance-mm 10"),
        (["--distance-mm", "400,300"], 2, "--distance-mm '400,300'"),
        (["--up", "0,0"], 2, "--up '0,0'"),
        (["--size", "12x"], 2, "--size '12x'"),
        (["--max-obliquity-deg", "95"], 2, "--max-obliquity-deg 95"),
        (["--favour", str(tmp_path / "nope.txt")], 2, "nope.txt"),
    ):
        capsys.readouterr()
        assert main(["suggest-views", str(job), "-o", str(out), *args]) == status, args
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err and err.startswith("workbench suggest-views: error:"), err
        assert not out.exists()
    # a view planned for another image size is refused by design, naming the key
    text = job.read_text() + "width_px = 640\nheight_px = 480\n"
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert main(["design", str(bad), "--out", str(tmp_path / "d"), "-q"]) == 1
    err = capsys.readouterr().err
    assert "views[0].width_px, height_px: 640 x 480, but the image logo.png is 1000 x 750 px" in err


@pytest.mark.slow
def test_face_mask_with_its_front_view_only(tmp_path):
    # the scanned head seen from the front alone: 67 % undecorated; at the image size the
    # print's 100 dpi needs, the best suggestion against 500 directions
    options = SuggestOptions()
    job, rem = remaining(job_with_views(tmp_path, "face-mask", ["front"]), options)
    assert rem.undecorated_mm2 / rem.area.sum() == pytest.approx(0.672, abs=0.005)
    suggestions = suggest_views(rem, options)
    check_against_dense_search(rem, options, suggestions)


@pytest.mark.slow
def test_face_mask_suggestion_pasted_into_the_job(tmp_path):
    job = job_with_views(tmp_path, "face-mask", ["front"])
    out = tmp_path / "suggest.toml"
    assert main(["suggest-views", str(job), "-o", str(out), "-n", "1", "-q"]) == 0
    doc = tomllib.loads(out.read_text())
    pasted = tmp_path / "pasted.toml"
    pasted.write_text(job.read_text() + "\n[[views]]\n" + out.read_text().split("\n[[views]]\n")[1])
    assert main(["design", str(pasted), "--out", str(tmp_path / "d"), "-q"]) == 0
    info = json.loads((tmp_path / "d" / "design.json").read_text())
    assert info["views"][1]["surface_owned_mm2"] == pytest.approx(doc["views"][0]["covers_mm2"], rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bunny-0", "cow-1"])
def test_real_meshes(tmp_path, name):
    options = SuggestOptions()
    _, rem = remaining(corpus_job(tmp_path, name), options)
    assert rem.undecorated_mm2 > 0.05 * rem.area.sum()
    suggestions = suggest_views(rem, options)
    check_against_dense_search(rem, options, suggestions)


@pytest.mark.slow
def test_real_mesh_suggestion_pasted_into_the_job(tmp_path):
    # bunny-0 on a free outline: the conformal solve flips edges, so design assigns the
    # views on the common subdivision, not on the mesh suggest-views scored (measured: 0.06 % apart)
    job = corpus_job(tmp_path, "bunny-0")
    out = tmp_path / "suggest.toml"
    assert main(["suggest-views", str(job), "-o", str(out), "-n", "1", "-q"]) == 0
    doc = tomllib.loads(out.read_text())
    pasted = tmp_path / "pasted.toml"
    pasted.write_text(job.read_text() + "\n[[views]]\n" + out.read_text().split("\n[[views]]\n")[1])
    assert main(["design", str(pasted), "--out", str(tmp_path / "d"), "-q"]) == 0
    info = json.loads((tmp_path / "d" / "design.json").read_text())
    assert info["flatten"]["intrinsic_flips"] > 0
    assert info["views"][1]["surface_owned_mm2"] == pytest.approx(doc["views"][0]["covers_mm2"], rel=0.02)


def test_nothing_left_to_suggest(tmp_path, capsys):
    # the default job's two views own every face: no suggestion, a file that says so
    out = tmp_path / "s.toml"
    assert main(["suggest-views", str(FIXTURES / "default" / "job.toml"), "-o", str(out)]) == 0
    doc = tomllib.loads(out.read_text())
    assert "views" not in doc and "nothing to suggest: no surface is left" in out.read_text()
    assert "0.0 % of the surface" in capsys.readouterr().err


def test_a_template_drawn_on_is_never_replaced(tmp_path, capsys):
    # issue 41: `suggest-views -o out/s.toml` overwrote a user's out/suggest-1.png; a rerun that
    # writes the same bytes is fine, a drawing on the template is kept and the run writes nothing
    job = job_with_views(tmp_path, "default", ["logo"])
    out = tmp_path / "s" / "s.toml"
    args = ["suggest-views", str(job), "-o", str(out), "--size", "200x150", "--fov-deg", "20", "-q"]
    assert main(args) == 0
    first = {p.name: p.read_bytes() for p in out.parent.iterdir()}
    assert "suggest-1.png" in first
    assert main(args) == 0 and {p.name: p.read_bytes() for p in out.parent.iterdir()} == first
    drawn = out.parent / "suggest-1.png"
    drawn.write_bytes(b"a picture drawn on the template")
    out.write_text("an earlier table")
    capsys.readouterr()
    assert main(args) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "suggest-1.png: exists and is not the template this run writes" in err[0]
    assert drawn.read_bytes() == b"a picture drawn on the template" and out.read_text() == "an earlier table"


def test_elevation_is_above_the_fixtures_plate_by_default(tmp_path, capsys):
    # the logo view looks down with its image's up along +y: elevations were measured from the plane
    # normal to +y (a camera overhead: "elevation 7.4°"); by default they are above the plate, +z
    job = job_with_views(tmp_path, "default", ["logo"])
    assert main(["suggest-views", str(job), "-n", "2", "--size", "320x240", "-q"]) == 0
    text = capsys.readouterr().out
    views = tomllib.loads(text)["views"]
    said = [float(x) for x in re.findall(r"elevation (-?[0-9.]+)°", text)]
    assert len(said) == len(views) == 2
    for v, elevation in zip(views, said, strict=True):
        d = np.subtract(v["position"], v["look_at"])
        assert v["up"] == [0.0, 0.0, 1.0]
        assert elevation == pytest.approx(np.degrees(np.arcsin(d[2] / np.linalg.norm(d))), abs=0.06)
    assert max(said) > 80.0  # (the suggestion overhead, 24 mm off the logo camera's axis)
