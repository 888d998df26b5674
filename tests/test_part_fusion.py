"""Several photos, one part: ink gone stays on the print in every photo; light moves with the camera."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import ROOT

from workbench.cli import main
from workbench.validate import print_warp
from workbench.validate.part import light_in_one_photo

PPM = 10.0


def two_photos(b_state: int, b_finds: bool):
    """Photo A finds 40 x 40 grid px (16 mm²) of ink gone; photo B gives the region ``b_state``."""
    H, W = 100, 100
    sa = np.full((H, W), print_warp.FULL, np.uint8)
    sa[40:80, 30:70] = print_warp.DEFECT
    sb = np.full((H, W), print_warp.FULL, np.uint8)
    sb[40:80, 30:70] = b_state
    maps = {}
    for k in (0, 1):
        maps[f"photo{k}_dropout"] = np.full((H, W), 1 if (k == 0 or b_finds) else 0, np.uint8)
        maps[f"photo{k}_scratch"] = np.zeros((H, W), np.uint8)
    d = {"kind": "missing", "area_mm2": 16.0, "bbox_mm": [3.0, 4.0, 7.0, 8.0], "centre_mm": [5.0, 6.0]}
    entries = [{"photo": "a.png", "defects": [d]}, {"photo": "b.png", "defects": []}]
    return entries, [sa, sb], maps


def test_ink_gone_in_one_photo_that_another_sees_intact_is_light():
    entries, states, maps = two_photos(print_warp.FULL, True)
    (d,) = light_in_one_photo(entries, states, maps, PPM, 4.0)
    assert d["photo_index"] == 0 and d["photo"] == "a.png" and d["area_mm2"] == 16.0
    assert d["decided_by"]["photo"] == "b.png" and d["decided_by"]["share"] == 1.0
    assert d["decided_by"]["hypothesis"] == "light" and "so this is light in a.png" in d["decided_by"]["words"]
    assert "dismissed" not in entries[0]["defects"][0]  # the photo's own entry stays as it found it


@pytest.mark.parametrize(
    "b_state, b_finds, why",
    [
        (print_warp.DEFECT, True, "the other photo finds it too: ink gone stays put"),
        (print_warp.FULL, False, "the other photo cannot find ink gone there"),
        (print_warp.HIGHLIGHT, True, "the other photo does not measure it"),
        (print_warp.OCCLUDED, True, "the other photo does not see it"),
    ],
)
def test_ink_gone_stays_when_no_other_photo_shows_the_ink(b_state, b_finds, why):
    entries, states, maps = two_photos(b_state, b_finds)
    assert light_in_one_photo(entries, states, maps, PPM, 4.0) == [], why


@pytest.mark.parametrize(
    "b_state, b_limit_um, dismissed",
    [
        (print_warp.FULL, 420, True),  # the other photo would find a slide of 0.42 mm there, and found none
        (print_warp.FULL, 460, False),  # it would find only a larger one than this photo's 0.44 mm
        (print_warp.DEFECT, 300, False),  # it found a defect there too: a slide stays put
        (print_warp.HIGHLIGHT, 300, False),  # it does not measure it
    ],
)
def test_a_slide_in_one_photo_that_another_sees_in_place_is_light(b_state, b_limit_um, dismissed):
    """A slid film stays on the print in every photo, as ink gone does: a slide one photo finds and
    another, which states it finds a slide that large there, does not, is light in the first."""
    entries, states, maps = two_photos(b_state, True)
    entries[0]["defects"][0].update(kind="shift", peak_mm=0.44, mean_mm=0.38)
    for k, um in ((0, 300), (1, b_limit_um)):
        maps[f"photo{k}_shift_limit_um"] = np.full(states[0].shape, um, np.uint16)
    got = light_in_one_photo(entries, states, maps, PPM, 4.0)
    assert bool(got) == dismissed
    if dismissed:
        assert got[0]["kind"] == "shift" and "finds a slide there and found none" in got[0]["decided_by"]["words"]


def test_a_photo_from_the_same_direction_overrules_nothing():
    """Two photos from one direction show one lamp's reflection alike: where they disagree, neither is light."""
    entries, states, maps = two_photos(print_warp.FULL, True)
    X = np.zeros((100, 100, 3))
    for e, c in zip(entries, ([0.0, 0.0, 300.0], [10.0, 0.0, 300.0]), strict=True):  # 1.9° apart
        e["pose"] = {"camera_center_mm": c}
    assert light_in_one_photo(entries, states, maps, PPM, 4.0, X) == []
    entries[1]["pose"]["camera_center_mm"] = [150.0, 0.0, 300.0]  # 26.6° apart
    assert len(light_in_one_photo(entries, states, maps, PPM, 4.0, X)) == 1


