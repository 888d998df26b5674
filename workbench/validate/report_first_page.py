"""The QA report's first page: is this part good, and what to do (the verdict, the action, the evidence)."""

from __future__ import annotations

import io
from xml.sax.saxutils import escape

from workbench.validate.dense.options import APART_DEG
from workbench.validate.rule import still_open

MARGIN_MM = 20.0  # left and right margins of every page
TOP_MM = 15.0  # top and bottom margins of a flowed page
MATCH_MM = 0.5  # a part's defect is a photo's circle when their centres are this close on the print


def actions(report: dict) -> list[str]:
    """What the technician does about this part, most decisive first, in words.

    Parameters
    ----------
    report : dict
        The content of validation.json.

    Returns
    -------
    list of str
        One sentence per action: move the film (from each photo's fitted ``placement``), reprint
        (defects over ``max_defect_mm2``, colour over ``max_delta_e``), retake (an INVALID photo, or
        an INCOMPLETE part's next photo), or accept.
    """
    part = report.get("part") or {}
    verdict = part.get("verdict", "INVALID")
    out = []
    for e in report.get("photos", []):
        place = e.get("placement")
        if place and place["verdict"] == "FAIL":
            (mx, my), t = place["move_mm"], place["turn_deg"]
            (x, y), r = place["offset_mm"], place["rotation_deg"]
            out.append(
                f"Move the film by ({mx:+.2f}, {my:+.2f}) mm and turn it by {t:+.2f}° on the next part "
                f"(print mm, x right, y down): {photo_name(e)} shows it ({x:+.2f}, {y:+.2f}) mm and {r:+.2f}° off."
            )
    moved = bool(out)
    limit = report.get("max_defect_mm2")
    over = [
        k + 1
        for k, d in enumerate(part.get("defects", []))
        if limit is not None and d["area_mm2"] > limit and not d.get("unresolved")
    ]
    still = [k + 1 for k, d in enumerate(part.get("defects", [])) if limit is not None and still_open(d, limit)]
    if still:
        # (a region no photo told ink gone from a glint on: one from elsewhere tells, the next photo says where)
        out.append(
            f"Look at {len(still)} region(s) larger than {limit:g} mm² (# {', '.join(map(str, still))} in the defect "
            "table) in another photo: no photo told ink gone from a glint there; a photo from more than "
            f"{APART_DEG:g}° away from those that show it decides."
        )
    if over:
        out.append(
            f"Reject or rework the part: {len(over)} defect(s) larger than {limit:g} mm² "
            f"(# {', '.join(map(str, over))} in the defect table); then look for their cause on the press or the "
            "forming tool."
        )
    colour = part.get("colour") or {}
    if colour.get("verdict") == "FAIL" and moved:
        # colour is compared where the design puts the ink: on a film off its place, across the print's edges
        out.append(
            f"Judge the colour again once the film is in place ({colour_words(colour, report.get('max_delta_e'))}): "
            "it is compared where the design puts each colour, so across its edges on a film that is off."
        )
    elif colour.get("verdict") == "FAIL":
        out.append(f"Check the ink and the print profile ({colour_words(colour, report.get('max_delta_e'))}).")
    for e in report.get("photos", []):
        if e["verdict"] == "INVALID":
            out.append(f"Retake {photo_name(e)}: {e['reason']}.")
    nxt = (part.get("coverage") or {}).get("next_photo")
    if verdict == "INCOMPLETE" and nxt:
        az, el, dist = nxt["orbit"]
        out.append(
            f"Retake from azimuth {az:g}°, elevation {el:g}°, {dist:g} mm from the part's centre (azimuth 0: in front "
            "of the part, towards -y, counter-clockwise seen from above) and validate the photos together."
        )
    elif verdict == "INCOMPLETE":
        out.append("Take another photo of what the coverage map shows uncovered and validate the photos together.")
    if verdict == "PASS" and not out:
        out.append("Accept the part: nothing to do.")
    if colour.get("verdict") == "not measured":
        out.append("To measure colour, keep the fixture's colour chart in the frame of the next photo.")
    return out


def photo_name(e: dict) -> str:
    """A photo's file name, without its folder."""
    return e["photo"].replace("\\", "/").rsplit("/", 1)[-1]


