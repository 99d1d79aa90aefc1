"""A database made by the first schema opens in the current version with nothing lost."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import inspect, text

from store import KeyStore, MapRepository, RobotStore
from store.db import make_engine, migrate
from store.keys import hash_key


def test_upgrade_from_first_schema_keeps_data(db_url: str) -> None:
    engine = make_engine(db_url)
    migrate(engine, "0001")
    assert "note" not in [c["name"] for c in inspect(engine).get_columns("landmarks")]
    with engine.begin() as conn:
        conn.execute(
            text(
                "INSERT INTO landmarks (id, x, y, z, radio, locked, created_at, updated_at) "
                "VALUES (7, 1.5, -2.25, 2.5, '0013A20041B2C3D4', :yes, "
                "'2025-01-02 03:04:05', '2025-01-02 03:04:05')"
            ),
            {"yes": True},
        )
        conn.execute(
            text(
                "INSERT INTO api_keys (name, role, prefix, hash, created_at, revoked) "
                "VALUES ('old', 'operator', 'irloc_abc', :h, '2025-01-02 03:04:05', :no)"
            ),
            {"h": hash_key("irloc_old-key"), "no": False},
        )
        conn.execute(
            text(
                "INSERT INTO robots (name, source, device, wheel_base, max_speed, camera, "
                "created_at, updated_at) VALUES ('r9', 'camera', '0', 0.42, 1.5, '{}', "
                "'2025-01-02 03:04:05', '2025-01-02 03:04:05')"
            )
        )
        conn.execute(
            text(
                "INSERT INTO battery_readings (landmark_id, t, supply_mv) "
                "VALUES (7, '2025-01-02 03:04:05', 2950)"
            )
        )
        conn.execute(
            text(
                "INSERT INTO audit_log (t, actor, action, landmark_id) "
                "VALUES ('2025-01-02 03:04:05', 'key:1', 'update-undone', 7)"
            )
        )
    engine.dispose()

    engine = make_engine(db_url)
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
    keys = KeyStore(engine)
    assert keys.role_of("irloc_old-key") == (1, "operator")
    keys.close()
    robot = RobotStore(engine).get("r9")
    assert (robot.source, robot.device, robot.wheel_base, robot.max_speed) == (
        "camera",
        "0",
        0.42,
        1.5,
    )
    assert (robot.wheel_port, robot.wheel_baud) == (None, 115200)  # added by 0003
    with engine.connect() as conn:
        assert conn.execute(text("SELECT supply_mv FROM battery_readings")).scalar() == 2950
        # 0004: an edit undone before redo existed is an edit that can no longer be redone
        row = conn.execute(text("SELECT action, undo_state, target_id FROM audit_log")).one()
        assert tuple(row) == ("update", "dropped", None)
        assert conn.execute(text("SELECT version_num FROM alembic_version")).scalar() == "0004"
    engine.dispose()


def test_sqlite_pragmas(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'p.db'}")
    with engine.connect() as conn:
        assert conn.execute(text("PRAGMA journal_mode")).scalar() == "wal"
        assert conn.execute(text("PRAGMA foreign_keys")).scalar() == 1
        assert conn.execute(text("PRAGMA synchronous")).scalar() == 2
