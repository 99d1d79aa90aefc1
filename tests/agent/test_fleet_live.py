"""The fleet shape end to end with a real Mosquitto: the site server in this process
(`--mqtt`, the virtual site without its robots), robot agents as separate processes
(`irloc agent --sim`), a plain subscriber watching the broker."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fleet.payloads import AgentStatus, LedStateMessage, MapMessage
from fleet.topics import SiteTopics, vda_topic
from tests.fleet.mosquitto import Mosquitto, mosquitto_binary
from tests.fleet.recorder import Recorder
from tests.fleet.vda import validate_vda
from tests.server.conftest import Api, start_api
from tests.server.test_reliability_metrics import scrape

pytestmark = pytest.mark.skipif(
    mosquitto_binary() is None,
    reason="Debian's mosquitto is not installed (apt-get install mosquitto; scripts/test.sh "
    "installs it when run as root)",
)
ROOT = Path(__file__).resolve().parents[2]
TOPICS = SiteTopics("default")
AGENTS = ("a1", "a2")
SKEW_S = 0.2
"""a2's wall clock is this far ahead (an agent without chrony)."""


@dataclass
class Fleet:
    broker: Mosquitto
    api: Api
    watch: Recorder
    agents: dict[str, subprocess.Popen[bytes]]
    truth: dict[str, Path]


def wait_until(pred: Callable[[], object], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return
        time.sleep(0.05)
    raise AssertionError(f"not within {timeout_s} s: {what}")


def _agent(
    broker: Mosquitto, name: str, robot: str, truth: Path, *extra: str
) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "irloc", "agent", "--mqtt", broker.url, "--name", name,
           "--robot", robot, "--sim", "--truth-csv", str(truth), "--log-level", "warning",
           *extra]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(cmd, env=env, cwd=ROOT)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    tmp = tmp_path_factory.mktemp("fleet")
    with Mosquitto() as broker:
        watch = Recorder(broker.port)
        truth = {"a1": tmp / "a1.csv", "a2": tmp / "a2.csv"}
        agents = {
            "a1": _agent(broker, "a1", "r1", truth["a1"]),
            "a2": _agent(broker, "a2", "r2", truth["a2"], "--light", "--clock-skew", str(SKEW_S)),
        }
        try:
            admitted = list(AGENTS)  # an open broker: the agents are admitted by name
            for api in start_api(tmp, mqtt_url=broker.url, sim_robots=False, mqtt_agents=admitted):
                yield Fleet(broker, api, watch, agents, truth)
        finally:
            for p in agents.values():
                if p.poll() is None:
                    p.terminate()
                    p.wait(10)
            watch.close()


def robots(f: Fleet) -> dict[str, dict[str, object]]:
    r = f.api.client.get("/api/v1/robots", headers=f.api.h("viewer"))
    assert r.status_code == 200
    return {x["name"]: x for x in r.json()}


def ws_connect(f: Fleet, robot: str) -> Any:
    return f.api.client.websocket_connect(
        f"/api/v1/poses/ws?robot={robot}", headers=f.api.h("viewer")
    )


def landmark_errors(path: Path) -> np.ndarray:
    """Position errors (m) of the agent's poses in landmark mode against the truth."""
    rows = [ln.split(",") for ln in path.read_text().splitlines() if ",landmark," in ln]
    a = np.array([[float(v) for v in r[2:]] for r in rows])
    return np.hypot(a[:, 0] - a[:, 3], a[:, 1] - a[:, 4])


