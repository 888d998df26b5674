"""Where the store is (``--store URL``, ``WORKBENCH_STORE``) and its connections: one-line errors, no traceback."""

from __future__ import annotations

import os
import stat
from contextlib import contextmanager
from pathlib import Path

from workbench.errors import UsageError, WorkbenchError

ENVIRONMENT = "WORKBENCH_STORE"
# SQLite: how long a writer waits for another's transaction before giving up (two stations at once)
BUSY_TIMEOUT_S = 60.0
# PostgreSQL: how long a connection may take before the server counts as unreachable (a host that
# drops packets would otherwise hold the command for minutes; one that refuses fails at once)
CONNECT_TIMEOUT_S = 10
# PostgreSQL: the transaction-scoped advisory lock that serialises schema migrations (any number)
MIGRATION_LOCK = 0x5742_5354  # "WBST"
# the driver a URL without one gets: psycopg 3 (a dependency), not SQLAlchemy's default psycopg2
POSTGRES_DRIVER = "postgresql+psycopg"


def store_text(given: str | None, environ=os.environ) -> str | None:
    """The store as given (``--store``), else ``WORKBENCH_STORE``, else None: no store."""
    if given is not None:
        return given
    return environ.get(ENVIRONMENT) or None


def store_url(text: str, option: str = "--store"):
    """A SQLAlchemy URL from a URL or a plain path (a SQLite file); a :class:`UsageError` naming ``option``."""
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError, NoSuchModuleError

    if not text.strip():
        raise UsageError(f"{option}: an empty store; give a path or a URL such as sqlite:///results.db")
    if "://" not in text:
        try:
            path = Path(text).expanduser()
        except RuntimeError as exc:  # ``~name/...`` for a user this machine does not know
            raise UsageError(f"{option} {text}: {exc}") from None
        return make_url("sqlite://").set(database=str(path.absolute()))
    try:
        url = make_url(text)
        if url.drivername in ("postgresql", "postgres"):
            url = url.set(drivername=POSTGRES_DRIVER)
        url.get_dialect()
    except NoSuchModuleError:  # (an ArgumentError: first)
        raise UsageError(f"{option} {text}: no database driver for {text.split(':', 1)[0]!r}") from None
    except (ArgumentError, ValueError):
        raise UsageError(f"{option} {text}: not a database URL (a path, or one such as sqlite:///results.db)") from None
    if url.get_backend_name() == "sqlite" and url.database in (None, "", ":memory:"):
        raise UsageError(f"{option} {text}: an in-memory SQLite store keeps nothing; give a file")
    return url


def shown(url) -> str:
    """The URL as messages show it (no password); a file name's bytes that are not UTF-8 as ``\\xfc``."""
    try:
        return url.render_as_string(hide_password=True)
    except UnicodeEncodeError:  # (a name the system gave as bytes: its surrogates cannot be quoted)
        name = url.database.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
        return url.set(database=name).render_as_string(hide_password=True)


def store_file(url) -> Path | None:
    """The SQLite file a URL names (an input no output may replace), None for a server's store."""
    return Path(url.database) if url.get_backend_name() == "sqlite" else None


