"""The store's backends in the tests: a SQLite file, or a fresh database on a real PostgreSQL server.

The server is the one ``WORKBENCH_TEST_POSTGRES`` names (a SQLAlchemy URL of a database on it whose
user may create databases; ``.ci/postgres start`` starts one and prints it). Without it the
PostgreSQL cases are skipped, except where ``CI`` or ``WORKBENCH_REQUIRE_POSTGRES=1`` is set: there
they fail, so that a CI run can never pass without them.
"""

from __future__ import annotations

import os
import uuid
from dataclasses import dataclass
from pathlib import Path

import pytest
from sqlalchemy import create_engine, func, select, text
from sqlalchemy.engine import make_url
from sqlalchemy.pool import NullPool

SERVER = "WORKBENCH_TEST_POSTGRES"
BACKENDS = ("sqlite", "postgresql")


def postgres_required(environ=os.environ) -> bool:
    """A CI run (``CI`` set) or ``WORKBENCH_REQUIRE_POSTGRES=1``: a missing server fails the tests."""
    return bool(environ.get("CI")) or environ.get("WORKBENCH_REQUIRE_POSTGRES") == "1"


def server_url():
    """The server's URL from :data:`SERVER`; skips the test, or fails it where PostgreSQL is required."""
    given = os.environ.get(SERVER)
    if not given:
        why = f'{SERVER} is not set (eval "$(.ci/postgres start)" starts a server and sets it)'
        if postgres_required():
            pytest.fail(f"PostgreSQL is required here (CI or WORKBENCH_REQUIRE_POSTGRES=1) but {why}")
        pytest.skip(f"no PostgreSQL server: {why}")
    return make_url(given)


@dataclass(frozen=True)
class TestStore:
    """One test's store: ``text`` is what ``--store`` takes, ``url`` the SQLAlchemy URL."""

    __test__ = False  # (not a test class, whatever its name)

    backend: str
    text: str
    url: object

    def engine(self):
        """An engine on the store (no pool: each use its own connection, closed after it)."""
        return create_engine(self.url, poolclass=NullPool)

    def count(self, table) -> int:
        """Rows in ``table`` (a SQLAlchemy Table of the store's schema)."""
        engine = self.engine()
        try:
            with engine.connect() as conn:
                return conn.execute(select(func.count()).select_from(table)).scalar()
        finally:
            engine.dispose()

    def column(self, column) -> list:
        """A column's values, in the order of the table's first column."""
        engine = self.engine()
        try:
            with engine.connect() as conn:
                return [r[0] for r in conn.execute(select(column).order_by(*column.table.primary_key.columns))]
        finally:
            engine.dispose()

    def scalar(self, sql: str):
        """The first value of a plain SQL query."""
        engine = self.engine()
        try:
            with engine.connect() as conn:
                return conn.execute(text(sql)).scalar()
        finally:
            engine.dispose()

    def execute(self, sql: str) -> None:
        """A plain SQL statement, committed."""
        engine = self.engine()
        try:
            with engine.begin() as conn:
                conn.execute(text(sql))
        finally:
            engine.dispose()

    def is_empty(self) -> bool:
        """No table at all (a SQLite file that does not exist, or a database with no table)."""
        if self.backend == "sqlite":
            return not Path(self.url.database).exists()
        return self.scalar("select count(*) from pg_tables where schemaname = current_schema()") == 0


def _admin(server):
    return create_engine(server, poolclass=NullPool, isolation_level="AUTOCOMMIT")


def make_store(backend: str, folder: Path):
    """A new, empty store of ``backend`` (a generator: yields a :class:`TestStore`, then removes it).

    SQLite: ``folder/s.db`` (not created). PostgreSQL: a database of its own on the server, dropped
    after the test (with whatever connections a killed process left).
    """
    if backend == "sqlite":
        path = folder / "s.db"
        yield TestStore("sqlite", str(path), make_url(f"sqlite:///{path}"))
        return
    server = server_url()
    name = f"wb_test_{uuid.uuid4().hex[:16]}"
    admin = _admin(server)
    try:
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
        url = server.set(database=name)
        yield TestStore("postgresql", url.render_as_string(hide_password=False), url)
    finally:
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()
