"""A single-floor database made by the code before floors existed opens unchanged: its map
becomes floor "0", version 1, and its old edits can still be undone.

`tests/data/floors/single_floor_0004.db` was written by the code of main at c7935bb
(schema 0004): three landmarks imported by `key:1`, then landmark 101 moved; robot r1.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from alembic import command
from sqlalchemy import Connection, text

from store import MapRepository, RobotStore
from store.db import alembic_config, make_engine, migrate
from store.floors import FloorStore, map_hash
from store.map_versions import MapVersions

FIXTURE = Path(__file__).parents[1] / "data" / "floors" / "single_floor_0004.db"


def _seed_0004_landmark(conn: Connection) -> None:
    """Landmark 7 at (1.5, -2.0, 2.5) as a schema-0004 database holds it (no floor)."""
    conn.execute(
        text(
            "INSERT INTO landmarks (id, x, y, z, radio, locked, note, created_at, "
            "updated_at) VALUES (7, 1.5, -2.0, 2.5, NULL, :no, '', '2025-01-02 03:04:05', "
            "'2025-01-02 03:04:05')"
        ),
        {"no": False},
    )


def test_a_single_floor_database_opens_as_floor_0(tmp_path: Path) -> None:
    db = tmp_path / "irloc.db"
    shutil.copy(FIXTURE, db)  # a copy: the fixture stays as today's code wrote it
    engine = make_engine(f"sqlite:///{db}")
    with engine.connect() as conn:
        assert conn.execute(text("SELECT version_num FROM alembic_version")).scalar() == "0004"
    migrate(engine)
    floors = FloorStore(engine)
    assert [(f.id, f.name, f.level, f.height) for f in floors.list()] == [("0", "Floor 0", 0, 0.0)]
    repo = MapRepository(engine)
    lms = repo.list()
    assert [(lm.id, lm.x, lm.y, lm.z, lm.radio, lm.locked, lm.note, lm.floor) for lm in lms] == [
        (100, 0.0, 0.0, 2.5, "0013A20041000064", False, "", "0"),
        (101, 1.25, 0.0, 2.5, "0013A20041000065", True, "", "0"),
        (102, 0.0, 1.2, 2.48, None, False, "by the door", "0"),
    ]
    versions = MapVersions(engine, repo, floors)
    first = versions.get("0")
    assert (first.version, first.action) == (1, "first")
    assert first.hash == map_hash([lm.model_dump(mode="json") for lm in lms])
    assert RobotStore(engine).get("r1").wheel_base == 0.4
    # an edit made before the migration is still its author's to undo (records name no floor)
    step = repo.history.undo("key:1")
    assert step.title == "undo move of landmark 101" and repo.get(101).x == 1.2
    assert versions.get("0").version == 2 and versions.get("0").action == "undo"
    # opening it again changes nothing
    versions.close()
    migrate(engine)
    again = MapVersions(engine, MapRepository(engine), floors)
    assert again.current("0") == (2, versions.get("0").hash)
    again.close()
    engine.dispose()


def test_0005_upgrades_a_0004_database_with_its_landmarks_and_downgrades(db_url: str) -> None:
    engine = make_engine(db_url)
    migrate(engine, "0004")
    with engine.begin() as conn:
        _seed_0004_landmark(conn)
    migrate(engine, "0005")
    with engine.connect() as conn:  # (the models are the head's: read the row as 0005 left it)
        assert conn.execute(text("SELECT floor FROM landmarks WHERE id = 7")).scalar() == "0"
    migrate(engine)
    assert MapRepository(engine).get(7).floor == "0"
    command.downgrade(alembic_config(engine), "0004")
    with engine.connect() as conn:
        assert conn.execute(text("SELECT x FROM landmarks WHERE id = 7")).scalar() == 1.5
    engine.dispose()


def test_0005_keeps_battery_readings(db_url: str) -> None:
    """Rebuilding the landmarks table would cascade-delete them: 0005 adds its column in place."""
    engine = make_engine(db_url)
    migrate(engine, "0004")
    with engine.begin() as conn:
        _seed_0004_landmark(conn)
        conn.execute(
            text(
                "INSERT INTO battery_readings (landmark_id, t, supply_mv) "
                "VALUES (7, '2025-01-02 03:04:05', 2950)"
            )
        )
    migrate(engine)
    with engine.connect() as conn:
        assert conn.execute(text("SELECT supply_mv FROM battery_readings")).scalar() == 2950
    engine.dispose()
