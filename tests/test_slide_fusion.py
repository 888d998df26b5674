"""A slide of the film fused over the part's photos: exact against least squares, agreement by χ², found together."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from workbench.validate import detection
from workbench.validate.slide_evidence import SlideMeasure
from workbench.validate.slide_fusion import (
    FusionOptions,
    fuse_slides,
    fuse_windows,
    fused_part_limit,
    slid_pixels,
    slid_regions,
    slides_found_together,
)

H, W = 80, 80
PPM = 10.0  # grid px per print mm
TOL = 0.2
Z = 3.0
USABLE = TOL / Z  # 0.0667 mm: what a photo's own measure may have, and a fused one
OPTS = FusionOptions(TOL, 4.0)


def measure(vector_mm, sigma_mm, normal=None, where=None, window=False, wide=None) -> SlideMeasure:
    """One photo's own measure, ``vector_mm`` (its component along ``normal`` where given, a unit
    vector or an (H, W, 2) field of them) over ``where`` (default: everywhere), NaN elsewhere;
    ``vector_mm`` may be an (H, W, 2) field. ``wide``: the windows' slides and their σ everywhere."""
    where = np.ones((H, W), bool) if where is None else where
    v = np.broadcast_to(np.asarray(vector_mm, np.float64), (H, W, 2)).copy()
    n = np.zeros((H, W, 2), np.float32)
    if normal is not None:
        u = np.broadcast_to(np.asarray(normal, np.float64), (H, W, 2))
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        v = (v * u).sum(-1)[..., None] * u
        n[where] = u[where]
    slide = np.where(where[..., None], v, np.nan).astype(np.float16)
    sigma = np.where(where, np.broadcast_to(np.asarray(sigma_mm, np.float64), (H, W)), np.nan).astype(np.float16)
    f16 = np.float16
    return SlideMeasure(
        slide,
        np.zeros((H, W, 2), f16),
        sigma,
        n.astype(f16),
        np.full((H, W), window) & where,
        np.zeros((H, W), np.int16),
        TOL,
        None if wide is None else np.broadcast_to(np.asarray(wide[0]), (H, W, 2)).astype(f16),
        None if wide is None else np.full((H, W), wide[1], f16),
    )


def half(v) -> np.ndarray:
    """As stored: half precision, back in float64."""
    return np.asarray(v, np.float16).astype(np.float64)


def test_two_whole_vectors_fuse_to_their_inverse_variance_mean():
    a, b = measure([0.30, -0.10], 0.03), measure([0.20, 0.10], 0.06)
    f = fuse_slides([a, b], Z, USABLE)
    wa, wb = 1 / half(0.03) ** 2, 1 / half(0.06) ** 2
    va, vb = half([0.30, -0.10]), half([0.20, 0.10])
    expect = (wa * va + wb * vb) / (wa + wb)
    assert np.allclose(f.slide_mm[40, 40], expect, atol=1e-6)
    assert f.sigma_mm[40, 40] == pytest.approx((wa + wb) ** -0.5, rel=1e-6)
    # the misfit of the two to one vector: Σ w |s_k - ŝ|²
    chi2 = wa * np.sum((va - expect) ** 2) + wb * np.sum((vb - expect) ** 2)
    assert f.chi2[40, 40] == pytest.approx(chi2, rel=1e-4)
    assert f.photos[:, 40, 40].tolist() == [True, True]


