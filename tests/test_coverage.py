"""A PASS is evidence only where the photos could have found a defect: the part's coverage per film and class."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT

from workbench.camera import Camera
from workbench.cli import main
from workbench.design_dir import Design
from workbench.render.defects import FILM_RGB
from workbench.validate import coverage, dense, print_warp
from workbench.validate.photo import design_print_grid

FILM = (255.0, 255.0, 255.0)
PPM = 10.0  # grid px per print mm


def test_where_each_defect_would_show_is_the_designs():
    # bare film, a pale ink (ΔE about 8 from the film, a step of 20 grey levels:
    # within the colour test's reach of 80, so broad ink loss is not sought there), a dark ink
    # (sought), a checker (a slide in any direction shows), vertical stripes (a slide along
    # them changes nothing) and a checker of two colours of one grey
    # (bands 150 px wide: the slide's window, 12 px, reaches 36 px into a band from its sides)
    ref = np.full((200, 900, 3), 255, np.uint8)
    ref[:, 150:300] = 235
    ref[:, 300:450] = 40
    jj, ii = np.meshgrid(np.arange(150), np.arange(200))
    ref[:, 450:600] = np.where(((ii // 10 + jj // 10) % 2 == 0)[..., None], 30, 220)
    ref[:, 600:750] = np.where(((jj // 10) % 2 == 0)[..., None], 30, 220)
    ref[:, 750:900] = np.where(((ii // 10 + jj // 10) % 2 == 0)[..., None], (200, 100, 100), (69, 156, 156))
    opts = coverage.CoverageOptions(tolerance_mm=0.5, max_delta_e=3.0)
    shows = coverage.where_defects_show(ref, PPM, FILM, opts)
    inner = slice(50, 150)

    def share(mask, band):
        return float(mask[inner, 150 * band + 50 : 150 * band + 100].mean())

    assert share(shows["ink_gone"], 0) == 0 and share(shows["scratch"], 0) == 0
    assert share(shows["ink_gone"], 1) == 0 and share(shows["ink_not_sought"], 1) == 1
    assert share(shows["scratch"], 1) == 1  # a scratch is sought against its surroundings
    assert share(shows["ink_gone"], 2) == 1
    assert share(shows["slide"], 2) == 0  # uniform ink: a slide changes nothing
    assert share(shows["slide"], 3) == 1
    assert share(shows["slide"], 4) == 0 and share(shows["slide_not_sought"], 4) == 0  # stripes: nothing shows
    # a checker of two colours of one grey: a slide shows, but the flow, on grey, cannot find it
    assert share(shows["slide"], 5) == 0 and share(shows["slide_not_sought"], 5) == 1


def test_a_slide_along_a_line_that_turns_slowly_does_not_show_and_one_over_dots_does():
    # a ring of 12 mm radius, 0.4 mm wide, of dark ink: over the slide's window (a Gaussian of
    # 1.2 mm) the line turns by about 10°, so a slide along it moves the line by a sixth of
    # itself, within the misregistration tolerance, though that sixth changes the colour of
    # its edge pixels by far more than ΔE 3; dots of 1 mm on a 2 mm pitch show a slide in every
    # direction whole
    ref = np.full((300, 600, 3), 255, np.uint8)
    ii, jj = np.mgrid[0:300, 0:600]
    ring = np.abs(np.hypot(ii - 150, jj - 150) - 120) < 2
    ref[ring] = 30
    ref[(np.hypot(ii % 20 - 10, (jj - 300) % 20 - 10) < 5) & (jj >= 300)] = 30
    for tol in (0.2, 0.5):
        shows = coverage.where_defects_show(ref, PPM, FILM, coverage.CoverageOptions(tolerance_mm=tol))
        either = shows["slide"] | shows["slide_not_sought"]
        assert not either[ring & (jj < 300)].any()
        assert shows["slide"][100:200, 400:500].all()


def test_each_films_share_is_counted_over_where_the_class_shows():
    H, W = 100, 200
    film = np.full((H, W), -1, np.int16)
    film[:, :100] = 0
    film[:, 100:] = 1
    shows = {c: np.zeros((H, W), bool) for c in coverage.CLASSES}
    found = {c: np.zeros((H, W), bool) for c in coverage.CLASSES}
    shows["ink_gone"][:, :] = True
    found["ink_gone"][:, :97] = True  # film 1: 97 %
    found["ink_gone"][:, 100:150] = True  # film 2: 50 %
    shows["slide"][:50, :100] = True
    found["slide"][:50, :100] = True  # film 1: all of where it shows; film 2: it shows nowhere
    opts = coverage.CoverageOptions(min_coverage=0.95)
    f1, f2 = coverage.film_coverage(found, shows, film, PPM, opts)
    assert f1["film"] == 1 and f1["area_mm2"] == pytest.approx(H * 100 / PPM**2)
    assert f1["ink_gone"]["share"] == pytest.approx(0.97) and f1["ink_gone"]["covered"]
    assert f2["ink_gone"]["share"] == pytest.approx(0.5) and not f2["ink_gone"]["covered"]
    assert f1["slide"]["share"] == 1.0 and f2["slide"]["share"] is None and f2["slide"]["covered"]
    assert f2["scratch"]["share"] is None
    words = coverage.coverage_words([f1, f2], opts)
    assert "ink that is gone on 50 % of film 2" in words and "film 1" not in words


def test_uncovered_regions_say_where_and_why():
    H, W = 120, 200
    combined = np.full((H, W), print_warp.FULL, np.uint8)
    combined[10:50, 10:60] = print_warp.HIGHLIGHT  # 4 x 5 mm under a glint
    combined[70:110, 100:180] = print_warp.OCCLUDED  # 4 x 8 mm hidden
    unc = {c: np.zeros((H, W), bool) for c in coverage.CLASSES}
    unc["ink_gone"][10:50, 10:60] = True
    unc["slide"][70:110, 100:180] = True
    unc["scratch"][0:3, 190:193] = True  # 0.09 mm²: counted, not listed
    out = coverage.uncovered_regions(unc, combined, PPM, coverage.CoverageOptions(max_defect_mm2=4.0))
    big, small = out["regions"]
    assert big["area_mm2"] == pytest.approx(32.0) and big["why"] == "occluded" and big["classes"] == ["slide"]
    assert big["centre_mm"] == pytest.approx([14.0, 9.0])  # (pixel centres at +0.5)
    assert small["why"] == "highlight" and small["classes"] == ["ink_gone"] and small["area_mm2"] == pytest.approx(20.0)
    assert out["smaller"] == 1 and out["area_mm2"] == pytest.approx(52.1)  # (rounded to 0.1 mm²)


def test_an_uncovered_ring_is_named_by_a_point_on_it():
    # a film's outline band uncovered all round: its centroid is the film's middle, where it is not
    H, W = 200, 300
    ring = np.zeros((H, W), bool)
    ring[20:180, 30:270] = True
    ring[26:174, 36:264] = False
    unc = {c: ring if c == "ink_gone" else np.zeros((H, W), bool) for c in coverage.CLASSES}
    combined = np.full((H, W), print_warp.EDGE, np.uint8)
    (r,) = coverage.uncovered_regions(unc, combined, PPM, coverage.CoverageOptions())["regions"]
    x, y = (int(round(v * PPM - 0.5)) for v in r["centre_mm"])
    assert ring[y, x]
    # on a long side's middle, the band nearest the centroid, at least half its largest depth
    # (3 px) from its edges: rows 21 to 24 of the top band 20 to 25 (or their mirror below)
    assert abs(x - 149.5) <= 1 and (21 <= y <= 24 or 175 <= y <= 178)


def test_the_next_photo_sees_what_is_uncovered_from_elsewhere():
    # a 100 x 100 mm plate at z = 0 seen from straight above: the next photo must see its
    # uncovered points at a scorable angle, from at least twice the mirror cone away
    V = np.array([[-50.0, -50.0, 0.0], [50.0, -50.0, 0.0], [50.0, 50.0, 0.0], [-50.0, 50.0, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(0)
    X = np.c_[rng.uniform(-40, 40, (500, 2)), np.zeros(500)]
    face = np.where(X[:, 1] < X[:, 0], 0, 1)  # (both triangles face +z: either will do)
    cam = Camera.look_at([0.0, 0.0, 400.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 40.0, 1600, 1200)

    def orbit(az, el, dist, w, h, fov, intr):
        a, e = np.radians(az), np.radians(el)
        eye = dist * np.array([np.sin(a) * np.cos(e), -np.cos(a) * np.cos(e), np.sin(e)])
        c = Camera.look_at(eye, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], fov, w, h)
        return Camera(intr.K, c.R, c.t, intr.width, intr.height)

    nxt = coverage.next_photo(V, F, X, face, np.array([[0.0, 0.0, 400.0]]), cam, orbit)
    az, el, dist = nxt["orbit"]
    assert dist == pytest.approx(400.0) and nxt["sees_share"] == 1.0
    assert el <= 90 - 2 * dense.MIRROR_DEG and el >= np.degrees(np.arcsin(1 / print_warp.MAX_GRAZING))
    assert coverage.next_photo(V, F, X[:0], face[:0], np.zeros((0, 3)), cam, orbit) is None


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    d = tmp_path_factory.mktemp("coverage")
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d / "design"), "-q"]) == 0
    p = d / "p.png"
    assert (
        main(
            ["render", str(d / "design"), "--orbit=10,55,330", "--size", "2000x1500", "--realistic", "-o", str(p), "-q"]
        )
        == 0
    )
    return d


def run(demo, out, *extra):
    args = [
        "validate",
        str(demo / "design"),
        str(demo / "p.png"),
        "--camera",
        str(demo / "p.json"),
        "--out",
        str(out),
        "-q",
    ]
    assert main([*args, *extra]) == 0
    return json.loads((out / "validation.json").read_text())


def test_a_perfect_part_seen_in_part_is_incomplete_not_passed(demo, tmp_path):
    # one photo of a perfect part: the photo PASSes, the part is INCOMPLETE with what is not
    # covered, why, and the next photo; asked for no coverage, the part PASSes
    report = run(demo, tmp_path / "a")
    part, photo = report["part"], report["photos"][0]
    assert photo["verdict"] == "PASS"
    cov = part["coverage"]
    (f,) = cov["films"]
    shares = {c: f[c]["share"] for c in coverage.CLASSES}
    assert part["verdict"] == "INCOMPLETE" and not cov["complete"], shares
    assert min(s for s in shares.values() if s is not None) < 0.95
    assert part["reason"].startswith("the photos find ") and "next photo: azimuth" in part["reason"]
    assert cov["next_photo"]["sees_share"] > 0 and cov["uncovered"]["regions"]
    assert (tmp_path / "a" / "uncovered_print.png").read_bytes().startswith(b"\x89PNG")
    # the shares are the detection maps' own: the part's maps, as written, over where each class shows
    grid = design_print_grid(Design(demo / "design"))
    z = dict(np.load(tmp_path / "a" / "detection.npz"))
    opts = coverage.CoverageOptions(tolerance_mm=0.5, max_delta_e=3.0)
    shows = coverage.where_defects_show(grid.reference, grid.px_per_mm, FILM_RGB, opts)
    found = coverage.found_maps(z, 0.5)
    for c in coverage.CLASSES:
        on = shows[c] & np.isfinite(grid.X[..., 0])
        assert f[c]["share"] == pytest.approx((on & found[c]).sum() / on.sum(), abs=1e-4)
    report = run(demo, tmp_path / "b", "--min-coverage", "0")
    g = report["part"]["coverage"]["films"][0]
    assert report["part"]["verdict"] == "PASS" and all(g[c]["covered"] for c in coverage.CLASSES)
    assert [g[c]["share"] for c in coverage.CLASSES] == [f[c]["share"] for c in coverage.CLASSES]
    assert main(["validate", str(demo / "design"), str(demo / "p.png"), "--camera", str(demo / "p.json"),
                 "--min-coverage", "1.5", "--out", str(tmp_path / "c"), "-q"]) == 2  # fmt: skip
    assert not (tmp_path / "c").exists()


def test_a_finer_photo_is_asked_for_by_the_ratio_of_the_stated_slide_to_the_one_needed():
    # tolerance 0.2 mm: a slide of 0.4 mm must be found; 90 pixels state 0.8 mm (a photo twice
    # as fine finds it), 10 find none at any size
    from workbench.validate.detection import NONE_UM

    limit = np.full((10, 10), 800, np.uint16)
    limit[0] = NONE_UM
    unc = np.ones((10, 10), bool)
    out = coverage.finer_photo({"part_shift_limit_um": limit}, unc, 0.2, 6.5)
    assert out == {
        "factor": 2.0,
        "photo_px_per_mm": 6.5,
        "needed_photo_px_per_mm": 13.0,
        "share_found_at_factor": 0.9,
        "share_without_limit": 0.1,
    }
    # (capped: beyond MAX_FINER the limit is not the photo's sampling)
    assert (
        coverage.finer_photo({"part_shift_limit_um": limit * 0 + 8000}, unc, 0.2, 6.5)["factor"] == coverage.MAX_FINER
    )
    assert coverage.finer_photo({"part_shift_limit_um": limit}, np.zeros((10, 10), bool), 0.2, 6.5) is None