def _not_a_store(path: Path) -> str | None:
    """Why an existing ``path`` cannot be a store (a folder, a device, a pipe, a name the system refuses),
    None for a regular file or nothing there. SQLite would open a device or a pipe as a file: it is
    never opened."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return None
    except OSError as exc:  # a name too long, a loop of links, a folder that cannot be searched
        return f"{path}: {exc.strerror or exc}"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return f"{path} is a folder, not a store"
    kinds = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe"))
    kind = next((name for test, name in kinds if test(mode)), "not a regular file")
    return f"{path} is {kind}, not a store"


def engine_for(url, *, create: bool, option: str = "--store"):
    """An engine on the store; ``create``: a SQLite file that does not exist yet may be made.

    SQLite: each transaction starts with ``BEGIN IMMEDIATE`` (it takes the write lock at once, so
    two writers queue instead of failing on a lock upgrade) and waits up to :data:`BUSY_TIMEOUT_S`
    for another's.
    """
    from sqlalchemy import create_engine, event
    from sqlalchemy.pool import NullPool

    path = store_file(url)
    if path is not None:
        if (why := _not_a_store(path)) is not None:
            raise WorkbenchError(f"{option} {shown(url)}: {why}")
        if not path.exists():
            if not create:
                raise WorkbenchError(f"{option} {shown(url)}: no store at {path}")
            if not path.parent.is_dir():
                raise WorkbenchError(f"{option} {shown(url)}: no folder {path.parent}")
        engine = create_engine(url, poolclass=NullPool, connect_args={"timeout": BUSY_TIMEOUT_S})

        @event.listens_for(engine, "connect")
        def _autocommit_driver(dbapi_connection, _record):
            dbapi_connection.isolation_level = None  # transactions are begun below, not by the driver

        @event.listens_for(engine, "begin")
        def _begin_immediate(conn):
            conn.exec_driver_sql("BEGIN IMMEDIATE")

        return engine
    connect_args = {"connect_timeout": CONNECT_TIMEOUT_S} if url.get_backend_name() == "postgresql" else {}
    try:
        return create_engine(url, poolclass=NullPool, connect_args=connect_args)
    except ImportError as exc:  # the dialect's driver (psycopg, ...) is not installed
        raise WorkbenchError(
            f"{option} {shown(url)}: its database driver is not installed ({exc.name or exc})"
        ) from None


@contextmanager
def transaction(engine, url, *, migrate: bool, option: str = "--store"):
    """A connection in one transaction, the schema checked (and with ``migrate``, brought up to date).

    Everything in the block is committed together or not at all. A store whose schema is newer
    than this workbench's, or that cannot be reached, is one line.
    """
    from sqlalchemy import text
    from sqlalchemy.exc import DBAPIError, SQLAlchemyError

    from workbench.store.schema import LATEST, stored_version
    from workbench.store.schema import migrate as apply_steps

    try:
        with engine.begin() as conn:
            version = stored_version(conn)
            if version > LATEST:
                raise WorkbenchError(
                    f"{option} {shown(url)}: a store of schema version {version}, newer than this workbench's "
                    f"({LATEST}); update the workbench"
                )
            if version == 0 and not migrate:
                raise WorkbenchError(f"{option} {shown(url)}: not a workbench store (schema version {version})")
            if version < LATEST:  # (a store an older workbench made is brought up to date by any command)
                if conn.dialect.name == "postgresql":
                    # two first records at once would both create the tables: the second waits for the
                    # first's commit here, then finds them (each statement sees what is committed)
                    conn.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": MIGRATION_LOCK})
                apply_steps(conn)
            yield conn
    except DBAPIError as exc:
        raise WorkbenchError(f"{option} {shown(url)}: {_first_line(exc.orig)}") from None
    except SQLAlchemyError as exc:
        raise WorkbenchError(f"{option} {shown(url)}: {_first_line(exc)}") from None
    except UnicodeDecodeError:  # SQLite hands back a text that is not UTF-8: a damaged file
        raise WorkbenchError(f"{option} {shown(url)}: a text in the store is not UTF-8 (a damaged store)") from None
    except engine.dialect.loaded_dbapi.Error as exc:  # the driver's own, from a query run on its cursor
        raise WorkbenchError(f"{option} {shown(url)}: {_first_line(exc)}") from None


def _first_line(exc) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


def check_store(url, option: str = "--store") -> None:
    """Before a validation's work: the store can be written (a SQLite file's folder exists; a store that
    exists is reachable and not newer than this workbench). Nothing is created."""
    path = store_file(url)
    engine = engine_for(url, create=True, option=option)
    if path is not None and not path.exists():
        if not os.access(path.parent, os.W_OK):
            raise WorkbenchError(f"{option} {shown(url)}: the folder {path.parent} is not writable")
        return
    from sqlalchemy.exc import DBAPIError

    try:
        with engine.connect() as conn:
            from workbench.store.schema import LATEST, stored_version

            version = stored_version(conn)
            if version > LATEST:
                raise WorkbenchError(
                    f"{option} {shown(url)}: a store of schema version {version}, newer than this workbench's "
                    f"({LATEST}); update the workbench"
                )
    except DBAPIError as exc:
        raise WorkbenchError(f"{option} {shown(url)}: {_first_line(exc.orig)}") from None
    finally:
        engine.dispose()
