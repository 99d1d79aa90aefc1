"""A database made by the first schema opens in the current version with nothing lost."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import inspect, text

from server.crud import KeyStore, MapRepository
from server.crud.keys import hash_key
from server.db import make_engine, migrate


def test_upgrade_from_first_schema_keeps_data(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'old.db'}")
    migrate(engine, "0001")
    assert "note" not in [c["name"] for c in inspect(engine).get_columns("landmarks")]
    with engine.begin() as conn:
        conn.execute(
            text(
                "INSERT INTO landmarks (id, x, y, z, radio, locked, created_at, updated_at) "
                "VALUES (7, 1.5, -2.25, 2.5, '0013A20041B2C3D4', 1, "
                "'2025-01-02 03:04:05', '2025-01-02 03:04:05')"
            )
        )
        conn.execute(
            text(
                "INSERT INTO api_keys (name, role, prefix, hash, created_at, revoked) "
                "VALUES ('old', 'operator', 'irloc_abc', :h, '2025-01-02 03:04:05', 0)"
            ),
            {"h": hash_key("irloc_old-key")},
        )
        conn.execute(
            text(
                "INSERT INTO battery_readings (landmark_id, t, supply_mv) "
                "VALUES (7, '2025-01-02 03:04:05', 2950)"
            )
        )
    engine.dispose()

    engine = make_engine(f"sqlite:///{tmp_path / 'old.db'}")
    migrate(engine)
    lm = MapRepository(engine).get(7)
    assert (lm.x, lm.y, lm.z, lm.radio, lm.locked, lm.note) == (
        1.5,
        -2.25,
        2.5,
        "0013A20041B2C3D4",
        True,
        "",
    )
    assert KeyStore(engine).role_of("irloc_old-key") == (1, "operator")
    with engine.connect() as conn:
        assert conn.execute(text("SELECT supply_mv FROM battery_readings")).scalar() == 2950
        assert conn.execute(text("SELECT version_num FROM alembic_version")).scalar() == "0003"


def test_sqlite_pragmas(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'p.db'}")
    with engine.connect() as conn:
        assert conn.execute(text("PRAGMA journal_mode")).scalar() == "wal"
        assert conn.execute(text("PRAGMA foreign_keys")).scalar() == 1
        assert conn.execute(text("PRAGMA synchronous")).scalar() == 2