def three_photos(angle_deg: float):
    """Photos A and C find the same 16 mm² of ink gone, B measures it clean and would find it; the
    surface is the plane z = 0 (1 mm per grid px / 10), A's camera straight above the region, B's
    20° from it one way and C's ``angle_deg`` the other, all 500 mm away."""
    (entries, states, maps) = two_photos(print_warp.FULL, True)
    sc = states[0].copy()
    states = [states[0], states[1], sc]
    maps["photo2_dropout"], maps["photo2_scratch"] = maps["photo0_dropout"], maps["photo0_scratch"]
    c = {"kind": "missing", "area_mm2": 16.0, "bbox_mm": [3.0, 4.0, 7.0, 8.0], "centre_mm": [5.0, 6.0]}
    entries.append({"photo": "c.png", "defects": [c]})
    ii, jj = np.indices(sc.shape)
    X = np.stack([(jj + 0.5) / PPM, (ii + 0.5) / PPM, np.zeros(sc.shape)], axis=-1)
    p = np.array([5.0, 6.0, 0.0])
    t = np.radians(angle_deg)
    b = np.radians(-20.0)  # (B 20° the other way: from A's own direction it could overrule nothing)
    for e, v in zip(entries, ([0, 0, 1], [np.sin(b), 0, np.cos(b)], [np.sin(t), 0, np.cos(t)]), strict=True):
        e["pose"] = {"camera_center_mm": list(p + 500.0 * np.asarray(v, float))}
    return entries, states, maps, X


def test_ink_gone_two_photos_find_from_directions_no_lamp_shares_stays():
    # A and C 30° apart seen from the region: no one lamp mirrors into both, so their agreement is
    # ink gone and B's clean view does not dismiss it; 10° apart, one glint may show in both
    entries, states, maps, X = three_photos(30.0)
    assert light_in_one_photo(entries, states, maps, PPM, 4.0, X) == []
    entries, states, maps, X = three_photos(10.0)
    gone = light_in_one_photo(entries, states, maps, PPM, 4.0, X)
    assert {d["photo"] for d in gone} == {"a.png", "c.png"} and {d["decided_by"]["photo"] for d in gone} == {"b.png"}
    # (without the surface, as before: B dismisses both)
    entries, states, maps, X = three_photos(30.0)
    assert len(light_in_one_photo(entries, states, maps, PPM, 4.0)) == 2


def test_a_small_region_is_not_judged():
    # below the verdict's area a region fails nothing: it is left as found
    entries, states, maps = two_photos(print_warp.FULL, True)
    assert light_in_one_photo(entries, states, maps, PPM, 16.0) == []


# the second renderer: Mitsuba 3's path tracer, its own lamp, noise and gloss
LOOKS = {
    "workbench": ["--realistic"],
    "mitsuba": ["--renderer", "mitsuba", "--spp", "8", "--gloss", "0.5", "--jpeg-quality", "90"],
}