def test_a_whole_vector_and_a_component_fuse_and_components_alone_do_not():
    """A whole vector at σ 0.05 and a component across x at σ 0.03: x known to the two fused,
    y to the whole vector's alone. Components alone (one print edge, one normal in every photo;
    or two edges 57° apart, which the print's one texture does not give) fix no vector."""
    s = np.array([0.35, -0.25])
    a = measure(s + [0.02, 0.0], 0.05)
    b = measure(s, 0.03, normal=[1, 0])
    f = fuse_slides([a, b], Z, USABLE)
    wa, wb = 1 / half(0.05) ** 2, 1 / half(0.03) ** 2
    assert f.slide_mm[40, 40, 0] == pytest.approx((wa * half(0.37) + wb * half(0.35)) / (wa + wb), abs=1e-5)
    assert f.slide_mm[40, 40, 1] == pytest.approx(half(-0.25), abs=1e-5)
    assert f.sigma_mm[40, 40] == pytest.approx(half(0.05), rel=1e-5)  # y: the whole vector's alone
    n2 = np.array([np.cos(1.0), np.sin(1.0)])
    assert np.isnan(fuse_slides([b, measure(s, 0.04, normal=n2)], Z, USABLE).slide_mm).all()
    assert np.isnan(fuse_slides([b, measure(s, 0.03, normal=[1, 0])], Z, USABLE).slide_mm).all()
    assert np.isnan(fuse_slides([a, None], Z, USABLE).slide_mm).all()


def test_a_fused_measure_must_be_usable_as_a_photo_measure_is():
    """A whole vector at σ 0.08 and a component across x: y known to 0.08 only, over the usable 0.067."""
    f = fuse_slides([measure([0.1, 0.0], 0.08), measure([0.1, 0.0], 0.03, normal=[1, 0])], Z, USABLE)
    assert np.isnan(f.slide_mm).all()
    g = fuse_slides([measure([0.1, 0.0], 0.08), measure([0.1, 0.0], 0.03, normal=[1, 0])], Z, 0.2)
    assert np.isfinite(g.slide_mm).all()


def test_a_window_measure_is_not_fused_with_a_pixels_own():
    f = fuse_slides([measure([0.3, 0.0], 0.05), measure([0.3, 0.0], 0.05, window=True)], Z, USABLE)
    assert np.isnan(f.slide_mm).all()


def test_photos_that_disagree_give_no_fused_measure():
    # 0.3 mm apart at σ 0.05 each: χ² = 18 against the 2-dof quantile at z 3 (11.8)
    f = fuse_slides([measure([0.3, 0.0], 0.05), measure([0.0, 0.0], 0.05)], Z, USABLE)
    assert np.isnan(f.slide_mm).all() and np.isfinite(f.chi2).all()
    # 0.1 mm apart: χ² = 2, they agree
    g = fuse_slides([measure([0.1, 0.0], 0.05), measure([0.0, 0.0], 0.05)], Z, USABLE)
    assert np.isfinite(g.slide_mm).all()


def test_consistent_measures_agree_whatever_half_precision_does():
    """Two edges and a whole vector of one slide, no noise, σ 6 µm: χ² stays within its quantile."""
    rng = np.random.default_rng(2)
    s = rng.uniform(-1.2, 1.2, (H, W, 2))
    ang = rng.uniform(0, np.pi, (H, W))
    n1 = np.dstack([np.cos(ang), np.sin(ang)])
    n2 = np.dstack([np.cos(ang + 1.2), np.sin(ang + 1.2)])
    f = fuse_slides([measure(s, 0.006, normal=n1), measure(s, 0.006, normal=n2), measure(s, 0.006)], Z, USABLE)
    assert np.isfinite(f.slide_mm).all()


def disc(cx, cy, r_mm):
    yy, xx = np.mgrid[0:H, 0:W]
    return np.hypot((xx + 0.5) / PPM - cx, (yy + 0.5) / PPM - cy) <= r_mm


def flat_grid(owner=None):
    """A flat part in the plane z = 0, print mm = surface mm."""
    yy, xx = np.mgrid[0:H, 0:W]
    X = np.dstack([(xx + 0.5) / PPM, (yy + 0.5) / PPM, np.zeros((H, W))])
    return SimpleNamespace(px_per_mm=PPM, owner=np.zeros((H, W), np.int32) if owner is None else owner, X=X)


def photo(name, azimuth_deg):
    """A photo's entry whose camera sees the part from ``azimuth_deg`` at 45° elevation, 300 mm away."""
    a = np.radians(azimuth_deg)
    centre = [4.0 + 212.0 * np.cos(a), 4.0 + 212.0 * np.sin(a), 212.0]
    return {"photo": f"p/{name}", "defects": [], "pose": {"camera_center_mm": centre}}


