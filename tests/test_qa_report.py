"""The QA report: its first page says what to do, and no text on any page is cut off."""

from __future__ import annotations

import json

import pypdfium2 as pdfium
import pytest
from conftest import ROOT

from workbench.cli import main
from workbench.design_dir import Design
from workbench.validate.report import qa_report
from workbench.validate.report_first_page import actions

MM = 72 / 25.4
MARGIN_MM = 10.0  # every character lies at least this far inside the page (the frames' margins are 15 and 20)


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    d = tmp_path_factory.mktemp("qa") / "design"
    assert main(["design", str(ROOT / "fixtures" / "default" / "job.toml"), "--out", str(d), "-q"]) == 0
    return Design(d)


def validated(design, folder, *render_flags):
    """A 2000 x 1500 photo rendered as the demo does, validated; (validation.json, qa_report.pdf's path)."""
    photo = folder / "p.jpg"
    args = ["render", str(design.dir), "--orbit=200,45,330", "--size", "2000x1500", "--realistic", "-q"]
    assert main([*args, *render_flags, "-o", str(photo)]) == 0
    out = folder / "out"
    main(
        ["validate", str(design.dir), str(photo), "--camera", str(photo.with_suffix(".json")), "--out", str(out), "-q"]
    )
    return json.loads((out / "validation.json").read_text()), out / "qa_report.pdf"


def page_texts(pdf_path) -> list[str]:
    """Each page's text, whitespace folded."""
    pdf = pdfium.PdfDocument(str(pdf_path))
    return [folded(pdf[i].get_textpage().get_text_range()) for i in range(len(pdf))]


def text_outside(pdf_path) -> list[tuple]:
    """The characters whose box leaves the page's frame (MARGIN_MM inside each edge): (page, char, box)."""
    bad = []
    pdf = pdfium.PdfDocument(str(pdf_path))
    for i in range(len(pdf)):
        page = pdf[i]
        W, H = page.get_size()
        tp = page.get_textpage()
        lo = MARGIN_MM * MM
        for k in range(tp.count_chars()):
            ch = tp.get_text_range(k, 1)
            if not ch.strip():
                continue
            left, bottom, right, top = tp.get_charbox(k)
            if left < lo or bottom < lo or right > W - lo or top > H - lo:
                bad.append((i + 1, ch, (round(left), round(bottom), round(right), round(top))))
    return bad


def folded(text: str) -> str:
    """Whitespace folded, and the increment sign a PDF's standard font extracts for Δ read as Δ."""
    return " ".join(text.replace("\u2206", "\u0394").split())


@pytest.fixture(scope="module")
def misplaced(design, tmp_path_factory):
    return validated(design, tmp_path_factory.mktemp("film"), "--film-offset-mm", "0.8,0")


@pytest.fixture(scope="module")
def defective(design, tmp_path_factory):
    flags = ["--gloss", "0.5", "--defect", "bubble:45,30,6,1", "--defect", "dropout:60,25,1.784"]
    return validated(design, tmp_path_factory.mktemp("defects"), *flags)


def test_a_misplaced_film_is_a_move_on_page_one_not_a_shift_defect(misplaced):
    report, pdf = misplaced
    place = report["photos"][0]["placement"]
    (mx, my), turn = place["move_mm"], place["turn_deg"]
    assert place["verdict"] == "FAIL" and mx == pytest.approx(-0.8, abs=0.05) and abs(my) < 0.05
    first = page_texts(pdf)[0]
    assert f"Move the film by ({mx:+.2f}, {my:+.2f}) mm and turn it by {turn:+.2f}°" in first, first
    assert not [d for d in report["part"]["defects"] if d["kind"] == "shift"]
    assert "No defect found" in first and "shift" not in first


