"""The store's tables and its migrations: numbered steps applied in order, in one transaction.

Not Alembic: Alembic is a developer's tool (an ini file, an ``env.py`` and a folder of
revision scripts) built to generate migrations; here the store is created by an end user's
command on first use, in the same transaction as its first record, and needs only a version
number to apply the missing steps and to refuse a store newer than this workbench. The steps
are SQLAlchemy Core, so the same ones run on SQLite and PostgreSQL.
"""

from __future__ import annotations

import json
from collections.abc import Callable

from sqlalchemy import Column, Float, ForeignKey, Index, Integer, MetaData, String, Table, Text, select, update

metadata = MetaData()

schema_version = Table(
    "schema_version",
    metadata,
    Column("version", Integer, primary_key=True, autoincrement=False),
    Column("description", Text, nullable=False),
)

validations = Table(
    "validations",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("part_id", String(200), nullable=False, index=True),
    Column("lot", String(200), index=True),
    Column("station", String(200), nullable=False),
    Column("operator", String(200), nullable=False),
    Column("recorded_at", String(32), nullable=False),
    Column("software_version", String(50), nullable=False),
    Column("job", String(200)),
    Column("job_sha256", String(64)),
    Column("design_json_sha256", String(64)),
    Column("print_sha256", String(64)),
    Column("verdict", String(20), nullable=False),
    Column("reason", Text),
    Column("photos", Integer, nullable=False),
    Column("photos_scored", Integer),
    Column("photos_pass", Integer, nullable=False),
    Column("photos_fail", Integer, nullable=False),
    Column("photos_invalid", Integer, nullable=False),
    Column("worst_p95_mm", Float),
    Column("defects", Integer, nullable=False),
    Column("largest_defect_mm2", Float),
    Column("coverage_complete", Integer),
    Column("tolerance_mm", Float),
    Column("max_defect_mm2", Float),
    Column("max_delta_e", Float),
    Column("out_dir", Text, nullable=False),
    Column("validation_json", Text, nullable=False),
    # version 2: the part's placement and colour, for the control charts (workbench trend)
    Column("film_offset_x_mm", Float),
    Column("film_offset_y_mm", Float),
    Column("film_rotation_deg", Float),
    Column("delta_e00_mean", Float),
    # version 3: photos whose verdict is INCOMPLETE (a region they cannot tell a defect from light on)
    Column("photos_incomplete", Integer),
    Index("ix_validations_design", "design_json_sha256", "id"),
    Index("ix_validations_job", "job", "id"),
)
# the columns and indexes version 2 added to ``validations``
ADDED_IN_2 = ("film_offset_x_mm", "film_offset_y_mm", "film_rotation_deg", "delta_e00_mean")
INDEXES_IN_2 = ("ix_validations_design", "ix_validations_job")
ADDED_IN_3 = ("photos_incomplete",)

photos = Table(
    "photos",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("validation_id", Integer, ForeignKey("validations.id"), nullable=False, index=True),
    Column("position", Integer, nullable=False),
    Column("photo", Text, nullable=False),
    Column("sha256", String(64)),
    Column("verdict", String(20), nullable=False),
    Column("reason", Text),
    Column("view", String(200)),
    Column("p95_mm", Float),
    Column("median_mm", Float),
    Column("film_offset_x_mm", Float),
    Column("film_offset_y_mm", Float),
    Column("film_rotation_deg", Float),
    Column("ssim", Float),
    Column("coverage", Float),
)

defects = Table(
    "defects",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("validation_id", Integer, ForeignKey("validations.id"), nullable=False, index=True),
    Column("kind", String(50), nullable=False),
    Column("area_mm2", Float, nullable=False),
    Column("centre_x_mm", Float),
    Column("centre_y_mm", Float),
    Column("photos", Text, nullable=False),  # a JSON list of the photos that show it
)

files = Table(
    "files",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("validation_id", Integer, ForeignKey("validations.id"), nullable=False, index=True),
    Column("path", Text, nullable=False),
    Column("sha256", String(64), nullable=False),
    Column("bytes", Integer, nullable=False),
)


