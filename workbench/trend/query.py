"""The series the charts are drawn from, read from the store: per design (validations) or per camera (checks)."""

from __future__ import annotations

import datetime

import numpy as np
from sqlalchemy import select

from workbench.errors import UsageError, WorkbenchError
from workbench.store.schema import calibrations, validations
from workbench.trend.analysis import Series
from workbench.trend.charts import Tolerance

# (column, chart): the validations' figures, in the order they are charted
PART_FIGURES = (
    ("film_offset_x_mm", "I-MR"),
    ("film_offset_y_mm", "I-MR"),
    ("film_rotation_deg", "I-MR"),
    ("worst_p95_mm", "I-MR"),
    ("delta_e00_mean", "I-MR"),
    ("defects", "u"),
)
CAMERA_FIGURES = ("fx", "fy", "cx", "cy")
PRINTER_FIGURES = ("scale_x", "scale_y")


def since_text(text: str) -> str:
    """``--since`` as the store's times are written (UTC ``YYYY-MM-DDTHH:MM:SSZ``); a date is its midnight UTC."""
    try:
        t = datetime.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise UsageError(f"--since {text}: not a date or time (such as 2026-03-01 or 2026-03-01T08:00:00Z)") from None
    if t.tzinfo is None:
        t = t.replace(tzinfo=datetime.UTC)
    return t.astimezone(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _as_array(column) -> np.ndarray:
    """Floats, NaN for None (a part without the figure)."""
    try:
        return np.array(column, dtype=np.float64)  # (no None: the fast way)
    except TypeError:
        return np.fromiter((np.nan if v is None else v for v in column), dtype=np.float64, count=len(column))


def _fetch(conn, query) -> list[tuple]:
    """The query's rows as plain tuples, through the driver's own cursor.

    (SQLAlchemy's rows cost 1 s of 2 over 100,000 parts; the query is compiled by the
    connection's dialect, its values inline: the same SQL on SQLite and PostgreSQL.)
    """
    sql = str(query.compile(dialect=conn.dialect, compile_kwargs={"literal_binds": True}))
    cursor = conn.connection.cursor()
    try:
        cursor.execute(sql)
        return cursor.fetchall()
    finally:
        cursor.close()


def design_groups(conn, design: str | None, filters: bool = True) -> dict[str, dict]:
    """The validations per design (its design.json's sha256, else ``job NAME``), in recording order.

    ``design``: a job name or the start (6 characters at least) of a design's sha256; one line
    when no record matches. ``filters``: read each part's station and time (for ``--station``
    and ``--since``; over 100,000 parts they cost a fifth of the read).

    Returns
    -------
    dict
        Per design, its columns (``part_id``, ``station``, ``recorded_at``, each of
        :data:`PART_FIGURES`: tuples in recording order) and ``tolerance_mm``, ``max_delta_e``
        (the last part's: what production is judged by now).
    """
    v = validations.c
    columns = ["design_json_sha256", "job", "part_id", *(name for name, _ in PART_FIGURES)]
    columns += ["station", "recorded_at"] if filters else []
    # one scan in recording order (an index search and its row look-ups took twice as long)
    query = select(*(v[c] for c in columns)).order_by(v.id)
    if design is not None:
        match = v.job == design
        if len(design) >= 6:
            match = match | v.design_json_sha256.startswith(design.lower(), autoescape=True)
        query = query.where(match)
    rows = _fetch(conn, query)
    if design is not None and not rows:
        raise WorkbenchError(f"--design {design}: no part of it is recorded (a job name, or a design's sha256)")
    keys = [sha or f"job {job}" for sha, job, *_ in rows]
    members: dict[str, list[int]] = {}
    if len(set(keys)) == 1:  # (one design: no index lists to build)
        members[keys[0]] = None
    else:
        for k, key in enumerate(keys):
            members.setdefault(key, []).append(k)
    groups = {}
    for name, idx in members.items():
        mine = rows if idx is None else [rows[k] for k in idx]
        group = dict(zip(columns, zip(*mine, strict=True), strict=True))
        if not filters:
            group["station"] = group["recorded_at"] = None
        match = (
            v.design_json_sha256 == name
            if not name.startswith("job ")
            else ((v.job == name[4:]) & v.design_json_sha256.is_(None))
        )
        last = select(v.tolerance_mm, v.max_delta_e).where(match).order_by(v.id.desc()).limit(1)
        group["tolerance_mm"], group["max_delta_e"] = _fetch(conn, last)[0]
        groups[name] = group
    return groups


def part_series(col: dict, baseline: int, station: str | None, since: str | None) -> list[Series]:
    """One design's series, one per figure of :data:`PART_FIGURES` that at least ``baseline`` parts have.

    The limits come from the design's first parts whatever the filters; ``station`` and ``since``
    choose the parts charted. Offsets are judged against ±``tolerance_mm``, the misregistration
    p95 against ``tolerance_mm``, the mean ΔE00 against ``max_delta_e``.
    """
    n = len(col["part_id"])
    shown = np.ones(n, dtype=bool)
    if station is not None:
        shown &= np.fromiter((s == station for s in col["station"]), dtype=bool, count=n)
    if since is not None:
        shown &= np.fromiter((t >= since for t in col["recorded_at"]), dtype=bool, count=n)
    tol_mm, max_de = col["tolerance_mm"], col["max_delta_e"]
    tolerances = {
        "film_offset_x_mm": Tolerance(-tol_mm, tol_mm) if tol_mm else None,
        "film_offset_y_mm": Tolerance(-tol_mm, tol_mm) if tol_mm else None,
        "worst_p95_mm": Tolerance(None, tol_mm) if tol_mm else None,
        "delta_e00_mean": Tolerance(None, max_de) if max_de else None,
    }
    labels = col["part_id"]
    out = []
    for name, kind in PART_FIGURES:
        x = _as_array(col[name])
        keep = np.flatnonzero(np.isfinite(x))
        if len(keep) < baseline:
            continue
        out.append(Series(name, x[keep], labels, shown[keep], tolerances.get(name), keep, kind))
    return out


def calibration_groups(conn, camera: str | None) -> dict[str, list]:
    """The calibration checks per profile name, in recording order; one line when ``camera`` has none."""
    query = select(calibrations).order_by(calibrations.c.id)
    if camera is not None:
        query = query.where(calibrations.c.camera == camera)
    rows = conn.execute(query).all()
    if camera is not None and not rows:
        raise WorkbenchError(f"--camera {camera}: no calibration check of it is recorded")
    groups: dict[str, list] = {}
    for r in rows:
        groups.setdefault(r.camera, []).append(r)
    return groups


def calibration_series(rows: list, baseline: int, station: str | None, since: str | None) -> list[Series]:
    """One profile's series: fx, fy, cx, cy (a camera) or scale_x, scale_y (a printer), each against the
    stored profile's value and the lab's tolerance (``--focal-tolerance-pct``, ``--pp-tolerance-px``,
    ``--tolerance-pct`` of the last check)."""
    last = rows[-1]
    shown = np.array(
        [(station is None or r.station == station) and (since is None or r.recorded_at >= since) for r in rows]
    )
    labels = [f"{r.recorded_at} #{r.id}" for r in rows]

    def band(centre, half):
        return Tolerance(centre - half, centre + half) if centre is not None and half is not None else None

    pct = last.focal_tolerance_pct
    tolerances = {
        "fx": band(last.profile_fx, pct and last.profile_fx and pct / 100 * last.profile_fx),
        "fy": band(last.profile_fy, pct and last.profile_fy and pct / 100 * last.profile_fy),
        "cx": band(last.profile_cx, last.pp_tolerance_px),
        "cy": band(last.profile_cy, last.pp_tolerance_px),
        "scale_x": band(last.profile_scale_x, last.scale_tolerance_pct and last.scale_tolerance_pct / 100),
        "scale_y": band(last.profile_scale_y, last.scale_tolerance_pct and last.scale_tolerance_pct / 100),
    }
    out = []
    for name in CAMERA_FIGURES + PRINTER_FIGURES:
        x = _as_array([getattr(r, name) for r in rows])
        keep = np.flatnonzero(np.isfinite(x))
        if len(keep) < baseline:
            continue
        out.append(Series(name, x[keep], labels, shown[keep], tolerances[name], keep))
    return out
