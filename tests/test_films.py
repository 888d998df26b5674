"""Several films on one part: films by hand and split automatically, closed loop across seams."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_design import FIXTURES, view_check

from workbench.cli import main
from workbench.design import design
from workbench.export import texture_uv
from workbench.films.fit import fit_film, outside_band
from workbench.films.regions import cut_to_disc, disc_region, face_graph, is_disc, is_disc_region
from workbench.films.sheet import pack_films
from workbench.films.split import smoothed_owner, split_films
from workbench.job import load_job
from workbench.mesh.io import format_obj
from workbench.mesh.topology import unique_edges
from workbench.mesh.validate import face_areas


def atlas_vt(r):
    rows, cols = r.grid.shape
    return texture_uv(r.flat.uv, cols / r.grid.px_per_mm, rows / r.grid.px_per_mm, r.flat.height_mm)


def default_job_with(tmp_path, extra: str, dpi: int = 300, material: str | None = None):
    """The default job in tmp_path with extra TOML appended (films)."""
    for name in ("part.obj", "logo.png", "front.png"):
        (tmp_path / name).write_bytes((FIXTURES / "default" / name).read_bytes())
    text = (FIXTURES / "default" / "job.toml").read_text().replace("dpi = 300", f"dpi = {dpi}")
    if material:
        text = text.replace('material = { name = "PET-G film 0.3 mm", max_stretch = 1.10 }', material)
    path = tmp_path / "job.toml"
    path.write_text(extra + "\n" + text if extra.startswith("films") else text + "\n" + extra)
    return path


HAND = """
[[films]]
name = "logo"
views = ["logo"]
outline = "free"

[[films]]
name = "front"
views = ["front"]
outline = "free"
"""


def test_two_films_by_hand_keep_every_view_exact_across_the_seam(tmp_path):
    # the default lid with one film per view: the logo's film is the dome, the front's a
    # ring around it, cut open to a disc; rendered through the atlas, each view shows its
    # image as the single-film design does (median 0.1, p95 0.3 view px), seam included
    job = load_job(default_job_with(tmp_path, HAND, dpi=600))
    r = design(job)
    assert [f.name for f in r.films] == ["logo", "front"]
    owned = r.view_status != 0
    first = np.where(owned.any(axis=1), np.argmax(owned, axis=1), -1)
    for k, f in enumerate(r.films):
        # each film is a disc made of the faces its view owns (plus holes filled)
        assert is_disc(f.flat.F) and (first[f.faces] == k).mean() > 0.97
    assert r.seams["length_mm"] > 100 and r.seams["in_view_mm"] == 0.0
    vt = atlas_vt(r)
    for v in range(len(job.views)):
        mis, coverage = view_check(job, r, vt, v)
        assert len(mis) >= 8
        assert np.median(mis) <= 0.1 and np.percentile(mis, 95) <= 0.3, (v, np.median(mis), np.percentile(mis, 95))
        assert coverage >= 0.99, (v, coverage)


def test_films_write_a_print_and_layout_each_and_one_material_each(tmp_path):
    import cv2

    path = default_job_with(tmp_path, HAND, dpi=100)
    out = tmp_path / "d"
    assert main(["design", str(path), "--out", str(out), "-q"]) == 0
    info = json.loads((out / "design.json").read_text())
    assert [f["film"] for f in info["films"]] == ["1 of 2", "2 of 2"]
    for f in info["films"]:
        img = cv2.imread(str(out / f["print"]), cv2.IMREAD_UNCHANGED)
        assert img.shape[:2] == (f["height_px"], f["width_px"]) and img.shape[2] == 4
        assert (out / f["flat"]).is_file() and f["within_material_share"] > 0.99
    obj = (out / "decorated.obj").read_text()
    assert obj.count("usemtl film-") == 2
    mtl = (out / "decorated.mtl").read_text()
    assert "map_Kd print-logo.png" in mtl and "map_Kd print-front.png" in mtl
    assert info["seams"]["length_mm"] > 100
    # the GLB: one mesh per film, each with its film's print as texture
    import trimesh

    scene = trimesh.load(out / "decorated.glb")
    assert sorted(scene.geometry) == ["front", "logo"]
    for f in info["films"]:
        material = scene.geometry[f["name"]].visual.material
        image = getattr(material, "baseColorTexture", None) or material.image
        assert image.size == (f["width_px"], f["height_px"])


def plan_share(films) -> float:
    """The share of the films' surface within the band, all films together (each film's own, area-weighted)."""
    area = np.array([float(f.flat.area_3d.sum()) for f in films])
    return float(np.array([f.within for f in films]) @ area / area.sum())


def hemisphere(radius=40.0, n=48):
    """A hemisphere of radius 40 mm (a deep dome no 1.3 film covers), z up, rim at z = 0."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    keep = m.triangles_center[:, 2] > 0.0
    sub = m.submesh([np.flatnonzero(keep)], append=True)
    return np.asarray(sub.vertices), np.asarray(sub.faces, dtype=np.int64)