@pytest.mark.parametrize("renderer", list(LOOKS))
def test_a_real_dropout_seen_by_two_photos_fails_the_part(tmp_path, renderer):
    # the same dropout of 20 mm² on dark checker ink, photographed from two sides: both photos
    # show it where it is on the print, neither dismisses the other's
    d = tmp_path / "design"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d), "-q"]) == 0
    photos = []
    for k, orbit in enumerate(("10,55,330", "-40,60,330")):
        p = tmp_path / f"p{k}.png"
        args = ["render", str(d), f"--orbit={orbit}", "--size", "2000x1500", *LOOKS[renderer]]
        assert main([*args, "--defect", "dropout:60,25,2.52", "-o", str(p), "-q"]) == 0
        photos.append(p)
    out = tmp_path / "v"
    args = [
        "validate",
        str(d),
        *map(str, photos),
        "--camera",
        str(photos[0].with_suffix(".json")),
        "--out",
        str(out),
        "-q",
    ]
    assert main(args) == 0
    report = json.loads((out / "validation.json").read_text())
    assert report["part"]["verdict"] == "FAIL"
    found = [x for e in report["photos"] for x in e["defects"] if x["kind"] == "missing" and x["area_mm2"] > 4]
    assert found and "dismissed" not in report["part"]
    (part,) = [x for x in report["part"]["defects"] if x["kind"] == "missing" and x["area_mm2"] > 4]
    assert np.hypot(part["centre_mm"][0] - 60, part["centre_mm"][1] - 25) <= 1.0
    # each photo tells it for ink gone, or (the default finish, glossy) leaves it open when white
    # film on dark ink looks like a glint; then the part decides it from the other photo, 26° away
    decided = {x["photo"] for x in report["part"].get("open_decided", [])}
    in_part = report["part"].get("photo_verdicts_in_part", {})
    for p, e in zip(photos, report["photos"], strict=True):
        (x,) = [x for x in e["defects"] if x["kind"] == "missing" and x["area_mm2"] > 4]
        if x.get("unresolved"):
            assert e["verdict"] == "INCOMPLETE" and p.name in decided and in_part[p.name] == "FAIL"
        else:
            assert e["verdict"] == "FAIL" and x["decided_by"]["fails"]
    assert not part.get("unresolved")
    if renderer == "workbench":
        # a matte film (the look has no gloss) adds no light: each photo alone finds the dropout,
        # its area within 25 % of its 20 mm²
        for p in photos:
            one = tmp_path / f"matte-{p.stem}"
            args = ["validate", str(d), str(p), "--camera", str(p.with_suffix(".json")), "--out", str(one), "-q"]
            assert main([*args, "--finish", "matte"]) == 0
            (e,) = json.loads((one / "validation.json").read_text())["photos"]
            (x,) = [x for x in e["defects"] if x["kind"] == "missing" and x["area_mm2"] > 4]
            assert e["verdict"] == "FAIL" and abs(x["area_mm2"] / (np.pi * 2.52**2) - 1) <= 0.25


def test_every_listed_defect_says_what_decided_it_and_whether_it_fails():
    from workbench.validate.rule import defect_decision

    slid = {"kind": "shift", "area_mm2": 28.3, "significance_z": 12.0, "explained_share": 0.9, "peak_mm": 1.02}
    d = defect_decision(slid, 4.0)
    assert d["hypothesis"] == "the film slid" and d["fails"] and d["z"] == 12.0
    assert d["words"].endswith("fails: 28.3 mm² > 4 mm²") and "explains 90 %" in d["words"]
    assert "(up to 1.02 mm)" in d["words"] and "(up to" not in defect_decision({**slid, "peak_mm": None}, 4.0)["words"]
    small = {"kind": "missing", "area_mm2": 1.9, "significance_z": 3.01}
    d = defect_decision(small, 4.0)
    assert not d["fails"] and d["words"].endswith("does not fail: 1.9 mm² is within the accepted 4 mm²")
    faint = {"kind": "missing", "area_mm2": 27.9, "significance_z": 0.07}
    d = defect_decision(faint, 4.0)
    assert not d["fails"] and "not significant (z 0.07 < 3)" in d["words"]


def test_the_placement_names_the_move_when_it_explains_the_misregistration():
    from workbench.validate.rule import placement, placement_words

    e = {
        "film_offset_mm": [0.8, -0.3], "film_rotation_deg": 0.02, "film_scale_pct": 0.0,
        "film_fit_rms_mm": 0.011, "misregistration_mm": {"p95": 0.86},
    }  # fmt: skip
    p = placement(e, 0.5)
    assert p["verdict"] == "FAIL" and p["explains"] and p["move_mm"] == [-0.8, 0.3] and p["turn_deg"] == -0.02
    assert placement_words(p).startswith("film placed off by (+0.80, -0.30) mm, turned +0.02°")
    assert "move it by (-0.80, +0.30) mm and turn it by -0.02°" in placement_words(p)
    # a field the placement leaves at an rms of 0.3 mm (p95 about 0.6): the film's shape, not where it lies
    p = placement({**e, "film_fit_rms_mm": 0.3}, 0.5)
    assert p["verdict"] == "PASS" and not p["explains"] and "the film's shape" in p["decided_by"]
    # within the tolerance: placed well enough
    assert placement({**e, "misregistration_mm": {"p95": 0.2}}, 0.5)["verdict"] == "PASS"
    assert placement({**e, "film_offset_mm": None}, 0.5) is None


