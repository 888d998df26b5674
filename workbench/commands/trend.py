"""``workbench trend``: control charts of the store's parts (or calibration checks), with the Nelson rules' alarms."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from workbench.errors import UsageError, WorkbenchError
from workbench.options import Number


def add_parser(sub) -> None:
    p = sub.add_parser(
        "trend",
        help="control charts of the recorded parts (or calibration checks): alarms before parts fail",
        description=(
            "Individuals and moving-range charts of each design's film offset x and y, rotation, misregistration "
            "p95 and mean ΔE00, and a u-chart of its defects per part, in recording order; limits from the first "
            "parts recorded for the design (--baseline-parts). A Nelson rule that fires is an alarm when the "
            "figure's least-squares trend over the last parts reaches its tolerance within --horizon parts "
            "(or the part is beyond it); every other firing is a signal. With --calibration, the same for the "
            "checks recorded by calibrate check --store: fx, fy, cx, cy (a camera), scale x and y (a printer)."
        ),
    )
    p.add_argument("--store", metavar="URL", help="the store (default: $WORKBENCH_STORE)")
    p.add_argument("--design", metavar="D", help="only this design: its job's name or its sha256 (6+ characters)")
    p.add_argument("--station", metavar="S", help="chart only the parts recorded at this station")
    p.add_argument("--since", metavar="T", help="chart only the parts recorded since T (ISO 8601 date or time, UTC)")
    p.add_argument(
        "--baseline-parts",
        action=Number,
        lo=2,
        hi=10**9,
        integer=True,
        default=15,
        metavar="N",
        help="the limits come from the first N parts recorded for the design (default 15)",
    )
    p.add_argument(
        "--rules",
        metavar="LIST",
        default="1,2,3,4,5,6,7,8",
        help="the Nelson rules applied, by number (default all eight; 1, 2, 3, 5 and 6 find shifts and "
        "trends, 4, 7 and 8 alternation, stratification and mixtures)",
    )
    p.add_argument(
        "--horizon",
        action=Number,
        lo=0,
        hi=10**9,
        default=25,
        metavar="PARTS",
        help="a firing is an alarm when the trend reaches the tolerance within this many parts (default 25)",
    )
    p.add_argument(
        "--every-signal",
        action="store_true",
        help="every firing is an alarm, whatever the tolerance (the classical chart: many false alarms)",
    )
    p.add_argument("--calibration", action="store_true", help="chart the calibration checks instead of parts")
    p.add_argument("--camera", metavar="NAME", help="with --calibration: only this profile (its file's stem)")
    p.add_argument("--json", action="store_true", help="print the charts' limits, the alarms and signals as JSON")
    p.add_argument("--out", metavar="DIR", help="write one PNG per chart and trend.html embedding them")
    p.set_defaults(run=run)


def parse_rules(text: str) -> tuple[int, ...]:
    """``--rules`` as rule numbers, sorted; one line for anything but numbers 1 to 8."""
    try:
        rules = sorted({int(t) for t in text.split(",") if t.strip()})
    except ValueError:
        rules = []
    if not rules or any(r < 1 or r > 8 for r in rules):
        raise UsageError(f"--rules {text}: give Nelson rule numbers 1 to 8, separated by commas (such as 1,2,3,5,6)")
    return tuple(rules)


def run(args) -> int:
    from workbench.atomic import check_output_dir
    from workbench.environment import print_result
    from workbench.store.database import engine_for, shown, store_file, store_text, store_url, transaction
    from workbench.trend import query
    from workbench.trend.charts import WINDOW, AlarmOptions
    from workbench.trend.summary import analyse_groups, summary_json, summary_text

    if args.camera is not None and not args.calibration:
        raise UsageError("--camera: charts calibration checks; give --calibration")
    if args.calibration and args.design is not None:
        raise UsageError("--design: charts parts; leave out --calibration")
    opts = AlarmOptions(parse_rules(args.rules), WINDOW, float(args.horizon), every_signal=args.every_signal)
    since = query.since_text(args.since) if args.since is not None else None
    text = store_text(args.store)
    if text is None:
        raise UsageError("--store: no store given (nor WORKBENCH_STORE)")
    option = "--store" if args.store is not None else "WORKBENCH_STORE"
    url = store_url(text, option)
    out = Path(args.out) if args.out else None
    if out is not None:
        check_output_dir(out, inputs=[store_file(url)])
    engine = engine_for(url, create=False, option=option)
    try:
        with transaction(engine, url, migrate=False, option=option) as conn:
            if args.calibration:
                groups = query.calibration_groups(conn, args.camera)
            else:
                groups = query.design_groups(conn, args.design, args.station is not None or since is not None)
    finally:
        engine.dispose()
    what = "calibration check" if args.calibration else "part"
    if not groups:
        raise WorkbenchError(f"{option} {shown(url)}: no {what} recorded")
    n = args.baseline_parts
    for name, rows in groups.items():
        if len(rows if args.calibration else rows["part_id"]) < n:
            raise WorkbenchError(
                f"--baseline-parts {n}: {'profile' if args.calibration else 'design'} {name} has "
                f"{len(rows if args.calibration else rows['part_id'])} {what}(s) recorded"
            )
    results = analyse_groups(groups, n, since, args.station, opts, args.calibration)
    if not any(c.series.shown.any() for charts in results.values() for c in charts):
        raise WorkbenchError(f"--station/--since: no {what} recorded matches them")
    d = summary_json(results, n, opts, args.calibration)
    # (before the charts are written: a full disk on standard output leaves no folder)
    print_result((json.dumps(d, indent=1) if args.json else summary_text(d)) + "\n")
    if out is not None:
        from workbench.atomic import write_folder
        from workbench.trend.report import report_files

        write_folder(out, report_files(out, results, args.calibration, shown(url)))
    if out is not None:
        print(f"wrote {out}", file=sys.stderr)
    return 0
