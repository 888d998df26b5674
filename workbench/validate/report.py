"""The QA acceptance report: a PDF with the verdicts, the pictures and the identifiers."""

from __future__ import annotations

import io

from workbench.printing.pdf import build_date

REPORT_IMAGE_PX = 1200  # widest picture embedded in the report
VERDICT_COLOURS = {
    "PASS": (0.1, 0.55, 0.2),
    "FAIL": (0.8, 0.1, 0.1),
    "INVALID": (0.55, 0.45, 0.1),
    "INCOMPLETE": (0.15, 0.35, 0.75),
}


def draw_row(c, cols: list[float], cells: list[str], y: float) -> None:
    """One row of a table: each cell at its column's x (mm from the left), at height y (points), in the current font."""
    from reportlab.lib.units import mm

    for x, v in zip(cols, cells, strict=True):
        c.drawString(x * mm, y, v)


def draw_picture(c, png: bytes, top: float, width: float, max_height: float) -> float:
    """A picture at 20 mm from the left, its top at ``top`` (points), as wide as ``width`` and no taller than
    ``max_height``; returns its height (points)."""
    from PIL import Image
    from reportlab.lib.units import mm
    from reportlab.lib.utils import ImageReader

    img = Image.open(io.BytesIO(png))
    h = min(width * img.height / img.width, max_height)
    c.drawImage(ImageReader(img), 20 * mm, top - h, width=h * img.width / img.height, height=h)
    return h


def detection_line(dn: dict) -> str:
    """One line of what a photo can find (its ``dense.detection_limit``), for its page."""
    lim = dn.get("detection_limit") or {}
    res = dn.get("resolution") or {}
    line = (
        f"photo noise {dn.get('noise_grey_levels') or 0:.1f} grey levels, {res.get('photo_px_per_mm') or 0:.1f} "
        f"px/mm on the part; finds defects from {lim.get('min_area_mm2', 0):.1f} mm²"
    )
    if lim.get("min_shift_mm_median") is not None:
        line += (
            f", a slide beyond {lim['min_shift_mm_median']:.2f} mm (median) over "
            f"{100 * lim['shift_found_share']:.0f} % of what it sees"
        )
    if lim.get("dropout_found_share_of_inked") is not None:
        line += f", ink gone over {100 * lim['dropout_found_share_of_inked']:.0f} % of the inked print it sees"
    if lim.get("scratch_found_share") is not None:
        line += f", a scratch over {100 * lim['scratch_found_share']:.0f} % of what it sees"
    return line + f" (z = {lim.get('significance_z', 0):g})"


def detectable_page(c, e: dict, stem: str, pictures: dict, pages: dict, W: float, H: float) -> None:
    """A photo's page of what it can find: its detection limit over the print."""
    from PIL import Image
    from reportlab.lib.units import mm
    from reportlab.lib.utils import ImageReader, simpleSplit

    name = f"{stem}_detectable_print.png"
    jpeg = pages.get(name) or (page_picture(Image.open(io.BytesIO(pictures[name]))) if name in pictures else None)
    dn = e.get("dense") or {}
    if jpeg is None or not dn.get("detection_limit"):
        return
    c.setFont("Helvetica-Bold", 11)
    c.drawString(20 * mm, H - 20 * mm, f"{stem}: what this photo can find")
    c.setFont("Helvetica", 8)
    text = (
        f"{detection_line(dn)}. Stated for a sound part from the design, the photo's noise, blur and sampling: "
        "a defect where it finds nothing is below this photo's limit; another photo, nearer or sharper, may find it."
    )
    top = H - 26 * mm
    for line in simpleSplit(text, "Helvetica", 8, W - 40 * mm):
        c.drawString(20 * mm, top, line)
        top -= 3.8 * mm
    img = ImageReader(io.BytesIO(jpeg))
    iw, ih = img.getSize()
    w = W - 40 * mm
    h = min(w * ih / iw, top - 20 * mm)
    w = h * iw / ih
    c.drawImage(img, 20 * mm, top - 2 * mm - h, width=w, height=h)
    c.showPage()