def test_a_defect_seen_in_several_photos_is_sized_by_the_median_of_those_that_see_it_whole():
    from workbench.validate.part import fused_view

    views = [
        {"photo": "top", "kind": "missing", "centre_mm": [1, 1], "area_mm2": 15.8, "px_per_mm": 9.0},
        {"photo": "side", "kind": "missing", "centre_mm": [2, 1], "area_mm2": 26.1, "px_per_mm": 11.0},
        {"photo": "edge", "kind": "missing", "centre_mm": [3, 1], "area_mm2": 9.0, "px_per_mm": 12.0},
        {"photo": "a", "kind": "missing", "centre_mm": [4, 1], "area_mm2": 17.4, "px_per_mm": 8.0},
        {"photo": "b", "kind": "missing", "centre_mm": [5, 1], "area_mm2": 27.5, "px_per_mm": 3.0},
    ]
    # "edge" samples finest but finds under half the largest area: it sees a part of it only
    got = fused_view(views)
    assert got["photo"] == "side" and got["centre_mm"] == [3.0, 1.0]  # the median of 1, 2, 4, 5
    assert got["area_mm2"] == pytest.approx(0.5 * (17.4 + 26.1))
    assert fused_view([views[4]])["area_mm2"] == 27.5
    # ink gone that one photo finds is ink gone, where another finds a colour defect there
    views[1]["kind"] = "colour"
    assert fused_view(views[:2])["kind"] == "missing" and fused_view(views[1:2])["kind"] == "colour"


def test_what_one_photo_found_apart_stays_apart_and_each_photo_shows_a_defect_once():
    """Two dropouts 14 mm apart whose boxes touch: the photo that found both keeps them two
    defects of the part (merged, they were one 54 mm² defect between them, and both escaped); a
    photo that found one joins the one its box overlaps most; each part defect lists a photo once."""
    from types import SimpleNamespace

    from workbench.validate.part import part_summary

    H, W = 100, 100
    state = np.full((H, W), print_warp.FULL, np.uint8)
    grid = SimpleNamespace(owner=np.zeros((H, W), np.int32))

    def missing(i, area, bbox, centre):
        return {"id": i, "kind": "missing", "area_mm2": area, "bbox_mm": bbox, "centre_mm": centre}

    left = missing(1, 28.1, [109.0, 134.9, 120.9, 147.1], [113.3, 140.5])
    right = missing(2, 25.1, [118.9, 130.3, 131.1, 144.0], [125.7, 136.0])
    other = missing(1, 25.9, [109.0, 134.9, 120.1, 145.3], [113.0, 140.1])
    entries = [
        {"photo": "a.png", "verdict": "FAIL", "defects": [left, right]},
        {"photo": "b.png", "verdict": "FAIL", "defects": [other]},
    ]
    _, _, defects = part_summary([state, state], grid, ["top"], entries)
    assert len(defects) == 2
    by_centre = sorted(defects, key=lambda d: d["centre_mm"][0])
    assert by_centre[0]["photos"] == ["a.png", "b.png"]
    assert by_centre[0]["area_mm2_by_photo"] == {"a.png": 28.1, "b.png": 25.9}
    assert by_centre[0]["centre_mm"] == pytest.approx([113.15, 140.3])
    assert by_centre[1]["photos"] == ["a.png"] and by_centre[1]["area_mm2"] == 25.1


