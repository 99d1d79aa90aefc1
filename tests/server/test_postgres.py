"""The CRUD, map import/export, auth and migration tests again, on a real PostgreSQL server.

A throwaway cluster (`pg_cluster.PgCluster`: Debian's initdb/pg_ctl, unix socket in a
temporary folder) is started once for this module, and every test gets a fresh database by
overriding the `db_url` fixture the imported tests use. Skipped, saying why, when the
PostgreSQL server binaries are not installed (scripts/test.sh installs them as root).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import pytest
from sqlalchemy import inspect, text

from store.db import make_engine, migrate
from tests.server.pg_cluster import PgCluster, why_unavailable

_why = why_unavailable()
if _why is not None:
    pytest.skip(_why, allow_module_level=True)

# the same test functions, collected again here with this module's `db_url`
from tests.server.test_auth import (  # noqa: E402
    test_admin_api_and_cli_show_last_use,
    test_revoked_key_is_refused,
)
from tests.server.test_landmarks import *  # noqa: E402, F403
from tests.server.test_map import *  # noqa: E402, F403
from tests.server.test_zones_history import (  # noqa: E402
    test_a_week_of_history_is_thinned_and_counted_in_the_database,
)
from tests.store.test_migrations import test_upgrade_from_first_schema_keeps_data  # noqa: E402

__all__ = [
    "test_a_week_of_history_is_thinned_and_counted_in_the_database",
    "test_admin_api_and_cli_show_last_use",
    "test_revoked_key_is_refused",
    "test_upgrade_from_first_schema_keeps_data",
]
_names = (f"irloc_test_{i}" for i in itertools.count())


EMPTY_DB_TESTS = {"test_upgrade_from_first_schema_keeps_data"}
"""Tests that need an empty database (the others get a copy of a migrated one: faster)."""


@pytest.fixture(scope="module")
def cluster() -> Iterator[PgCluster]:
    c = PgCluster()
    c.start()
    engine = make_engine(c.create_db("irloc_migrated"))
    migrate(engine)
    engine.dispose()
    yield c
    c.stop()


@pytest.fixture
def db_url(cluster: PgCluster, request: pytest.FixtureRequest) -> Iterator[str]:
    """A fresh PostgreSQL database for one test: migrated, or empty for a migration test."""
    name = next(_names)
    empty = request.node.originalname in EMPTY_DB_TESTS
    yield cluster.create_db(name, "template0" if empty else "irloc_migrated")
    cluster.drop_db(name)


def test_postgres_gets_no_sqlite_pragmas_and_runs_in_utc(db_url: str) -> None:
    engine = make_engine(db_url)
    migrate(engine)
    assert engine.dialect.name == "postgresql"
    with engine.connect() as conn:
        assert conn.execute(text("SHOW timezone")).scalar() == "UTC"
    tables = set(inspect(engine).get_table_names())
    assert {"landmarks", "robots", "api_keys", "audit_log", "alembic_version"} <= tables
    engine.dispose()
