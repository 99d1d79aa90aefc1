"""Alerts end to end: a robot lost and found reaches the SSE stream, a real Mosquitto
(retained while active, cleared when resolved) and a real HTTP webhook receiver, and the
API lists it while active and in the history after."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import pytest

from fleet.topics import SiteTopics
from tests.fleet.mosquitto import Mosquitto, mosquitto_binary
from tests.fleet.recorder import Recorder
from tests.live.still_robot import set_mode, still_runner
from tests.live.webhook_receiver import Receiver
from tests.server.conftest import Api, start_api

T = SiteTopics("default")
FAST = {
    "alert_raise_after_s": 0.0,
    "alert_clear_after_s": 0.0,
    "alert_min_interval_s": 0.0,
    "alert_stale_s": 3600.0,
}


def wait_until(pred: Callable[[], object], what: str, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() > deadline:
            raise AssertionError(f"not within {timeout_s} s: {what}")
        time.sleep(0.05)


@pytest.mark.skipif(mosquitto_binary() is None, reason="needs Debian's mosquitto")
def test_a_lost_robot_is_raised_and_resolved_on_every_channel(tmp_path: Path) -> None:
    topic = T.alert("robot_lost", "r9")
    ghost = T.alert("robot_lost", "ghost")  # retained by a previous run that ended mid-alert
    with Mosquitto() as broker, Receiver() as rx:
        old = Recorder(broker.port, "unused/#")
        old.client.publish(ghost, b'{"state":"raised"}', qos=1, retain=True).wait_for_publish(5)
        old.close()
        for api in start_api(tmp_path, site_enabled=False, mqtt_url=broker.url,
                             alert_webhook_urls=[rx.url], **FAST):  # fmt: skip
            bridge: Any = api.client.app.state.mqtt_bridge  # type: ignore[attr-defined]
            wait_until(partial(_connected, bridge), "the bridge connected")
            mqtt = Recorder(broker.port, T.alerts_wildcard)
            text = _lose_and_find(api, rx)
            mqtt.wait_for(topic, lambda m: m.payload == b"" and m.retain is False)
            history = api.client.get("/api/v1/alerts/history", headers=api.h("viewer")).json()
            assert api.client.get("/api/v1/alerts", headers=api.h("viewer")).json() == []
            mqtt.close()
            late = Recorder(broker.port, T.alerts_wildcard)  # what a new subscriber finds
            time.sleep(0.3)
            assert [m for m in late.messages if m.payload] == []  # the ghost too: cleared
            late.close()
    sse = [json.loads(line[6:]) for line in text.splitlines() if line.startswith("data: ")]
    assert [(e["kind"], e["data"]["key"]) for e in sse] == [
        ("alert_raised", "robot_lost:r9"),
        ("alert_resolved", "robot_lost:r9"),
    ]
    assert sse[1]["message"] == "resolved: robot r9 is lost"
    on_mqtt = [json.loads(m.payload) for m in mqtt.on(topic) if m.payload]
    assert [(m["state"], m["active"]) for m in on_mqtt] == [("raised", True), ("resolved", False)]
    hooks = rx.wait_for(2)
    assert [(b["state"], b["kind"], b["robot"]) for b in hooks] == [
        ("raised", "robot_lost", "r9"), ("resolved", "robot_lost", "r9"),
    ]  # fmt: skip
    assert hooks[0]["text"] == "[irloc default] RAISED critical: robot r9 is lost"
    assert [(h["state"], h["event_id"] > 0) for h in history] == [
        ("resolved", True), ("raised", True),
    ]  # fmt: skip
    assert history[0]["resolved_at"] is not None and history[1]["seq"] < history[0]["seq"]


def _connected(bridge: Any) -> bool:
    return bool(bridge.connects >= 1)


def _lose_and_find(api: Api, rx: Receiver) -> str:
    """Robot r9 lost until the alert is listed, then found; the SSE stream's text."""
    c, h = api.client, api.h("viewer")
    runner = still_runner("r9", "lost")
    with c.stream("GET", "/api/v1/events/stream?limit=2", headers=h) as stream:
        api.services.robots.add(runner)
        wait_until(lambda: c.get("/api/v1/alerts", headers=h).json() != [], "alert listed")
        (listed,) = c.get("/api/v1/alerts", headers=h).json()
        assert listed["key"] == "robot_lost:r9" and listed["severity"] == "critical"
        assert listed["active"] and listed["robot"] == "r9"
        rx.wait_for(1)
        set_mode(runner, "landmark", 10**9)
        return "".join(stream.iter_text())


def test_the_webhook_test_message_and_who_may_send_it(tmp_path: Path) -> None:
    with Receiver() as rx:
        for api in start_api(tmp_path, site_enabled=False, alert_webhook_urls=[rx.url]):
            r = api.client.post("/api/v1/alerts/test", headers=api.h("viewer"))
            assert r.status_code == 403
            r = api.client.post("/api/v1/alerts/test", headers=api.h("operator"))
            assert r.status_code == 200 and r.json()["urls"] == 1
            (body,) = rx.wait_for(1)
    assert body["state"] == "test" and "test message" in body["text"]


def test_a_webhook_url_that_is_not_http_is_refused() -> None:
    from live.settings import Settings

    with pytest.raises(ValueError, match="alert_webhook_urls: 'ftp://x' is not an http"):
        Settings(alert_webhook_urls=["ftp://x"])