def colour_words(colour: dict | None, max_delta_e: float | None) -> str:
    """The part's colour in words, in full (its reasons when not measured)."""
    if not colour:
        return "colour: not measured"
    if colour["verdict"] == "not measured":
        why = "; ".join(r.removeprefix("colour not measured: ") for r in colour["reasons"])
        return f"colour: not measured ({why})"
    shading = "; shading taken out" if colour.get("shading_directional") else ""
    if colour.get("delta_e00"):  # the part's own: each print pixel from its squarest photo
        n = len(colour.get("decided_by_photo") or {})
        return (
            f"colour: {colour['verdict']}, mean ΔE00 {colour['delta_e00']['mean']:.2f} (limit {max_delta_e:g}) over "
            f"the part, each print pixel from the photo that sees it most squarely ({n} photo(s)){shading}"
        )
    worst = colour["worst_delta_e00"]
    return (
        f"colour: {colour['verdict']}, mean ΔE00 {worst['mean']:.2f} (limit {max_delta_e:g}) in the worst of "
        f"{colour['photos_measured']} photo(s){shading}"
    )


def figures_words(report: dict) -> list[str]:
    """The part's coverage figures, each named for what it is a share of.

    Three different shares, so that none reads as another: how much of its view each photo
    shows (``photos[].coverage``), how much of the part's print the photos measured
    (``part.measured_share_of_part``), and on how much of each film they can find each defect
    class (``part.coverage``, what INCOMPLETE is decided on).
    """
    part = report.get("part") or {}
    out = []
    shows = [f"{photo_name(e)} {100 * e['coverage']:.0f} % of view {e.get('view')}" for e in report["photos"]
             if e.get("coverage") is not None]  # fmt: skip
    if shows:
        out.append("each photo shows of its view's region: " + ", ".join(shows))
    measured = part.get("measured_share_of_part")
    if measured is not None:
        views = ", ".join(f"{k} {100 * v['measured']:.0f} %" for k, v in part.get("coverage_by_view", {}).items())
        out.append(f"measured (misregistration or colour): {100 * measured:.0f} % of the part's print ({views})")
    cov = part.get("coverage")
    if cov:
        from workbench.validate.coverage import CLASS_WORDS, CLASSES

        worst = {
            k: min((f[k]["share"] for f in cov["films"] if f[k]["share"] is not None), default=None) for k in CLASSES
        }
        shares = ", ".join(f"{CLASS_WORDS[k]} {100 * v:.0f} %" for k, v in worst.items() if v is not None)
        out.append(
            f"can find a defect on (least covered film, {100 * cov['min_coverage']:.0f} % needed): {shares} "
            "(see the page 'Not covered, not counted, and why')"
        )
    return out


def circled_photo(report: dict) -> dict | None:
    """The photo shown circled on the first page: the one with the most defects, else the first scored one."""
    scored = [e for e in report["photos"] if e["verdict"] != "INVALID" and e.get("pictures")]
    if not scored:
        return None
    return max(scored, key=lambda e: len(e.get("defects") or []))


def circle_number(d: dict, shown: dict | None) -> str:
    """The number of a part's defect's circle in the shown photo ("-": not in that photo)."""
    for k, p in enumerate((shown or {}).get("defects") or []):
        if max(abs(a - b) for a, b in zip(p["centre_mm"], d["centre_mm"], strict=True)) <= MATCH_MM:
            return str(k + 1)
    return "-"


def styles() -> dict:
    """The report's paragraph styles, by name."""
    from reportlab.lib.styles import ParagraphStyle

    return {
        "title": ParagraphStyle("title", fontName="Helvetica-Bold", fontSize=14, leading=17, spaceAfter=4),
        "head": ParagraphStyle("head", fontName="Helvetica-Bold", fontSize=10, leading=13, spaceBefore=5, spaceAfter=2),
        "action": ParagraphStyle(
            "action", fontName="Helvetica-Bold", fontSize=10, leading=12.5, leftIndent=10, bulletIndent=0, spaceAfter=2
        ),
        "body": ParagraphStyle("body", fontName="Helvetica", fontSize=8.5, leading=10.5, spaceAfter=1),
        "small": ParagraphStyle("small", fontName="Helvetica-Oblique", fontSize=7.5, leading=9.5),
        "cell": ParagraphStyle("cell", fontName="Helvetica", fontSize=7.5, leading=9),
    }


