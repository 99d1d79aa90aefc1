"""Zones (enter, exit, dwell events) and the pose history (bounded rate, time ranges, a
coverage heatmap): the keeper on synthetic poses, then the API on the live demo site."""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from live.poses import PoseUpdate
from live.zones_history import HistoryConfig, ZonesAndHistory, coverage_grid
from store.db import make_engine, migrate
from store.zones import PoseHistory, ZoneStore
from tests.server.conftest import Api, start_api


def _pose(robot: str, x: float, y: float, wall_s: float, mode: str = "landmark") -> PoseUpdate:
    return PoseUpdate(robot, int(wall_s * 1e9), mode, x, y, 0.0, np.diag([1e-4, 1e-4, 1e-4]),
                      computed_wall_ns=int(wall_s * 1e9))  # type: ignore[arg-type]  # fmt: skip


def test_enter_dwell_exit_and_one_kept_pose_a_second(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine)
    zones, history = ZoneStore(engine), PoseHistory(engine)
    events: list[tuple[str, dict[str, Any]]] = []
    keeper = ZonesAndHistory(None, zones, history, lambda kind, msg, **kw: events.append(
        (kind, kw)), HistoryConfig(keep_every_s=1.0))  # fmt: skip
    zones.add_listener(keeper._on_zones)
    dock = zones.create("dock", [(0, 0), (2, 0), (2, 2), (0, 2)], dwell_s=5.0)
    t0 = 1_800_000_000.0
    # r1 drives along y = 1 from x = -1 to x = 4 at 0.5 m/s, 10 poses a second
    batch = [_pose("r1", -1 + 0.05 * k, 1.0, t0 + 0.1 * k) for k in range(101)]
    batch.insert(50, _pose("r1", 99.0, 99.0, t0 + 5.0, mode="identifying"))  # no pose: ignored
    assert keeper.take(batch) == 11  # one a second of 10 s
    kinds = [k for k, _ in events]
    assert kinds == ["zone_enter", "zone_exit"], kinds  # 4 s inside: no dwell (5 s)
    zones.create("bay", [(2.5, 0), (10, 0), (10, 2), (2.5, 2)], dwell_s=0.5)
    keeper.take([_pose("r1", 3.0 + 0.05 * k, 1.0, t0 + 10.1 + 0.1 * k) for k in range(10)])
    assert [k for k, _ in events[2:]] == ["zone_enter", "zone_dwell"]
    events[2:] = []
    enter, leave = (kw for _, kw in events)
    assert enter["robot"] == "r1" and enter["data"]["zone_id"] == dock.id
    assert leave["data"]["spent_s"] == pytest.approx(4.0, abs=0.15)  # x 0..2 at 0.5 m/s
    kept = history.query(robot="r1")
    kept = [p for p in kept if p.t_ns <= int((t0 + 10.0) * 1e9)]
    assert len(kept) == 11 and all(p.mode == "landmark" for p in kept)
    since = datetime.fromtimestamp(t0 + 2.5, UTC)
    assert [round(p.x, 2) for p in history.query(since=since, until=since + timedelta(seconds=3))] \
        == [0.5, 1.0, 1.5]  # fmt: skip
    (x0, y0), counts = coverage_grid(np.array([[p.x, p.y] for p in kept]), 1.0)
    assert (x0, y0) == (-1.0, 1.0) and counts.sum() == 11 and counts.shape == (1, 6)
    with pytest.raises(ValueError, match="at least 3"):
        zones.create("line", [(0, 0), (1, 1)])
    with pytest.raises(ValueError, match="no area"):
        zones.create("flat", [(0, 0), (1, 1), (2, 2)])
    engine.dispose()


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    yield from start_api(tmp_path_factory.mktemp("zones"), seed=4)


