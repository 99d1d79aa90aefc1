"""The database engine, the session dependency and the schema migrations run at start.

Only `make_engine` knows about dialects: SQLite gets WAL, foreign keys and synchronous=FULL
(an acknowledged commit survives a `kill -9`); PostgreSQL sessions run in UTC (the tables'
timestamps are UTC without a zone). Everything else (models, queries, migrations) is
portable SQL, tested on both (tests/server/test_postgres.py).
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine, event
from sqlmodel import create_engine

MIGRATIONS_DIR = Path(__file__).parent / "migrations"


def make_engine(url: str) -> Engine:
    """An engine for `url`; for SQLite: WAL journal, foreign keys on, full sync, and the
    folder of the file created; for PostgreSQL (`postgresql+psycopg://...`): UTC sessions."""
    if url.startswith("postgresql"):
        return create_engine(url, pool_pre_ping=True, connect_args={"options": "-c timezone=UTC"})
    if not url.startswith("sqlite"):
        return create_engine(url, pool_pre_ping=True)
    path = url.split("///", 1)[-1]
    if path and path != ":memory:":
        prepare_sqlite_file(Path(path))
    engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": 30})

    @event.listens_for(engine, "connect")
    def _sqlite_pragmas(dbapi_conn: Any, _record: Any) -> None:
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA journal_mode=WAL")
        cur.execute("PRAGMA foreign_keys=ON")
        cur.execute("PRAGMA synchronous=FULL")
        cur.close()

    return engine


class DatabaseFileError(ValueError):
    """The SQLite file cannot be the site's database (empty, unreadable, not SQLite)."""


SQLITE_MAGIC = b"SQLite format 3\x00"


def prepare_sqlite_file(path: Path) -> None:
    """Make sure `path` can be the site's database: a new file is created readable by this
    user only (0600, its folder 0700); an existing one must be a readable, writable SQLite
    file (an empty one is refused: it would silently start a new site, with a new admin
    key, over what was there) and is made 0600 if others could read it.

    Raises:
        DatabaseFileError: naming the file and what is wrong with it.
    """
    if not path.exists():
        if not path.parent.exists():
            path.parent.mkdir(parents=True, mode=0o700)
        old = os.umask(0o077)
        try:  # created 0600 (its -wal and -shm take the same mode), the header written
            con = sqlite3.connect(path)
            con.execute("PRAGMA journal_mode=WAL")
            con.close()
        finally:
            os.umask(old)
        return
    try:
        with path.open("rb") as f:
            head = f.read(len(SQLITE_MAGIC))
    except OSError as exc:
        raise DatabaseFileError(
            f"database {path}: cannot be read ({exc.strerror}); check its owner and mode"
        ) from None
    if not head:
        raise DatabaseFileError(
            f"database {path}: the file is empty (0 bytes), not a database; irloc will not "
            "start a new site over it. Restore your backup there, or move it away to "
            "start a new site"
        )
    if head != SQLITE_MAGIC:
        raise DatabaseFileError(
            f"database {path}: not an SQLite database (it starts with {head[:8]!r}); restore "
            "your backup there, or move it away to start a new site"
        )
    if not os.access(path, os.W_OK):
        raise DatabaseFileError(f"database {path}: not writable by this user")
    if path.stat().st_mode & 0o077:
        os.chmod(path, 0o600)


def alembic_config(engine: Engine) -> Config:
    """An Alembic configuration that migrates `engine` with the scripts shipped here."""
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.attributes["engine"] = engine
    return cfg


def migrate(engine: Engine, revision: str = "head") -> None:
    """Bring the schema to `revision` (idempotent; an older database is upgraded in place)."""
    command.upgrade(alembic_config(engine), revision)
