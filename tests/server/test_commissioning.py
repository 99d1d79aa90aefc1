"""`/commissioning`: roles, bad input, and an identification on the live demo site driven
through the REST API alone (the viewer's panel drives the same server-side wizard)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest

from tests.server.conftest import Api, start_api

W = "/api/v1/commissioning/wizard"


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    yield from start_api(tmp_path_factory.mktemp("commissioning"), seed=5)


def test_reads_need_a_key_and_actions_the_admin_role(api: Api) -> None:
    c = api.client
    assert c.get(W).status_code == 401
    r = c.get(W, headers=api.h("viewer"))
    assert r.status_code == 200 and r.json()["phase"] == "idle" and not r.json()["can_confirm"]
    assert c.get("/api/v1/commissioning/doubts", headers=api.h("viewer")).json() == []
    assert c.get("/api/v1/commissioning/candidates", headers=api.h("viewer")).json() == []
    body = {"robot": "r1", "landmarks": [1]}
    for role in ("viewer", "operator"):
        r = c.post(W + "/start", json=body, headers=api.h(role))
        assert r.status_code == 403 and "admin" in r.json()["detail"]
    for action in ("confirm", "skip", "switch-anyway", "cancel"):
        assert c.post(f"{W}/{action}", json={}, headers=api.h("operator")).status_code == 403
    r = c.post("/api/v1/commissioning/candidates/discover", headers=api.h("viewer"))
    assert r.status_code == 403


def test_coverage_and_spacing_of_the_live_map(live: Api) -> None:
    c, h = live.client, live.h("viewer")
    r = c.get("/api/v1/commissioning/coverage", params={"robot": "r1", "step_m": 0.5}, headers=h)
    assert r.status_code == 200, r.text
    cov = r.json()
    assert len(cov["counts"]) == len(cov["ys"]) and len(cov["counts"][0]) == len(cov["xs"])
    assert np.diff(cov["xs"]) == pytest.approx(0.5)
    assert max(max(row) for row in cov["counts"]) >= 4  # the demo grid: several in view
    errs = [e for row in cov["error_m"] for e in row if e is not None]
    assert errs and 0.0 < float(np.median(errs)) < 0.05
    r = c.get("/api/v1/commissioning/coverage", params={"robot": "nobody"}, headers=h)
    assert r.status_code == 404
    r = c.get("/api/v1/commissioning/coverage", params={"robot": "r1", "step_m": 0.01}, headers=h)
    assert r.status_code == 422
    flags = c.get("/api/v1/commissioning/spacing", headers=h).json()
    assert all(f["problem"] in ("too_close", "too_far") for f in flags)


def test_bad_input_is_named(api: Api) -> None:
    c, h = api.client, api.h("admin")
    r = c.post(W + "/start", json={"robot": "r1"}, headers=h)
    assert r.status_code == 422 and "name at least one" in r.json()["detail"]
    r = c.post(W + "/start", json={"robot": "r1", "radios": ["12G4"]}, headers=h)
    assert r.status_code == 422 and "radios" in r.json()["detail"]
    r = c.post(W + "/start", json={"robot": "bad name!", "landmarks": [1]}, headers=h)
    assert r.status_code == 422 and "robot" in r.json()["detail"]
    r = c.post(W + "/start", json={"robot": "r1", "landmarks": [-1]}, headers=h)
    assert r.status_code == 422
    r = c.post(W + "/start", json={"robot": "r1", "landmarks": [1]}, headers=h)
    assert r.status_code == 503 and "no radio" in r.json()["detail"]  # no live site here
    r = c.post(W + "/confirm", json={"position": {"x": "a", "y": 0, "z": 2.5}}, headers=h)
    assert r.status_code == 422 and "position.x" in r.json()["detail"]
    r = c.post(W + "/confirm", json={}, headers=h)
    assert r.status_code == 409 and "not running" in r.json()["detail"]


def _ahead(api: Api, robot: str, distance_m: float) -> tuple[float, float]:
    """Where `robot` will truly be once it drove `distance_m` on along its route."""
    sim = api.services.virtual_site
    assert sim is not None
    x, y, _ = sim.true_pose(robot)
    for wx, wy in sim.planned_route(robot):
        leg = float(np.hypot(wx - x, wy - y))
        if leg >= distance_m:
            return x + (wx - x) * distance_m / leg, y + (wy - y) * distance_m / leg
        distance_m -= leg
        x, y = wx, wy
    return x, y


def _passed_under(api: Api, robot: str) -> int:
    """The bright landmark `robot` will pass under while the wizard measures (the nearest to
    where it will be 1.5 m on along its route, 2.5 s): measured while the robot drives,
    whichever test ran before."""
    sim = api.services.virtual_site
    assert sim is not None
    x, y = _ahead(api, robot, 1.5)
    lms = [
        lm
        for lm in sim.world.landmarks.values()
        if lm.reachable and lm.battery.led_brightness() > 0.8
    ]
    best = min(lms, key=lambda lm: np.hypot(lm.p_true[0] - x, lm.p_true[1] - y))
    return best.id


@pytest.mark.slow
def test_identification_on_the_live_site_keeps_the_other_robots_tracking(live: Api) -> None:
    """A landmark moved in the map is measured by r1 while it patrols; r2 and r3 stay in
    landmark mode on >= 95 % of their frames meanwhile; a far-off map position is flagged and
    Confirm refuses it without accept_far; the confirmed position is the true one."""
    c, h = live.client, live.h("admin")
    sub = live.services.robots.subscribe_poses(maxsize=100_000)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # every robot tracking first
        if all(live.services.robots.mode(n) == "landmark" for n in live.services.robots.names()):
            break
        time.sleep(0.2)
    sim = live.services.virtual_site
    assert sim is not None
    used = live.services.robots.latest("r1")
    deadline = time.monotonic() + 30.0  # r1 may be between landmarks (dead reckoning) now
    while (used is None or not used.landmark_ids) and time.monotonic() < deadline:
        time.sleep(0.2)
        used = live.services.robots.latest("r1")
    assert used is not None and used.landmark_ids
    lid = _passed_under(live, "r1")
    truth = next(lm.p_true for lm in sim.world.landmarks.values() if lm.id == lid)
    lm = live.services.map.get(lid)
    moved = {"x": lm.x + 3.0, "y": lm.y + 3.0, "z": lm.z}  # the map says 4.2 m away
    assert c.patch(f"/api/v1/landmarks/{lid}", json=moved, headers=h).status_code == 200
    sub.drain()
    r = c.post(W + "/start", json={"robot": "r1", "landmarks": [lid]}, headers=h)
    assert r.status_code == 200, r.text
    again = c.post(W + "/start", json={"robot": "r1", "landmarks": [lid]}, headers=h)
    assert again.status_code == 409
    st = live.wait_for(W, lambda s: s["measurement"] is not None, 40)
    poses = sub.drain()
    deadline = time.monotonic() + 15.0  # it goes on measuring until confirmed: enough frames
    while (
        time.monotonic() < deadline
        and min(sum(p.robot == robot for p in poses) for robot in ("r2", "r3")) <= 60
    ):
        time.sleep(0.2)
        poses += sub.drain()
    st = c.get(W, headers=h).json()
    m = st["measurement"]
    assert m["far"] and st["needs_accept_far"] and not st["can_confirm"], st
    np.testing.assert_allclose([m["x"], m["y"]], truth[:2], atol=0.05)
    r = c.post(W + "/confirm", json={}, headers=h)
    assert r.status_code == 422 and "far from the map" in r.json()["detail"]
    assert live.services.map.get(lid).x == pytest.approx(moved["x"])  # nothing saved
    for robot in ("r2", "r3"):
        modes = [p.mode for p in poses if p.robot == robot]
        share = modes.count("landmark") / len(modes)
        assert len(modes) > 60 and share >= 0.95, (robot, share, len(modes))
    r = c.post(W + "/confirm", json={"accept_far": True}, headers=h)
    assert r.status_code == 200 and r.json()["phase"] == "done", r.text
    saved = live.services.map.get(lid)
    assert np.hypot(saved.x - truth[0], saved.y - truth[1]) < 0.05
    sub.close()


@pytest.mark.slow
def test_a_radio_deleted_from_the_map_is_found_measured_and_saved_back(live: Api) -> None:
    """Discovery offers the radio (not in the map any more); the wizard lights it alone
    (every landmark stays lit) and the robot's frames place it; confirmed, it is a landmark
    again, with its address, where the simulator has it."""
    c, h = live.client, live.h("admin")
    sim = live.services.virtual_site
    assert sim is not None
    used = live.services.robots.latest("r1")
    deadline = time.monotonic() + 30.0  # r1 may be between landmarks (dead reckoning) now
    while (used is None or not used.landmark_ids) and time.monotonic() < deadline:
        time.sleep(0.2)
        used = live.services.robots.latest("r1")
    assert used is not None and used.landmark_ids
    lid = _passed_under(live, "r1")
    address = live.services.map.get(lid).radio
    assert address is not None
    truth = next(lm.p_true for lm in sim.world.landmarks.values() if lm.id == lid)
    assert c.delete(f"/api/v1/landmarks/{lid}", headers=h).status_code == 204
    r = c.post("/api/v1/commissioning/candidates/discover", headers=live.h("operator"))
    assert r.status_code == 200, r.text
    new = [x for x in r.json() if x["radio"] == address]
    assert len(new) == 1 and "new radio" in new[0]["reason"], r.json()
    r = c.post(W + "/start", json={"robot": "r1", "radios": [address]}, headers=h)
    assert r.status_code == 200, r.text
    st = live.wait_for(W, lambda s: s["can_confirm"] or s["needs_accept_far"], 40)
    assert st["can_confirm"], st  # inside the mapped area: plausible
    m = st["measurement"]
    np.testing.assert_allclose([m["x"], m["y"]], truth[:2], atol=0.05)
    r = c.post(W + "/confirm", json={}, headers=h)
    assert r.status_code == 200 and r.json()["phase"] == "done", r.text
    saved = live.services.map.get(new[0]["landmark_id"])
    assert saved.radio == address
    assert np.hypot(saved.x - truth[0], saved.y - truth[1]) < 0.05
