"""One figure's chart: its limits from the baseline, the Nelson rules' firings, and which are alarms.

A Nelson rule firing is a *signal*: the process is not what the baseline was. It is an *alarm*
when it threatens the parts: the least-squares trend over the last ``window`` parts (its slope
at least ``min_t`` standard errors from zero: :func:`slope_significance`) reaches the
figure's tolerance within ``horizon`` parts, or the point is beyond the tolerance already. Why: a process sixteen sigma
inside its tolerance, charted over hundreds of parts and six figures with limits from fifteen
parts, fires some rule by chance in every run (measured over 100 simulated 200-part runs: rule
1 alone fires on one figure in 53 % of them, some rule on some figure in all of them; with the
tolerance's test, 12 % raise an alarm); the tolerance is what makes a firing worth stopping
the line for. Figures without a tolerance
(rotation, defect counts) and the moving-range charts give signals only. ``every_signal``
raises every firing as an alarm: the classical chart, with its false-alarm rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.trend import nelson
from workbench.trend.charts import (
    AlarmOptions,
    IMRLimits,
    Tolerance,
    ULimits,
    firings,
    imr_limits,
    parts_to_tolerance,
    rolling_trend,
    rule_fires,
    standardized,
    u_limits,
)


@dataclass(frozen=True)
class Series:
    """One figure's values in recording order.

    figure : the figure's name (a store column: ``film_offset_x_mm``, ``fx``, ...)
    values : its values, one per part (or check) that has one
    labels : the group's part ids (or check times), every record's: point ``p``'s is ``labels[order[p]]``
    shown : which points the filters (station, since) keep on the chart
    tolerance : the bounds a part fails beyond, or None
    order : each point's position among the group's records
    kind : ``"I-MR"`` or ``"u"``
    """

    figure: str
    values: np.ndarray
    labels: list[str]
    shown: np.ndarray
    tolerance: Tolerance | None
    order: np.ndarray
    kind: str = "I-MR"


@dataclass
class Chart:
    """A figure's chart: its series, limits, alarms and signals (JSON-ready dicts)."""

    series: Series
    baseline: int
    limits: IMRLimits | ULimits
    alarms: list[dict] = field(default_factory=list)
    signals: list[dict] = field(default_factory=list)  # one per chart and rule: counted


def label(series: Series, p: int) -> str:
    """Point ``p``'s part id (or check time)."""
    return series.labels[series.order[p]]


def shown_ids(series: Series, lo: int, hi: int) -> list[str]:
    """The labels of the points ``lo`` ... ``hi`` (indices, inclusive) the chart shows."""
    return [label(series, p) for p in range(lo, hi + 1) if series.shown[p]]


def _name(rule: int, chart: str) -> str:
    return "point beyond the moving-range limit" if chart == "moving range" else nelson.NAMES[rule]


def _alarm(rule: int, series: Series, first: int, lo: int, hi: int, key: str) -> dict:
    return {
        "_span": ([lo], [hi]),  # (indices into the series: the pictures mark them; not in the JSON)
        "_order": int(series.order[first]),
        "rule": rule,
        "rule_name": _name(rule, "individuals"),
        "figure": series.figure,
        "chart": "individuals",
        key: shown_ids(series, lo, hi),
        "first": label(series, first),
        "value": round(float(series.values[first]), 6),
    }


def _signals(rule: int, series: Series, runs: tuple, chart: str, key: str) -> list[dict]:
    """A rule's firings on one chart that are not alarms, counted (one dict, or none when it never fired)."""
    first, lo, hi = runs
    if not len(first):
        return []
    last = int(first[-1])
    return [
        {
            "_span": (lo, hi),
            "_order": int(series.order[last]),
            "rule": rule,
            "rule_name": _name(rule, chart),
            "figure": series.figure,
            "chart": chart,
            "count": len(first),
            "last": label(series, last),
            "last_" + key: shown_ids(series, int(lo[-1]), int(hi[-1])),
        }
    ]