calibrations = Table(
    "calibrations",
    metadata,
    Column("id", Integer, primary_key=True),
    Column("kind", String(40), nullable=False),  # camera-profile or printer-profile
    Column("camera", String(200), nullable=False),  # the profile's name (its file's stem)
    Column("profile_sha256", String(64), nullable=False),
    Column("station", String(200), nullable=False),
    Column("operator", String(200), nullable=False),
    Column("recorded_at", String(32), nullable=False),
    Column("software_version", String(50), nullable=False),
    Column("verdict", String(20), nullable=False),  # OK or DRIFT
    Column("reason", Text),
    Column("inputs", Integer, nullable=False),
    Column("fx", Float),
    Column("fy", Float),
    Column("cx", Float),
    Column("cy", Float),
    # the stored profile's values and the lab's tolerances they are charted against
    Column("profile_fx", Float),
    Column("profile_fy", Float),
    Column("profile_cx", Float),
    Column("profile_cy", Float),
    Column("focal_tolerance_pct", Float),
    Column("pp_tolerance_px", Float),
    Column("scale_x", Float),
    Column("scale_y", Float),
    Column("profile_scale_x", Float),
    Column("profile_scale_y", Float),
    Column("scale_tolerance_pct", Float),
    Column("check_json", Text, nullable=False),
    Index("ix_calibrations_camera", "camera", "id"),
)


def _create_version_1(conn) -> None:
    # version 1's validations, as released: without the columns and indexes later versions added
    v1 = MetaData()
    Table(
        "validations",
        v1,
        *(
            Column(c.name, c.type, primary_key=c.primary_key, nullable=c.nullable, index=c.index)
            for c in validations.columns
            if c.name not in ADDED_IN_2 + ADDED_IN_3
        ),
    )
    for table in (photos, defects, files):
        table.to_metadata(v1)
    v1.create_all(conn)


def _create_version_2(conn) -> None:
    from workbench.store.figures import part_figures

    for name in ADDED_IN_2:
        column = validations.c[name]
        conn.exec_driver_sql(f"ALTER TABLE validations ADD COLUMN {name} {column.type.compile(dialect=conn.dialect)}")
    for index in validations.indexes:
        if index.name in INDEXES_IN_2:
            index.create(conn)
    metadata.create_all(conn, tables=[calibrations])
    # the parts recorded before: their figures from the validation.json each record keeps
    rows = conn.execute(select(validations.c.id, validations.c.validation_json)).all()
    for vid, text in rows:
        figures = part_figures(json.loads(text))
        if any(v is not None for v in figures.values()):
            conn.execute(update(validations).where(validations.c.id == vid).values(**figures))


def _create_version_3(conn) -> None:
    for name in ADDED_IN_3:
        column = validations.c[name]
        conn.exec_driver_sql(f"ALTER TABLE validations ADD COLUMN {name} {column.type.compile(dialect=conn.dialect)}")
    # the parts recorded before: their INCOMPLETE photos from the validation.json each record keeps
    rows = conn.execute(select(validations.c.id, validations.c.validation_json)).all()
    for vid, text in rows:
        verdicts = [(e or {}).get("verdict") for e in json.loads(text).get("photos") or [] if isinstance(e, dict)]
        n = verdicts.count("INCOMPLETE")
        conn.execute(update(validations).where(validations.c.id == vid).values(photos_incomplete=n))


# (number, what it does, the step): append a step for every change, never edit one released
MIGRATIONS: list[tuple[int, str, Callable]] = [
    (1, "validations, their photos, defects and files", _create_version_1),
    (2, "the part's film offset, rotation and mean colour difference; calibration checks", _create_version_2),
    (3, "the part's photos whose verdict is INCOMPLETE", _create_version_3),
]
LATEST = MIGRATIONS[-1][0]


def stored_version(conn) -> int:
    """The store's schema version: 0 for an empty database (no version table)."""
    if not conn.dialect.has_table(conn, "schema_version"):
        return 0
    return conn.execute(select(schema_version.c.version).order_by(schema_version.c.version.desc())).scalar() or 0


def migrate(conn) -> int:
    """Apply the missing steps in order, inside the caller's transaction; returns the version reached."""
    version = stored_version(conn)
    if version == 0:
        metadata.create_all(conn, tables=[schema_version])
    for number, description, step in MIGRATIONS:
        if number > version:
            step(conn)
            conn.execute(schema_version.insert().values(version=number, description=description))
            version = number
    return version