def page_names(stem: str, view: str) -> list[str]:
    """The pictures on a photo's page, by file name, top to bottom."""
    return [f"{stem}_dense_print.png", f"{stem}_defects_photo.png", f"{stem}_defects_{view}.png"]


def page_picture(img) -> bytes:
    """A picture as a photo's page embeds it: JPEG, at most :data:`REPORT_IMAGE_PX` wide.

    A third of an A4 page needs no more, and ReportLab embeds JPEG data as it is, where it
    encodes every pixel of any other image in Python (a second per full-size picture).
    Made where the picture is made (one worker per photo), not by the report.

    Parameters
    ----------
    img : PIL.Image.Image
        The picture (RGB or RGBA; the alpha channel is dropped).

    Returns
    -------
    bytes
        JPEG, quality 90.
    """
    from PIL import Image

    if img.width > REPORT_IMAGE_PX:
        img = img.convert("RGB").resize(
            (REPORT_IMAGE_PX, max(1, round(img.height * REPORT_IMAGE_PX / img.width))), Image.LANCZOS
        )
    buf = io.BytesIO()
    img.convert("RGB").save(buf, format="JPEG", quality=90, optimize=False)
    return buf.getvalue()


def _wrapped(
    c, line: str, y: float, W: float, x_mm: float = 20.0, font: tuple[str, float] = ("Helvetica", 8.0)
) -> float:
    """A line of text wrapped to the page's width, from ``x_mm`` to the 20 mm right margin, in ``font``
    (name, size in points; the leading is 1.35 times the size); returns the y below it (points)."""
    from reportlab.lib.units import mm
    from reportlab.lib.utils import simpleSplit

    name, size = font
    c.setFont(name, size)
    for piece in simpleSplit(line, name, size, W - (x_mm + 20) * mm):
        c.drawString(x_mm * mm, y, piece)
        y -= 1.35 * size
    return y


