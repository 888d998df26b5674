"""``workbench lot``: accept or reject a lot by ISO 2859-1 from the parts recorded in the store."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

from workbench.errors import UsageError, WorkbenchError
from workbench.lots.tables import LEVELS
from workbench.options import Number


def add_parser(sub) -> None:
    p = sub.add_parser(
        "lot",
        help="accept or reject a lot by ISO 2859-1 (AQL sampling) from the parts validated into the store",
        description=(
            "The single sampling plan of ISO 2859-1 for the lot's size, the inspection level and the AQL: its "
            "sample size code letter, sample size, acceptance and rejection numbers; the parts the store has "
            "for the lot against it (a FAIL is nonconforming; INVALID and INCOMPLETE parts are not inspected, "
            "never conforming); and the decision: accept, reject, or how many more parts to inspect. The "
            "inspection (normal, tightened, reduced, or discontinued) follows the standard's switching rules "
            "over the lots recorded before it for the same design, each decided with the same level and AQL "
            "(and --lot-size, when given)."
        ),
    )
    p.add_argument("lot", metavar="LOT")
    p.add_argument("--aql", metavar="AQL", required=True, help="acceptance quality limit: 0.010 ... 1000 (Table 2-A)")
    p.add_argument("--level", default="II", choices=LEVELS, help="inspection level (default II)")
    p.add_argument(
        "--lot-size",
        action=Number,
        lo=2,
        hi=10**12,
        integer=True,
        help="items in the lot (default: the parts the store has for it)",
    )
    p.add_argument(
        "--allow-reduced",
        action="store_true",
        help="production is steady and reduced inspection is approved: a switching score of 30 switches to "
        "reduced inspection (ISO 2859-1 9.3.3; without it, normal inspection continues)",
    )
    p.add_argument("--store", metavar="URL", help="the store (default: $WORKBENCH_STORE)")
    p.add_argument("--json", action="store_true", help="print the plan and the decision as JSON")
    p.add_argument(
        "--report",
        metavar="FILE",
        action="append",
        help="write the lot report (FILE.html or FILE.pdf; give it twice for both): the plan, the decision, "
        "and every part with its verdict and evidence",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    from workbench.atomic import check_outputs, write_files
    from workbench.environment import print_result
    from workbench.lots.decision import decision_dict, lot_decision, lot_parts
    from workbench.lots.plan import aql_text, code_letter, sampling_plan
    from workbench.lots.report import lot_report_html, lot_report_pdf
    from workbench.store.database import engine_for, shown, store_file, store_text, store_url, transaction
    from workbench.store.export import lot_records

    aql = aql_text(args.aql)  # (before the store: a bad option is the command line's fault)
    if args.lot_size is not None:
        code_letter(args.lot_size, args.level)
    text = store_text(args.store)
    if text is None:
        raise UsageError("--store: no store given (nor WORKBENCH_STORE)")
    option = "--store" if args.store is not None else "WORKBENCH_STORE"
    url = store_url(text, option)
    reports = [Path(r) for r in args.report or []]
    for r in reports:
        if r.suffix.lower() not in (".html", ".pdf"):
            raise UsageError(f"--report {r}: give a .html or a .pdf file")
    if reports:
        check_outputs(*reports, inputs=[store_file(url)])
    engine = engine_for(url, create=False, option=option)
    try:
        with transaction(engine, url, migrate=False, option=option) as conn:
            everything = lot_records(conn)
    finally:
        engine.dispose()
    by_lot: dict[str, list[dict]] = {}
    for r in everything:  # (in recording order: each lot where its first record is)
        by_lot.setdefault(r["lot"], []).append(r)
    records = by_lot.get(args.lot)
    if not records:
        raise WorkbenchError(f"lot {args.lot}: no part of it is recorded in {shown(url)}")
    parts = lot_parts(records)
    lot_size = args.lot_size if args.lot_size is not None else max(len(parts), 2)
    if lot_size < len(parts):
        raise WorkbenchError(f"--lot-size {lot_size}: the store has {len(parts)} parts of lot {args.lot}")
    switching = lot_switching(args, aql, by_lot)
    inspection = "tightened" if switching.inspection == "discontinued" else switching.inspection
    decision = lot_decision(sampling_plan(lot_size, args.level, aql, inspection), parts)
    if switching.inspection == "discontinued":
        decision = replace(decision, decision="discontinued (ISO 2859-1 9.4: no lot is accepted by sampling)")
    d = decision_dict(args.lot, decision, switching)
    if args.json:
        print_result(json.dumps(d, indent=1) + "\n")
    else:
        size = "" if args.lot_size is not None else f" (the {len(parts)} part(s) recorded, at least 2; give --lot-size)"
        print_result(
            f"lot {args.lot}: {d['decision']}: {d['inspection']} inspection ({switching.rule}"
            + (f": lots {', '.join(switching.lots)}" if switching.lots else "")
            + f"); {lot_size} items{size}, level {d['level']}, AQL {d['aql']}: "
            f"code letter {d['code_letter']}, sample {d['sample_size']}"
            + (" (100 %)" if d["hundred_percent"] else "")
            + f", accept {d['accept']}, reject {d['reject']}; inspected {d['inspected']}, nonconforming "
            f"{d['nonconforming']}, not inspected (INVALID, INCOMPLETE) {d['not_inspected']}\n"
        )
    if reports:  # (after the decision is printed: a full disk on standard output leaves no report)
        make = {".html": lot_report_html, ".pdf": lot_report_pdf}
        write_files({r: make[r.suffix.lower()](args.lot, decision, parts, shown(url), switching) for r in reports})
    for r in reports:
        print(f"wrote {r}", file=sys.stderr)
    return 0


def lot_switching(args, aql: str, by_lot: dict[str, list[dict]]):
    """The lot's inspection by the switching rules over the lots recorded before it for the same design.

    A lot's design is its first record's design (``design.json``'s hash); the earlier lots are the
    lots of that design whose first record precedes the lot's, in that order. Each is decided with
    this command's level and AQL, and lot size (``--lot-size``, or its own parts, at least 2).
    """
    from workbench.lots.decision import lot_parts
    from workbench.lots.plan import sampling_plan
    from workbench.lots.switching import series_inspection

    first = by_lot[args.lot][0]
    earlier = [
        (name, lot_parts(rs))
        for name, rs in by_lot.items()
        if rs[0]["id"] < first["id"] and rs[0]["design_json_sha256"] == first["design_json_sha256"]
    ]

    def plan_for(parts, inspection):
        size = max(args.lot_size or 0, len(parts), 2)
        return sampling_plan(size, args.level, aql, inspection)

    return series_inspection(earlier, plan_for, args.allow_reduced)
