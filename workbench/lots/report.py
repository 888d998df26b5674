"""The lot report as HTML and PDF: the plan, the decision and every part with its verdict and evidence."""

from __future__ import annotations

from html import escape

from workbench.lots.decision import LotDecision, LotPart, decision_dict


def lot_report_html(lot: str, decision: LotDecision, parts: list[LotPart], store: str, switching=None) -> bytes:
    """A self-contained HTML page (no script, no outside resource); the same bytes for the same records."""
    d = decision_dict(lot, decision, switching)
    why = d.pop("switching")
    plan_rows = "".join(
        f"<tr><th>{escape(k.replace('_', ' '))}</th><td>{escape(str(v))}</td></tr>" for k, v in d.items() if k != "lot"
    )
    lots = f" (lots {', '.join(why['lots'])})" if why["lots"] else ""
    part_rows = "".join(
        f'<tr class="{escape(p.verdict.lower())}"><td>{k + 1}</td><td>{escape(p.part_id)}</td>'
        f"<td>{escape(p.verdict)}</td><td>{escape(p.recorded_at)}</td>"
        f'<td><a href="{escape(p.out_dir)}/validation.json">{escape(p.out_dir)}</a></td>'
        f"<td>{escape(p.reason)}</td></tr>"
        for k, p in enumerate(parts)
    )
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Lot {escape(lot)}: {escape(decision.decision)}</title>
<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}
td,th{{border:1px solid #bbb;padding:.2em .5em;text-align:left;vertical-align:top}}
tr.fail td{{background:#fdd}}tr.invalid td,tr.incomplete td{{background:#ffd}}</style></head>
<body><h1>Lot {escape(lot)}: {escape(decision.decision)}</h1>
<p>ISO 2859-1 single sampling, {escape(d["inspection"])} inspection: {escape(why["rule"] + lots)}; store
{escape(store)}. INVALID and INCOMPLETE parts are not inspected (never conforming); each part counts once, by its
first PASS or FAIL.</p>
<table>{plan_rows}</table>
<h2>Parts ({len(parts)})</h2>
<table><tr><th>#</th><th>part</th><th>verdict</th><th>recorded (UTC)</th><th>evidence</th><th>reason</th></tr>
{part_rows}</table></body></html>
"""
    return page.encode()


def lot_report_pdf(lot: str, decision: LotDecision, parts: list[LotPart], store: str, switching=None) -> bytes:
    """The lot report as a PDF (A4): the plan, the decision and why this inspection, then every part
    with its verdict, time and evidence (its validation.json), as many pages as the parts need.

    Reproducible: ReportLab's invariant mode (no date, a fixed document id); the same bytes for
    the same records.
    """
    import io

    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.lib.utils import simpleSplit
    from reportlab.pdfgen import canvas as rl_canvas

    d = decision_dict(lot, decision, switching)
    why = d.pop("switching")
    buf = io.BytesIO()
    c = rl_canvas.Canvas(buf, pagesize=A4, invariant=1, pageCompression=1)
    c.setTitle(f"Lot {lot}: {decision.decision}")
    c.setCreator("workbench lot")
    W, H = A4
    left, width, bottom = 15 * mm, W - 30 * mm, 15 * mm
    y = H - 18 * mm

    def line(text: str, font: str = "Helvetica", size: float = 8.5, step: float = 4.2) -> None:
        nonlocal y
        for piece in simpleSplit(text, font, size, width) or [""]:
            if y < bottom:
                c.showPage()
                y = H - 18 * mm
            c.setFont(font, size)
            c.drawString(left, y, piece)
            y -= step * mm

    line(f"Lot {lot}: {decision.decision}", "Helvetica-Bold", 14, 7)
    lots = f" (lots {', '.join(why['lots'])})" if why["lots"] else ""
    line(f"ISO 2859-1 single sampling, {d['inspection']} inspection: {why['rule']}{lots}.")
    line(f"Store {store}. INVALID and INCOMPLETE parts are not inspected (never conforming); each part counts "
         "once, by its first PASS or FAIL.")  # fmt: skip
    y -= 2 * mm
    for k, v in d.items():
        if k != "lot":
            line(f"{k.replace('_', ' ')}: {v}")
    y -= 3 * mm
    line(f"Parts ({len(parts)})", "Helvetica-Bold", 11, 6)
    cols = (0, 10 * mm, 55 * mm, 75 * mm, 108 * mm)  # #, part, verdict, recorded, evidence and reason
    evidence_width = width - cols[4]

    def row(cells, font):
        nonlocal y
        wrapped = [simpleSplit(cells[4], font, 7.5, evidence_width) or [""]]
        need = (len(wrapped[0]) + 0.3) * 3.6 * mm
        if y - need < bottom:
            c.showPage()
            y = H - 18 * mm
        c.setFont(font, 7.5)
        for x, text in zip(cols[:4], cells[:4], strict=True):
            c.drawString(left + x, y, text)
        for j, piece in enumerate(wrapped[0]):
            c.drawString(left + cols[4], y - j * 3.6 * mm, piece)
        y -= need

    row(("#", "part", "verdict", "recorded (UTC)", "evidence; reason"), "Helvetica-Bold")
    for k, p in enumerate(parts):
        evidence = f"{p.out_dir}/validation.json" + (f"; {p.reason}" if p.reason else "")
        row((str(k + 1), p.part_id[:28], p.verdict, p.recorded_at, evidence), "Helvetica")
    c.save()
    return buf.getvalue()