def coverage_page(c, report: dict, pictures: dict[str, bytes], W: float, H: float) -> None:
    """What the part's photos cover per film and defect class, the uncovered regions and why, the next photo, and
    what one photo found that another showed to be light (not counted)."""
    from reportlab.lib.units import mm
    from reportlab.lib.utils import simpleSplit

    from workbench.validate.coverage import CLASS_WORDS, CLASSES

    part = report.get("part") or {}
    cov = part.get("coverage")
    if not cov:
        return
    c.setFont("Helvetica-Bold", 14)
    c.drawString(20 * mm, H - 20 * mm, "Not covered, not counted, and why")
    c.setFont("Helvetica", 8)
    y = H - 28 * mm
    # what one photo found and another showed to be light
    for x in part.get("dismissed", [])[:6]:
        line = (
            f"Not counted: {x['photo']}'s {x['kind']} of {x['area_mm2']:.1f} mm² at ({x['centre_mm'][0]:.1f}, "
            f"{x['centre_mm'][1]:.1f}) mm: {x['decided_by']['words']}"
        )
        y = _wrapped(c, line, y, W)
    # what each photo took for light, the largest first, with the test that took it
    light = sorted(
        ((e.get("photo", ""), x) for e in report.get("photos", []) for x in e.get("not_counted") or []),
        key=lambda px: -px[1]["area_mm2"],
    )
    for name, x in light[:8]:
        line = (
            f"Taken for light in {name}: {x['area_mm2']:.1f} mm² at ({x['centre_mm'][0]:.1f}, {x['centre_mm'][1]:.1f}) "
            f"mm ({x['decided_by']['rule']}): {x['decided_by']['words']}"
        )
        y = _wrapped(c, line, y, W)
    if part.get("dismissed") or light:
        y -= 2 * mm
    need = f"at least {100 * cov['min_coverage']:.0f} % of each film, per class, for a PASS"
    c.drawString(20 * mm, y, f"Where the part's photos together can find each defect class ({need}):")
    y -= 5 * mm
    cols = [20, 34, 62, 100, 138]
    draw_row(c, cols, ["film", "area mm²", *(CLASS_WORDS[k] for k in CLASSES)], y)
    for f in cov["films"]:
        y -= 4.2 * mm
        cells = [str(f["film"]), f"{f['area_mm2']:.0f}"]
        for k in CLASSES:
            share = f[k]["share"]
            cells.append(
                "shows nowhere" if share is None else f"{100 * share:.1f} %" + ("" if f[k]["covered"] else " (short)")
            )
        draw_row(c, cols, cells, y)
    y -= 6 * mm
    for line in simpleSplit(cov.get("note", ""), "Helvetica-Oblique", 7, W - 40 * mm):
        c.setFont("Helvetica-Oblique", 7)
        c.drawString(20 * mm, y, line)
        y -= 3.5 * mm
    c.setFont("Helvetica", 8)
    nxt = cov.get("next_photo")
    if nxt:
        az, el, dist = nxt["orbit"]
        y -= 2 * mm
        line = (
            f"Next photo: azimuth {az:g}°, elevation {el:g}°, {dist:g} mm from the part's centre "
            f"(sees {100 * nxt['sees_share']:.0f} % of {nxt.get('for', 'what is uncovered')} from a new angle)"
        )
        y = _wrapped(c, line, y, W, font=("Helvetica-Bold", 9)) + 1.35 * 9 - 4 * mm
        c.setFont("Helvetica", 7)
        c.drawString(20 * mm, y, "azimuth 0: in front of the part (towards -y), counter-clockwise seen from above")
        y -= 5 * mm
    fine = cov.get("finer_photo")
    if fine and fine.get("needed_photo_px_per_mm"):
        c.setFont("Helvetica", 8)
        line = (
            f"A photo {fine['factor']:g} times finer ({fine['needed_photo_px_per_mm']:g} photo px per print mm; the "
            f"finest now {fine['photo_px_per_mm']:g}) finds a slide on {100 * fine['share_found_at_factor']:.0f} % of "
            "where none is found yet"
        )
        y = _wrapped(c, line, y, W) + 1.35 * 8 - 5 * mm
    unc = cov.get("uncovered") or {}
    if unc.get("measured_share"):
        line = (
            f"{100 * unc['measured_share']:.0f} % of what is uncovered was measured and is below the "
            "stated limit there: a finer photo (closer, or more pixels) or one without the lamp's glint there"
        )
        y = _wrapped(c, line, y, W) + 1.35 * 8 - 5 * mm
    regions = unc.get("regions", [])
    c.setFont("Helvetica-Bold", 9)
    c.drawString(20 * mm, y, f"Uncovered regions: {unc.get('area_mm2', 0):.0f} mm² in all, the largest {len(regions)}")
    y -= 4.5 * mm
    c.setFont("Helvetica", 7)
    for k, r in enumerate(regions[:10]):
        x0, y0 = r["centre_mm"]
        line = (
            f"{k + 1}. ({x0:.1f}, {y0:.1f}) mm, {r['area_mm2']:.0f} mm², {', '.join(r['classes'])}: "
            f"{r['why']} ({100 * r['why_share']:.0f} % of it)"
        )
        y = _wrapped(c, line, y, W, font=("Helvetica", 7))
    if "uncovered_print.png" in pictures:
        draw_picture(c, pictures["uncovered_print.png"], y - 2 * mm, W - 40 * mm, y - 22 * mm)
    c.showPage()