def test_a_region_one_photo_cannot_tell_from_light_is_open_not_failed():
    """On a glossy film, ink gone that no test tells from a glint fails nothing and passes nothing."""
    from workbench.validate.rule import defect_decision, photo_verdict

    d = {
        "kind": "missing", "area_mm2": 46.7, "significance_z": 25.6, "centre_mm": [86.2, 39.2], "unresolved": True,
        "photometric": {"hypothesis": "not told", "separation_sigma": 0.35},
    }  # fmt: skip
    why = defect_decision(d, 4.0)
    assert why["hypothesis"] == "ink gone or light" and not why["fails"] and why["open"]
    assert "(the two 0.35 σ of the photo's noise apart)" in why["words"] and "more than 16° away" in why["words"]
    entry = {
        "tiles": 20, "tiles_examined": 20, "ssim": 0.9, "misregistration_mm": {"p95": 0.1}, "defects": [d],
    }  # fmt: skip
    verdict, reason = photo_verdict(entry, 0.2, 4.0)
    assert verdict == "INCOMPLETE" and reason.startswith("1 region > 4 mm² the photo cannot tell a defect from light")
    assert "no defect > 4 mm²" in reason  # (the open region is not counted among the defects told)
    # told ink gone beside it: the photo fails
    told = {"kind": "missing", "area_mm2": 20.0, "significance_z": 9.0, "centre_mm": [10.0, 10.0]}
    assert photo_verdict({**entry, "defects": [d, told]}, 0.2, 4.0)[0] == "FAIL"
    # an open region within the accepted area leaves the photo as it was
    assert photo_verdict({**entry, "defects": [{**d, "area_mm2": 3.0}]}, 0.2, 4.0)[0] == "PASS"
    # a slide a smooth light explains as well, out of the lamp's cone: open alike
    slid = {
        "kind": "shift", "area_mm2": 23.1, "significance_z": 24.8, "centre_mm": [75.5, 97.8], "peak_mm": 0.67,
        "explained_share": 0.74, "explained_under_light_share": 0.32, "unresolved": True,
    }  # fmt: skip
    why = defect_decision(slid, 4.0)
    assert why["hypothesis"] == "the film slid or light" and not why["fails"] and why["open"]
    assert "(32 % with the light)" in why["words"]
    assert photo_verdict({**entry, "defects": [slid]}, 0.2, 4.0)[0] == "INCOMPLETE"
    assert defect_decision({**slid, "unresolved": False}, 4.0)["fails"]


@pytest.mark.parametrize("angle_deg, told", [(30.0, True), (10.0, False)])
def test_an_open_region_two_photos_find_from_directions_no_lamp_shares_is_ink_gone(angle_deg, told):
    """A and C both find the region and cannot tell it from light: 30° apart seen from it, no one
    glint shows in both, and it is ink gone, which fails the part; 10° apart it stays open."""
    from types import SimpleNamespace

    from workbench.validate.part import decided_in_part, open_told_elsewhere, part_summary
    from workbench.validate.rule import defect_decision, photo_verdict

    entries, states, maps, X = three_photos(angle_deg)
    entries, states = [entries[0], entries[2]], [states[0], states[2]]
    for e in entries:
        d = e["defects"][0]
        d.update(id=1, significance_z=20.0, unresolved=True)
        d["decided_by"] = defect_decision(d, 4.0)
        e.update(tiles=20, tiles_examined=20, ssim=0.9, misregistration_mm={"p95": 0.1})
        e["verdict"], e["reason"] = photo_verdict(e, 0.2, 4.0)
        assert e["verdict"] == "INCOMPLETE"
    got = open_told_elsewhere(entries, states, PPM, 4.0, X)
    grid = SimpleNamespace(owner=np.zeros(states[0].shape, np.int32))
    if not told:
        assert got == []
        part, _, defects = part_summary(states, grid, ["top"], entries)
        assert part["verdict"] == "INCOMPLETE" and defects[0]["unresolved"]
        return
    assert [x["photo"] for x in got] == ["a.png", "c.png"]
    assert got[0]["decided_by"]["hypothesis"] == "ink gone" and got[0]["decided_by"]["apart_deg"] == 30.0
    assert "c.png found it too, at the same print position, from 30° away" in got[0]["decided_by"]["words"]
    in_part = {}
    for x in got:
        e = entries[x["photo_index"]]
        kept = {**e, "defects": [decided_in_part(d, x, 4.0) for d in e["defects"]]}
        assert kept["defects"][0]["decided_by"]["fails"] and "unresolved" not in kept["defects"][0]
        in_part[x["photo_index"]] = photo_verdict(kept, 0.2, 4.0)
    part, _, defects = part_summary(states, grid, ["top"], entries, got, in_part)
    assert part["verdict"] == "FAIL" and "unresolved" not in defects[0]
    # (the photos' own entries stay as each found it)
    assert all(e["defects"][0]["unresolved"] for e in entries)
    # without the surface no angle is known: it stays open
    assert open_told_elsewhere(entries, states, PPM, 4.0) == []
