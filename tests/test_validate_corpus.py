"""The validate corpus: what a QA engineer relies on, on real meshes, real artwork and photos by two renderers.

A perfect part PASSes; a part with one defect above the detection limit validate states
FAILs, with the defect found within 1 mm of its place and its area within 25 %. The fast
subset (6 photos at 2000 x 1500 of 6 real parts: photographs, a low-contrast logo, fine
text, checkers, gradients; matte, glossy, lens distortion) runs in ``make test``; the issue's
acceptance cases at 12 Mpx (8 perfect parts; the 1 mm bubble of 12 mm, the 0.5 mm bubble of
6 mm, a 10 mm² dropout, a 20 mm scratch on two parts) on both renderers are marked slow
(``make bench``). The whole corpus (252 photos per renderer, 2000 x 1500 to 6000 x 4000, about
two hours on two cores with the workbench renderer) is ``python benchmarks/validate_corpus.py
--subset full``. All come from
that runner: one ``workbench render`` and one ``workbench validate`` command per photo,
against the truth in PHOTO.json.

``KNOWN_FAILING``: the cases today's validate gets wrong (issue 19), with what it says. They
are xfails; the rest of the subset is asserted. An entry goes when its case passes (run with
``--runxfail`` to see which).
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import subprocess
import sys

import cv2
import pytest
from conftest import ROOT

from workbench.render.defects import Defect
from workbench.validate.dense import SHIFT_EXPLAINS

spec = importlib.util.spec_from_file_location("validate_corpus", ROOT / "benchmarks" / "validate_corpus.py")
vc = importlib.util.module_from_spec(spec)
sys.modules["validate_corpus"] = vc
spec.loader.exec_module(vc)

# photo id -> what today's validate says (issue 19: no false rejects on real artwork)
KNOWN_FAILING = {
    # measured 2026-12-02 on the uncertainty-aware validate (issue 19 in progress)
    "arm-top-perfect-lens-2000x1500-workbench": "soft gradient: INVALID, 'too little texture to measure "
    "misregistration here' (0 tiles, SSIM 0.99): the photo says so rather than a false verdict",
    # the 12 Mpx acceptance cases (make bench), measured 2026-12-02 on both renderers: every other one holds
    "camelhead-top-perfect-glossy-4000x3000-workbench": "soft gradient: INVALID, 'too little texture to measure "
    "misregistration here' (0 tiles, SSIM 0.99): the photo says so rather than a false verdict",
    "camelhead-top-perfect-glossy-4000x3000-mitsuba": "as on the workbench renderer: INVALID, too little texture",
}


class Args:
    revalidate = True
    report_only = False
    spp = 16
    validation = "validation"
    finish = "look"


def run(photos: list, out) -> dict:
    """Each photo rendered and validated; the Mitsuba ones only when the render command has --renderer."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if not vc.accepts_renderer(env):
        photos = [p for p in photos if p.renderer != "mitsuba"]
    designs = {part: vc.design_part(part, out, env) for part in sorted({p.part for p in photos})}
    return {p.id: vc.run_photo(p, out, designs, env, env, Args) for p in photos} | {"designs": designs}


FAST = vc.grid("fast", ["workbench", "mitsuba"])


@pytest.fixture(scope="module")
def fast(tmp_path_factory):
    return run(FAST, tmp_path_factory.mktemp("validate_corpus"))


