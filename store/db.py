"""The database engine, the session dependency and the schema migrations run at start.

Only `make_engine` knows about dialects: SQLite gets WAL, foreign keys and synchronous=FULL
(an acknowledged commit survives a `kill -9`); PostgreSQL sessions run in UTC (the tables'
timestamps are UTC without a zone). Everything else (models, queries, migrations) is
portable SQL, tested on both (tests/server/test_postgres.py).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine, event
from sqlmodel import Session, create_engine

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
        Path(path).parent.mkdir(parents=True, exist_ok=True)
    engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": 30})

    @event.listens_for(engine, "connect")
    def _sqlite_pragmas(dbapi_conn: Any, _record: Any) -> None:
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA journal_mode=WAL")
        cur.execute("PRAGMA foreign_keys=ON")
        cur.execute("PRAGMA synchronous=FULL")
        cur.close()

    return engine


def alembic_config(engine: Engine) -> Config:
    """An Alembic configuration that migrates `engine` with the scripts shipped here."""
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.attributes["engine"] = engine
    return cfg


def migrate(engine: Engine, revision: str = "head") -> None:
    """Bring the schema to `revision` (idempotent; an older database is upgraded in place)."""
    command.upgrade(alembic_config(engine), revision)


def session_scope(engine: Engine) -> Iterator[Session]:
    """One session per request (the FastAPI dependency wraps this)."""
    with Session(engine, expire_on_commit=False) as session:
        yield session
