"""The API on the live virtual site (`demo` scenario): robots, LEDs, radio, recordings."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from recording.reader import read_recording
from tests.server.conftest import Api, start_api

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    yield from start_api(tmp_path_factory.mktemp("site"))


def _wait(predicate: object, timeout_s: float) -> bool:
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        if predicate():  # type: ignore[operator]
            return True
        time.sleep(0.1)
    return False


def test_demo_site_has_its_robots_and_surveyed_map(site: Api) -> None:
    robots = site.client.get("/api/v1/robots", headers=site.h("viewer")).json()
    assert [r["name"] for r in robots] == ["r1", "r2", "r3"]
    assert all(r["source"] == "sim" for r in robots)
    truth = {int(r["id"]): r for r in site.services.virtual_site.landmark_records()}
    lms = site.client.get("/api/v1/landmarks", headers=site.h("viewer")).json()
    assert {lm["id"] for lm in lms} == set(truth)
    for lm in lms:
        assert lm["radio"] == truth[lm["id"]]["radio"]
    assert _wait(lambda: all(r.frames > 5 for r in site.services.robots.runners()), 30)


def test_led_command_switches_the_virtual_landmark(site: Api) -> None:
    c, h = site.client, site.h("operator")
    world = site.services.virtual_site.world
    r = c.post("/api/v1/landmarks/105/led", json={"on": False}, headers=h)
    assert r.status_code == 200, r.text
    assert 105 not in r.json()["lit"] or r.json()["all_lit"] is False
    assert 105 not in world.lit_ids()
    r = c.post("/api/v1/landmarks/105/led", json={"on": True}, headers=h)
    assert r.status_code == 200 and 105 in world.lit_ids()


def test_unanswering_radio_is_504_naming_the_landmark_and_server_carries_on(site: Api) -> None:
    c = site.client
    body = {"id": 999, "x": 20.0, "y": 20.0, "z": 2.5, "radio": "0013A200DEADBEEF"}
    assert c.post("/api/v1/landmarks", json=body, headers=site.h("admin")).status_code == 201
    assert _wait(lambda: 999 in site.services.leds.gateway.landmarks, 5)
    r = c.post("/api/v1/landmarks/999/led", json={"on": True}, headers=site.h("operator"))
    assert r.status_code == 504 and "landmark 999" in r.json()["detail"]
    assert c.get("/healthz").json()["status"] == "ok"
    assert c.delete("/api/v1/landmarks/999", headers=site.h("admin")).status_code == 204


def test_battery_refresh_stores_a_reading(site: Api) -> None:
    c = site.client
    r = c.get("/api/v1/landmarks/101/battery?refresh=true", headers=site.h("operator"))
    assert r.status_code == 200, r.text
    body = r.json()
    assert 2000 < body["supply_mv"] < 3400 and len(body["history"]) == 1
    assert 0 <= body["percent"] <= 100
    again = c.get("/api/v1/landmarks/101/battery", headers=site.h("viewer")).json()
    assert again["history"] == body["history"]


def test_discover_lists_no_radio_already_in_the_map(site: Api) -> None:
    r = site.client.post("/api/v1/radio/discover", headers=site.h("operator"))
    assert r.status_code == 200
    known = {lm.radio for lm in site.services.map.list()}
    assert all(d["address"] not in known for d in r.json())


def test_recording_is_readable_by_replay(site: Api) -> None:
    c, h = site.client, site.h("operator")
    r = c.post("/api/v1/robots/r2/recording/start", headers=h)
    assert r.status_code == 200 and r.json()["recording"] is True
    frames0 = site.services.robots.get("r2").frames
    assert _wait(lambda: site.services.robots.get("r2").frames > frames0 + 10, 30)
    r = c.post("/api/v1/robots/r2/recording/stop", headers=h)
    rec = read_recording(Path(r.json()["path"]))
    assert len(rec.frames) >= 10
    assert len(rec.landmark_map) == len(site.services.map.list())


def test_a_recording_does_not_start_on_a_nearly_full_disk(site: Api) -> None:
    runner = site.services.robots.get("r3")
    kept = runner.recording_limits
    runner.recording_limits = dataclasses.replace(kept, min_free_bytes=1 << 62)
    try:
        r = site.client.post("/api/v1/robots/r3/recording/start", headers=site.h("operator"))
    finally:
        runner.recording_limits = kept
    assert r.status_code == 507 and "MB free" in r.json()["detail"]
    assert runner.recorder is None


def test_an_operator_saves_a_black_box_listed_with_its_trigger(site: Api) -> None:
    c, h = site.client, site.h("operator")
    assert _wait(lambda: site.services.robots.get("r2").frames > 20, 30)
    r = c.post("/api/v1/robots/r2/black-box", headers=h)
    assert r.status_code == 201, r.text
    saved = r.json()
    assert (saved["robot"], saved["trigger"]) == ("r2", "operator") and saved["bytes"] > 0
    rec = read_recording(Path(saved["path"]))  # an ordinary recording: irloc replay reads it
    assert len(rec.frames) >= 10 and len(rec.landmark_map) == len(site.services.map.list())
    listed = c.get("/api/v1/robots/r2/black-boxes", headers=site.h("viewer")).json()
    assert saved in listed
    among = c.get("/api/v1/recordings?robot=r2", headers=site.h("viewer")).json()
    assert {"name": Path(saved["path"]).name, "trigger": "black_box_operator"} in [
        {k: r[k] for k in ("name", "trigger")} for r in among
    ]  # among the robot's recordings, with its trigger
    assert c.get("/api/v1/robots/r9/black-boxes", headers=site.h("viewer")).status_code == 404
    assert c.post("/api/v1/robots/r2/black-box", headers=site.h("viewer")).status_code == 403


def test_every_robot_localizes_near_the_truth_and_never_far_from_it(site: Api) -> None:
    """End to end: virtual cameras -> localizers sharing the LEDs -> pose bus -> API. Every
    robot gets a fix within a few centimetres of the truth at its frame's time, and no pose
    in landmark mode is ever far from it (a misidentified landmark would show here)."""
    sim = site.services.virtual_site
    names = set(sim.robot_names)
    good: set[str] = set()
    worst = 0.0
    with site.services.robots.subscribe_poses(maxsize=100_000) as sub:
        deadline = time.time() + 90
        while good != names and time.time() < deadline:
            time.sleep(0.2)
            for u in sub.drain():
                truth = sim.true_pose_at(u.robot, u.t_ns)
                if u.mode != "landmark" or u.x is None or u.y is None or truth is None:
                    continue
                err = float(np.hypot(u.x - truth[0], u.y - truth[1]))
                worst = max(worst, err)
                if err < 0.03:
                    good.add(u.robot)
    assert good == names
    assert worst < 0.10
    runner = site.services.robots.get("r1")
    upd = runner.latest  # before the request: the API may only return this pose or a newer one
    pose = site.client.get("/api/v1/robots/r1/pose", headers=site.h("viewer")).json()
    assert upd is not None and pose["t_ns"] >= upd.t_ns
    assert pose["mode"] in ("landmark", "dead_reckoning", "lost", "identifying")
    assert pose["age_s"] >= 0 and len(pose["covariance"]) == 3
    assert 0.0 <= pose["quality"] <= 1.0 and pose["deviation_m"] > 0
    assert (pose["reason"] is None) == (pose["mode"] == "landmark")


def test_relocalize_sends_the_robot_back_to_identifying(site: Api) -> None:
    deadline = time.monotonic() + 60
    while site.services.robots.mode("r1") != "landmark" and time.monotonic() < deadline:
        time.sleep(0.1)
    r = site.client.post("/api/v1/robots/r1/relocalize", headers=site.h("operator"))
    assert r.status_code == 202 and r.json()["mode"] in ("identifying", "lost")
    # its last (tight) pose is no longer served as current, and the site says why
    pose = site.client.get("/api/v1/robots/r1/pose", headers=site.h("viewer")).json()
    if pose["mode"] in ("identifying", "lost"):  # (it may have identified already)
        assert pose["stale"] is True and pose["x"] is None and pose["covariance"] is None
    events: list[dict[str, object]] = []
    while time.monotonic() < deadline + 10:
        events = site.client.get("/api/v1/events", headers=site.h("viewer")).json()
        if any(e["kind"] == "robot_identifying" and e["robot"] == "r1" for e in events):
            break
        time.sleep(0.1)
    assert any(e["kind"] == "robot_identifying" and e["robot"] == "r1" for e in events), events
    x, y, theta = site.services.virtual_site.true_pose("r1")
    r = site.client.post(
        "/api/v1/robots/r1/relocalize",
        json={"x": x, "y": y, "theta": theta},
        headers=site.h("operator"),
    )
    assert r.status_code == 202
    bad = site.client.post(
        "/api/v1/robots/r1/relocalize", json={"x": 1e9, "y": 0}, headers=site.h("operator")
    )
    assert bad.status_code == 422 and "x" in bad.text


def test_metrics_count_poses_per_robot(site: Api) -> None:
    text = site.client.get("/api/v1/metrics", headers=site.h("viewer")).text
    frames = {
        line.split('"')[1]: float(line.split()[-1])
        for line in text.splitlines()
        if line.startswith("irloc_frames_total{")
    }
    assert set(frames) == {"r1", "r2", "r3"} and min(frames.values()) > 0


def test_pose_ws_filtered_on_an_unknown_robot_is_told_so(site: Api) -> None:
    """A filter that matches no robot of the site would stay silent forever: closed with
    1008, naming it and the site's robots."""
    from starlette.websockets import WebSocketDisconnect

    url = f"/api/v1/poses/ws?robot=r1&robot=nobody&token={site.keys['viewer']}"
    with pytest.raises(WebSocketDisconnect) as exc, site.client.websocket_connect(url) as ws:
        ws.receive_text()
    assert exc.value.code == 1008 and "nobody" in exc.value.reason and "r2" in exc.value.reason
