"""A slide of the film is one field on the print: a photo that measured it in place overrules another photo."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT
from test_part_fusion import PPM, two_photos

from workbench.validate import print_warp
from workbench.validate.part import light_in_one_photo
from workbench.validate.slide_evidence import SlideMeasure, claim_seen_smaller, seen_smaller

H, W = 100, 100
REGION = (slice(40, 80), slice(30, 70))  # two_photos' defect: 40 x 40 grid px


def measure(vector_mm, sigma_mm: float, normal=None, claim: bool = False) -> SlideMeasure:
    """One photo's measure over the region: ``vector_mm`` there (the component along ``normal``
    where it is given: the edge's), NaN elsewhere; its claim, defect 1, over the region."""
    slide = np.full((H, W, 2), np.nan, np.float32)
    sigma = np.full((H, W), np.nan, np.float32)
    across = np.zeros((H, W), bool)
    n = np.zeros((H, W, 2), np.float32)
    v = np.asarray(vector_mm, np.float32)
    if normal is not None:
        u = np.asarray(normal, np.float32) / np.linalg.norm(normal)
        v = (v @ u) * u
        across[REGION], n[REGION] = True, u
    slide[REGION], sigma[REGION] = v, sigma_mm
    labels = np.zeros((H, W), np.int32)
    labels[REGION] = 1
    return SlideMeasure(slide, sigma, across, n, labels.astype(bool) & claim, labels)


@pytest.mark.parametrize(
    "b, smaller, why",
    [
        (measure([0.05, 0.0], 0.02, normal=[1, 0]), True, "the same edge, measured in place"),
        (measure([0.96, 0.0], 0.02, normal=[1, 0]), False, "the same edge, moved as far: the film slid"),
        # |1.0 - 0.90| = 0.10 against 3 sqrt(0.02² + 0.02²) = 0.085: beyond; 0.93 is within
        (measure([0.90, 0.0], 0.02, normal=[1, 0]), True, "moved 0.1 mm less, beyond the noise"),
        (measure([0.93, 0.0], 0.02, normal=[1, 0]), False, "moved 0.07 mm less, within the noise"),
        (measure([-1.0, 0.0], 0.02, normal=[1, 0]), False, "as far the other way: not in place"),
        (measure([0.0, 0.0], 0.02, normal=[0, 1]), False, "another edge (90° off) measures another component"),
        (measure([0.0, 0.0], 0.02, normal=[np.cos(0.3), np.sin(0.3)]), True, "the same edge within 20° (17°)"),
        (measure([0.0, 0.9], 0.02), True, "the full vector: its component across a's edge is 0"),
        (measure([0.99, 0.4], 0.02), False, "the full vector: across a's edge as far"),
        (measure([0.05, 0.0], 0.5, normal=[1, 0]), False, "in place, but too uncertain to say"),
    ],
)
def test_a_photo_that_measured_the_edge_in_place_sees_the_slide_smaller(b, smaller, why):
    # a: the print's edge (normal +x) moved 1 mm across itself, to 0.02 mm
    a = measure([1.0, 0.0], 0.02, normal=[1, 0], claim=True)
    got = seen_smaller(a, b, a.claim, 3.0)
    assert bool(got[REGION].all()) == smaller and not got[:40].any(), why
    share, median = claim_seen_smaller(a, b, 1, 3.0)
    assert share == (1.0 if smaller else 0.0)
    if smaller:
        assert median == pytest.approx(float(np.hypot(*b.slide_mm[50, 50])), abs=1e-6)


def test_full_vectors_compare_along_their_difference():
    # a: the full vector (0.6, 0.8) mm; b: (0.6, 0.0), in place across x and not across y
    a = measure([0.6, 0.8], 0.02, claim=True)
    assert seen_smaller(a, measure([0.6, 0.0], 0.02), a.claim, 3.0)[REGION].all()
    assert not seen_smaller(a, measure([0.6, 0.78], 0.02), a.claim, 3.0)[REGION].any()
    # (an across-only b compares along its own edge: across y, 0.8 against 0; across x both moved 0.6)
    assert seen_smaller(a, measure([0.0, 0.0], 0.02, normal=[0, 1]), a.claim, 3.0)[REGION].all()
    assert not seen_smaller(a, measure([0.6, 0.0], 0.02, normal=[1, 0]), a.claim, 3.0)[REGION].any()
    assert seen_smaller(a, measure([0.0, 0.0], 0.02, normal=[1, 0]), a.claim, 3.0)[REGION].all()


def test_only_the_claim_and_what_both_measured_count():
    a = measure([1.0, 0.0], 0.02, normal=[1, 0], claim=True)
    b = measure([0.0, 0.0], 0.02, normal=[1, 0])
    b.slide_mm[40:60] = np.nan  # b measured half of the region
    share, _ = claim_seen_smaller(a, b, 1, 3.0)
    assert share == pytest.approx(0.5)
    assert claim_seen_smaller(a, b, 2, 3.0) == (0.0, None)  # no such defect: no claim
    unclaimed = measure([1.0, 0.0], 0.02, normal=[1, 0], claim=False)
    assert claim_seen_smaller(unclaimed, b, 1, 3.0) == (0.0, None)


@pytest.mark.parametrize(
    "b_vector, b_share, dismissed",
    [
        ([0.03, 0.0], 1.0, True),  # measured in place over the whole claim
        ([0.03, 0.0], 0.55, True),  # over more than SHIFT_SHARE of it
        ([0.03, 0.0], 0.45, False),  # over less
        ([0.44, 0.0], 1.0, False),  # measured the same slide: the film's
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
        assert why["measured_there_mm"] == pytest.approx(0.03, abs=1e-6)
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