def test_auto_split_keeps_every_film_within_the_material(tmp_path):
    # a hemisphere under one view from above: one free film squeezes its rim (stretch far
    # outside [0.8, 1.3]); films = "auto" splits it in two, every film within the band on
    # 99 % of its surface, every decorated face on exactly one film, and the closed loop
    # through the atlas stays exact across the seams
    V, F = hemisphere()
    (tmp_path / "part.obj").write_bytes(format_obj(V, F))
    (tmp_path / "top.png").write_bytes((FIXTURES / "deformed-grid" / "top.png").read_bytes())
    path = tmp_path / "job.toml"
    path.write_text(
        """films = "auto"
[object]
mesh = "part.obj"
material = { name = "PET-G", max_stretch = 1.3 }
[print]
dpi = 400
outline = "free"
[[views]]
name = "top"
image = "top.png"
position = [0, 0, 300]
look_at = [0, 0, 0]
up = [0, 1, 0]
fov_deg = 24
"""
    )
    job = load_job(path)
    r = design(job)
    # one film does not fit, two do: the split and its merges end at two
    assert len(r.films) == 2
    for f in r.films:
        assert f.within >= 0.99, (f.name, f.within)
    covered = np.concatenate([f.faces for f in r.films])
    decorated = np.flatnonzero((r.view_status != 0).any(axis=1))
    assert len(np.unique(covered)) == len(covered) and set(decorated) <= set(covered)
    assert r.seams["length_mm"] > 0
    mis, coverage = view_check(job, r, atlas_vt(r), 0)
    assert np.median(mis) <= 0.1 and np.percentile(mis, 95) <= 0.3 and coverage >= 0.99


def test_a_ring_is_cut_open_to_a_disc():
    # an annulus (12 x 40 grid wrapped round) becomes a disc: one boundary loop, Euler
    # characteristic 1, the cut's vertices repeated after the input's
    n_r, n_t = 6, 40
    r = np.linspace(1, 2, n_r)
    t = np.linspace(0, 2 * np.pi, n_t, endpoint=False)
    R, T = np.meshgrid(r, t)
    V = np.stack([(R * np.cos(T)).ravel(), (R * np.sin(T)).ravel(), np.zeros(R.size)], 1)
    idx = np.arange(n_r * n_t).reshape(n_t, n_r)
    nxt = np.roll(idx, -1, axis=0)
    a, b, c, d = idx[:, :-1].ravel(), idx[:, 1:].ravel(), nxt[:, 1:].ravel(), nxt[:, :-1].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    assert not is_disc(F)
    Vc, Fc, source = cut_to_disc(V, F)
    assert is_disc(Fc) and len(Vc) > len(V) and (source[: len(V)] == np.arange(len(V))).all()
    assert np.allclose(Vc, V[source]) and np.allclose(face_areas(Vc, Fc), face_areas(V, F))


def test_disc_region_fills_holes_and_opens_pinches():
    # a grid with a region of two squares touching at one corner (a pinch) and a hole
    from fixtures.make_fixtures import grid_mesh

    P, F = grid_mesh(12, 12, np.random.default_rng(0), jitter=0.0)
    V = np.column_stack([P, np.zeros(len(P))])
    c = V[F].mean(axis=1)
    area = face_areas(V, F)
    ring = (np.abs(c[:, 0] - 0.5) < 0.35) & (np.abs(c[:, 1] - 0.5) < 0.35)
    ring &= ~((np.abs(c[:, 0] - 0.5) < 0.1) & (np.abs(c[:, 1] - 0.5) < 0.1))
    region = disc_region(F, ring, area, graph=face_graph(F))
    assert is_disc(F[region]) and region.sum() > ring.sum()  # the hole is filled
    blocked = np.zeros(len(F), bool)
    blocked[(np.abs(c[:, 0] - 0.5) < 0.1) & (np.abs(c[:, 1] - 0.5) < 0.1)] = True
    with pytest.raises(Exception, match="encloses"):
        disc_region(F, ring, area, allowed=~blocked)
    kept = disc_region(F, ring, area, allowed=~blocked, keep_holes=True)
    assert not is_disc(F[kept]) and is_disc(cut_to_disc(V, F[kept])[1])
    # the same judged on the part's faces: the ring is no disc, the filled region is
    assert not is_disc_region(F, kept) and is_disc_region(F, region)


def test_disc_region_takes_no_other_body_of_the_mesh_for_a_hole():
    # a sheet and, beside it, a closed body (a tetrahedron: no rim, like a scan's loose eye or
    # tooth): the sheet's region is the sheet alone, not the sheet with the body "filled in"
    V, F = grid_mesh(6)
    tet = np.array([[10.0, 0, 0], [11, 0, 0], [10, 1, 0], [10, 0, 1]])
    T = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]) + len(V)
    V, F = np.vstack([V, tet]), np.vstack([F, T])
    area = face_areas(V, F)
    sheet = np.arange(len(F)) < 72
    region = disc_region(F, np.ones(len(F), bool), area, graph=face_graph(F))
    assert (region == sheet).all()
    # a hole in the sheet is still one
    wanted = sheet.copy()
    wanted[[2 * 14, 2 * 14 + 1]] = False
    assert (disc_region(F, wanted, area, graph=face_graph(F)) == sheet).all()


