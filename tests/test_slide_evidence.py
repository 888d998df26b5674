"""A slide of the film is one field on the print: a photo that measured it in place overrules another photo."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT
from test_part_fusion import PPM, two_photos

from workbench.validate import print_warp
from workbench.validate.part import light_in_one_photo
from workbench.validate.slide_evidence import SlideMeasure, claim_seen_in_place, seen_in_place

H, W = 100, 100
REGION = (slice(40, 80), slice(30, 70))  # two_photos' defect: 40 x 40 grid px
GRID = (slice(None), slice(None))
TOL = 0.2


def measure(
    vector_mm, sigma_mm: float, normal=None, claim: bool = False, placement=(0.0, 0.0), window: bool = False
) -> SlideMeasure:
    """One photo's measure over the region: its slide ``vector_mm`` there (the component along
    ``normal`` where it is given: the edge's; a window's with ``window``), NaN elsewhere, its
    placement; its claim, defect 1."""
    slide = np.full((H, W, 2), np.nan, np.float32)
    sigma = np.full((H, W), np.nan, np.float32)
    n = np.zeros((H, W, 2), np.float32)
    v = np.asarray(vector_mm, np.float32)
    if normal is not None:
        u = np.asarray(normal, np.float32) / np.linalg.norm(normal)
        v = (v @ u) * u
        n[REGION] = u
    slide[REGION], sigma[REGION] = v, sigma_mm
    ids = np.zeros((H, W), np.int16)
    ids[REGION] = 1 if claim else 0
    place = np.broadcast_to(np.asarray(placement, np.float32), (H, W, 2))
    f16 = np.float16
    windows = np.zeros((H, W), bool)
    windows[REGION] = window
    return SlideMeasure(slide.astype(f16), place.astype(f16), sigma.astype(f16), n.astype(f16), windows, ids, TOL)


@pytest.mark.parametrize(
    "b, seen, why",
    [
        (measure([0.05, 0.0], 0.02, normal=[1, 0]), True, "the same edge, measured in place"),
        (measure([0.96, 0.0], 0.02, normal=[1, 0]), False, "the same edge, moved as far: the film slid"),
        # within the tolerance 0.2 by 3 x 0.02: 0.25 is in place, 0.30 is a slide of b's own
        (measure([0.25, 0.0], 0.02, normal=[1, 0]), True, "moved 0.25 mm: within the tolerance, in place"),
        (measure([0.30, 0.0], 0.02, normal=[1, 0]), False, "moved 0.30 mm: less than a, but slid, not in place"),
        (measure([-1.0, 0.0], 0.02, normal=[1, 0]), False, "as far the other way: not in place"),
        (measure([0.0, 0.0], 0.02, normal=[0, 1]), False, "another edge (90° off) measures another component"),
        (measure([0.0, 0.0], 0.02, normal=[np.cos(0.3), np.sin(0.3)]), True, "the same edge within 20° (17°)"),
        (measure([0.0, 0.15], 0.02), True, "the full vector: across a's edge it is in place"),
        (measure([0.99, 0.1], 0.02), False, "the full vector: across a's edge as far"),
        (measure([0.05, 0.0], 0.5, normal=[1, 0]), False, "in place, but too uncertain to say"),
    ],
)
def test_a_photo_that_measured_the_edge_in_place_overrules_the_slide(b, seen, why):
    # a: the print's edge (normal +x) moved 1 mm across itself, to 0.02 mm
    a = measure([1.0, 0.0], 0.02, normal=[1, 0], claim=True)
    got = seen_in_place(a, b, GRID, 3.0)
    assert bool(got[REGION].all()) == seen and not got[:40].any(), why
    share, median = claim_seen_in_place(a, b, 1, 3.0, REGION, np.ones((40, 40), bool))
    assert share == (1.0 if seen else 0.0)
    if seen:
        assert median == pytest.approx(float(np.hypot(*b.slide_mm[50, 50].astype(float))), abs=1e-3)


def test_full_vectors_compare_along_the_claim():
    # a: the full vector (0.6, 0.8) mm; along it b's (0.6, 0) is 0.36: a slide of its own, not in place
    a = measure([0.6, 0.8], 0.02, claim=True)
    assert not seen_in_place(a, measure([0.6, 0.0], 0.02), REGION, 3.0).any()
    assert seen_in_place(a, measure([0.0, 0.0], 0.02), REGION, 3.0).all()
    assert not seen_in_place(a, measure([0.6, 0.78], 0.02), REGION, 3.0).any()
    # (a b that knows one component compares along its edge: across x, 0.6 against 0, or 0.6)
    assert seen_in_place(a, measure([0.0, 0.0], 0.02, normal=[1, 0]), REGION, 3.0).all()
    assert not seen_in_place(a, measure([0.6, 0.0], 0.02, normal=[1, 0]), REGION, 3.0).any()


def test_a_windows_slide_is_compared_with_a_windows_only():
    # a window answers a small bubble's 0.5 mm slide at a fraction of it, in every photo: b's window
    # at 0.20 (within the tolerance) against a's own 0.5 says nothing; against a's window at 0.21 it
    # is the same slide
    a = measure([0.5, 0.0], 0.01, claim=True)
    assert not seen_in_place(a, measure([0.20, 0.0], 0.01, window=True), REGION, 3.0).any()
    a_window = measure([0.21, 0.0], 0.01, claim=True, window=True)
    assert not seen_in_place(a_window, measure([0.20, 0.0], 0.01, window=True), REGION, 3.0).any()
    # (a glint a's window followed, which b's does not: light)
    a_glint = measure([0.9, 0.0], 0.01, claim=True, window=True)
    assert seen_in_place(a_glint, measure([0.02, 0.0], 0.01, window=True), REGION, 3.0).all()


def test_each_photos_placement_is_part_of_what_it_measured():
    # a real slide of 0.30 mm along x: photo a fitted no placement (it rounds one within the
    # tolerance's share to none) and measures 0.30; photo b fitted 0.08 of it as placement and
    # measures 0.22 after it, within the tolerance (0.2 + 3 x 0.01). The film moved alike in both
    a = measure([0.30, 0.0], 0.01, normal=[1, 0], claim=True)
    b = measure([0.22, 0.0], 0.01, normal=[1, 0], placement=(0.08, 0.0))
    assert not seen_in_place(a, b, REGION, 3.0).any()
    # (compared after each photo's placement alone, 0.08 apart is 5.7 of their 0.014: light)
    b_without = measure([0.22, 0.0], 0.01, normal=[1, 0])
    assert seen_in_place(a, b_without, REGION, 3.0).all()


def test_only_the_claim_and_what_both_measured_count():
    a = measure([1.0, 0.0], 0.02, normal=[1, 0], claim=True)
    b = measure([0.0, 0.0], 0.02, normal=[1, 0])
    b.slide_mm[40:60] = np.nan  # b measured half of the region
    everywhere = np.ones((40, 40), bool)  # (over the region's box)
    share, _ = claim_seen_in_place(a, b, 1, 3.0, REGION, everywhere)
    assert share == pytest.approx(0.5)
    clean = everywhere.copy()
    clean[20:30] = False  # b found a defect over a quarter of it (grid rows 60 to 70)
    assert claim_seen_in_place(a, b, 1, 3.0, REGION, clean)[0] == pytest.approx(0.25)
    assert claim_seen_in_place(a, b, 2, 3.0, REGION, everywhere) == (0.0, None)  # no such defect: no claim
    unclaimed = measure([1.0, 0.0], 0.02, normal=[1, 0], claim=False)
    assert claim_seen_in_place(unclaimed, b, 1, 3.0, REGION, everywhere) == (0.0, None)


@pytest.mark.parametrize(
    "b_vector, b_share, dismissed",
    [
        ([0.03, 0.0], 1.0, True),  # measured in place over the whole claim
        ([0.03, 0.0], 0.55, True),  # over more than SHIFT_SHARE of it
        ([0.03, 0.0], 0.45, False),  # over less
        ([0.44, 0.0], 1.0, False),  # measured the same slide: the film's
        ([0.30, 0.0], 1.0, False),  # measured less of it, but a slide beyond the tolerance all the same
    ],
)
def test_the_part_takes_a_slide_another_photo_measured_in_place_for_light(b_vector, b_share, dismissed):
    # photo b's stated limit (1 mm) is coarser than a's slide (0.44 mm): only its measure can overrule
    entries, states, maps = two_photos(print_warp.FULL, True)
    entries[0]["defects"][0].update(kind="shift", peak_mm=0.44, mean_mm=0.40, id=1)
    for k in (0, 1):
        maps[f"photo{k}_shift_limit_um"] = np.full((H, W), 1000, np.uint16)
    a = measure([0.44, 0.0], 0.02, normal=[1, 0], claim=True)
    b = measure(b_vector, 0.02, normal=[1, 0])
    b.slide_mm[40 + int(round(40 * b_share)) : 80] = np.nan
    assert light_in_one_photo(entries, states, maps, PPM, 4.0) == []  # (without the measures: kept)
    got = light_in_one_photo(entries, states, maps, PPM, 4.0, None, [a, b])
    assert bool(got) == dismissed
    if dismissed:
        why = got[0]["decided_by"]
        assert why["hypothesis"] == "light" and why["photo"] == "b.png" and why["share"] == pytest.approx(b_share)
        assert why["measured_there_mm"] == pytest.approx(0.03, abs=1e-3)
        assert "measured the print in place" in why["words"] and "light in a.png" in why["words"]
    # a photo that found a defect there itself does not overrule (the region is not clean in it)
    states[1][REGION] = print_warp.DEFECT
    assert light_in_one_photo(entries, states, maps, PPM, 4.0, None, [a, b]) == []


@pytest.mark.parametrize("renderer", ["workbench", "mitsuba"])
def test_a_real_bubble_in_two_photos_is_measured_slid_in_both_and_fails_the_part(tmp_path, renderer):
    """The measure that overrules a glint never overrules the film: a 12 mm bubble slid 1 mm, photographed
    from two directions 11° apart seen from the part (far enough for one photo to overrule the other, too
    near for their agreement alone to keep it), is slid in both photos' measures and fails the part."""
    from test_defects import LOOK, MITSUBA

    from workbench.cli import main

    design = tmp_path / "design"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(design), "-q"]) == 0
    look = LOOK if renderer == "workbench" else MITSUBA
    photos = []
    for az in (10, 30):
        p = tmp_path / f"az{az}.png"
        args = ["render", str(design), f"--orbit={az},55,330", "--size", "2000x1500", *look]
        assert main([*args, "--defect", "bubble:45,30,6,1", "-o", str(p), "-q"]) == 0
        photos.append(p)
    out = tmp_path / "out"
    args = ["validate", str(design), *map(str, photos), "--camera", str(photos[0].with_suffix(".json"))]
    assert main([*args, "--tolerance-mm", "0.2", "--out", str(out), "-q"]) == 0
    report = json.loads((out / "validation.json").read_text())
    part = report["part"]
    assert not [x for x in part.get("dismissed", []) if x["kind"] == "shift"], part.get("dismissed")
    near = [d for d in part["defects"] if np.hypot(d["centre_mm"][0] - 45, d["centre_mm"][1] - 30) <= 1.5]
    assert part["verdict"] == "FAIL" and near and near[0]["kind"] == "shift", part["defects"]