def slope_significance(slope: np.ndarray, t_window: np.ndarray, window: int, sigma: float) -> np.ndarray:
    """Each slope in standard errors, the error from the larger of the baseline's sigma and the
    window's own scatter about its line (the smaller of the two t).

    Either alone lets chance through: eight points that happen to lie close to a line give a
    window's t of 3 to one slope in forty of a process in control (Student's t, six degrees of
    freedom), and fifteen baseline parts put sigma a third low now and then, which makes every
    slope look significant (over 100 simulated 200-part runs, the baseline's alone raised a false
    alarm in 21 %, the larger of the two in 12 %; the drift was caught 15 parts ahead in 56 % and
    50 %).

    Parameters
    ----------
    slope : per point, figure units per part
    t_window : the slope over its standard error from the window's own residuals
    window : parts in the trend
    sigma : the baseline's sigma, figure units
    """
    sxx = window * (window**2 - 1) / 12  # sum of (t - mean t)^2 over the window
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.minimum(np.abs(slope) * np.sqrt(sxx) / sigma, t_window)


def analyse(series: Series, baseline: int, opts: AlarmOptions, key: str = "part_ids") -> Chart:
    """Limits from the first ``baseline`` points, the rules from the point after it on, alarms and signals.

    Parameters
    ----------
    series : the figure's values
    baseline : points the limits come from (at least 2)
    opts : rules and the drift's projection
    key : what the points are called in an alarm (``part_ids``, ``checks``)

    Returns
    -------
    Chart
        Alarms and signals each ``rule``, ``rule_name``, ``figure``, ``chart``, ``key`` (the
        triggering points shown, in recording order), ``first`` (where the pattern first
        completed) and ``value``; a drift's alarm also ``parts_to_tolerance`` and
        ``trend_per_part`` at that point.
    """
    x = series.values
    if series.kind == "u":
        lim = u_limits(x[:baseline])
        chart = Chart(series, baseline, lim)
        chart.signals += _signals(1, series, firings(x > lim.ucl, 1, baseline, series.shown), "u", key)
        return chart
    lim = imr_limits(x[:baseline])
    chart = Chart(series, baseline, lim)
    mr = np.concatenate([[0.0], np.abs(np.diff(x))])
    beyond_mr = firings(mr > lim.mr_ucl, 2, baseline, series.shown)
    z = standardized(x, lim)
    if series.tolerance is not None:
        slope, now, t_window = rolling_trend(x, opts.window)
        t = slope_significance(slope, t_window, opts.window, lim.sigma)
        ptt = parts_to_tolerance(slope, now, series.tolerance)
        beyond = parts_to_tolerance(np.zeros(len(x)), x, series.tolerance) == 0
        threat = beyond | ((ptt <= opts.horizon) & (t >= opts.min_t))
    else:
        slope = ptt = np.full(len(x), np.nan)
        threat = np.zeros(len(x), dtype=bool)
    if opts.every_signal:
        threat = np.ones(len(x), dtype=bool)
    for rule, fires in rule_fires(z, opts.rules).items():
        window = nelson.WINDOWS[rule]
        for first, lo, hi in zip(*firings(fires & threat, window, baseline, series.shown), strict=True):
            event = _alarm(rule, series, int(first), int(lo), int(hi), key)
            if np.isfinite(slope[first]):
                event["trend_per_part"] = round(float(slope[first]), 6)
                event["parts_to_tolerance"] = round(float(ptt[first]), 1) if np.isfinite(ptt[first]) else None
            chart.alarms.append(event)
        chart.signals += _signals(
            rule, series, firings(fires & ~threat, window, baseline, series.shown), "individuals", key
        )
    chart.signals += _signals(1, series, beyond_mr, "moving range", key)
    chart.alarms.sort(key=lambda e: (e["_order"], e["rule"]))
    return chart


def chart_json(chart: Chart) -> dict:
    """The chart's limits and its baseline, JSON-ready (alarms and signals are listed apart)."""
    s = chart.series
    d = {"figure": s.figure, "chart": s.kind, "points": int(s.shown.sum()), "baseline_points": chart.baseline}
    lim = chart.limits
    if isinstance(lim, ULimits):
        d.update({"centre": round(lim.centre, 6), "ucl": lim.ucl, "lcl": 0.0})
    else:
        d.update(
            {
                "centre": round(lim.centre, 6),
                "sigma": round(lim.sigma, 6),
                "lcl": round(lim.lcl, 6),
                "ucl": round(lim.ucl, 6),
                "mr_centre": round(lim.mr_centre, 6),
                "mr_ucl": round(lim.mr_ucl, 6),
            }
        )
    if s.tolerance is not None:
        d["tolerance"] = {"lo": s.tolerance.lo, "hi": s.tolerance.hi}
    return d
