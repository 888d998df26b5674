"""The QA acceptance report: a PDF with the verdicts, the pictures and the identifiers."""

from __future__ import annotations

import io

from workbench.printing.pdf import build_date

VERDICT_COLOURS = {"PASS": (0.1, 0.55, 0.2), "FAIL": (0.8, 0.1, 0.1), "INVALID": (0.55, 0.45, 0.1)}


def qa_report(report: dict, pictures: dict[str, bytes]) -> bytes:
    """PDF: a summary page (verdicts, figures, identifiers and hashes), then one page per scored photo.

    Parameters
    ----------
    report : dict
        The content of validation.json.
    pictures : dict of name to PNG bytes
        The warped photos, overlays and heat maps, by file name.

    Returns
    -------
    bytes
        Reproducible PDF (the date is ``SOURCE_DATE_EPOCH`` when set).
    """
    from PIL import Image
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.lib.utils import ImageReader
    from reportlab.pdfgen import canvas as rl_canvas

    buf = io.BytesIO()
    c = rl_canvas.Canvas(buf, pagesize=A4, invariant=1, pageCompression=1)
    W, H = A4
    job = report["design"].get("job") or {}
    c.setTitle(f"workbench QA report: {job.get('name', '')}")
    c.setCreator(f"workbench {report['software']['version']}")
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
    for line in ids:
        c.drawString(20 * mm, y, line)
        y -= 4.2 * mm
    y -= 4 * mm
    cols = [20, 62, 80, 98, 118, 134, 150, 172]
    heads = ["photo", "view", "verdict", "p95 mm", "max mm", "SSIM", "coverage", "film offset mm / rot"]
    c.setFont("Helvetica-Bold", 8)
    for x, h in zip(cols, heads, strict=True):
        c.drawString(x * mm, y, h)
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
        c.setFont("Helvetica-Oblique", 7)
        c.drawString(24 * mm, y, f"{e['reason']}  (photo sha256 {e.get('sha256', '?')[:16]})"[:150])
        c.setFont("Helvetica", 8)
        if y < 30 * mm:
            c.showPage()
            y = H - 20 * mm
    c.showPage()
    for e in report["photos"]:
        if e["verdict"] == "INVALID":
            continue
        stem = e.get("pictures") or e["photo"].rsplit("/", 1)[-1].rsplit(".", 1)[0]
        names = [f"{stem}_overlay_{e['view']}.png", f"{stem}_heatmap_{e['view']}.png"]
        c.setFont("Helvetica-Bold", 11)
        c.setFillColorRGB(*VERDICT_COLOURS[e["verdict"]])
        c.drawString(20 * mm, H - 20 * mm, f"{stem}: {e['verdict']} in view {e['view']}")
        c.setFillColorRGB(0, 0, 0)
        c.setFont("Helvetica", 8)
        c.drawString(20 * mm, H - 26 * mm, e["reason"])
        top = H - 32 * mm
        for name in names:
            if name not in pictures:
                continue
            img = Image.open(io.BytesIO(pictures[name]))
            w = W - 40 * mm
            h = w * img.height / img.width
            h = min(h, (H - 60 * mm) / 2)
            w = h * img.width / img.height
            c.drawImage(ImageReader(img), 20 * mm, top - h, width=w, height=h)
            top -= h + 6 * mm
        c.showPage()
    c.save()
    return buf.getvalue()
