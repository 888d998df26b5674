"""The store's tables and its migrations: numbered steps applied in order, in one transaction.

Not Alembic: Alembic is a developer's tool (an ini file, an ``env.py`` and a folder of
revision scripts) built to generate migrations; here the store is created by an end user's
command on first use, in the same transaction as its first record, and needs only a version
number to apply the missing steps and to refuse a store newer than this workbench. The steps
are SQLAlchemy Core, so the same ones run on SQLite and PostgreSQL.
"""

from __future__ import annotations

from collections.abc import Callable

from sqlalchemy import Column, Float, ForeignKey, Integer, MetaData, String, Table, Text, select

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
)

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


def _create_version_1(conn) -> None:
    metadata.create_all(conn, tables=[validations, photos, defects, files])


# (number, what it does, the step): append a step for every change, never edit one released
MIGRATIONS: list[tuple[int, str, Callable]] = [
    (1, "validations, their photos, defects and files", _create_version_1),
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