def bubble_photos(k=2, slide=0.36, sigma=0.06, r_mm=1.6, noise=0.0, seed=3):
    """``k`` photos' own whole vectors of a disc at (4, 3.5) mm slid ``slide`` mm along x."""
    rng = np.random.default_rng(seed)
    bubble = disc(4.0, 3.5, r_mm)
    out = []
    for _ in range(k):
        v = np.where(bubble[..., None], [slide, 0.0], [0.0, 0.0]) + rng.normal(0, noise, (H, W, 2))
        out.append(measure(v, sigma))
    return bubble, out


def test_a_slide_no_photo_finds_alone_is_found_together():
    """A disc of 8 mm² slid 0.36 mm, measured at σ 0.06 by each photo (z 2.7 alone): fused σ 0.042, z 3.8."""
    bubble, fields = bubble_photos(noise=0.01)
    alone = [(np.hypot(*m.slide_mm[35, 40].astype(float)) - TOL) / float(m.sigma_mm[35, 40]) for m in fields]
    assert max(alone) < Z
    entries = [photo("a.jpg", 0.0), photo("b.jpg", 60.0)]
    owner = np.zeros((H, W), np.int32)
    owner[:, 40:] = 1
    found, light = slides_found_together(fields, entries, [], flat_grid(owner), OPTS, ["left", "right"])
    assert light == [] and len(found) == 1
    d = found[0]
    assert d["centre_mm"] == pytest.approx([4.0, 3.5], abs=0.1)
    assert d["area_mm2"] == pytest.approx(bubble.sum() / PPM**2, rel=0.1)
    assert d["photos"] == ["a.jpg", "b.jpg"] and d["view"] == "right"
    assert d["decided_by"]["hypothesis"] == "slide" and d["decided_by"]["z"] > Z
    assert d["apart_deg"] == pytest.approx(41.4, abs=0.5)
    # below the verdict's area it is not listed; one photo alone is not fused
    assert slides_found_together(fields, entries, [], flat_grid(), FusionOptions(TOL, 9.0), ["v"]) == ([], [])
    assert slides_found_together([fields[0], None], entries, [], flat_grid(), OPTS, ["v"]) == ([], [])