def check(photo, may_be_below: bool = True) -> None:
    """A perfect photo PASSes; a defect FAILs, found where it is at its size, unless validate
    states it cannot find it there (``may_be_below``; the issue's acceptance cases at 12 Mpx
    must be above the stated limit). On a glossy film a defect the photo cannot tell from a
    glint may be open instead (the photo INCOMPLETE, the defect located and sized among its open
    regions: a second photo decides it), and a perfect photo INCOMPLETE alike, never FAIL; on a
    matte film so may a slide the photo cannot tell from a smooth light."""
    r = photo.result
    assert "verdict" in r, r  # rendered and validated
    glossy = vc.look_finish(photo.look) == "glossy"
    if photo.defect is None:
        may_be_open = glossy or "a slide stays at its print position" in (r["reason"] or "")
        why = (r["reason"], r["defects_found"])
        assert r["verdict"] == "PASS" or (may_be_open and r["verdict"] == "INCOMPLETE"), why
        return
    assert r["stated"] is not None, "validate states no detection maps"
    if vc.below_stated_limit(r["truth"], r["detection_limit"], r["stated"]):
        assert may_be_below, f"{photo.defect}: validate states it cannot find it here: {r['stated']}"
        pytest.skip(f"{photo.defect} is below the detection limit validate states: {r['stated']}")
    slide_open = "a slide stays at its print position" in (r["reason"] or "")
    assert r["verdict"] == "FAIL" or ((glossy or slide_open) and r["outcome"] == "open"), r["reason"]
    assert len(r["truth"]) == 1
    m = r["match"][0]
    assert m["found"] is not None, r["defects_found"]
    assert m["distance_mm"] <= vc.LOCATE_MM, m
    assert abs(m["area_error"]) <= vc.AREA_SHARE, m
    # and nothing else over the verdict's area: a defect that is not there is a false reject of its own
    assert r["false_defects"] == 0, r["defects_found"]


def marked(photos: list) -> list:
    return [
        pytest.param(
            p,
            id=p.id,
            marks=[pytest.mark.xfail(strict=False, reason=KNOWN_FAILING[p.id])] if p.id in KNOWN_FAILING else [],
        )
        for p in photos
    ]


def test_the_fast_subset_is_representative():
    kinds = vc.artwork_of()
    assert {kinds[(p.part, p.view)] for p in FAST} >= {"photo", "logo", "text", "checker", "gradient"}
    assert sum(p.defect is None for p in FAST) >= 3 and {p.defect.split("-")[0] for p in FAST if p.defect} == {
        "bubble",
        "dropout",
        "scratch",
    }
    full = vc.grid("full", ["workbench"])
    assert sum(p.defect is None for p in full) >= 100 and sum(p.defect is not None for p in full) >= 100
    assert len({p.part for p in full}) >= 10 and {p.size for p in full} >= {"2000x1500", "6000x4000"}


def test_defects_go_where_they_show(fast):
    # each defect's truth is what was asked, and its centre lies in its view's own region of the print
    for p in FAST:
        if p.defect is None or p.id not in fast:
            continue
        r = fast[p.id].result
        assert "truth" in r, (p.id, r)  # placed, rendered and validated
        t = r["truth"]
        assert [d["kind"] for d in t] == [vc.DEFECTS[p.defect][0]] and t[0]["spec"] == Defect.parse(p.spec).spec()
        design = fast["designs"][p.part]
        owner = cv2.imread(str(design / "owner.png"), cv2.IMREAD_UNCHANGED).astype(int) - 1
        names = [v["name"] for v in json.loads((design / "design.json").read_text())["views"]]
        x, y = (int(c * vc.print_px_per_mm(design)) for c in t[0]["centre_mm"])
        assert names[owner[y, x]] == p.view


@pytest.mark.parametrize("photo", marked(FAST))
def test_fast_subset(fast, photo):
    if photo.id not in fast:
        pytest.skip("Mitsuba: the render command has no --renderer")
    check(fast[photo.id])


BENCH = vc.grid("bench", ["workbench", "mitsuba"])


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    return run(BENCH, tmp_path_factory.mktemp("validate_corpus_bench"))


@pytest.mark.slow
@pytest.mark.parametrize("photo", marked(BENCH))
def test_acceptance_at_12_mpx(bench, photo):
    if photo.id not in bench:
        pytest.skip("Mitsuba: the render command has no --renderer")
    check(bench[photo.id], may_be_below=False)