def colour_pages(c, report: dict, pictures: dict[str, bytes], pages: dict[str, bytes], W: float, H: float) -> None:
    """The colour page(s): per photo the ΔE00 against the soft proof, the chart's fit, shading, regions, the map."""
    from PIL import Image
    from reportlab.lib.units import mm
    from reportlab.lib.utils import ImageReader

    photos = [e for e in report["photos"] if e.get("colour")]
    if not photos:
        return
    proof = report.get("soft_proof") or {}
    c.setFont("Helvetica-Bold", 14)
    c.drawString(20 * mm, H - 20 * mm, "colour: CIEDE2000 against the design's soft proof")
    c.setFont("Helvetica", 8)
    lines = [
        "the photo corrected by the fixture's colour chart (a fit per photo), against the design's colours as the "
        "press prints them, on the print's uniform areas;",
        f"soft proof: {proof.get('output_profile') or proof.get('note') or '?'}; limit: mean ΔE00 "
        f"{report.get('max_delta_e', 3.0):g}. A camera screens colour; a spectrophotometer decides conformance.",
    ]
    y = H - 27 * mm
    y = _wrapped(c, " ".join(lines), y, W) - 2 * mm
    cols = [20, 66, 88, 104, 120, 136, 156, 172]
    heads = ["photo", "colour", "mean", "p95", "max", "chromatic", "chart fit", "shading"]
    c.setFont("Helvetica-Bold", 8)
    draw_row(c, cols, heads, y)
    c.setFont("Helvetica", 8)
    for e in photos:
        y -= 5 * mm
        col = e["colour"]
        name = e["photo"].rsplit("/", 1)[-1][:28]
        if not col.get("measured"):
            c.drawString(cols[0] * mm, y, name)
            y = _wrapped(c, col["reason"], y, W, cols[1], ("Helvetica", 8)) + 1.35 * 8
            continue
        de, ch, sh = col["delta_e00"], col["delta_e00_chromatic"], col.get("shading") or {}
        row = [
            name,
            col.get("verdict", ""),
            f"{de['mean']:.2f}",
            f"{de['p95']:.2f}",
            f"{de['max']:.2f}",
            f"{ch['mean']:.2f}",
            f"{col['chart_fit_delta_e00']:.2f}",
            f"{100 * sh['share']:.0f} %" if sh.get("directional") else "none",
        ]
        draw_row(c, cols, row, y)
        if y < 30 * mm:
            c.showPage()
            c.setFont("Helvetica", 8)
            y = H - 20 * mm
    shown = []
    part = report["part"].get("colour") or {}
    if part.get("delta_e00") and "colour_print.png" in pictures:
        decided = "; ".join(
            f"{k}: {100 * v['share']:.0f} % of it, mean {v['mean']:.2f}" for k, v in part["decided_by_photo"].items()
        )
        shown.append(("colour_print.png", [f"the part: {part['verdict']}; {part['words']}", f"by photo: {decided}"]))
    for e in photos:
        col = e["colour"]
        name = f"{e.get('pictures') or ''}_colour_print.png"
        if not col.get("measured") or (name not in pages and name not in pictures):
            continue
        regions = ", ".join(
            f"{k} {v['mean']:.2f}" if v.get("mean") is not None else f"{k} -" for k, v in col.get("regions", {}).items()
        )
        text = [
            f"{e['photo'].rsplit('/', 1)[-1]}: {col.get('verdict', '')}; chart: {col['chart']['patches_used']} "
            f"patches, fit mean ΔE00 {col['chart_fit_delta_e00']:.2f}, max {col['chart']['fit_max_delta_e00']:.2f}; "
            f"compared {col['delta_e00']['pixels']} print pixels ({100 * col['compared_share']:.0f} % of those scored)",
            f"lightness: mean ΔL* {col['lightness']['mean_delta_l']:+.2f}; "
            + (col.get("shading") or {}).get("note", ""),
            f"mean ΔE00 by region: {regions}",
        ]
        shown.append((name, text))
    for name, text in shown:
        jpeg = pages.get(name) or page_picture(Image.open(io.BytesIO(pictures[name])))
        img = ImageReader(io.BytesIO(jpeg))
        iw, ih = img.getSize()
        h = min((W - 40 * mm) * ih / iw, (H - 60 * mm) / 2)
        w = h * iw / ih
        if y - h - 20 * mm < 20 * mm:
            c.showPage()
            y = H - 15 * mm
        y -= 6 * mm
        c.setFont("Helvetica", 7)
        for line in text:
            y = _wrapped(c, line, y, W, font=("Helvetica", 7))
        c.drawImage(img, 20 * mm, y - h, width=w, height=h)
        y -= h + 4 * mm
    c.showPage()


