"""The charts as pictures (one PNG each) and ``trend.html``, a self-contained page embedding them."""

from __future__ import annotations

import base64
import os
from html import escape
from pathlib import Path

import numpy as np

from workbench.trend.analysis import Chart
from workbench.trend.charts import ULimits

# at most this many part ids along the x axis (the others' positions keep their ticks unlabelled)
MAX_TICK_LABELS = 12
TITLES = {
    "film_offset_x_mm": "film offset x (mm)",
    "film_offset_y_mm": "film offset y (mm)",
    "film_rotation_deg": "film rotation (degrees)",
    "worst_p95_mm": "misregistration p95 (mm)",
    "delta_e00_mean": "mean ΔE00",
    "defects": "defects per part (u-chart)",
    "fx": "fx (px)",
    "fy": "fy (px)",
    "cx": "cx (px)",
    "cy": "cy (px)",
    "scale_x": "printer scale x",
    "scale_y": "printer scale y",
}


def _marks(events: list[dict], shown: np.ndarray) -> np.ndarray:
    """The indices of the shown points the events span."""
    # +1 at each span's start, -1 after its end: the running sum is positive inside a span
    edges = np.zeros(len(shown) + 1, dtype=np.int64)
    for e in events:
        lo, hi = (np.asarray(v, dtype=np.int64) for v in e["_span"])
        np.add.at(edges, lo, 1)
        np.add.at(edges, hi + 1, -1)
    return np.flatnonzero((np.cumsum(edges[:-1]) > 0) & shown)


def _axis(ax, positions: np.ndarray, labels: list[str], word: str) -> None:
    step = max(1, int(np.ceil(len(positions) / MAX_TICK_LABELS)))
    ax.set_xticks(positions[::step], [labels[k] for k in range(0, len(labels), step)], rotation=60, fontsize=6)
    ax.set_xlabel(f"{word}, in recording order", fontsize=8)


def chart_picture(chart: Chart, title: str, word: str = "part") -> bytes:
    """One chart's PNG: points, centre line, limits, tolerance; alarms in red, signals in orange.

    I-MR: the individuals above, the moving ranges below. The x axis is the points' order,
    labelled with their part ids (or check times).
    """
    from workbench.figures import _figure, figure_png

    plt = _figure()
    s = chart.series
    idx = np.flatnonzero(s.shown)
    x = s.values
    labels = [s.labels[s.order[k]] for k in idx]
    u = isinstance(chart.limits, ULimits)
    fig, axes = plt.subplots(1 if u else 2, 1, figsize=(9, 3.2 if u else 5.2), dpi=100, squeeze=False, sharex=True)
    ax = axes[0, 0]
    ax.plot(idx, x[idx], "-o", color="#333", lw=0.6, ms=2.5)
    lim = chart.limits
    lines = [(lim.centre, "-", "centre")] + (
        [(lim.ucl, "--", "UCL")] if u else [(lim.ucl, "--", "UCL"), (lim.lcl, "--", "LCL")]
    )
    for y, style, name in lines:
        ax.axhline(y, ls=style, color="#1f77b4", lw=0.8)
        ax.annotate(f"{name} {y:.4g}", (1.0, y), xycoords=("axes fraction", "data"), fontsize=6, va="center")
    if s.tolerance is not None:
        for y in (s.tolerance.lo, s.tolerance.hi):
            if y is not None:
                ax.axhline(y, ls=":", color="#888", lw=0.8)
    for events, colour in ((chart.signals, "#f90"), (chart.alarms, "#d00")):
        m = _marks([e for e in events if e["chart"] != "moving range"], s.shown)
        if len(m):
            ax.plot(m, x[m], "o", color=colour, ms=5, mfc="none", mew=1.2)
    ax.axvspan(-0.5, chart.baseline - 0.5, color="#eee", zorder=0)
    ax.set_title(title, fontsize=9)
    if not u:
        mr = np.concatenate([[np.nan], np.abs(np.diff(x))])
        ax2 = axes[1, 0]
        ax2.plot(idx, mr[idx], "-o", color="#333", lw=0.6, ms=2.5)
        ax2.axhline(lim.mr_centre, color="#1f77b4", lw=0.8)
        ax2.axhline(lim.mr_ucl, ls="--", color="#1f77b4", lw=0.8)
        m = _marks([e for e in chart.signals if e["chart"] == "moving range"], s.shown)
        if len(m):
            ax2.plot(m, mr[m], "o", color="#f90", ms=5, mfc="none", mew=1.2)
        ax2.set_ylabel("moving range", fontsize=8)
        ax.tick_params(labelbottom=False)
        _axis(ax2, idx, labels, word)
    else:
        _axis(ax, idx, labels, word)
    fig.tight_layout()
    return figure_png(fig)


def _png_name(group: str, figure: str) -> str:
    safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in group)[:40]
    return f"{safe}-{figure}.png"


def report_files(out: Path, results: dict[str, list[Chart]], calibration: bool, store: str) -> dict[Path, bytes]:
    """The PNGs and ``trend.html`` to write into ``out`` (the same bytes for the same records)."""
    files: dict[Path, bytes] = {}
    word = "profile" if calibration else "design"
    sections = []
    for group, charts in results.items():
        blocks = []
        for c in charts:
            title = f"{TITLES.get(c.series.figure, c.series.figure)}: {word} {group[:16]}"
            png = chart_picture(c, title, "check" if calibration else "part")
            name = _png_name(group, c.series.figure)
            files[out / name] = png
            rows = "".join(
                f"<li class=alarm>rule {e['rule']} ({escape(e['rule_name'])}): "
                f"{escape(', '.join(e['part_ids' if 'part_ids' in e else 'checks'][:20]))}"
                + (
                    f"; tolerance {e['parts_to_tolerance']:g} parts away"
                    if e.get("parts_to_tolerance") is not None
                    else ""
                )
                + "</li>"
                for e in c.alarms
            )
            blocks.append(
                f'<h3>{escape(title)}</h3><img alt="{escape(name)}" '
                f'src="data:image/png;base64,{base64.b64encode(png).decode()}"><ul>{rows}</ul>'
            )
        sections.append(f"<h2>{word} {escape(group)}</h2>" + "".join(blocks))
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    stamp = ""
    if epoch and epoch.isdigit():
        from workbench.store.record import recorded_at

        stamp = f" Made {recorded_at(int(epoch))}."
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Control charts</title>
<style>body{{font-family:sans-serif;margin:2em}}img{{max-width:100%}}li.alarm{{color:#b00}}</style></head>
<body><h1>Control charts</h1>
<p>Store {escape(store)}.{stamp} Limits from the first parts recorded (shaded); red circles: alarms (a Nelson
rule fired and the trend reaches the tolerance, dotted, within the horizon); orange: signals (a rule fired with no
tolerance at stake, or the moving range beyond its limit).</p>
{"".join(sections)}</body></html>
"""
    files[out / "trend.html"] = page.encode()
    return files