def test_split_films_puts_every_decorated_body_on_films():
    # two sheets apart (a part and a loose piece beside it), both decorated: each on its own
    # film, every face on one, none on two
    from workbench.conformal.flatten import FlattenOptions

    V, F = grid_mesh(6)
    V = np.vstack([V, V + [20.0, 0.0, 0.0]])
    F = np.vstack([F, F + len(V) // 2])
    films = split_films(V, F, np.ones(len(F), bool), np.zeros(len(F), np.int64), 1.5, FlattenOptions())
    covered = np.sort(np.concatenate([f.faces for f in films]))
    assert len(films) == 2 and np.array_equal(covered, np.arange(len(F)))


def test_pack_films_places_prints_without_overlap():
    sizes = [(50, 80), (120, 40), (30, 30), (70, 70), (10, 200)]
    offsets, (rows, cols) = pack_films(sizes, 5)
    boxes = [(r, c, r + h, c + w) for (r, c), (h, w) in zip(offsets, sizes, strict=True)]
    for i, a in enumerate(boxes):
        assert a[2] <= rows and a[3] <= cols
        for b in boxes[i + 1 :]:
            assert a[2] + 5 <= b[0] or b[2] + 5 <= a[0] or a[3] + 5 <= b[1] or b[3] + 5 <= a[1]


def test_the_plan_says_what_share_of_the_surface_its_films_keep_within_the_material(tmp_path):
    # the hemisphere's films at max_stretch 1.3: design.json's within_material against the
    # stretch recomputed from each film's own triangles (a conformal map's stretch is the root
    # of the ratio of the areas on the part and on the print), and the log's line
    from workbench.commands.design import within_material, within_material_line

    V, F = hemisphere(n=24)
    (tmp_path / "part.obj").write_bytes(format_obj(V, F))
    (tmp_path / "top.png").write_bytes((FIXTURES / "deformed-grid" / "top.png").read_bytes())
    path = tmp_path / "job.toml"
    path.write_text(
        'films = "auto"\n[object]\nmesh = "part.obj"\nmaterial = { name = "PET-G", max_stretch = 1.3 }\n'
        '[print]\ndpi = 100\noutline = "free"\n[[views]]\nname = "top"\nimage = "top.png"\n'
        "position = [0, 0, 300]\nlook_at = [0, 0, 0]\nup = [0, 1, 0]\nfov_deg = 24\n"
    )
    r = design(load_job(path))
    plan = within_material(r, 1.3)
    total = outside = 0.0
    for f in r.films:
        fl = f.flat
        a3 = 0.5 * np.linalg.norm(
            np.cross(fl.V[fl.F[:, 1]] - fl.V[fl.F[:, 0]], fl.V[fl.F[:, 2]] - fl.V[fl.F[:, 0]]), axis=1
        )
        e1, e2 = fl.uv[fl.F[:, 1]] - fl.uv[fl.F[:, 0]], fl.uv[fl.F[:, 2]] - fl.uv[fl.F[:, 0]]
        a2 = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        ok = ~fl.collapsed
        st = np.sqrt(a3[ok] / a2[ok])
        total += a3[ok].sum()
        outside += a3[ok][(st > 1.3) | (st < 0.8)].sum()
    assert plan["band"] == [0.8, 1.3] and len(r.films) >= 2
    assert plan["share"] == pytest.approx(1 - outside / total, abs=1e-6) and plan["share"] >= 0.99
    assert plan["outside_mm2"] == pytest.approx(outside, rel=1e-4, abs=1e-6)
    areas = [x["area_mm2"] for x in plan["regions"]]
    assert areas == sorted(areas, reverse=True)
    if not plan["regions_not_listed"]:
        assert sum(areas) == pytest.approx(outside, abs=0.01 * len(areas))
    for x in plan["regions"]:
        # each region on the part (the hemisphere of radius 40 mm) and on a film of the plan
        assert np.linalg.norm(x["centre_mm"]) <= 40.0 + 1e-6 and x["film"] in {f.name for f in r.films}
        assert (x["stretch"] > 1.3) == (x["beyond"] == "max_stretch")
    line = within_material_line(plan)
    assert line.startswith(f"{100 * plan['share']:.2f} % of the surface within the material's band [0.8, 1.3]")


def test_films_join_where_the_plans_surface_outside_the_band_stays_within_its_budget():
    # the hemisphere at max_stretch 1.3: two films, each wholly within the band; as one film,
    # 21.6 % of it leaves the band. A budget just below that keeps two films, one just above
    # joins them, and the joined film's surface outside the band is what the budget allowed
    from workbench.conformal.flatten import FlattenOptions
    from workbench.films.fit import off_band_mm2
    from workbench.films.joins import join_within_budget

    V, F = hemisphere(n=24)
    films = split_films(V, F, np.ones(len(F), bool), np.zeros(len(F), np.int64), 1.3, FlattenOptions())
    assert len(films) == 2 and all(off_band_mm2(f) < 1e-9 for f in films)
    area = sum(float(f.flat.area_3d.sum()) for f in films)
    assert len(join_within_budget(V, F, films, 0.21 * area, 1.3, FlattenOptions())) == 2
    (one,) = join_within_budget(V, F, films, 0.23 * area, 1.3, FlattenOptions())
    assert sorted(one.faces) == list(range(len(F)))
    assert 0.21 * area < off_band_mm2(one) <= 0.23 * area


def test_split_films_counts_the_films_after_joining_them_against_the_limit():
    # the hemisphere at 1.3 ends at two films whatever the pieces the split went through: one
    # film is too few, and the refusal says how many the plan has
    from workbench.conformal.flatten import FlattenOptions
    from workbench.errors import WorkbenchError

    V, F = hemisphere(n=24)
    args = (V, F, np.ones(len(F), bool), np.zeros(len(F), np.int64), 1.3, FlattenOptions())
    assert len(split_films(*args, max_films=2)) == 2
    with pytest.raises(WorkbenchError, match=r"more than 1 films would be needed .* \(2 after joining"):
        split_films(*args, max_films=1)


def test_split_films_refuses_in_one_line_when_nothing_fits():
    # max_stretch 0.81: the band [0.8, 0.81] is too narrow for any curved piece
    from workbench.conformal.flatten import FlattenOptions
    from workbench.errors import WorkbenchError

    V, F = hemisphere(n=20)
    owner = np.zeros(len(F), dtype=np.int64)
    with pytest.raises(WorkbenchError, match="films|cannot be split"):
        split_films(V, F, np.ones(len(F), bool), owner, 0.81, FlattenOptions(), max_films=6)


def test_split_films_names_a_face_of_zero_area_not_the_material():
    # a scan's cap: one face's corner moved onto its opposite edge. No film maps it; the split
    # used to go on around it to the film limit and then blame max_stretch
    from workbench.conformal.flatten import FlattenOptions
    from workbench.errors import WorkbenchError

    V, F = hemisphere(n=20)
    V = V.copy()
    a, b, c = F[100]
    V[c] = 0.4 * V[a] + 0.6 * V[b]
    owner = np.zeros(len(F), dtype=np.int64)
    x, y, z = V[F[100]].mean(axis=0)
    with pytest.raises(
        WorkbenchError, match=rf"1 decorated faces have zero area .* at \({x:.3f}, {y:.3f}, {z:.3f}\) mm"
    ):
        split_films(V, F, np.ones(len(F), bool), owner, 1.5, FlattenOptions(), max_films=6)


@pytest.mark.parametrize(
    ("extra", "fragment"),
    [
        ('films = "auto"', "set [object].material.max_stretch"),
        ('[[films]]\nname = "a"\nviews = ["nope"]', "no view named 'nope'"),
        ('[[films]]\nname = "../x"\nviews = ["logo"]', "film name '../x'"),
        ('[[films]]\nname = "a"', "give the surface as views"),
        ('[[films]]\nname = "a"\nviews = ["logo"]\noutline = "free"\ncorners = [1, 2, 3, 4]', "corners belong"),
    ],
)
def test_film_job_errors_name_the_key(tmp_path, capsys, extra, fragment):
    material = 'material = { name = "PET-G" }' if extra.startswith("films") else None
    path = default_job_with(tmp_path, extra, material=material)
    assert main(["design", str(path), "--out", str(tmp_path / "o"), "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0] and "job.toml" in err[0], err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("share", ["1.5", "0.2", '"most"'])
def test_a_share_within_the_material_out_of_range_names_the_key(tmp_path, capsys, share):
    material = f'material = {{ name = "PET-G", max_stretch = 1.5, within_share = {share} }}'
    path = default_job_with(tmp_path, 'films = "auto"', material=material)
    assert main(["design", str(path), "--out", str(tmp_path / "o"), "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "object.material" in err[0] and "within_share" in err[0] and "job.toml" in err[0], err
    assert not (tmp_path / "o").exists()


def test_pdf_has_one_page_per_film_with_its_trim_and_label(tmp_path):
    import pypdf

    path = default_job_with(tmp_path, HAND, dpi=100)
    out = tmp_path / "d"
    assert main(["design", str(path), "--out", str(out), "-q"]) == 0
    assert main(["pdf", str(out), "-o", str(tmp_path / "p.pdf"), "--paper", "A4", "-q"]) == 0
    info = json.loads((out / "design.json").read_text())
    reader = pypdf.PdfReader(tmp_path / "p.pdf")
    assert len(reader.pages) == len(info["films"]) == 2
    for k, (page, f) in enumerate(zip(reader.pages, info["films"], strict=True)):
        box = page.trimbox
        w, h = (float(box.right) - float(box.left)) * 25.4 / 72, (float(box.top) - float(box.bottom)) * 25.4 / 72
        assert abs(w - f["width_mm"]) < 0.01 and abs(h - f["height_mm"]) < 0.01
        assert f"film {k + 1} of 2: {f['name']}" in page.extract_text()
        assert "/OCCut" in page["/Resources"]["/Properties"]


def test_render_moves_one_film_alone(tmp_path):
    # --film-offset-mm 2:0.5,-0.2 moves the texture of film 2 only, by exactly that (in
    # print px at the design's dpi); film 1 stays; a film the design lacks is refused
    from workbench.design_dir import Design
    from workbench.render.imperfections import Imperfections

    path = default_job_with(tmp_path, HAND, dpi=100)
    out = tmp_path / "d"
    assert main(["design", str(path), "--out", str(out), "-q"]) == 0
    d = Design(out)
    film = d.vertex_film()
    still = d.scene(Imperfections(), fixture=False)
    moved = d.scene(Imperfections(film_offsets_mm=((2, 0.5, -0.2),)), fixture=False)
    ppm = 100 / 25.4
    n = len(d.V)
    du = moved.uv[:n] - still.uv[:n]
    assert np.abs(du[film == 0]).max() == 0
    assert np.allclose(du[film == 1], [-0.5 * ppm, 0.2 * ppm])
    photo = tmp_path / "p.png"
    args = ["render", str(out), "--orbit", "0,60,300", "--size", "400x300", "-o", str(photo), "-q"]
    assert main([*args, "--film-offset-mm", "2:0.5,0"]) == 0
    truth = json.loads(photo.with_suffix(".json").read_text())
    assert truth["imperfections"]["film_offsets_mm"] == [[2, 0.5, 0.0]]
    assert main([*args, "--film-offset-mm", "3:0.5,0"]) == 1


def test_validate_through_the_films_atlas(tmp_path):
    # photos of the two-film lid: a perfect one passes (p95 below 0.05 mm, seam
    # included), one with film 2 moved 0.5 mm fails at p95 0.5 mm (against 0.4 mm: at the
    # default 0.5 mm the move is the tolerance itself, and its verdict a knife's edge)
    path = default_job_with(tmp_path, HAND, dpi=300)
    out = tmp_path / "d"
    assert main(["design", str(path), "--out", str(out), "-q"]) == 0
    photos = []
    for k, extra in enumerate(([], ["--film-offset-mm", "2:0.5,0"])):
        photos.append(tmp_path / f"p{k}.jpg")
        args = ["render", str(out), "--orbit", "10,55,330", "--size", "2000x1500", "-o", str(photos[-1]), "-q"]
        assert main(args + extra) == 0
    v = tmp_path / "v"
    args = ["validate", str(out), *map(str, photos), "--camera", str(tmp_path / "p0.json"), "--out", str(v), "-q"]
    main([*args, "--tolerance-mm", "0.4"])
    perfect, moved = json.loads((v / "validation.json").read_text())["photos"]
    assert perfect["verdict"] == "PASS" and perfect["misregistration_mm"]["p95"] < 0.05
    assert moved["verdict"] == "FAIL" and abs(moved["misregistration_mm"]["p95"] - 0.5) < 0.05
    # placement per film: the front view's film is measured moved by (0.5, 0) to 0.05 mm;
    # the same photo compared with the logo's view finds the logo's film in place
    front = {f["name"]: f for f in moved["films"]}["front"]
    assert front["tiles"] >= 8 and np.allclose(front["offset_mm"], [0.5, 0.0], atol=0.05)
    assert np.allclose({f["name"]: f for f in perfect["films"]}["front"]["offset_mm"], [0, 0], atol=0.05)
    v2 = tmp_path / "v2"
    main(
        ["validate", str(out), str(photos[1]), "--camera", str(tmp_path / "p0.json"), "--view", "logo"]
        + ["--out", str(v2), "-q"]
    )
    (entry,) = json.loads((v2 / "validation.json").read_text())["photos"]
    logo = {f["name"]: f for f in entry["films"]}["logo"]
    assert logo["tiles"] >= 8 and np.allclose(logo["offset_mm"], [0.0, 0.0], atol=0.05)
    # the QA report has a page per film with its placement per photo
    import pypdf

    text = [page.extract_text() for page in pypdf.PdfReader(v / "qa_report.pdf").pages]
    front_page = next(t for t in text if "film 2 of 2: front" in t)
    offset = front["offset_mm"]
    assert "p1.jpg" in front_page and f"{offset[0]:+.3f}, {offset[1]:+.3f}" in front_page
    assert any("film 1 of 2: logo" in t for t in text)


@pytest.mark.slow
def test_face_mask_splits_into_films_within_the_material_and_stays_exact():
    # the bundled face-mask-films job: the films within [0.8, 1.3] on 99 % of the surface, every
    # decorated face on one film, and the closed loop through the atlas exact in every
    # view across the seams (median 0.1 px, p95 0.3 px)
    job = load_job(FIXTURES / "face-mask-films" / "job.toml")
    r = design(job)
    assert len(r.films) >= 2 and plan_share(r.films) >= 0.99
    covered = np.concatenate([f.faces for f in r.films])
    decorated = np.flatnonzero((r.view_status != 0).any(axis=1))
    assert len(np.unique(covered)) == len(covered) and set(decorated) <= set(covered)
    vt = atlas_vt(r)
    for v in range(len(job.views)):
        mis, coverage = view_check(job, r, vt, v)
        assert np.median(mis) <= 0.1 and np.percentile(mis, 95) <= 0.3, (v, np.median(mis), np.percentile(mis, 95))
        assert coverage >= 0.99, (v, coverage)


def test_stretch_window_centres_the_band_on_the_most_surface():
    from workbench.films.fit import stretch_window

    # 90 % of the area between 2.0 and 2.4 (log spread 0.18 < log(1.3 / 0.8) = 0.49), the
    # rest far off: scaled by s, that 90 % sits inside [0.8, 1.3] with equal margins
    stretch = np.r_[np.linspace(2.0, 2.4, 90), np.full(10, 9.0)]
    area = np.ones(100)
    s, share = stretch_window(stretch, area, 1.3)
    assert share == pytest.approx(0.9)
    lo, hi = np.log(2.0 / s / 0.8), np.log(1.3 / (2.4 / s))
    assert lo > 0 and hi > 0 and lo == pytest.approx(hi)


def test_a_mesh_no_rectangle_prints_is_made_by_films():
    # cow-1 of the real-mesh corpus: every rectangle crowds part of it below half a
    # print pixel (150 mm part, 300 dpi); split into films of max_stretch 1.5, every
    # face is on exactly one film and every film is within the band (3 films; 23
    # before the merges)
    from conftest import ROOT

    from workbench.conformal.flatten import CrowdingError, FlattenOptions, flatten

    d = np.load(ROOT / "tests" / "data" / "corpus" / "cow-1.npz")
    V = d["V"] / np.ptp(d["V"], axis=0).max() * 150
    F = d["F"]
    options = FlattenOptions(min_print_mm=0.5 * 25.4 / 300)
    with pytest.raises(CrowdingError):
        flatten(V, F, options)
    films = split_films(V, F, np.ones(len(F), bool), np.zeros(len(F), np.int64), 1.5, options)
    covered = np.concatenate([f.faces for f in films])
    assert np.array_equal(np.sort(covered), np.arange(len(F)))
    assert plan_share(films) >= 0.99 and len(films) >= 2
    # the fewest the merges reach: no two adjacent films could be one (their union is
    # no disc, or leaves the band, overlaps itself or crowds)
    graph = face_graph(F)
    film_of = np.full(len(F), -1)
    for k, f in enumerate(films):
        film_of[f.faces] = k
    _, _, edge_faces = graph
    inner = edge_faces[edge_faces[:, 1] >= 0]
    a, b = film_of[inner[:, 0]], film_of[inner[:, 1]]
    pairs = sorted({(min(x, y), max(x, y)) for x, y in zip(a.tolist(), b.tolist(), strict=True) if x != y})
    assert pairs
    for x, y in pairs:
        faces = np.union1d(films[x].faces, films[y].faces)
        region = np.isin(np.arange(len(F)), faces)
        assert not is_disc_region(F, region, graph) or fit_film(V, F, faces, 1.5, options)[0] is None, (x, y)


# (46 s; validating through the films' atlas stays in make test)
@pytest.mark.slow
def test_validate_measures_the_misregistration_across_seams(tmp_path):
    # the lid in three films cut across x = -15 and x = 15 mm (both seams cross the logo
    # view's dome); a photo with film 1 (west) moved by (0.5, 0) mm in its print, scored
    # against the logo view: the west film is measured moved, the seam west | mid apart
    # by 0.5 mm times the west film's scale on the part (its stretch, within 1 % of 1
    # here), the seam mid | east in place; a perfect photo finds both seams in place
    from workbench.mesh.io import read_mesh

    V, F = read_mesh(FIXTURES / "default" / "part.obj")
    x = V[F].mean(axis=1)[:, 0]
    films = ""
    for name, faces in (("west", x < -15), ("mid", np.abs(x) <= 15), ("east", x > 15)):
        (tmp_path / f"{name}.txt").write_text("\n".join(map(str, np.flatnonzero(faces))))
        films += f'\n[[films]]\nname = "{name}"\nfaces = "{name}.txt"\noutline = "free"\n'
    out = tmp_path / "d"
    assert main(["design", str(default_job_with(tmp_path, films)), "--out", str(out), "-q"]) == 0
    info = json.loads((out / "design.json").read_text())
    west = info["films"][0]
    photos = []
    for k, extra in enumerate(([], ["--film-offset-mm", "1:0.5,0"])):
        photos.append(tmp_path / f"p{k}.jpg")
        args = ["render", str(out), "--orbit", "10,55,330", "--size", "2000x1500", "-o", str(photos[-1]), "-q"]
        assert main(args + extra) == 0
    v = tmp_path / "v"
    main(
        ["validate", str(out), *map(str, photos), "--camera", str(tmp_path / "p0.json"), "--view", "logo"]
        + ["--out", str(v), "-q"]
    )
    perfect, moved = json.loads((v / "validation.json").read_text())["photos"]
    fits = {f["name"]: f for f in moved["films"]}
    assert all(f["measured"] and f["tiles"] >= 8 for f in fits.values())
    assert np.allclose(fits["west"]["offset_mm"], [0.5, 0.0], atol=0.05)
    seams = {tuple(s["films"]): s for s in moved["seams"]}
    assert sorted(seams) == [("mid", "east"), ("west", "mid")]
    for s in seams.values():
        assert 20 < s["seen_mm"] <= s["length_mm"] + 1e-9
    # the seams validate finds on the atlas are the design's, edge for edge
    assert sum(s["length_mm"] for s in seams.values()) == pytest.approx(info["seams"]["length_mm"], rel=1e-9)
    truth = 0.5 * west["stretch"]["p50"]
    mis = seams[("west", "mid")]["misregistration_mm"]
    assert abs(mis["mean"] - truth) < 0.05 and mis["max"] < 0.5 * west["stretch"]["max"] + 0.05, mis
    assert seams[("mid", "east")]["misregistration_mm"]["max"] < 0.05
    for s in perfect["seams"]:
        assert s["misregistration_mm"]["max"] < 0.05, s
    import pypdf

    text = "".join(page.extract_text() for page in pypdf.PdfReader(v / "qa_report.pdf").pages)
    assert "seams between films" in text and f"{mis['mean']:.3f}" in text


@pytest.mark.slow
def test_face_mask_film_moved_is_measured_and_the_others_stay(tmp_path):
    # the face mask split automatically; photos of its front view at twice the view's
    # resolution. In a perfect photo every film the view measures is in place (0.05 mm);
    # with the film of most tiles moved by (0.5, 0) mm, that film is measured moved and
    # every other measured film in place, each within 0.05 mm; a film with fewer than
    # four tiles in this view is reported unmeasured, and so are its seams
    out = tmp_path / "d"
    assert main(["design", str(FIXTURES / "face-mask-films" / "job.toml"), "--out", str(out), "-q"]) == 0
    info = json.loads((out / "design.json").read_text())
    cam = next(v["camera"] for v in info["views"] if v["name"] == "front")
    K = np.asarray(cam["K"], dtype=float)
    K[:2] *= 2
    K[:2, 2] += 0.5  # pixel centres: x' = (x + 0.5) 2 - 0.5
    w, h = cam["image_size"]
    camera = {"K": K.tolist(), "dist": [0.0] * 5, "image_size": [2 * w, 2 * h], "R": cam["R"], "t": cam["t"]}
    (tmp_path / "front2.json").write_text(json.dumps(camera))

    def measure(name, extra):
        photo = tmp_path / f"{name}.jpg"
        args = ["render", str(out), "--camera", str(tmp_path / "front2.json"), "-o", str(photo), "-q", *extra]
        assert main(args) == 0
        v = tmp_path / f"v-{name}"
        main(
            ["validate", str(out), str(photo), "--camera", str(tmp_path / "front2.json"), "--view", "front"]
            + ["--out", str(v), "-q"]
        )
        (entry,) = json.loads((v / "validation.json").read_text())["photos"]
        return entry

    perfect = measure("perfect", [])
    films = {f["name"]: f for f in perfect["films"]}
    for f in films.values():
        assert f["measured"] == (f["tiles"] >= 4)
        if f["measured"]:
            assert np.hypot(*f["offset_mm"]) < 0.05, f
    k = max(range(len(info["films"])), key=lambda i: perfect["films"][i]["tiles"])
    name = info["films"][k]["name"]
    moved = measure("moved", ["--film-offset-mm", f"{k + 1}:0.5,0"])
    measured = [f for f in moved["films"] if f["measured"]]
    assert len(measured) >= 2 and any(f["name"] == name for f in measured)
    for f in measured:
        truth = [0.5, 0.0] if f["name"] == name else [0.0, 0.0]
        assert np.hypot(*np.subtract(f["offset_mm"], truth)) < 0.05, f
    unmeasured = {f["name"] for f in moved["films"] if not f["measured"]}
    for s in moved["seams"]:
        assert bool(set(s["films"]) & unmeasured) == ("misregistration_mm" not in s), s
    # across a seam of the moved film with a measured one, the inks land apart by 0.5 mm
    # times the moved film's scale on the part along print x, which the design's
    # geometry gives edge by edge: the measured mean lies within the seam's range
    from workbench.design_dir import Design
    from workbench.validate.films import film_seams

    d = Design(out)
    edges = film_seams(d.V, d.F, d.flat, info["print"]["height_mm"], info["films"])
    names = [f["name"] for f in info["films"]]
    checked = 0
    for s in moved["seams"]:
        if name not in s["films"] or "misregistration_mm" not in s:
            continue
        a, b = sorted(names.index(n) for n in s["films"])
        on = (edges.films[:, 0] == a) & (edges.films[:, 1] == b)
        truth = np.linalg.norm(edges.J[on, 0 if a == k else 1] @ [0.5, 0.0], axis=1)
        mean = s["misregistration_mm"]["mean"]
        assert truth.min() - 0.05 < mean < truth.max() + 0.05, (s, truth.min(), truth.max())
        checked += 1
    assert checked >= 1


def grid_mesh(n: int):
    """An n x n grid of 1 mm squares in the plane z = 0, two triangles each (face 2k and 2k + 1 in square k,
    squares row by row)."""
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    F = np.stack([np.stack([i, i + 1, i + n + 2], -1), np.stack([i, i + n + 2, i + n + 1], -1)], 1).reshape(-1, 3)
    return V, F


def test_smoothed_owner_straightens_a_zig_zag_border_and_keeps_a_straight_one():
    n = 12
    V, F = grid_mesh(n)
    _, FE, _ = unique_edges(F)
    edge_faces = face_graph(F)[2]
    col = np.repeat(np.arange(n * n) % n, 2)
    straight = np.where(col < 6, 0, 1)
    everywhere = np.ones(len(F), bool)
    # a border between whole squares: every face has one neighbour across it at most
    assert (smoothed_owner(straight, edge_faces, FE, everywhere) == straight).all()
    # notches one triangle deep: every other square's upper triangle beside the border taken by
    # view 1, and an island of one triangle of view 2 inside view 0
    zig = straight.copy()
    square = np.arange(n * n)
    notch = 2 * square[(square % n == 5) & (square // n % 2 == 0)] + 1
    zig[notch] = 1
    zig[2 * (3 * n + 2)] = 2
    f = np.arange(len(F))[:, None]
    across = np.where(edge_faces[FE, 0] == f, edge_faces[FE, 1], edge_faces[FE, 0])

    def notched(owner, region):
        # faces of the region two of whose neighbours in it share another owner
        nb = np.where((across >= 0) & region[np.maximum(across, 0)], owner[np.maximum(across, 0)], -9)
        a, b = nb[:, [0, 0, 1]], nb[:, [1, 2, 2]]
        return region & ((a == b) & (a != owner[:, None]) & (a >= -1)).any(axis=1)

    assert notched(zig, everywhere).sum() >= n // 2 + 1
    out = smoothed_owner(zig, edge_faces, FE, everywhere)
    # no notch is left, the island is gone, and the border moved by half a square at most (the
    # notches' squares go one way or the other whole, or split along their diagonal)
    assert not notched(out, everywhere).any() and out[2 * (3 * n + 2)] == 0
    assert (out[col < 5] == 0).all() and (out[col > 6] == 1).all() and (out[(col == 6)] == 1).all()
    # nothing outside the region changes, and its owners do not count
    region = col >= 3
    out = smoothed_owner(zig, edge_faces, FE, region)
    assert (out[~region] == zig[~region]).all() and not notched(out, region).any()


def test_outside_band_finds_each_region_its_area_centre_and_worst_stretch():
    n = 10
    V, F = grid_mesh(n)
    area = np.full(len(F), 0.5)
    stretch = np.ones(len(F))
    square = np.repeat(np.arange(n * n), 2)
    r, c = square // n, square % n
    a = (r >= 1) & (r < 4) & (c >= 1) & (c < 4)  # 3 x 3 squares stretched 2.0, one face 2.5
    b = (r >= 6) & (r < 8) & (c >= 6) & (c < 8)  # 2 x 2 squares squeezed to 0.5
    stretch[a], stretch[b] = 2.0, 0.5
    stretch[np.flatnonzero(a)[4]] = 2.5
    ok = np.ones(len(F), bool)
    labels, figures = outside_band(V, F, stretch, area, ok, 1.5)
    assert len(figures) == 2 and (labels[a] == 0).all() and (labels[b] == 1).all() and (labels[~(a | b)] == -1).all()
    assert figures[0] == pytest.approx([9.0, 2.5, 2.5, 0.0, 2.5])
    assert figures[1] == pytest.approx([4.0, 7.0, 7.0, 0.0, 0.5])
    # a face whose stretch is not known (collapsed in the plane) belongs to no region
    ok[b] = False
    labels, figures = outside_band(V, F, stretch, area, ok, 1.5)
    assert len(figures) == 1 and (labels[b] == -1).all()
    assert outside_band(V, F, np.ones(len(F)), area, ok, 1.5)[1].shape == (0, 5)


@pytest.mark.slow
def test_a_scanned_cow_designs_on_few_films_and_says_what_stays_within_the_material(tmp_path):
    # Spot (CC0), 120 mm, a film of max_stretch 1.5 and three views of a photograph: films =
    # "auto" keeps 99 % of the seen surface within [0.8, 1.5] on at most 8 films (48 pieces
    # and a refusal before the views' borders were made straight and the films joined again
    # within the plan's share), every decorated face on one film, and design.json says the
    # share, what lies outside and where
    import matplotlib.cbook

    data = FIXTURES.parent / "tests" / "data" / "scans" / "spot.ply"
    (tmp_path / "part.ply").write_bytes(data.read_bytes())
    with matplotlib.cbook.get_sample_data("grace_hopper.jpg") as f:
        (tmp_path / "art.jpg").write_bytes(f.read())
    views = "".join(
        f'[[views]]\nname = "{n}"\nimage = "art.jpg"\nposition = [{x}, 0, {z}]\nlook_at = [0, 0, 0]\n'
        "up = [0, 1, 0]\nfov_deg = 20\n"
        for n, x, z in (("front", 0.0, 400.0), ("left", -346.4, 200.0), ("right", 346.4, 200.0))
    )
    path = tmp_path / "job.toml"
    path.write_text(
        'films = "auto"\n[object]\nmesh = "part.ply"\nsurface = "seen"\n'
        'material = { name = "PET-G", max_stretch = 1.5, within_share = 0.99 }\n'
        '[print]\ndpi = 100\noutline = "free"\n' + views
    )
    out = tmp_path / "d"
    assert main(["design", str(path), "--out", str(out), "-q"]) == 0
    info = json.loads((out / "design.json").read_text())
    plan = info["within_material"]
    assert 2 <= len(info["films"]) <= 8
    assert plan["share"] >= 0.99 and plan["stated_share"] == 0.99
    # every face of the seen surface on one film
    assert sum(f["faces"] for f in info["films"]) == info["surface"]["selected_faces"]
    # the regions outside the band lie on the cow (66 x 118 x 120 mm about its centre)
    for x in plan["regions"]:
        assert (np.abs(x["centre_mm"]) <= np.array([33.0, 60.0, 60.0]) + 1e-6).all()
