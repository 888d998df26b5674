"""The lot report as HTML: the plan, the decision and every part with its verdict and evidence."""

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
