"""The store's records read back: for ``workbench lot`` and as CSV or JSON."""

from __future__ import annotations

import csv
import io
import json

from sqlalchemy import select

from workbench.errors import WorkbenchError
from workbench.store.schema import defects, files, photos, validations

# the CSV's columns: every column of a validation but its validation.json
CSV_COLUMNS = [c.name for c in validations.columns if c.name != "validation_json"]


def validation_records(conn, lot: str | None = None) -> list[dict]:
    """The validations (all, or a lot's), in recording order, as dicts of their columns."""
    query = select(validations).order_by(validations.c.id)
    if lot is not None:
        query = query.where(validations.c.lot == lot)
    return [dict(r._mapping) for r in conn.execute(query)]


# what the lots and their switching rules read of a record (not its validation.json: a store of
# 100,000 parts would otherwise be read whole for each lot)
LOT_COLUMNS = ("id", "part_id", "lot", "verdict", "reason", "recorded_at", "out_dir", "design_json_sha256")


def lot_records(conn) -> list[dict]:
    """Every validation recorded in a lot, in recording order, with the columns of :data:`LOT_COLUMNS`."""
    query = select(*(validations.c[k] for k in LOT_COLUMNS)).where(validations.c.lot.is_not(None))
    return [dict(r._mapping) for r in conn.execute(query.order_by(validations.c.id))]


def full_records(conn, lot: str | None = None) -> list[dict]:
    """Validations with their photos, defects and files, and ``validation`` the parsed validation.json."""
    out = []
    for v in validation_records(conn, lot):
        rec = {k: v[k] for k in CSV_COLUMNS}
        for table, key in ((photos, "photos"), (defects, "defects"), (files, "files")):
            rows = conn.execute(select(table).where(table.c.validation_id == v["id"]).order_by(table.c.id))
            rec[key] = [{k: x for k, x in r._mapping.items() if k not in ("id", "validation_id")} for r in rows]
        for d in rec["defects"]:
            d["photos"] = _stored_json(d["photos"], f"validation {v['id']}'s defect's photos")
        rec["validation"] = _stored_json(v["validation_json"], f"validation {v['id']}'s validation.json")
        out.append(rec)
    return out


def _stored_json(text, what: str):
    """A JSON text the store keeps, parsed; a damaged store's (not JSON, or no text) is one line naming ``what``."""
    try:
        return json.loads(text)
    except (TypeError, ValueError):
        raise WorkbenchError(f"the store's {what} is not JSON (a damaged store)") from None


def as_json(records: list[dict]) -> str:
    """The records as a JSON array (keys sorted: the same records give the same bytes)."""
    return json.dumps(records, indent=1, sort_keys=True) + "\n"


def as_csv(records: list[dict]) -> str:
    """One CSV row per validation, the columns of :data:`CSV_COLUMNS`."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, CSV_COLUMNS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in records:
        w.writerow({k: "" if r[k] is None else r[k] for k in CSV_COLUMNS})
    return buf.getvalue()