def test_agents_localize_on_the_sites_leds_and_appear_as_robots(fleet: Fleet) -> None:
    wait_until(
        lambda: (
            {n: r["mode"] for n, r in robots(fleet).items()} == {"a1": "landmark", "a2": "landmark"}
        ),
        30.0,
        "both agents localized",
    )
    got = robots(fleet)
    for name in ("a1", "a2"):
        assert got[name]["source"] == "agent" and got[name]["connected"] is True
    # they identified by asking the site's gateway for LED switches
    leds = fleet.api.services.leds.coordinator
    assert leds.requests >= 2 and leds.applied >= 2
    # a2's clock runs 0.2 s ahead: measured (server minus agent), reported, warned about
    wait_until(lambda: robots(fleet)["a2"]["clock_offset_s"] is not None, 10.0, "a2 clock")
    a2 = robots(fleet)["a2"]
    # the measured offset is the skew to within the exchange's own error bound
    assert abs(a2["clock_offset_s"] + SKEW_S) <= a2["clock_error_s"] + 1e-4  # type: ignore[operator]
    assert a2["clock_error_s"] < 0.05  # type: ignore[operator]
    assert a2["clock_ok"] is False and robots(fleet)["a1"]["clock_ok"] is True
    a1 = robots(fleet)["a1"]  # same machine: the true offset is 0, within the error bound
    assert abs(a1["clock_offset_s"]) <= a1["clock_error_s"] + 1e-4  # type: ignore[operator]
    kinds = [(e.kind, e.robot) for e in fleet.api.services.events.recent(100)]
    assert ("clock_offset", "a2") in kinds and ("robot_connected", "a1") in kinds
    # poses on the REST API, the WebSocket stream, and right against the simulated truth
    r = fleet.api.client.get("/api/v1/robots/a1/pose", headers=fleet.api.h("viewer"))
    assert r.json()["x"] is not None and len(r.json()["covariance"]) == 3
    with fleet.api.client.websocket_connect(
        "/api/v1/poses/ws?robot=a2", headers=fleet.api.h("viewer")
    ) as ws:
        batch = json.loads(ws.receive_text())
    assert {p["robot"] for p in batch} == {"a2"} and batch[-1]["x"] is not None
    # an agent's poses name the floor and the map version it localizes on
    version = fleet.api.services.map_versions.version("0")
    assert (batch[-1]["floor"], batch[-1]["map_version"]) == ("0", version) and version >= 1
    time.sleep(1.0)
    for name in ("a1", "a2"):
        err = landmark_errors(fleet.truth[name])
        assert len(err) >= 5, name
        assert np.median(err) < 0.03 and err.max() < 0.15, (name, np.median(err), err.max())


def test_metrics_count_the_fleet_link(fleet: Fleet) -> None:
    """/metrics with the MQTT bridge running: its connection and message counters, and the
    refusals its guard keeps (admitted agents by name: none refused here)."""
    wait_until(lambda: "a1" in fleet.api.services.robots.names(), 30.0, "a1 joined")
    got = scrape(fleet.api)
    assert got[("irloc_mqtt_connects_total", ())] >= 1
    assert got[("irloc_mqtt_received_total", ())] > 0
    for name in ("led_requests_refused", "foreign_maps", "poses_outside"):
        assert got[(f"irloc_mqtt_{name}_total", ())] == 0, name
    assert got[("irloc_mqtt_agents_refused", ())] == 0


def test_vda5050_messages_validate_against_the_official_schemas(fleet: Fleet) -> None:
    wait_until(
        lambda: len(fleet.watch.on(vda_topic("irloc", "a1", "visualization"))) >= 2, 10, "vis"
    )
    for name in ("a1", "a2"):
        vis = fleet.watch.on(vda_topic("irloc", name, "visualization"))
        conn = fleet.watch.on(vda_topic("irloc", name, "connection"))
        for m in vis:
            validate_vda("visualization", json.loads(m.payload))
        for m in conn:
            validate_vda("connection", json.loads(m.payload))
        last = json.loads(vis[-1].payload)
        assert last["agvPosition"]["positionInitialized"] is True
        assert json.loads(conn[-1].payload)["connectionState"] == "ONLINE"
        headers = [json.loads(m.payload)["headerId"] for m in vis]
        assert headers == sorted(headers) and len(set(headers)) == len(headers)