def test_a_misplaced_films_colour_is_judged_where_the_film_lies(misplaced):
    # compared where the design puts each ink, the film 0.8 mm off read its print's every edge as a
    # colour difference (7.6 ΔE00 on the demo's part at 4000 x 3000, a colour FAIL beside the
    # placement's); where the film lies, its colour passes as the perfect part's does (0.96 there)
    report = misplaced[0]
    colour = report["photos"][0]["colour"]
    assert colour["measured"] and colour["verdict"] == "PASS", colour.get("delta_e00")
    assert report["part"]["colour"]["verdict"] == "PASS", report["part"]["colour"]


def test_a_defect_is_circled_and_tabled_on_page_one(defective):
    report, pdf = defective
    first = page_texts(pdf)[0]
    over = [d for d in report["part"]["defects"] if d["area_mm2"] > report["max_defect_mm2"]]
    # (a region the one glossy photo cannot tell from a glint is open: to look at again, not to reject)
    still = [d for d in over if d.get("unresolved")]
    over = [d for d in over if not d.get("unresolved")]
    assert over, report["part"]["defects"]
    assert f"Reject or rework the part: {len(over)} defect(s) larger than 4 mm²" in first
    # (the glossy photo's dropout over the checker's dark ink: one photo cannot tell it from a glint)
    assert still and f"Look at {len(still)} region(s) larger than 4 mm²" in first
    for d in report["part"]["defects"]:
        assert f"x {d['centre_mm'][0]:.1f}, y {d['centre_mm'][1]:.1f}" in first
    assert "defect(s) circled and numbered" in first


@pytest.mark.parametrize("which", ["misplaced", "defective"])
def test_no_text_is_cut_off_on_any_page(which, request):
    report, pdf = request.getfixturevalue(which)
    assert text_outside(pdf) == []
    pages = page_texts(pdf)
    text = " ".join(pages)
    assert "..." not in text and "…" not in text
    # the rule and every photo's reason in full, the rule after page one
    assert folded(report["verdict_rule"]["text"]) in " ".join(pages[1:])
    for e in report["photos"]:
        assert folded(e["reason"]) in text


def report_of(photos: list[dict], part: dict) -> dict:
    """A validation.json as the QA report reads it: design, software, camera, rule, ``photos`` and ``part``."""
    return {
        "design": {"dir": "design", "design_json_sha256": "0" * 64, "print_sha256": "1" * 64, "job": {"name": "lid"}},
        "software": {"version": "0"},
        "camera_profile": {"file": "cam.json", "sha256": "2" * 64},
        "tolerance_mm": 0.2,
        "max_defect_mm2": 4.0,
        "photos": photos,
        "part": part,
    }


def test_a_long_first_page_runs_on_rather_than_off_the_page(tmp_path):
    # forty defects and a reason of several lines: the table splits onto a second page, nothing leaves the frame
    reason = "misregistration p95 0.412 mm > tolerance 0.2 mm; " * 12
    defects = [
        {"kind": "missing", "centre_mm": [1.0 + k, 2.0], "area_mm2": 5.0 + k, "view": "logo", "photos": ["a.jpg"]}
        for k in range(40)
    ]
    photo = {"photo": "a.jpg", "verdict": "FAIL", "reason": reason, "view": "front", "defects": []}
    report = report_of([photo], {"verdict": "FAIL", "defects": defects})
    (tmp_path / "r.pdf").write_bytes(qa_report(report, {}))
    assert text_outside(tmp_path / "r.pdf") == []
    pages = page_texts(tmp_path / "r.pdf")
    assert folded(f"a.jpg: {reason}") in pages[0]
    text = " ".join(pages[:2])
    assert all(f"x {1.0 + k:.1f}, y 2.0" in text for k in range(40))