def test_a_glint_one_photo_cannot_tell_from_ink_gone_is_open_on_a_glossy_film(tmp_path):
    """The snail's shell seen from above, glossy, perfect: a soft glint over dark ink reaches the
    film's colour without clipping, and no light the photo shows elsewhere tells it from ink that
    is gone (it failed as 30.8 mm² of "missing", separation 0.6 sigma). Alone, on a glossy film,
    the photo is INCOMPLETE with that region open and no ink gone stated found under it; said to be
    matte, the film adds no light, and the region is ink gone."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    photo = vc.Photo("snail", "top", "2000x1500", "glossy", "workbench", seed=218)
    designs = {"snail": vc.design_part("snail", tmp_path, env)}
    reports = {}
    for finish in ("glossy", "matte"):
        args = type("A", (Args,), {"finish": finish, "validation": f"validation_{finish}"})
        assert vc.run_photo(photo, tmp_path, designs, env, env, args).result.get("verdict"), photo.result
        vdir = tmp_path / "photos" / photo.id / args.validation
        reports[finish] = json.loads((vdir / "validation.json").read_text())
    glossy, matte = (reports[f]["photos"][0] for f in ("glossy", "matte"))
    assert glossy["verdict"] == "INCOMPLETE" and reports["glossy"]["part"]["verdict"] == "INCOMPLETE"
    (shell,) = [d for d in glossy["defects"] if d["area_mm2"] > 4]
    assert shell["unresolved"] and shell["decided_by"]["hypothesis"] == "ink gone or light"
    assert not shell["decided_by"]["fails"] and "cannot tell" in reports["glossy"]["part"]["reason"]
    assert matte["verdict"] == "FAIL"
    (gone,) = [d for d in matte["defects"] if d["area_mm2"] > 4]
    assert gone["kind"] == "missing" and gone["decided_by"]["fails"] and "unresolved" not in gone
    assert gone["centre_mm"] == pytest.approx(shell["centre_mm"])


def test_a_perfect_photo_of_artwork_stretched_into_streaks_shows_no_slide(tmp_path):
    """The lily's top, --realistic (seed 37 of the full corpus): its windows' slides over the faint
    streaks the design stretched err by several times what the photo's noise alone states (3.5
    times on the median, 14 % of them 3 of it past the tolerance): judged on the noise, a
    41.4 mm² slide at (98.8, 14.2) mm, z 18.9, failed the perfect part. With what the photo's own
    windows err by (:func:`workbench.validate.dense.uncertainty.window_mismatch`) it passes."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    photo = vc.Photo("lilium", "top", "2000x1500", "realistic", "workbench", seed=37)
    designs = {"lilium": vc.design_part("lilium", tmp_path, env)}
    result = vc.run_photo(photo, tmp_path, designs, env, env, Args).result
    assert result["verdict"] == "PASS", (result["reason"], result["defects_found"])
    report = json.loads((tmp_path / "photos" / photo.id / "validation" / "validation.json").read_text())
    assert not [d for d in report["photos"][0]["defects"] if d["kind"] == "shift" and d["area_mm2"] > 1.0]


