"""The charts of every design (or calibration profile) analysed, as JSON and as a short text."""

from __future__ import annotations

from workbench.trend import nelson, query
from workbench.trend.analysis import Chart, analyse, chart_json
from workbench.trend.charts import AlarmOptions


def analyse_groups(
    groups: dict[str, list],
    baseline: int,
    since: str | None,
    station: str | None,
    opts: AlarmOptions,
    calibration: bool,
) -> dict[str, list[Chart]]:
    """Each group's charts (a design's parts, or a profile's checks), in the store's order of groups."""
    key = "checks" if calibration else "part_ids"
    series_of = query.calibration_series if calibration else query.part_series
    return {
        name: [analyse(s, baseline, opts, key) for s in series_of(rows, baseline, station, since)]
        for name, rows in groups.items()
    }


def summary_json(results: dict[str, list[Chart]], baseline: int, opts: AlarmOptions, calibration: bool) -> dict:
    """``charts`` (each group's limits), ``alarms`` (each with its group, in recording order), ``signals``
    (counted per chart and rule: over 100,000 parts a process in control fires some rule thousands of
    times), and the method's settings."""
    group = "camera" if calibration else "design"
    order = {name: k for k, name in enumerate(results)}
    charts, alarms, signals = [], [], []
    for name, cs in results.items():
        for c in cs:
            charts.append({group: name, **chart_json(c)})
            alarms += [{group: name, **a} for a in c.alarms]
            signals += [{group: name, **s} for s in c.signals]
    # each group's alarms in recording order, whatever the figure
    alarms.sort(key=lambda e: (order[e[group]], e["_order"]))
    return {
        "baseline_parts": baseline,
        "rules": {str(r): nelson.NAMES[r] for r in opts.rules},
        "trend_window_parts": opts.window,
        "horizon_parts": opts.horizon,
        "min_t": opts.min_t,
        "every_signal": opts.every_signal,
        "charts": charts,
        "alarms": [_public(e) for e in alarms],
        "signals": [_public(e) for e in signals],
        "not_charted": [] if calibration else not_charted(results, baseline),
    }


def not_charted(results: dict[str, list[Chart]], baseline: int) -> list[dict]:
    """The part figures a design has no chart of: fewer than ``baseline`` of its parts have them
    (ΔE00 where no photo shows the colour chart, offsets where no photo was scored)."""
    return [
        {"design": name, "figure": figure, "reason": f"fewer than {baseline} of its parts have it"}
        for name, cs in results.items()
        for figure, _ in query.PART_FIGURES
        if figure not in {c.series.figure for c in cs}
    ]


def _public(e: dict) -> dict:
    return {k: v for k, v in e.items() if not k.startswith("_")}


def summary_text(d: dict) -> str:
    """A few lines: per group its points, then each alarm; the signals counted."""
    group = "camera" if any("camera" in c for c in d["charts"]) else "design"
    key = "checks" if group == "camera" else "part_ids"
    lines = []
    seen = []
    for c in d["charts"]:
        if c[group] not in seen:
            seen.append(c[group])
            lines.append(
                f"{group} {c[group]}: {c['points']} point(s) charted, limits from its first {d['baseline_parts']}"
            )
    for a in d["alarms"]:
        drift = ""
        if a.get("parts_to_tolerance") is not None:
            drift = f"; at {a['trend_per_part']:+g} per part the tolerance is {a['parts_to_tolerance']:g} parts away"
        ids = a[key]
        span = ", ".join(ids) if len(ids) <= 6 else f"{', '.join(ids[:3])} ... {ids[-1]} ({len(ids)} points)"
        lines.append(
            f"ALARM {a['figure']} ({group} {a[group][:12]}): rule {a['rule']}, {a['rule_name']}: {span}{drift}"
        )
    if not d["alarms"]:
        lines.append("no alarm")
    for m in d.get("not_charted", []):
        lines.append(f"no chart of {m['figure']} ({group} {m[group][:12]}): {m['reason']}")
    n = sum(s["count"] for s in d["signals"])
    if n:
        lines.append(f"{n} signal(s): rules that fired with no tolerance at stake (counted in --json)")
    return "\n".join(lines)