def test_why_gives_each_photo_as_the_part_judges_it(tmp_path):
    # b.jpg failed alone on a slide another photo measured in place (light in b.jpg), and passes in the
    # part; c.jpg fails in the part on a dropout: "Why" names c.jpg with its reason in the part, not b.jpg
    light = "1 defect > 4 mm² (largest: shift, 79.2 mm² at (75.3, 6.1) mm on the print)"
    dropout = "1 defect > 4 mm² (largest: missing, 19.8 mm² at (12.0, 30.0) mm on the print)"
    report = report_of(
        [
            {"photo": "a.jpg", "verdict": "PASS", "reason": "no defect > 4 mm²", "view": "top", "defects": []},
            {"photo": "b.jpg", "verdict": "FAIL", "reason": light, "view": "top", "defects": []},
            {"photo": "c.jpg", "verdict": "FAIL", "reason": dropout + "; " + light, "view": "top", "defects": []},
        ],
        {
            "verdict": "FAIL",
            "defects": [],
            "photo_verdicts_in_part": {"b.jpg": "PASS", "c.jpg": "FAIL"},
            "photo_reasons_in_part": {"b.jpg": "no defect > 4 mm²", "c.jpg": dropout},
        },
    )
    (tmp_path / "r.pdf").write_bytes(qa_report(report, {}))
    first = page_texts(tmp_path / "r.pdf")[0]
    assert folded(f"c.jpg: {dropout}") in first and "79.2" not in first
    assert "b.jpg:" not in first


def test_the_actions_name_the_next_photo_and_the_photo_to_retake():
    report = {
        "max_defect_mm2": 4.0,
        "photos": [
            {"photo": "dir/a.jpg", "verdict": "PASS", "reason": "", "placement": None},
            {"photo": "b.jpg", "verdict": "INVALID", "reason": "the fixture's markers are not in the photo"},
        ],
        "part": {
            "verdict": "INCOMPLETE",
            "defects": [],
            "coverage": {"next_photo": {"orbit": [60.0, 50.0, 330.0], "sees_share": 1.0}},
            "colour": {"verdict": "not measured", "reasons": ["colour not measured: no chart"]},
        },
    }
    said = actions(report)
    assert said[0] == "Retake b.jpg: the fixture's markers are not in the photo."
    assert said[1].startswith("Retake from azimuth 60°, elevation 50°, 330 mm from the part's centre")
    assert said[2] == "To measure colour, keep the fixture's colour chart in the frame of the next photo."
    assert actions({**report, "photos": report["photos"][:1], "part": {"verdict": "PASS", "defects": []}}) == [
        "Accept the part: nothing to do."
    ]


def test_the_circled_photo_is_the_part_cropped_with_its_circles(design, defective):
    # the photo's page picture: the part's box in the photo (its vertices projected by the pose the
    # validation measured) and a 10 % margin, not the whole fixture; each defect's circle on it
    import cv2
    import numpy as np

    from workbench.camera import Camera, load_camera_profile
    from workbench.validate.photo import part_box

    report, pdf = defective
    e = report["photos"][0]
    img = cv2.imread(str(pdf.parent / f"{e['pictures']}_defects_photo.png"))
    lens = load_camera_profile(pdf.parent.parent / "p.json")
    cam = Camera(lens.K, np.array(e["pose"]["R"]), np.array(e["pose"]["t"]), lens.width, lens.height, lens.dist)
    x0, y0, x1, y1 = part_box(cam, design.V, (lens.height, lens.width))
    # (the crop is from the part where the validation seated it; this pose is the board's: a pixel or two apart)
    assert np.abs(np.subtract(img.shape[:2], (y1 - y0, x1 - x0))).max() <= 2
    assert (x1 - x0) * (y1 - y0) < 0.5 * lens.width * lens.height
    red = (img[..., 2] > 200) & (img[..., 1] < 40) & (img[..., 0] < 40)
    rows, cols = np.nonzero(red)
    for d in e["defects"]:
        cx, cy = d["photo_px"][0] - x0, d["photo_px"][1] - y0
        r = max(d["photo_radius_px"], 12)
        on = np.abs(np.hypot(cols - cx, rows - cy) - r) <= 3  # the circle's ring, 3 px wide
        assert on.sum() > 2 * np.pi * r, (d["id"], on.sum())