def test_zones_and_history_through_the_api(live: Api) -> None:
    c, admin, viewer = live.client, live.h("admin"), live.h("viewer")
    everywhere = {"name": "hall", "polygon": [[-50, -50], [50, -50], [50, 50], [-50, 50]]}
    assert c.post("/api/v1/zones", json=everywhere, headers=viewer).status_code == 403
    r = c.post("/api/v1/zones", json=everywhere, headers=admin)
    assert r.status_code == 201, r.text
    zone = r.json()
    assert c.post("/api/v1/zones", json=everywhere, headers=admin).status_code == 409
    bad = c.post("/api/v1/zones", json={"name": "x", "polygon": [[0, 0], [1, 1]]}, headers=admin)
    assert bad.status_code == 422 and "polygon" in bad.text
    start = datetime.now(UTC)
    deadline = time.monotonic() + 90
    entered: list[dict[str, Any]] = []
    while time.monotonic() < deadline and not entered:
        entered = c.get("/api/v1/events?kind=zone_enter", headers=viewer).json()
        time.sleep(0.5)
    assert entered and entered[0]["data"]["zone"] == "hall", entered
    time.sleep(3.0)
    poses = c.get("/api/v1/history/poses", params={"since": start.isoformat()},
                  headers=viewer).json()  # fmt: skip
    robots = {p["robot"] for p in poses}
    assert robots and len(poses) >= 2
    for name in robots:  # about one a second each
        ts = [datetime.fromisoformat(p["t"]) for p in poses if p["robot"] == name]
        gaps = [(b - a).total_seconds() for a, b in itertools.pairwise(ts)]
        assert all(g >= 0.99 for g in gaps), gaps
    cov = c.get("/api/v1/history/coverage?cell_m=1", headers=viewer).json()
    assert cov["poses"] > 0 and sum(map(sum, cov["counts"])) == cov["poses"]
    r = c.get("/api/v1/history/poses", params={"since": "2030-01-02T00:00:00Z",
              "until": "2030-01-01T00:00:00Z"}, headers=viewer)  # fmt: skip
    assert r.status_code == 422 and "until" in r.json()["detail"]
    thin = c.get("/api/v1/history/poses", params={"max_points": 3}, headers=viewer).json()
    assert 2 <= len(thin) <= 3 and {p["floor"] for p in thin} == {"0"}
    assert c.get("/api/v1/history/poses", params={"floor": "7"}, headers=viewer).json() == []
    r = c.post("/api/v1/zones", json={**everywhere, "name": "up", "floor": "7"}, headers=admin)
    assert r.status_code == 404 and "'7'" in r.text  # no such floor: nothing stored
    r = c.patch(f"/api/v1/zones/{zone['id']}", json={"name": "hall 2", "dwell_s": 30},
                headers=admin)  # fmt: skip
    assert r.status_code == 200 and r.json()["name"] == "hall 2" and r.json()["dwell_s"] == 30
    r = c.patch(f"/api/v1/zones/{zone['id']}", json={"dwell_s": None}, headers=admin)
    assert r.json()["dwell_s"] is None and r.json()["name"] == "hall 2"
    assert c.patch(f"/api/v1/zones/{zone['id']}", json={"name": "x"},
                   headers=viewer).status_code == 403  # fmt: skip
    assert c.delete(f"/api/v1/zones/{zone['id']}", headers=admin).status_code == 204
    assert c.get(f"/api/v1/zones/{zone['id']}", headers=viewer).status_code == 404


def test_a_week_of_history_is_thinned_and_counted_in_the_database(db_url: str) -> None:
    """(Run again on PostgreSQL by tests/server/test_postgres.py: the window function and
    floor() of the two reads.)"""
    from store.models import PoseRecord

    engine = make_engine(db_url)
    migrate(engine)
    history = PoseHistory(engine)
    t0 = datetime(2026, 12, 1, tzinfo=UTC)
    rng = np.random.default_rng(3)
    n = 4_000  # a pose every 150 s for a week
    xy = rng.uniform(-4.0, 6.0, size=(n, 2))
    history.add([PoseRecord(robot="r1", t=t0 + timedelta(seconds=150 * k), t_ns=k, x=xy[k, 0],
                            y=xy[k, 1], theta=0.0, sigma_m=0.01, mode="landmark")
                 for k in range(n)])  # fmt: skip
    history.add([PoseRecord(robot="r2", t=t0, t_ns=0, x=0.0, y=0.0, theta=0.0, mode="landmark")])
    poses, total = history.thinned(robot="r1", max_points=500)
    assert total == n and len(poses) == 500  # every 8th
    assert [p.t_ns for p in poses[:3]] == [0, 8, 16] and poses[-1].t_ns == n - 8
    day2 = t0 + timedelta(days=1)
    poses, total = history.thinned(robot="r1", since=day2, until=day2 + timedelta(hours=1),
                                   max_points=1000)  # fmt: skip
    assert total == 24 and len(poses) == 24  # an hour: every pose
    cells, counted = history.cell_counts(1.0, robot="r1")
    assert counted == n
    (x0, y0), dense = coverage_grid(xy, 1.0)
    from live.zones_history import grid_from_cells

    (gx0, gy0), grid = grid_from_cells(cells, 1.0)
    assert (gx0, gy0) == (x0, y0) == (-4.0, -4.0)
    np.testing.assert_array_equal(grid, dense)
    assert history.cell_counts(1.0)[1] == n + 1
    with pytest.raises(ValueError, match="max_points"):
        history.thinned(max_points=1)
    engine.dispose()


