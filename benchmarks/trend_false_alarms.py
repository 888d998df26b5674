"""How often ``workbench trend`` raises a false alarm, and how early it warns of a drift: measured over seeds.

    .venv/bin/python benchmarks/trend_false_alarms.py [--seeds 100] [--parts 200] [--horizon 25]
        [--min-t 3] [--rules 1,2,3,4,5,6,7,8] [--every-signal] [--oracle]

The simulated production run of tests/trend_run.py (film placement scattered by 0.03 mm, tolerance
0.5 mm), charted by the same code as the command (limits from the first 15 parts, six figures):

- without drift, ``--parts`` parts: the share of runs with at least one alarm (a false alarm:
  nothing changed), and with at least one signal;
- with the film drifting 0.025 mm per part after the 15th: how many parts before the first FAIL
  the first alarm comes (the share of runs warned 15 parts or more ahead, the median lead), and
  which rule gave it. Any alarm counts, a chance one before the drift too: with --every-signal
  the lead is mostly such false alarms'.

``--oracle`` measures the bound no chart passes: a detector told what a chart has to estimate (the
process's sigma, that the drift is a ramp in +x and that x alone will drift), the matched filter of
a ramp of any age up to ORACLE_AGES parts, its threshold set so that the runs without drift raise a
false alarm in 5 % (``--oracle-false-alarm``); the share of drifting runs it warns 15, 12 and 10
parts before the first FAIL.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from trend_run import MAX_DELTA_E, TOLERANCE_MM, production_run  # noqa: E402

from workbench.commands.trend import parse_rules  # noqa: E402
from workbench.trend.analysis import Series, analyse  # noqa: E402
from workbench.trend.charts import AlarmOptions, Tolerance  # noqa: E402

BASELINE = 15
ORACLE_AGES = 30  # the oldest ramp the oracle's matched filter looks for, parts
SCATTER_MM = 0.03  # the simulation's sigma, which the oracle is told


def ramp_statistic(x: np.ndarray, sigma: float) -> np.ndarray:
    """At each part, the largest matched-filter z of a ramp that started 1 ... ORACLE_AGES parts before it.

    A ramp of age L ending at part t has weights 1 ... L on x[t-L+1 ... t]; against noise of
    known sigma its statistic sum(w x) / (sigma |w|) is standard normal, and a ramp of slope b
    raises it by b |w| / sigma: the most any test of that ramp can have.
    """
    best = np.full(len(x), -np.inf)
    for age in range(1, min(ORACLE_AGES, len(x)) + 1):
        w = np.arange(1, age + 1, dtype=np.float64)
        z = np.convolve(x, w[::-1], mode="valid") / (sigma * np.sqrt((w * w).sum()))
        best[age - 1 :] = np.maximum(best[age - 1 :], z)
    return best


def oracle(seeds: int, parts: int, false_alarm: float) -> None:
    """The oracle's warnings (see the module's docstring), on the same simulated runs as the charts'."""
    null = [ramp_statistic(production_run(s, parts).x, SCATTER_MM)[BASELINE:].max() for s in range(seeds)]
    threshold = float(np.quantile(null, 1.0 - false_alarm))
    leads = []
    for seed in range(seeds):
        drift = production_run(seed, 60, drift_mm=0.025)
        fail = int(np.flatnonzero(drift.fails())[0])
        over = np.flatnonzero(ramp_statistic(drift.x, SCATTER_MM)[BASELINE:] > threshold)
        leads.append(fail - (int(over[0]) + BASELINE) if len(over) else -1)
    leads = np.array(leads)
    print(
        f"oracle (sigma, the ramp's shape and sign, the figure known), {100 * false_alarm:g} % false alarms over "
        f"{parts} parts (z > {threshold:.2f}): warned >= 15 parts before the first FAIL in {np.mean(leads >= 15):.0%} "
        f"of runs, >= 12 in {np.mean(leads >= 12):.0%}, >= 10 in {np.mean(leads >= 10):.0%}"
    )


def charts(run, opts: AlarmOptions):
    """The run's six charts, as ``workbench trend`` draws them from the store."""
    n = len(run.x)
    labels = [str(k) for k in range(n)]
    shown = np.ones(n, dtype=bool)
    order = np.arange(n)
    tol = Tolerance(-TOLERANCE_MM, TOLERANCE_MM)
    series = [
        Series("film_offset_x_mm", run.x, labels, shown, tol, order),
        Series("film_offset_y_mm", run.y, labels, shown, tol, order),
        Series("film_rotation_deg", run.rotation, labels, shown, None, order),
        Series("worst_p95_mm", run.p95, labels, shown, Tolerance(None, TOLERANCE_MM), order),
        Series("delta_e00_mean", run.delta_e, labels, shown, Tolerance(None, MAX_DELTA_E), order),
        Series("defects", run.defects.astype(float), labels, shown, None, order, "u"),
    ]
    return [analyse(s, BASELINE, opts) for s in series]


def first_alarm(cs) -> tuple[int, int] | None:
    """(part index, rule) of the earliest alarm over the charts; None without one."""
    found = [(e["_order"], e["rule"]) for c in cs for e in c.alarms]
    return min(found) if found else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--parts", type=int, default=200)
    ap.add_argument("--horizon", type=float, default=25.0)
    ap.add_argument("--min-t", type=float, default=3.0)
    ap.add_argument("--rules", default="1,2,3,4,5,6,7,8")
    ap.add_argument("--every-signal", action="store_true")
    ap.add_argument("--oracle", action="store_true")
    ap.add_argument("--oracle-false-alarm", type=float, default=0.05)
    a = ap.parse_args()
    if a.oracle:
        oracle(a.seeds, a.parts, a.oracle_false_alarm)
        return
    opts = AlarmOptions(parse_rules(a.rules), horizon=a.horizon, min_t=a.min_t, every_signal=a.every_signal)
    false_alarms = signalled = 0
    leads, rules, by_figure = [], Counter(), Counter()
    for seed in range(a.seeds):
        cs = charts(production_run(seed, a.parts), opts)
        if any(c.alarms for c in cs):
            false_alarms += 1
            by_figure.update({c.series.figure for c in cs if c.alarms})
        signalled += any(c.signals for c in cs)
        drift = production_run(seed, 60, drift_mm=0.025)
        fail = int(np.flatnonzero(drift.fails())[0])
        first = first_alarm(charts(drift, opts))
        leads.append(fail - first[0] if first else -1)
        if first:
            rules[first[1]] += 1
    leads = np.array(leads)
    print(f"rules {a.rules}, horizon {a.horizon:g} parts, min t {a.min_t:g}, every signal {a.every_signal}")
    print(
        f"no drift, {a.parts} parts, {a.seeds} seeds: {false_alarms / a.seeds:.0%} of runs with a false alarm "
        f"({dict(by_figure)}); {signalled / a.seeds:.0%} with a signal"
    )
    print(
        f"drift 0.025 mm/part after part 15: warned >= 15 parts before the first FAIL in {np.mean(leads >= 15):.0%} "
        f"of runs (>= 12 in {np.mean(leads >= 12):.0%}, >= 10 in {np.mean(leads >= 10):.0%}); "
        f"median lead {np.median(leads):g} parts; no alarm before 60 parts in {np.mean(leads < 0):.0%}; "
        f"first alarm's rule {dict(sorted(rules.items()))}"
    )


if __name__ == "__main__":
    main()