def film_pages(c, report: dict, W: float, H: float) -> None:
    """With several films, a page per film: its placement as each photo measured it."""
    from reportlab.lib.units import mm

    names: list[str] = []
    for e in report["photos"]:
        for f in e.get("films") or []:
            if f["name"] not in names:
                names.append(f["name"])
    for k, name in enumerate(names):
        c.setFont("Helvetica-Bold", 14)
        c.drawString(20 * mm, H - 20 * mm, f"film {k + 1} of {len(names)}: {name}")
        c.setFont("Helvetica", 8)
        c.drawString(
            20 * mm,
            H - 27 * mm,
            "placement fitted on this film's own tiles (print coordinates: x right, y down; rotation "
            "counter-clockwise on the print)",
        )
        cols = [20, 70, 88, 112, 140, 160]
        heads = ["photo", "tiles", "p95 mm", "offset mm (x, y)", "rotation °", "scale %"]
        y = H - 36 * mm
        c.setFont("Helvetica-Bold", 8)
        draw_row(c, cols, heads, y)
        c.setFont("Helvetica", 8)
        for e in report["photos"]:
            f = next((f for f in e.get("films") or [] if f["name"] == name), None)
            if f is None:
                continue
            y -= 5 * mm
            mis = f.get("misregistration_mm") or {}
            off = f.get("offset_mm")
            row = [
                e["photo"].rsplit("/", 1)[-1][:30],
                str(f["tiles"]),
                f"{mis['p95']:.3f}" if mis.get("p95") is not None else "-",
                f"{off[0]:+.3f}, {off[1]:+.3f}" if off else "not seen (fewer than 4 tiles)",
                f"{f['rotation_deg']:+.3f}" if off else "",
                f"{f['scale_pct']:+.3f}" if off else "",
            ]
            draw_row(c, cols, row, y)
            if y < 30 * mm:
                c.showPage()
                y = H - 20 * mm
        c.showPage()


def seam_page(c, report: dict, W: float, H: float) -> None:
    """With several films, a page of the seams each photo shows and the misregistration across them."""
    from reportlab.lib.units import mm

    rows = [(e, s) for e in report["photos"] for s in e.get("seams") or []]
    if not rows:
        return
    c.setFont("Helvetica-Bold", 14)
    c.drawString(20 * mm, H - 20 * mm, "seams between films")
    c.setFont("Helvetica", 8)
    c.drawString(
        20 * mm,
        H - 27 * mm,
        "how far apart the two films' inks land along the seam, from each film's fitted placement "
        "(mm on the part; mean weighted by length)",
    )
    cols = [20, 70, 125, 150, 168]
    heads = ["photo", "films", "seen / seam mm", "mean mm", "max mm"]
    y = H - 36 * mm
    c.setFont("Helvetica-Bold", 8)
    draw_row(c, cols, heads, y)
    c.setFont("Helvetica", 8)
    for e, s in rows:
        y -= 5 * mm
        mis = s.get("misregistration_mm")
        row = [
            e["photo"].rsplit("/", 1)[-1][:30],
            " | ".join(s["films"])[:34],
            f"{s['seen_mm']:.0f} / {s['length_mm']:.0f}",
            f"{mis['mean']:.3f}" if mis else "not measured: " + ", ".join(s.get("unmeasured", [])),
            f"{mis['max']:.3f}" if mis else "",
        ]
        draw_row(c, cols, row, y)
        if y < 30 * mm:
            c.showPage()
            c.setFont("Helvetica", 8)
            y = H - 20 * mm
    c.showPage()