def test_a_slide_a_smooth_light_explains_as_well_is_open_on_a_matte_film_too(tmp_path):
    """The scanned face seen from above, the lens look (matte, seed 4 of the full corpus), perfect.
    With the print blurred as the photo is (an ellipse where the photo sees the surface obliquely),
    the model's own error no longer hides a 0.48 mm "slide" over 61 mm² of the photograph's smooth
    skin, where moving the print explains 10 % of what a smooth light leaves: a slide the photo
    cannot tell from a light the matte film's shading model misses (interreflections, cast
    shadows). It is open, as on a glossy film, not a slide that fails the part (it failed it as a
    265 mm² shift)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    photo = vc.Photo("face", "top", "2000x1500", "lens", "workbench", seed=4)
    designs = {"face": vc.design_part("face", tmp_path, env)}
    result = vc.run_photo(photo, tmp_path, designs, env, env, Args).result
    assert result["verdict"] in ("PASS", "INCOMPLETE"), (result["reason"], result["defects_found"])
    report = json.loads((tmp_path / "photos" / photo.id / "validation" / "validation.json").read_text())
    slides = [d for d in report["photos"][0]["defects"] if d["kind"] == "shift" and d["area_mm2"] > 4.0]
    assert slides, report["photos"][0]["defects"]  # (the case: the region is there, and open)
    for d in slides:
        assert d["unresolved"] and d["decided_by"]["hypothesis"] == "the film slid or light", d
        assert d["explained_under_light_share"] < SHIFT_EXPLAINS and not d["decided_by"]["fails"]


def test_a_windows_slide_along_an_edge_that_barely_turns_is_no_evidence_of_a_slide(tmp_path):
    """The lily, perfect, matte, photographed by Mitsuba from where the part's coverage asked for
    the next photo (azimuth 210°, elevation 65°: ``random_defects.py``'s perfect matte lily). Its
    lobes' rims are arcs of uniform green against the white film; over a window of about a
    millimetre they barely turn, and the window's slide along them is what the detection limit
    states it answers a twentieth of (``WINDOW_GAIN_ALONG_EDGE``). Taken as evidence, it failed
    the photo on three slides of 24 to 52 mm², "up to 0.56 mm" at z 11 to 26, where the pixels'
    own flow measured 0.01 mm (the workbench renderer's photo from there passed)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if not vc.accepts_renderer(env):
        pytest.skip("Mitsuba: the render command has no --renderer")
    design = vc.design_part("lilium", tmp_path, env)
    photo = tmp_path / "lobes.png"
    render = [sys.executable, "-m", "workbench", "render", str(design), "--orbit=210,65,346.2", "--fov-deg", "40"]
    render += ["--size", "2000x1500", "--gloss", "0", "--seed", "4", "--renderer", "mitsuba", "--spp", "8"]
    subprocess.run([*render, "--out", str(photo)], check=True, env=env, capture_output=True, timeout=600)
    out = tmp_path / "v"
    validate = [sys.executable, "-m", "workbench", "validate", str(design), str(photo), "--camera"]
    validate += [str(photo.with_suffix(".json")), "--tolerance-mm", "0.2", "--finish", "matte", "--out", str(out)]
    subprocess.run([*validate, "--jobs", "1", "-q"], env=env, capture_output=True, timeout=600)
    report = json.loads((out / "validation.json").read_text())["photos"][0]
    assert not [d for d in report["defects"] if d["kind"] == "shift" and d["area_mm2"] > 4.0], report["defects"]
    assert report["verdict"] != "FAIL", report["reason"]


def test_light_a_matte_films_model_finds_on_a_slid_edge_does_not_hide_the_slide(tmp_path):
    """The fandisk from above, the soft look (matte, seed 186 of the full corpus), a 12 mm bubble
    slid 1 mm. The edges the bubble moved show the film where the design has ink; the photometric
    model took some for light (71 to 183 px), and the flow's windows, which leave out what light
    covers and their reach around it, lost the slide over most of the bubble: the photo passed,
    the bubble stated found over half of it. On a matte film that light is a gain, which the
    flow's local normalisation divides away: only the light the photo shows for sure is left out."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    photo = vc.Photo("fandisk", "top", "2000x1500", "soft", "workbench", defect="bubble-12mm-1.0", seed=186)
    designs = {"fandisk": vc.design_part("fandisk", tmp_path, env)}
    result = vc.run_photo(photo, tmp_path, designs, env, env, Args).result
    assert result["verdict"] == "FAIL", (result["reason"], result["defects_found"])
    report = json.loads((tmp_path / "photos" / photo.id / "validation" / "validation.json").read_text())
    (truth,) = result["truth"]
    slides = [d for d in report["photos"][0]["defects"] if d["kind"] == "shift" and d["area_mm2"] > 4.0]
    near = [d for d in slides if math.dist(d["centre_mm"], truth["centre_mm"]) < 0.5 * truth["radius_mm"]]
    assert near and abs(near[0]["area_mm2"] / truth["area_mm2"] - 1.0) <= 0.25, slides
