"""Zones (enter, exit, dwell events) and the pose history (bounded rate, time ranges, a
coverage heatmap): the keeper on synthetic poses, then the API on the live demo site."""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
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
    assert c.delete(f"/api/v1/zones/{zone['id']}", headers=admin).status_code == 204
    assert c.get(f"/api/v1/zones/{zone['id']}", headers=viewer).status_code == 404
