"""The site server on a broker open to anyone (no ACL) still bounds what a hostile client
can do: only admitted agents are registered (so only their LED requests count), a pose
outside the site is dropped and counted, a foreign map is replaced by the site's at once;
each is a `fleet_intrusion` event."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import paho.mqtt.client as mqtt
import pytest

from fleet.payloads import AgentStatus, MapMessage, PoseMessage
from fleet.topics import SiteTopics, vda_topic
from fleet.vda5050 import connection_message
from localizer.camera import sensor_from_camera
from sim.cameras import wide_angle_camera
from tests.fleet.mosquitto import Mosquitto, mosquitto_binary
from tests.server.conftest import Api, start_api

pytestmark = pytest.mark.skipif(mosquitto_binary() is None, reason="needs Debian's mosquitto")
T = SiteTopics("default")


def wait_until(pred: Callable[[], object], timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if pred():
            return
        time.sleep(0.05)
    raise AssertionError(f"not within {timeout_s} s: {what}")


class Client:
    """A plain paho client (the intruder, or a well-behaved agent)."""

    def __init__(self, port: int, name: str) -> None:
        self.seen: list[tuple[str, bytes, bool]] = []
        self.lock = threading.Lock()
        self.c = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=name)
        self.c.on_message = self._on
        self.c.connect("127.0.0.1", port)
        self.c.loop_start()

    def _on(self, _c: object, _u: object, m: mqtt.MQTTMessage) -> None:
        with self.lock:
            self.seen.append((m.topic, bytes(m.payload), bool(m.retain)))

    def pub(self, topic: str, payload: bytes, retain: bool = False) -> None:
        self.c.publish(topic, payload, qos=1, retain=retain).wait_for_publish(5)

    def arrive(self, robot: str) -> None:
        status = AgentStatus(source="sim", camera=sensor_from_camera(wide_angle_camera("fisheye")),
                             wheel_base=0.4, max_speed=1.0, mode="identifying")  # fmt: skip
        self.pub(T.status(robot), status.encode(), retain=True)
        online = connection_message(0, time.time_ns(), "irloc", robot, "ONLINE")
        self.pub(vda_topic("irloc", robot, "connection"), json.dumps(online).encode(), True)

    def close(self) -> None:
        self.c.loop_stop()
        self.c.disconnect()


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Api, int]]:
    tmp: Path = tmp_path_factory.mktemp("guard")
    with Mosquitto() as broker:
        settings = {"mqtt_url": broker.url, "sim_robots": False, "mqtt_agents": ["a1"]}
        for api in start_api(tmp, **settings):
            bridge = api.client.app.state.mqtt_bridge  # type: ignore[attr-defined]
            wait_until(lambda b=bridge: b.connects >= 1, 10, "the bridge connected")
            yield api, broker.port


def kinds(api: Api) -> list[tuple[str, str | None, str]]:
    return [(e.kind, e.robot, e.message) for e in api.services.events.recent(50)]


def test_only_admitted_agents_are_registered(site: tuple[Api, int]) -> None:
    api, port = site
    c = Client(port, "intruder")
    try:
        c.arrive("a1")
        c.arrive("phantom")
        wait_until(lambda: "a1" in api.services.robots.names(), 10, "a1 registered")
        wait_until(lambda: any(k == "fleet_intrusion" and r == "phantom" for k, r, _ in kinds(api)),
                   5, "phantom refused")  # fmt: skip
        assert "phantom" not in api.services.robots.names()
        msg = next(m for k, r, m in kinds(api) if r == "phantom")
        assert "mqtt_agents" in msg
    finally:
        c.close()


def test_a_pose_outside_the_site_is_dropped_and_counted(site: tuple[Api, int]) -> None:
    api, port = site
    bridge = api.client.app.state.mqtt_bridge  # type: ignore[attr-defined]
    c = Client(port, "a1-again")
    try:
        c.arrive("a1")
        wait_until(lambda: "a1" in api.services.robots.names(), 10, "a1 registered")
        far = PoseMessage(seq=1, t_ns=time.time_ns(), wall_ns=time.time_ns(), mode="landmark",
                          x=1e300, y=0.0, theta=0.0)  # fmt: skip
        c.pub(T.pose("a1"), far.encode())
        wait_until(lambda: bridge.guard.poses_outside >= 1, 5, "the far pose counted")
        r = api.client.get("/api/v1/robots/a1/pose", headers=api.h("viewer"))
        assert r.status_code in (200, 404) and (r.status_code == 404 or r.json()["x"] != 1e300)
        assert any(k == "fleet_intrusion" and "outside the site" in m for k, _, m in kinds(api))
    finally:
        c.close()


def test_a_foreign_map_is_replaced_by_the_sites(site: tuple[Api, int]) -> None:
    api, port = site
    bridge = api.client.app.state.mqtt_bridge  # type: ignore[attr-defined]
    ours = bridge.map_message()
    fake = MapMessage(map_id="fake", landmarks=[]).encode()
    c = Client(port, "mapper")
    try:
        c.pub(T.map, fake, retain=True)
        wait_until(lambda: bridge.guard.foreign_maps >= 1, 5, "the foreign map seen")
    finally:
        c.close()
    late = Client(port, "late-agent")  # an agent arriving now gets the retained map
    try:
        late.c.subscribe(T.map, qos=1)
        wait_until(lambda: late.seen, 5, "the retained map")
        assert late.seen[-1][1] == ours
    finally:
        late.close()


def test_on_an_open_broker_without_a_list_led_requests_are_not_served(
    site: tuple[Api, int],
) -> None:
    api, port = site
    bridge = api.client.app.state.mqtt_bridge  # type: ignore[attr-defined]
    coordinator = api.services.leds.coordinator
    c = Client(port, "a1-leds")
    kept = bridge.guard.admitted
    try:
        c.arrive("a1")
        wait_until(lambda: "a1" in api.services.robots.names(), 10, "a1 registered")
        bridge.guard.admitted = ()  # as with no mqtt_agents and no broker login
        before = coordinator.requests
        c.pub(T.led_request("a1"), json.dumps({"lit": [], "all_lit": True, "dark": [101]}).encode())
        wait_until(lambda: bridge.guard.led_requests_refused >= 1, 5, "the request refused")
        assert coordinator.requests == before
        wait_until(  # (events are stored by the site's event writer, on its own thread)
            lambda: any("not served" in m for k, _, m in kinds(api) if k == "fleet_intrusion"),
            5,
            "a fleet_intrusion event saying the request was not served",
        )
    finally:
        bridge.guard.admitted = kept
        c.close()