def defect_table(report: dict, shown: dict | None, width: float):
    """The part's defects as a table flowable (every row; it splits over pages), or None without one."""
    from reportlab.lib import colors
    from reportlab.platypus import Paragraph, Table, TableStyle

    from workbench.validate.report import VERDICT_COLOURS

    defects = (report.get("part") or {}).get("defects", [])
    if not defects:
        return None
    st = styles()["cell"]
    limit = report.get("max_defect_mm2")
    circle = f"circle in {photo_name(shown)}" if shown else "circle"
    head = styles()["cell"].clone("head", fontName="Helvetica-Bold")
    heads = ["#", "kind", "where on the print (mm, y down)", "area mm²", "view", "over limit", circle, "photos"]
    rows = [[Paragraph(escape(h), head) for h in heads]]
    over_rows = []
    for k, d in enumerate(defects):
        over = limit is not None and d["area_mm2"] > limit
        if over and not d.get("unresolved"):
            over_rows.append(k + 1)
        rows.append(
            [
                str(k + 1),
                # (a region no photo told ink gone, or a slide, from light on: open, not failed)
                f"{'shift' if d['kind'] == 'shift' else 'missing'} or light?" if d.get("unresolved") else d["kind"],
                f"x {d['centre_mm'][0]:.1f}, y {d['centre_mm'][1]:.1f}",
                f"{d['area_mm2']:.1f}",
                d.get("view") or "-",
                ("open" if d.get("unresolved") else "yes") if over else "no",
                circle_number(d, shown),
                Paragraph(escape(", ".join(d["photos"])), st),
            ]
        )
    fr = [0.05, 0.1, 0.2, 0.09, 0.08, 0.08, 0.14]
    widths = [f * width for f in fr] + [width * (1 - sum(fr))]
    t = Table(rows, colWidths=widths, repeatRows=1, hAlign="LEFT")
    style = [
        ("FONT", (0, 0), (-1, 0), "Helvetica-Bold", 7.5),
        ("FONT", (0, 1), (-1, -1), "Helvetica", 7.5),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
        ("LINEBELOW", (0, 0), (-1, 0), 0.5, colors.black),
        ("TOPPADDING", (0, 0), (-1, -1), 1),
        ("BOTTOMPADDING", (0, 0), (-1, -1), 1),
        ("LEFTPADDING", (0, 0), (-1, -1), 2),
    ]
    style += [("TEXTCOLOR", (0, r), (-2, r), colors.Color(*VERDICT_COLOURS["FAIL"])) for r in over_rows]
    t.setStyle(TableStyle(style))
    return t


def picture(png: bytes, width: float, height: float):
    """A picture flowable no wider than ``width`` and no taller than ``height`` (points), its shape kept."""
    from PIL import Image as PILImage
    from reportlab.platypus import Image

    with PILImage.open(io.BytesIO(png)) as img:
        iw, ih = img.size
    s = min(width / iw, height / ih)
    return Image(io.BytesIO(png), width=iw * s, height=ih * s, hAlign="LEFT")


def first_page_story(report: dict, pictures: dict[str, bytes], pages: dict[str, bytes], W: float) -> list:
    """The first page's text: the verdict, what to do, why, the figures and the defect table (flowables)."""
    from reportlab.lib import colors
    from reportlab.lib.styles import ParagraphStyle
    from reportlab.lib.units import mm
    from reportlab.platypus import Paragraph, Spacer

    from workbench.validate.report import VERDICT_COLOURS

    st = styles()
    part = report.get("part") or {}
    verdict = part.get("verdict", "INVALID")
    job = report["design"].get("job") or {}
    photos = report["photos"]
    counts = ", ".join(
        f"{n} {v}"
        for v in ("PASS", "FAIL", "INCOMPLETE", "INVALID")
        if (n := sum(e["verdict"] == v for e in photos)) or v != "INCOMPLETE"
    )
    big = ParagraphStyle(
        "verdict", fontName="Helvetica-Bold", fontSize=30, leading=34, textColor=colors.Color(*VERDICT_COLOURS[verdict])
    )
    story = [
        Paragraph(escape(f"Is this part good?  {job.get('name', 'design')}"), st["title"]),
        Paragraph(escape(verdict), big),
        Paragraph(escape(f"{len(photos)} photo(s): {counts}"), st["body"]),
        Paragraph("What to do", st["head"]),
    ]
    story += [Paragraph(escape(a), st["action"], bulletText="•") for a in actions(report)]
    story.append(Paragraph("Why", st["head"]))
    # (each photo as the part judges it: without what another photo showed to be light in it, and
    # with its colour judged over all the photos; its own verdict and reason are on its page)
    in_part = part.get("photo_verdicts_in_part") or {}
    why_in_part = part.get("photo_reasons_in_part") or {}
    fails = [e for e in photos if in_part.get(photo_name(e), e["verdict"]) == "FAIL"]
    whys = [f"{photo_name(e)}: {why_in_part.get(photo_name(e), e['reason'])}" for e in fails]
    whys = whys or ([part["reason"]] if part.get("reason") else [])
    whys.append(colour_words(part.get("colour"), report.get("max_delta_e")))
    story += [Paragraph(escape(w), st["body"]) for w in whys + figures_words(report)]
    table = defect_table(report, circled_photo(report), W - 2 * MARGIN_MM * mm)
    defects = part.get("defects", [])
    story.append(Paragraph(f"Where it is wrong: {len(defects)} defect(s) on the print" if defects else
                           "No defect found", st["head"]))  # fmt: skip
    if table is not None:
        story.append(table)
    story.append(Spacer(1, 2 * mm))
    return story