def test_a_photos_own_defect_decides_only_when_it_fails_or_is_light():
    _, fields = bubble_photos(noise=0.01)
    entries = [photo("a.jpg", 0.0), photo("b.jpg", 60.0)]
    # each photo lists the slide, not significant alone: the part's photos together find it
    for e in entries:
        e["defects"] = [{"id": 1, "area_mm2": 8.0, "significance_z": 2.6, "bbox_mm": [2.4, 1.9, 5.6, 5.1]}]
    assert len(slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"])[0]) == 1
    # a's own, significant: it fails the part already, and is not listed twice
    entries[0]["defects"][0]["significance_z"] = 4.0
    assert slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"]) == ([], [])
    # a's own, significant, over part of it only: what remains beyond its box is the fused slide's
    entries[0]["defects"][0]["bbox_mm"] = [2.4, 1.9, 3.6, 5.1]
    assert len(slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"])[0]) == 1
    entries[0]["defects"][0]["bbox_mm"] = [2.4, 1.9, 5.6, 5.1]
    # a's own, not significant, but b showed it to be light: it stays light
    entries[0]["defects"][0]["significance_z"] = 2.6
    assert slides_found_together(fields, entries, [{"photo_index": 0, "id": 1}], flat_grid(), OPTS, ["v"]) == ([], [])


def test_a_perfect_part_finds_nothing_together():
    """Three photos of a sound part, whole vectors with noise at their σ: nothing found. Two photos
    that see one print edge, their normals 8 to 14° apart (the structure tensor's error), each
    measuring the component across it to 5 µm while DIS drifts 1 mm along it: the two do not fix
    the vector (edges within SAME_EDGE_DEG are one edge), nothing found."""
    rng = np.random.default_rng(5)
    fields = [measure(rng.normal(0, 0.05, (H, W, 2)), 0.05) for _ in range(3)]
    entries = [photo(f"{k}.jpg", 120.0 * k) for k in range(3)]
    assert slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"]) == ([], [])
    ang = np.radians(rng.uniform(8, 14, (H, W)))
    drift = np.broadcast_to([0.0, 1.0], (H, W, 2))
    edges = [measure(drift, 0.005, normal=[1, 0]), measure(drift, 0.005, normal=np.dstack([np.cos(ang), np.sin(ang)]))]
    assert np.isnan(fuse_slides(edges, Z, USABLE).slide_mm).all()
    assert slides_found_together(edges, entries[:2], [], flat_grid(), OPTS, ["v"]) == ([], [])


def test_windows_fuse_window_with_window_and_the_region_is_sized_at_half_its_height():
    """Windows' slides of a 12.6 mm² bubble, 0.36 mm at σ 0.06 in each of three photos (z 2.7 alone),
    no own measure anywhere: fused σ 0.035 (z 4.6), found; eroded evidence grown back to its rim."""
    bubble = disc(4.0, 4.0, 2.0)
    v = np.where(bubble[..., None], [0.0, 0.36], [0.0, 0.0])
    nothing = np.zeros((H, W), bool)
    fields = [measure([0.0, 0.0], 0.05, where=nothing, wide=(v, 0.06)) for _ in range(3)]
    assert np.isnan(fuse_slides(fields, Z, USABLE).slide_mm).all()
    f = fuse_windows(fields, Z, USABLE)
    assert f.sigma_mm[40, 40] == pytest.approx(half(0.06) / np.sqrt(3), rel=1e-6)
    assert np.allclose(f.slide_mm[40, 40], [0.0, half(0.36)], atol=1e-6)
    entries = [photo(f"{k}.jpg", 120.0 * k) for k in range(3)]
    found, _ = slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"])
    assert len(found) == 1 and found[0]["centre_mm"] == pytest.approx([4.0, 4.0], abs=0.1)
    assert found[0]["area_mm2"] == pytest.approx(bubble.sum() / PPM**2, rel=0.15)
    assert found[0]["median_mm"] == pytest.approx(0.36, abs=1e-3)
    # two photos alone: σ 0.042, z 3.7: still found
    assert len(slides_found_together(fields[:2], entries[:2], [], flat_grid(), OPTS, ["v"])[0]) == 1


def test_slid_regions_grow_to_half_the_slides_height():
    """A slide of 0.5 mm inside a 2 mm disc ramping to 0 over 1 mm outside it, slid pixels only
    where it exceeds 0.4 mm: the region reaches where it is 0.25 mm, the disc of 2.5 mm."""
    yy, xx = np.mgrid[0:H, 0:W]
    r = np.hypot((xx + 0.5) / PPM - 4.0, (yy + 0.5) / PPM - 4.0)
    mag = 0.5 * np.clip((3.0 - r) / 1.0, 0.0, 1.0)
    slide = np.dstack([mag, np.zeros_like(mag)])
    labels, n = slid_regions(mag > 0.4, slide, PPM, 3.0, 4.0)
    assert n == 1 and (labels > 0).sum() == pytest.approx(disc(4.0, 4.0, 2.5).sum(), rel=0.05)


def test_slid_regions_need_two_windows_of_evidence():
    """Slid specks of 3 x 3 pixels (9 px, under two windows' 226) 6 px apart, which the closing would
    join into 36 mm²: no region."""
    seeds = np.zeros((H, W), bool)
    for y in range(10, 70, 6):
        for x in range(10, 70, 6):
            seeds[y : y + 3, x : x + 3] = True
    slide = np.where(seeds[..., None], [0.5, 0.0], [0.0, 0.0])
    assert slid_regions(seeds, slide, PPM, 3.0, 4.0)[1] == 0
    assert slid_regions(disc(4.0, 4.0, 1.5), np.full((H, W, 2), 0.5), PPM, 3.0, 4.0)[1] == 1


def test_two_photos_from_one_direction_may_share_a_glint():
    """Cameras 10° apart seen from the slide (within twice the lamp's 8°): not counted, and why."""
    _, fields = bubble_photos()
    entries = [photo("a.jpg", 0.0), photo("b.jpg", 14.0)]
    found, light = slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"])
    assert found == [] and len(light) == 1
    assert light[0]["decided_by"]["hypothesis"] == "light" and light[0]["decided_by"]["apart_deg"] < 16.0
    assert light[0]["photo"] == "a.jpg, b.jpg"
    # no camera known for one: undecided, not counted, and says so
    entries[1]["pose"] = None
    found, light = slides_found_together(fields, [photo("a.jpg", 0.0), entries[1]], [], flat_grid(), OPTS, ["v"])
    assert found == [] and "not known" in light[0]["decided_by"]["words"]
    # apart, but measured together over less than two flow windows: not counted, and the words say so
    # (a and b 10° apart see all of it; c, 41° from a, only 1.5 mm² of it)
    _, three = bubble_photos(k=3)
    three[2] = dataclasses.replace(three[2], set_aside=~disc(4.0, 3.5, 0.7))
    near = [photo("a.jpg", 0.0), photo("b.jpg", 14.0), photo("c.jpg", 60.0)]
    found, light = slides_found_together(three, near, [], flat_grid(), OPTS, ["v"])
    assert found == [] and "measured only" in light[0]["decided_by"]["words"]
    # two files of one name in different folders, 90° apart: each by its own camera
    same = [photo("a.jpg", 0.0), photo("a.jpg", 90.0)]
    assert len(slides_found_together(fields, same, [], flat_grid(), OPTS, ["v"])[0]) == 1


def test_many_photos_each_named():
    """Twenty photos around the part (more than a 16-bit mask holds): every one that measured is named."""
    _, fields = bubble_photos(k=20, slide=0.26, sigma=0.06)  # z 1.0 alone, 4.5 fused
    entries = [photo(f"{k}.jpg", 18.0 * k) for k in range(20)]
    found, light = slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"])
    assert len(found) == 1 and light == [] and found[0]["photos"] == [f"{k}.jpg" for k in range(20)]


def test_fused_shift_limit_is_tolerance_plus_z_of_the_inverse_variance_sigma():
    a = np.full((4, 4), 60, np.uint16)
    b = np.full((4, 4), 80, np.uint16)
    b[0, 0] = detection.NONE_UM
    got = detection.fused_shift_limit([a, b], 0.2, 4.645)
    assert got[1, 1] == pytest.approx(0.2 + 4.645 * (0.06**-2 + 0.08**-2) ** -0.5, rel=1e-6)
    assert np.isnan(got[0, 0])  # one photo there: its own limit, not a fused one
    window = detection.fused_shift_limit([a, b], 0.2, 4.645, gain=0.75)
    assert window[1, 1] == pytest.approx(got[1, 1] / 0.75, rel=1e-6)


def test_the_part_claims_the_fused_limit_only_where_two_photos_apart_measure():
    S, none = (4, 4), np.full((4, 4), detection.NONE_UM, np.uint16)
    zero = np.zeros(S, np.uint8)
    entries = [
        {"detection_maps": {"shift_limit_um": np.full(S, 479, np.uint16), "slide_sigma_um": np.full(S, 30, np.uint16),
                            "window_sigma_um": none, "dropout": zero, "scratch": zero}},
        {"detection_maps": {"shift_limit_um": np.full(S, 572, np.uint16), "slide_sigma_um": np.full(S, 40, np.uint16),
                            "window_sigma_um": none, "dropout": zero, "scratch": zero}},
    ]  # fmt: skip
    maps = detection.part_maps(entries)
    assert (maps["part_shift_limit_um"] == 479).all()  # the better photo's own
    X = np.zeros((*S, 3))
    fused = round(1000 * (0.2 + 4.645 * (0.03**-2 + 0.04**-2) ** -0.5))
    apart = [photo("a", 0.0)["pose"]["camera_center_mm"], photo("b", 60.0)["pose"]["camera_center_mm"]]
    assert (fused_part_limit(maps, X, apart, 0.2) == fused).all()
    together = [apart[0], photo("b", 10.0)["pose"]["camera_center_mm"]]
    assert (fused_part_limit(maps, X, together, 0.2) == 479).all()
    assert (fused_part_limit(maps, X, [apart[0], None], 0.2) == 479).all()


def test_what_the_fused_limit_claims_the_detector_finds():
    """Two photos stating σ 0.03 each: the fused limit, 0.2 + 4.645 x 0.03 / √2 = 0.299 mm, below
    each photo's own (0.339 mm); a disc slid by it, measured at those σ, is found by the part at
    z = 4.645 (the stated limit's 95 % detection: 1.645 beyond the significance)."""
    sigma = 0.03
    limit = float(detection.fused_shift_limit([np.full((1, 1), 30, np.uint16)] * 2, TOL, 4.645)[0, 0])
    assert limit == pytest.approx(0.2985, abs=1e-4) and limit < TOL + 4.645 * sigma
    _, fields = bubble_photos(slide=limit, sigma=sigma, r_mm=1.8)
    entries = [photo("a.jpg", 0.0), photo("b.jpg", 90.0)]
    found, _ = slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"])
    assert len(found) == 1 and found[0]["decided_by"]["z"] == pytest.approx(4.645, abs=0.05)


def test_slid_pixels_erode_a_windows_evidence():
    v = np.where(disc(4, 4, 2)[..., None], [0.5, 0], 0)
    f = fuse_windows([measure([0, 0], 0.05, where=np.zeros((H, W), bool), wide=(v, 0.03)) for _ in range(2)], Z, USABLE)
    assert slid_pixels(f, TOL, Z, erode_px=6).sum() == pytest.approx(disc(4, 4, 1.4).sum(), rel=0.15)


def test_a_slide_found_together_fails_the_part_and_says_why():
    from workbench.validate.part import add_found_together

    _, fields = bubble_photos(noise=0.01)
    found, _ = slides_found_together(fields, [photo("a.jpg", 0.0), photo("b.jpg", 60.0)], [], flat_grid(), OPTS, ["v"])
    part = {"verdict": "PASS", "defects": [{"kind": "missing", "area_mm2": 2.0, "centre_mm": [9.0, 9.0]}]}
    add_found_together(part, found)
    assert part["verdict"] == "FAIL" and part["reason"] == found[0]["decided_by"]["words"]
    assert [d.get("located_by") for d in part["defects"]] == ["fused", None]  # the largest first
    failed = {"verdict": "FAIL", "reason": "a photo's", "defects": []}
    add_found_together(failed, found)
    assert failed["reason"] == "a photo's" and len(failed["defects"]) == 1
    unchanged = {"verdict": "PASS", "defects": []}
    add_found_together(unchanged, [])
    assert unchanged == {"verdict": "PASS", "defects": []}


def test_what_a_photo_set_aside_as_light_takes_no_part():
    """Two photos each took the region for light (its flow did not explain the photo): their measures
    there are not the film's, and fused they find nothing; with one photo's set aside only, one
    photo's measure remains there, which is no fusion."""
    bubble, fields = bubble_photos(noise=0.01)
    entries = [photo("a.jpg", 0.0), photo("b.jpg", 60.0)]
    aside = [dataclasses.replace(m, set_aside=bubble) for m in fields]
    assert slides_found_together(aside, entries, [], flat_grid(), OPTS, ["v"]) == ([], [])
    assert slides_found_together([aside[0], fields[1]], entries, [], flat_grid(), OPTS, ["v"]) == ([], [])
    assert len(slides_found_together(fields, entries, [], flat_grid(), OPTS, ["v"])[0]) == 1