def qa_report(report: dict, pictures: dict[str, bytes], pages: dict[str, bytes] | None = None) -> bytes:
    """PDF: a first page (is the part good, where is it wrong), a summary page (verdicts, figures,
    identifiers and hashes), with several films a page per film (its placement per photo)
    and one of the seams (misregistration across each), then one page per scored photo.

    Parameters
    ----------
    report : dict
        The content of validation.json.
    pictures : dict of name to PNG bytes
        The warped photos, overlays and heat maps, by file name.
    pages : dict of name to JPEG bytes, optional
        The photos' pages' pictures made already (:func:`page_picture`), by the name of the
        picture they show; the others are made here from ``pictures``.

    Returns
    -------
    bytes
        Reproducible PDF (the date is ``SOURCE_DATE_EPOCH`` when set).
    """
    from PIL import Image
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.lib.utils import ImageReader, simpleSplit
    from reportlab.pdfgen import canvas as rl_canvas

    from workbench.validate.report_first_page import first_page, rule_page
    from workbench.validate.seating import seating_text

    pages = pages or {}
    buf = io.BytesIO()
    c = rl_canvas.Canvas(buf, pagesize=A4, invariant=1, pageCompression=1)
    W, H = A4
    job = report["design"].get("job") or {}
    c.setTitle(f"workbench QA report: {job.get('name', '')}")
    c.setCreator(f"workbench {report['software']['version']}")
    first_page(c, report, pictures, pages, W, H)
    coverage_page(c, report, pictures, W, H)
    rule_page(c, report, W, H)
    c.setFont("Helvetica-Bold", 14)
    c.drawString(20 * mm, H - 20 * mm, f"QA acceptance report: {job.get('name', 'design')}")
    c.setFont("Helvetica", 8)
    y = H - 28 * mm
    ids = [
        f"date {build_date()}, workbench {report['software']['version']}, tolerance {report['tolerance_mm']} mm (p95)",
        f"job {job.get('file', '?')}  sha256 {job.get('sha256', '?')}",
        f"design {report['design']['dir']}  design.json sha256 {report['design']['design_json_sha256']}",
        f"print.png sha256 {report['design']['print_sha256']}",
        f"camera profile {report['camera_profile']['file']}  sha256 {report['camera_profile']['sha256']}",
    ]
    part_seat = (report.get("part") or {}).get("seating")
    for line in ids + ([f"the part: {seating_text(part_seat)}"] if part_seat else []):
        y = _wrapped(c, line, y, W)
    y -= 4 * mm
    cols = [20, 62, 80, 98, 118, 134, 150, 172]
    heads = ["photo", "view", "verdict", "p95 mm", "max mm", "SSIM", "shows view", "film offset mm / rot"]
    c.setFont("Helvetica-Bold", 8)
    draw_row(c, cols, heads, y)
    c.setFont("Helvetica", 8)
    for e in report["photos"]:
        y -= 5 * mm
        mm_ = e.get("misregistration_mm") or {}
        off = e.get("film_offset_mm")
        row = [
            e["photo"].rsplit("/", 1)[-1][:24],
            e.get("view") or "-",
            e["verdict"],
            f"{mm_['p95']:.3f}" if mm_.get("p95") is not None else "-",
            f"{mm_['max']:.3f}" if mm_.get("max") is not None else "-",
            f"{e['ssim']:.3f}" if e.get("ssim") is not None else "-",
            f"{100 * e['coverage']:.0f} %" if e.get("coverage") is not None else "-",
            f"{off[0]:+.2f}, {off[1]:+.2f} / {e['film_rotation_deg']:+.2f}°" if off else "-",
        ]
        for x, v in zip(cols, row, strict=True):
            if v == e["verdict"]:
                c.setFillColorRGB(*VERDICT_COLOURS[v])
                c.setFont("Helvetica-Bold", 8)
            c.drawString(x * mm, y, v)
            c.setFillColorRGB(0, 0, 0)
            c.setFont("Helvetica", 8)
        y -= 4 * mm
        line = f"{e['reason']}  (photo sha256 {e.get('sha256', '?')[:16]})"
        y = _wrapped(c, line, y, W, 24, ("Helvetica-Oblique", 7)) + 1.35 * 7
        if e.get("seating"):
            y = _wrapped(c, seating_text(e["seating"]), y - 1.35 * 7, W, 24, ("Helvetica-Oblique", 7)) + 1.35 * 7
        c.setFont("Helvetica", 8)
        if y < 30 * mm:
            c.showPage()
            y = H - 20 * mm
    c.showPage()
    film_pages(c, report, W, H)
    seam_page(c, report, W, H)
    colour_pages(c, report, pictures, pages, W, H)
    for e in report["photos"]:
        if e["verdict"] == "INVALID":
            continue
        stem = e.get("pictures") or e["photo"].rsplit("/", 1)[-1].rsplit(".", 1)[0]
        names = page_names(stem, e["view"])
        c.setFont("Helvetica-Bold", 11)
        c.setFillColorRGB(*VERDICT_COLOURS[e["verdict"]])
        c.drawString(20 * mm, H - 20 * mm, f"{stem}: {e['verdict']} in view {e['view']}")
        c.setFillColorRGB(0, 0, 0)
        c.setFont("Helvetica", 8)
        top = _wrapped(c, e["reason"], H - 26 * mm, W) - 2 * mm
        dn = e.get("dense") or {}
        if dn:
            mm_ = dn.get("misregistration_mm") or {}
            ag = dn.get("agreement_with_tiles_mm") or {}
            cov = ", ".join(f"{k} {100 * v['measured']:.0f} %" for k, v in (dn.get("coverage") or {}).items())
            line = f"dense field: p95 {mm_.get('p95') or 0:.3f} mm, max {mm_.get('max') or 0:.3f} mm"
            if ag.get("median_mm") is not None:
                line += f"; agrees with the {ag['tiles']} tiles to a median of {ag['median_mm']:.3f} mm"
            c.drawString(20 * mm, top, f"{line}; measured: {cov}")
            top -= 4.2 * mm
            # what this photo can judge: its noise, resolution and the smallest defect it finds
            lim = dn.get("detection_limit") or {}
            res = dn.get("resolution") or {}
            if lim:
                for line in simpleSplit(detection_line(dn), "Helvetica", 8, W - 40 * mm):
                    c.drawString(20 * mm, top, line)
                    top -= 4.2 * mm
                if res.get("needed_photo_px_per_mm"):
                    c.drawString(
                        20 * mm,
                        top,
                        f"{100 * res['unresolved_share']:.1f} % of what it sees is detail too fine for it: a photo "
                        f"{res['needed_resolution_factor']:.1f} times as fine ({res['needed_photo_px_per_mm']:.0f} "
                        "px/mm) would resolve it",
                    )
                    top -= 4.2 * mm
        for d in (e.get("defects") or [])[:6]:
            c.drawString(
                24 * mm,
                top,
                f"{d['id']}. {d['kind']} at x {d['centre_mm'][0]:.1f}, y {d['centre_mm'][1]:.1f} mm: "
                f"{d['area_mm2']:.1f} mm², misregistration peak {d['peak_mm'] or 0:.2f} mm, "
                f"mean {d['mean_mm'] or 0:.2f} mm"
                + (f", confidence {100 * d['confidence']:.2f} %" if d.get("confidence") is not None else ""),
            )
            top -= 3.8 * mm
        top -= 2 * mm
        # the pictures share the height the text leaves, down to the bottom margin
        shown = [n for n in names if n in pages or n in pictures]
        each = (top - 15 * mm - 6 * mm * max(len(shown) - 1, 0)) / max(len(shown), 1)
        if shown and each < 30 * mm:  # (text down to the bottom: the pictures on a page of their own)
            c.showPage()
            top = H - 20 * mm
            each = (top - 15 * mm - 6 * mm * (len(shown) - 1)) / len(shown)
        for name in shown:
            if name in pages:
                jpeg = pages[name]
            else:
                jpeg = page_picture(Image.open(io.BytesIO(pictures[name])))
            img = ImageReader(io.BytesIO(jpeg))
            iw, ih = img.getSize()
            w = W - 40 * mm
            h = w * ih / iw
            h = min(h, each)
            w = h * iw / ih
            c.drawImage(img, 20 * mm, top - h, width=w, height=h)
            top -= h + 6 * mm
        c.showPage()
        detectable_page(c, e, stem, pictures, pages, W, H)
    c.save()
    return buf.getvalue()