def test_a_zone_is_renamed_reshaped_and_its_dwell_dropped(tmp_path: Path) -> None:
    from store.errors import ConflictError, NotFoundError

    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine)
    zones = ZoneStore(engine)
    heard: list[int] = []
    zones.add_listener(lambda zs: heard.append(len(zs)))
    dock = zones.create("dock", [(0, 0), (2, 0), (2, 2)], dwell_s=5.0)
    zones.create("bay", [(3, 0), (4, 0), (4, 1)])
    assert dock.id is not None
    z = zones.update(dock.id, name="dock A", polygon=[(0, 0), (3, 0), (3, 3), (0, 3)])
    assert (z.name, len(z.polygon), z.dwell_s) == ("dock A", 4, 5.0)
    assert zones.update(dock.id, clear_dwell=True).dwell_s is None
    with pytest.raises(ConflictError, match="'bay'"):
        zones.update(dock.id, name="bay")
    with pytest.raises(ValueError, match="no area"):
        zones.update(dock.id, polygon=[(0, 0), (1, 1), (2, 2)])
    with pytest.raises(NotFoundError):
        zones.update(999, name="x")
    assert zones.get(dock.id).name == "dock A" and heard == [1, 2, 2, 2]
    engine.dispose()


def test_zones_and_history_keep_to_the_robots_floor(tmp_path: Path) -> None:
    """A robot on floor 1 at the x, y of a floor-0 zone is not in it (each floor has its own
    map frame); a zone of no floor is on every floor; kept poses carry their floor and are
    read back per floor. Poses kept before the floor column (migration 0009) are floor 0's."""
    from sqlalchemy import text

    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine, "0008")
    with engine.begin() as conn:
        row = "VALUES ('r0', '2026-12-01 00:00:00', 0, 1, 1, 0, 'landmark')"
        conn.execute(text(f"INSERT INTO pose_history (robot, t, t_ns, x, y, theta, mode) {row}"))
    migrate(engine)
    zones, history = ZoneStore(engine), PoseHistory(engine)
    assert [(p.robot, p.floor) for p in history.query()] == [("r0", "0")]
    events: list[tuple[str, dict[str, Any]]] = []
    keeper = ZonesAndHistory(None, zones, history, lambda kind, msg, **kw: events.append(
        (kind, kw)), HistoryConfig(keep_every_s=1.0))  # fmt: skip
    zones.add_listener(keeper._on_zones)
    zones.create("hall dock", [(0, 0), (2, 0), (2, 2), (0, 2)], floor="0")
    zones.create("lift", [(0, 0), (2, 0), (2, 2), (0, 2)])  # every floor
    t0 = 1_800_000_000.0
    up = [replace(_pose("r2", 1.0, 1.0, t0 + k), floor="1") for k in range(3)]
    assert keeper.take(up) == 3
    assert [(k, kw["data"]["zone"]) for k, kw in events] == [("zone_enter", "lift")]
    assert [p.floor for p in history.query(robot="r2")] == ["1", "1", "1"]
    assert history.thinned(floor="1", max_points=10)[1] == 3
    assert history.thinned(floor="0", max_points=10)[1] == 1
    assert history.cell_counts(1.0, floor="1") == ([(1, 1, 3)], 3)
    engine.dispose()
