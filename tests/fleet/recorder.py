"""A plain MQTT subscriber for tests: every message of a topic filter, with receipt times."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import paho.mqtt.client as mqtt


@dataclass(frozen=True)
class Received:
    topic: str
    payload: bytes
    retain: bool
    t_mono: float


class Recorder:
    """Subscribe to `topic_filter` on the broker at 127.0.0.1:`port` (paho's own thread)."""

    def __init__(self, port: int, topic_filter: str = "#") -> None:
        self.messages: list[Received] = []
        self._lock = threading.Lock()
        self._filter = topic_filter
        self._subscribed = threading.Event()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
        self.client.on_message = self._on_message
        self.client.on_connect = self._on_connect
        self.client.on_subscribe = lambda *a: self._subscribed.set()
        self.client.connect("127.0.0.1", port, keepalive=5)
        self.client.loop_start()
        if not self._subscribed.wait(5.0):
            raise TimeoutError(f"no subscription to {topic_filter} within 5 s")

    def _on_connect(self, client: mqtt.Client, *args: object) -> None:
        client.subscribe(self._filter, qos=1)

    def _on_message(self, client: mqtt.Client, userdata: object, msg: mqtt.MQTTMessage) -> None:
        with self._lock:
            self.messages.append(
                Received(msg.topic, bytes(msg.payload), msg.retain, time.monotonic())
            )

    def on(self, topic: str) -> list[Received]:
        with self._lock:
            return [m for m in self.messages if m.topic == topic]

    def wait_for(self, topic: str, pred: object = None, timeout_s: float = 5.0) -> Received:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for m in self.on(topic):
                if pred is None or pred(m):  # type: ignore[operator]
                    return m
            time.sleep(0.01)
        raise TimeoutError(f"nothing on {topic} within {timeout_s} s")

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()
