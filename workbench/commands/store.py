"""``workbench store``: the results store's records exported as CSV or JSON."""

from __future__ import annotations

from pathlib import Path

from workbench.errors import WorkbenchError


def add_parser(sub) -> None:
    p = sub.add_parser(
        "store",
        help="export the results store's records (CSV or JSON)",
        description="The validations recorded in a store (workbench validate --store), exported.",
    )
    actions = p.add_subparsers(dest="action", metavar="ACTION", required=True, parser_class=type(p))
    e = actions.add_parser(
        "export",
        help="every validation (or a lot's) as CSV (one row each) or JSON (with photos, defects, files)",
        description=(
            "CSV: one row per validation, its columns (the part, lot, station, operator, time, design "
            "hashes, verdicts and key figures). JSON: each validation with its photos, defects, the files "
            "written with their sha256, and its validation.json."
        ),
    )
    e.add_argument("url", metavar="URL", help="the store: a SQLite file's path or a SQLAlchemy URL")
    e.add_argument("--format", choices=("csv", "json"), default="json", help="default json")
    e.add_argument("--lot", metavar="LOT", help="only this lot's validations")
    e.add_argument("-o", "--out", metavar="FILE", help="write to FILE (default: standard output)")
    e.set_defaults(run=run_export)


def run_export(args) -> int:
    from workbench.atomic import check_outputs, write_files
    from workbench.environment import print_result
    from workbench.store.database import engine_for, shown, store_file, store_url, transaction
    from workbench.store.export import as_csv, as_json, full_records

    url = store_url(args.url, "URL")
    out = Path(args.out) if args.out else None
    if out is not None:
        check_outputs(out, inputs=[store_file(url)])  # (-o the store itself replaced it with its export)
    engine = engine_for(url, create=False, option="URL")
    try:
        with transaction(engine, url, migrate=False, option="URL") as conn:
            records = full_records(conn, args.lot)
    finally:
        engine.dispose()
    if args.lot is not None and not records:
        raise WorkbenchError(f"--lot {args.lot}: no part of it is recorded in {shown(url)}")
    text = as_csv(records) if args.format == "csv" else as_json(records)
    if out is None:
        print_result(text)
    else:
        write_files({out: text.encode()})
    return 0