def pictures_row(
    report: dict, pictures: dict[str, bytes], pages: dict[str, bytes], width: float, height: float
) -> list:
    """The circled photo and the coverage map in ``width`` x ``height`` points, each with its caption (flowables):
    side by side, or one above the other where that shows them larger."""
    from reportlab.lib.units import mm
    from reportlab.platypus import Paragraph, Spacer, Table, TableStyle

    st = styles()["small"]
    shown = circled_photo(report)
    cells, captions = [], []
    name = f"{shown['pictures']}_defects_photo.png" if shown else None
    png = pages.get(name) or pictures.get(name) if name else None
    if png is not None:
        n = len(shown.get("defects") or [])
        cells.append(png)
        captions.append(f"{photo_name(shown)}: {n} defect(s) circled and numbered" if n else
                        f"{photo_name(shown)}: no defect found")  # fmt: skip
    if "coverage_print.png" in pictures:
        cells.append(pictures["coverage_print.png"])
        captions.append("the part's print: what was measured, the defects numbered as in the table (mm, y down)")
    if not cells:
        return []
    gap = 4 * mm
    w = (width - gap * (len(cells) - 1)) / len(cells)
    caption_h = 2 * 9.5 + 2
    side = [picture(p, w, height - caption_h) for p in cells]
    each = (height - len(cells) * (caption_h + gap)) / len(cells)
    stacked = [picture(p, width, each) for p in cells]
    if sum(f.drawWidth * f.drawHeight for f in stacked) > sum(f.drawWidth * f.drawHeight for f in side):
        pairs = zip(stacked, captions, strict=True)
        return [x for f, c in pairs for x in (f, Paragraph(escape(c), st), Spacer(1, gap))]
    row = [side, [Paragraph(escape(c), st) for c in captions]]
    t = Table(row, colWidths=[w + (gap if k < len(cells) - 1 else 0) for k in range(len(cells))], hAlign="LEFT")
    t.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP"), ("LEFTPADDING", (0, 0), (-1, -1), 0),
                           ("RIGHTPADDING", (0, 0), (-1, -1), 0), ("TOPPADDING", (0, 0), (-1, -1), 0),
                           ("BOTTOMPADDING", (0, 0), (-1, -1), 0)]))  # fmt: skip
    return [t]


def flow(c, story: list, W: float, H: float) -> None:
    """Flowables drawn page after page within the margins until none is left; each page shown.

    Text wraps and tables split at their rows, so nothing is cut off; a flowable no page can
    hold (a picture taller than a page) is scaled down to the frame.
    """
    from reportlab.lib.units import mm
    from reportlab.platypus import Frame, KeepInFrame

    fw, fh = W - 2 * MARGIN_MM * mm, H - 2 * TOP_MM * mm
    story = [KeepInFrame(fw, fh, [f], mode="shrink") if f.wrap(fw, fh)[1] > fh else f for f in story]
    while story:
        frame = Frame(MARGIN_MM * mm, TOP_MM * mm, fw, fh, leftPadding=0, rightPadding=0, topPadding=0,
                      bottomPadding=0, showBoundary=0)  # fmt: skip
        left = len(story)
        frame.addFromList(story, c)
        c.showPage()
        if len(story) == left:  # (cannot happen once each fits a frame; a guard against a loop)
            story.pop(0)


def first_page(c, report: dict, pictures: dict[str, bytes], pages: dict[str, bytes], W: float, H: float) -> None:
    """Page one: the verdict, what to do, why, the defect table, the circled photo and the coverage map.

    The pictures take the height the text leaves (at least a third of the page); where the
    text leaves less, they go on the next page rather than shrink away.
    """
    from reportlab.lib.units import mm

    fw, fh = W - 2 * MARGIN_MM * mm, H - 2 * TOP_MM * mm
    story = first_page_story(report, pictures, pages, W)
    used = sum(f.wrap(fw, fh)[1] + f.getSpaceBefore() + f.getSpaceAfter() for f in story)
    room = fh - used - 2
    flow(c, story + pictures_row(report, pictures, pages, fw, room if room > fh / 3 else fh / 2), W, H)


def rule_page(c, report: dict, W: float, H: float) -> None:
    """How the verdict is decided: the rule in full, and where the method is told."""
    from reportlab.platypus import Paragraph

    st = styles()
    rule = (report.get("verdict_rule") or {}).get("text")
    if not rule:
        return
    story = [
        Paragraph("How the verdict is decided", st["title"]),
        Paragraph(escape(rule), st["body"]),
        Paragraph(
            escape(
                "Print coordinates everywhere in this report: mm from the print's top-left corner, x right, y down. "
                "Every figure, threshold and identifier is in validation.json beside this report."
            ),
            st["small"],
        ),
    ]
    flow(c, story, W, H)
