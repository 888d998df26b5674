"""A validation recorded: who, where and when, the verdicts and figures, the defects and the files written."""

from __future__ import annotations

import datetime
import getpass
import hashlib
import json
import os
import socket
from dataclasses import dataclass
from pathlib import Path

from workbench.store.database import engine_for, transaction
from workbench.store.figures import part_figures
from workbench.store.schema import calibrations, defects, files, photos, validations


@dataclass(frozen=True)
class Recorder:
    """Who records, where, and under which part and lot: ``workbench validate``'s store options."""

    url: object  # a sqlalchemy URL
    part_id: str
    lot: str | None
    station: str
    operator: str


def default_station() -> str:
    """This machine's host name (``--station`` overrides it)."""
    return socket.gethostname() or "unknown"


def default_operator() -> str:
    """The login name (``--operator`` overrides it)."""
    try:
        return getpass.getuser()
    except (KeyError, OSError):  # no name for the uid (a container)
        return f"uid {os.getuid()}" if hasattr(os, "getuid") else "unknown"


def recorded_at(epoch: int | None) -> str:
    """The record's time, UTC ISO 8601 to the second: ``SOURCE_DATE_EPOCH`` when set, else now."""
    t = (
        datetime.datetime.fromtimestamp(epoch, datetime.UTC)
        if epoch is not None
        else datetime.datetime.now(datetime.UTC)
    )
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")


def _sha256(path: Path) -> tuple[str, int]:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest(), path.stat().st_size


def _number(x) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else None


def validation_rows(report_text: str, out: Path, written: list[Path], rec: Recorder, when: str) -> dict:
    """The rows of one validation from its ``validation.json`` (as written) and the files written.

    Returns
    -------
    dict
        ``validation`` (one row), ``photos``, ``defects`` and ``files`` (lists of rows, without
        the validation's id).
    """
    report = json.loads(report_text)
    part = report["part"]
    entries = report["photos"]
    verdicts = [e.get("verdict") for e in entries]
    p95s = [_number((e.get("misregistration_mm") or {}).get("p95")) for e in entries]
    p95s = [x for x in p95s if x is not None]
    part_defects = part.get("defects") or []
    job = report["design"].get("job") or {}
    coverage = part.get("coverage")
    validation = {
        "part_id": rec.part_id,
        "lot": rec.lot,
        "station": rec.station,
        "operator": rec.operator,
        "recorded_at": when,
        "software_version": report["software"]["version"],
        "job": job.get("name") if isinstance(job, dict) else None,
        "job_sha256": job.get("sha256") if isinstance(job, dict) else None,
        "design_json_sha256": report["design"].get("design_json_sha256"),
        "print_sha256": report["design"].get("print_sha256"),
        "verdict": part["verdict"],
        "reason": part.get("reason"),
        "photos": len(entries),
        "photos_scored": part.get("photos_scored"),
        "photos_pass": verdicts.count("PASS"),
        "photos_fail": verdicts.count("FAIL"),
        "photos_invalid": verdicts.count("INVALID"),
        "photos_incomplete": verdicts.count("INCOMPLETE"),
        "worst_p95_mm": max(p95s) if p95s else None,
        "defects": len(part_defects),
        "largest_defect_mm2": max((d["area_mm2"] for d in part_defects), default=None),
        "coverage_complete": None if not isinstance(coverage, dict) else int(bool(coverage.get("complete"))),
        "tolerance_mm": report.get("tolerance_mm"),
        "max_defect_mm2": report.get("max_defect_mm2"),
        "max_delta_e": report.get("max_delta_e"),
        "out_dir": str(out.absolute()),
        "validation_json": report_text,
        **part_figures(report),
    }
    photo_rows = []
    for k, e in enumerate(entries):
        mm = e.get("misregistration_mm") or {}
        offset = e.get("film_offset_mm") or [None, None]
        photo_rows.append(
            {
                "position": k,
                "photo": e.get("photo"),
                "sha256": e.get("sha256"),
                "verdict": e.get("verdict"),
                "reason": e.get("reason"),
                "view": e.get("view"),
                "p95_mm": _number(mm.get("p95")),
                "median_mm": _number(mm.get("median")),
                "film_offset_x_mm": _number(offset[0]) if len(offset) > 0 else None,
                "film_offset_y_mm": _number(offset[1]) if len(offset) > 1 else None,
                "film_rotation_deg": _number(e.get("film_rotation_deg")),
                "ssim": _number(e.get("ssim")),
                "coverage": _number(e.get("coverage")),
            }
        )
    defect_rows = [
        {
            "kind": d["kind"],
            "area_mm2": d["area_mm2"],
            "centre_x_mm": (d.get("centre_mm") or [None, None])[0],
            "centre_y_mm": (d.get("centre_mm") or [None, None])[1],
            "photos": json.dumps(d.get("photos") or []),
        }
        for d in part_defects
    ]
    file_rows = []
    for path in sorted(written):
        digest, size = _sha256(path)
        file_rows.append({"path": str(path.absolute()), "sha256": digest, "bytes": size})
    return {"validation": validation, "photos": photo_rows, "defects": defect_rows, "files": file_rows}


def record_validation(rows: dict, url) -> int:
    """Insert one validation's rows in one transaction (the schema made or updated in it); its id."""
    engine = engine_for(url, create=True)
    try:
        with transaction(engine, url, migrate=True) as conn:
            vid = conn.execute(validations.insert().values(**rows["validation"])).inserted_primary_key[0]
            for table, key in ((photos, "photos"), (defects, "defects"), (files, "files")):
                if rows[key]:
                    conn.execute(table.insert(), [{**r, "validation_id": vid} for r in rows[key]])
        return vid
    finally:
        engine.dispose()


def record_calibration(row: dict, url) -> int:
    """Insert one calibration check (a row of ``calibrations``) in one transaction, the schema made or
    updated in it; its id."""
    engine = engine_for(url, create=True)
    try:
        with transaction(engine, url, migrate=True) as conn:
            return conn.execute(calibrations.insert().values(**row)).inserted_primary_key[0]
    finally:
        engine.dispose()