def test_a_broker_restart_heals_by_itself(fleet: Fleet) -> None:
    services = fleet.api.services
    bridge = fleet.api.client.app.state.mqtt_bridge  # type: ignore[attr-defined]
    connects = bridge.connects
    with fleet.api.client.websocket_connect(
        "/api/v1/poses/ws?robot=a1", headers=fleet.api.h("viewer")
    ) as ws:
        json.loads(ws.receive_text())
        fleet.watch.close()
        fleet.broker.restart(down_s=1.0)
        t_back = time.time_ns()
        poses = {n: services.robots.get(n).poses for n in ("a1", "a2")}
        # the server reconnects, both agents reconnect and their poses flow again
        wait_until(lambda: bridge.connects == connects + 1, 10.0, "server reconnected")
        wait_until(
            lambda: all(services.robots.get(n).poses > poses[n] + 5 for n in poses),
            10.0,
            "poses flowing again",
        )
        # the WebSocket opened before the restart carries poses computed after it
        while True:
            batch = json.loads(ws.receive_text())
            if any(p["computed_wall_ns"] > t_back for p in batch):
                break
    assert {n: r["connected"] for n, r in robots(fleet).items()} == {"a1": True, "a2": True}
    # the new broker (no persistence) holds the map and the LED state again (retained), and
    # the retained LED state is the gateway's own: nothing left half-applied
    fleet.watch = Recorder(fleet.broker.port)
    lmap = MapMessage.model_validate_json(fleet.watch.wait_for(TOPICS.map).payload)
    assert len(lmap.landmarks) == len(services.map.list())
    wait_until(lambda: not services.leds.coordinator.waiting, 5.0, "LED queue drained")

    def retained_is_the_gateways() -> bool:
        """The latest LED state on the broker is the one in force (every LED, or the
        schedule's set), not a switch left in flight."""
        msgs = fleet.watch.on(TOPICS.leds)
        state = services.leds.gateway.leds
        if not msgs or state is None or state.changing:
            return False
        m = LedStateMessage.model_validate_json(msgs[-1].payload)
        return (m.all_lit, set(m.lit), set(m.changing)) == (state.all_lit, set(state.lit), set())

    wait_until(retained_is_the_gateways, 5.0, "retained LED state the gateway's, settled")
    assert all(robots(fleet)[n]["mode"] == "landmark" for n in ("a1", "a2"))


def test_kill_9_gives_connection_broken_and_an_event_within_2_s(fleet: Fleet) -> None:
    topic = vda_topic("irloc", "a2", "connection")
    events = fleet.api.services.events
    before = max((e.id for e in events.recent(20)), default=0)  # not an earlier test's
    t0 = time.monotonic()
    fleet.agents["a2"].send_signal(signal.SIGKILL)
    fleet.agents["a2"].wait(5)
    m = fleet.watch.wait_for(
        topic, lambda m: json.loads(m.payload)["connectionState"] == "CONNECTIONBROKEN", 2.0
    )
    assert m.t_mono - t0 < 2.0
    validate_vda("connection", json.loads(m.payload))
    wait_until(
        lambda: any(
            e.kind == "robot_disconnected" and e.robot == "a2" and e.id > before
            for e in events.recent(20)
        ),
        max(0.05, 2.0 - (time.monotonic() - t0)),
        "robot_disconnected event for a2",
    )
    assert robots(fleet)["a2"]["connected"] is False
    assert robots(fleet)["a1"]["connected"] is True


def test_an_agent_holding_an_old_map_version_is_told(fleet: Fleet) -> None:
    """A status naming an older version of its floor's map than the server's: an event
    `agent_map_outdated` and the current map published again (retained)."""
    wait_until(lambda: "a1" in robots(fleet), 30.0, "a1 registered")
    status = AgentStatus(source="sim", camera={}, wheel_base=0.36, max_speed=1.0,
                         mode="landmark", map_id="old", map_version=0)  # fmt: skip
    fleet.watch.client.publish(TOPICS.status("a1"), status.encode(), qos=1)
    wait_until(
        lambda: any(e.kind == "agent_map_outdated" and e.robot == "a1"
                    for e in fleet.api.services.events.recent(50)),
        10.0,
        "agent_map_outdated for a1",
    )  # fmt: skip
    ev = next(e for e in fleet.api.services.events.recent(50) if e.kind == "agent_map_outdated")
    assert ev.data["held"] == 0 and ev.data["current"] == fleet.api.services.map_versions.version(
        "0"
    )
    maps = fleet.watch.on(TOPICS.map)
    assert json.loads(maps[-1].payload)["version"] == ev.data["current"]
